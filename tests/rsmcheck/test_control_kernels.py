"""The compiled per-sample arithmetic (rsmcheck.driver.control_kernels) against the Python
formulas it stands for: the floating-point blocks (remainder, hypot, the rotation
products) to the bit against references that round the same on every CPU (CPython's
floats and math, exact rationals); the programme controller in every reference and base
mode (the Python law below is the controller's former per-sample code: measure, eqs. 13–14
on the references' `__call__`, rate filter, saturation) and the runner's supervisor to the
round-off of their terms, since the Python formulas' numpy products round as the CPU's
OpenBLAS kernels and SIMD loops make them; and the laws on analytic cases."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from rsmcheck.core.cases import ArmGains, BaseGains, ControllerSpec
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.geometry import rot
from rsmcheck.core.params import Params
from rsmcheck.core.programme import ArmCommand, Segment, TargetCommand
from rsmcheck.driver import control_kernels as ck
from rsmcheck.driver import runner
from rsmcheck.driver.controllers import (
    ArmModel,
    ProgrammeController,
    base_pd,
    jacobian_transpose,
    measure,
    retrograde_attitude,
    saturate,
    wrap_near,
)

P = Params()
RNG = np.random.default_rng(20210613)
Q0 = np.radians([60.0, -120.0, 60.0, -60.0, 120.0, -60.0])


def bits(a) -> list[int]:
    """The IEEE bit patterns of `a` (equality to the bit, the sign of zero included)."""
    return np.asarray(a, np.float64).reshape(-1).view(np.int64).tolist()


#: the unit round-off of float64 (half the spacing of doubles at 1)
U = np.finfo(float).eps / 2


def assert_roundoff(a, b, scale, what=None):
    """|a − b| ≤ 4u · scale elementwise: equal to round-off, where `scale` is the size of
    the terms a result was formed from (not the result, which may have cancelled).  numpy
    rounds its products and norms as the CPU it runs on makes it (OpenBLAS's kernel family,
    its SIMD dispatch), so the Python formulas that use it are compared with the kernels to
    round-off, never to the bit; the kernels themselves are pinned (fma where written, plain
    products elsewhere) and compared to the bit with exact references below."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    bound = 4.0 * U * np.broadcast_to(np.asarray(scale, float), a.shape)
    assert np.all(np.abs(a - b) <= bound), (what, a - b, bound)


def exact_fma(a: float, b: float, c: float) -> float:
    """a·b + c rounded once, from exact rational arithmetic (IEEE's fused multiply-add on
    every CPU: `float(Fraction)` rounds correctly)."""
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def random_sensors(t: float, rng=RNG, orbit: bool = True, grasp=(1, 0)) -> Sensors:
    """A plausible sample: the nominal Z configurations moved by a few degrees, the end
    effectors a few mm off the rigid model's tips (link bending), a moving base and target."""
    q = Q0 + rng.normal(0.0, 0.05, 6)
    base = np.array([0.0, 0.0, 0.0]) + rng.normal(0.0, [0.05, 0.05, 0.2])
    c, s = math.cos(base[2]), math.sin(base[2])
    tips = [ArmModel(P, 1).pose(q[:3])[:2], ArmModel(P, 2).pose(q[3:])[:2]]
    ee = np.array([base[:2] + np.array([[c, -s], [s, c]]) @ e for e in tips]) + rng.normal(0.0, 3e-3, (2, 2))
    r = 7.078e6 * np.array([math.cos(t / 900.0), math.sin(t / 900.0)])
    v = 7504.0 * np.array([-math.sin(t / 900.0), math.cos(t / 900.0)])
    return Sensors(time=t, base_pose_I=base, base_rate_I=rng.normal(0.0, 0.01, 3), joint_angles=q,
                   joint_rates=rng.normal(0.0, 0.05, 6), joint_frame_angles=q.copy(),
                   joint_frame_rates=np.zeros(6), motor_angles=q.copy(), motor_rates=np.zeros(6),
                   ee_pos_I=ee, ee_vel_I=rng.normal(0.0, 0.02, (2, 2)),
                   target_pose_I=np.array([5.65, 0.1, 0.0]) + rng.normal(0.0, [0.05, 0.05, 0.3]),
                   target_rate_I=rng.normal(0.0, 0.01, 3), com_pos_B=np.array([3.0, rng.normal(0.0, 0.02)]),
                   wrist_angles=rng.normal(0.0, 0.1, 2), grasp_state=np.array(grasp),
                   system_mass=918.94, orbit_r_I=r if orbit else np.zeros(2), orbit_v_I=v if orbit else np.zeros(2))


class PythonLaw:
    """The programme controller's laws in Python, as `ProgrammeController.__call__` computed
    them before they were compiled: the reference the kernel must equal to round-off."""

    def __init__(self, ctl: ProgrammeController, rates: np.ndarray):
        self.ctl = ctl
        self.rates = np.asarray(rates, float).copy()
        self.t_prev: float | None = None

    def __call__(self, s: Sensors) -> Inputs:
        ctl = self.ctl
        m = measure(s, ctl.arms, ctl.spec.feedback)
        t = s.time
        dt = ctl.period if self.t_prev is None or t <= self.t_prev else t - self.t_prev
        self.t_prev = t
        fc = ctl.spec.rate_filter_hz
        alpha = 1.0 - math.exp(-2.0 * math.pi * fc * dt) if fc > 0 else 1.0
        self.rates += alpha * (np.asarray(s.joint_rates, float) - self.rates)
        tau: list[float] = []
        q = s.joint_angles.tolist()
        rates = self.rates.tolist()
        for k in range(2):
            ref = ctl.refs[k]
            if ref is None:
                tau += ctl.open_loop[k].tolist()
                continue
            err = (m.ee_B[k] - ref(t, m)).tolist()
            err[2] = math.remainder(err[2], 2.0 * math.pi)
            tau += jacobian_transpose(ctl.arms[k].pins_list(q[3 * k:3 * k + 3]), err, rates[3 * k:3 * k + 3],
                                      ctl.kp[k], ctl.kd[k])
        tau_B = 0.0
        b = ctl.spec.base
        if ctl.base_mode != "off":
            if ctl.base_mode == "retrograde":
                goal, rate = retrograde_attitude(s.orbit_r_I, s.orbit_v_I, ctl.params.orbit.mu)
                goal = wrap_near(goal, s.base_pose_I[2])
            else:
                goal, rate = ctl.base_goal, 0.0
            tau_B = base_pd(s.base_pose_I[2], s.base_rate_I[2], goal, rate, b.kp, b.kd)
        return saturate(Inputs(tau_m=np.array(tau), tau_B=tau_B, thrust=ctl.thrust), ctl.params)


# ---------------------------------------------------------------------------------------
# floating-point blocks
# ---------------------------------------------------------------------------------------
def test_remainder_is_math_remainder():
    @ck.njit
    def rem(x, y):
        return ck._remainder(x, y)

    xs = np.concatenate([RNG.normal(0.0, 4.0, 20000), RNG.normal(0.0, 1e-9, 2000), np.arange(-20, 21) * math.pi,
                         np.arange(-20, 21) + 0.5, [0.0, -0.0, 1e300, -1e-300]])
    for y in (2.0 * math.pi, 1.0, 0.5, math.inf):
        for x in xs:
            assert bits(rem(float(x), y)) == bits(math.remainder(float(x), y))
    # where math.remainder raises (an infinite x, y = 0) or gets NaN: NaN
    assert all(math.isnan(rem(x, y)) for x, y in ((math.inf, 1.0), (1.0, 0.0), (math.nan, 1.0), (1.0, math.nan)))


def test_hypot_is_math_hypot():
    @ck.njit
    def hyp(a, b):
        return ck._hypot(a, b)

    xs = np.concatenate([RNG.normal(0.0, 7e6, (100000, 2)), RNG.normal(0.0, 1.0, (50000, 2)),
                         RNG.normal(0.0, 1e-160, (2000, 2)), RNG.normal(0.0, 1e150, (2000, 2))])
    xs[:1000, 1] *= 1e-9  # far apart in size
    bad = [(a, b) for a, b in xs if hyp(a, b) != math.hypot(a, b)]
    assert not bad
    assert hyp(0.0, 0.0) == 0.0 and hyp(-3.0, 0.0) == 3.0 and hyp(math.inf, math.nan) == math.inf


@pytest.mark.parametrize("transpose", [False, True])
def test_rotation_products_are_pinned_and_numpy_s_to_round_off(transpose):
    """A(a) v to the bit as fma(c, x, −s·y), fma(s, x, c·y) (exact rational references) and
    A(a)ᵀ v as the plain products (CPython's floats round each operation), on every CPU;
    numpy's rot(a) @ v and rot(a).T @ v equal them to round-off (OpenBLAS's SkylakeX
    kernels round rot(a).T @ v with an fma where its Haswell kernels do not)."""

    @ck.njit
    def prod(c, s, x, y):
        return ck._rot_t(c, s, x, y) if transpose else ck._rot(c, s, x, y)

    for a, x, y in RNG.normal(0.0, 3.0, (20000, 3)):
        c, s = math.cos(a), math.sin(a)
        got = prod(c, s, x, y)
        pinned = (c * x + s * y, -s * x + c * y) if transpose else (exact_fma(c, x, -s * y), exact_fma(s, x, c * y))
        assert bits(got) == bits(pinned)
        A = rot(a)
        assert_roundoff(got, (A.T if transpose else A) @ np.array([x, y]), abs(c * x) + abs(s * y) + abs(s * x)
                        + abs(c * y))


def test_retrograde_wrap_and_quintic_are_the_python_formulas():
    mu = P.orbit.mu
    for rx, ry, vx, vy, th in np.column_stack([RNG.normal(0.0, 7e6, (5000, 2)), RNG.normal(0.0, 7.5e3, (5000, 2)),
                                               RNG.normal(0.0, 10.0, 5000)]):
        assert bits(ck.retrograde_attitude(rx, ry, vx, vy, mu)) == bits(retrograde_attitude([rx, ry], [vx, vy], mu))
        goal = retrograde_attitude([rx, ry], [vx, vy], mu)[0]
        assert bits(ck.wrap_near(goal, th)) == bits(wrap_near(goal, th))
    assert ck.retrograde_attitude(7e6, 0.0, 0.0, 0.0, mu) == (0.0, 0.0)
    from rsmcheck.core.trajectories import quintic

    for t, t0, T in np.column_stack([RNG.uniform(-5.0, 25.0, 5000), RNG.uniform(0.0, 5.0, 5000),
                                     RNG.uniform(-1.0, 20.0, 5000)]):
        assert bits(ck.quintic_s(t, t0, T)) == bits(quintic(t, t0, T)[0])


# ---------------------------------------------------------------------------------------
# the programme controller
# ---------------------------------------------------------------------------------------
def _controller(feedback="measured", fc=0.0, base=BaseGains(100.0, 1000.0)) -> ProgrammeController:
    spec = ControllerSpec(kind="programme", gains="test", base=base, feedback=feedback, rate_filter_hz=fc,
                          arm1=ArmGains((3000.0, 2500.0, 900.0), (200.0, 150.0, 100.0)),
                          arm2=ArmGains((2000.0, 2000.0, 800.0), (180.0, 120.0, 60.0)))
    return ProgrammeController(spec, P, 1e-3)


SEGMENTS = [
    Segment(name="hold", duration=5.0),
    Segment(name="moves", duration=5.0, base="angle", base_angle_deg=3.0,
            arm1=ArmCommand(mode="move", to=(3.9, 0.9, 10.0), time=2.0),
            arm2=ArmCommand(mode="approach", point_T=(-0.35, -0.2), phi_deg=-20.0, time=3.0)),
    Segment(name="approach", duration=5.0, base="retrograde", arm1=ArmCommand(mode="freeze"),
            arm2=ArmCommand(mode="approach", point_T=(-0.35, -0.2), time=4.0)),
    Segment(name="carry", duration=5.0, base="retrograde", arm1=ArmCommand(mode="carry"),
            arm2=ArmCommand(mode="carry"), target=TargetCommand(mode="move", to=(5.9, 0.2, 15.0), time=3.0)),
    Segment(name="push", duration=5.0, base="freeze", arm1=ArmCommand(mode="carry"),
            arm2=ArmCommand(mode="torque", torques=(1.0, -200.0, 3.0)),
            target=TargetCommand(mode="push", by=(0.1, -0.05), time=2.0)),
    Segment(name="align", duration=50.0, base="off", thrust=True, arm1=ArmCommand(mode="carry"),
            arm2=ArmCommand(mode="off"),
            target=TargetCommand(mode="com_align", tolerance=1e-6, step_time=1.0, settle_time=0.5)),
    Segment(name="after", duration=5.0, base="hold", arm1=ArmCommand(mode="hold"), arm2=ArmCommand(mode="hold")),
]


#: the size of the terms of τ_m (eq. 14) in the test's sensors [N·m]: K_p (≤ 3 000) × the
#: positions the pose error is formed from (≤ 6 m, the base, target and arm tips) × a
#: Jacobian entry (≤ 5 m), and a few such terms summed
TAU_TERMS = 4 * 3000.0 * 6.0 * 5.0


@pytest.mark.parametrize("feedback, fc", [("measured", 0.0), ("kinematic", 0.0), ("measured", 25.0)])
def test_programme_controller_is_the_python_law(feedback, fc):
    """Every reference kind (fixed, move, approach, held on a fixed, quintic and COM-alignment
    target path, open loop) and base mode (goal, retrograde, off), the kinematic feedback,
    the rate filter, saturated torques, a capture's new reference: τ_B to the bit (both sides
    scalar arithmetic and libm), τ_m to round-off of its terms (the Python law's numpy
    products round as the CPU makes them).  The terms: K_p up to 3 000 times a pose error
    formed from positions of ≲ 6 m, through Jacobian entries of ≲ 5 m: TAU_TERMS."""
    ctl = _controller(feedback, fc)
    rng = np.random.default_rng(7)
    t = 0.0
    s = random_sensors(t, rng)
    ctl.start(s)
    law = PythonLaw(ctl, s.joint_rates)
    saturated = iterations = 0
    for seg in SEGMENTS:
        ctl.enter(seg, s)
        for k in range(40):
            s = random_sensors(t, rng)
            if seg.name == "approach" and k == 20:
                ctl.captured(2, s)
            u = ctl(s)
            expected = law(s)
            assert_roundoff(u.tau_m, expected.tau_m, TAU_TERMS, (seg.name, k))
            assert bits(u.tau_B) == bits(expected.tau_B) and u.thrust == expected.thrust
            saturated += int(np.any(np.abs(u.tau_m) == P.motor.torque_max))
            t += 0.05 if seg.name != "align" else 0.3
        if seg.name == "align":
            iterations = ctl.com_align.iterations
    assert saturated > 0  # the clipping was exercised
    assert iterations >= 2  # the COM alignment moved the target


def test_base_pd_at_a_chosen_error_eq_13():
    """τ_B = −k_p (θ − θ_des) − k_d θ̇ about a held attitude, saturated at 12 N·m."""
    ctl = _controller(base=BaseGains(100.0, 1000.0))
    s = random_sensors(0.0)
    ctl.start(s)
    ctl.enter(Segment(name="angle", duration=1.0, base="angle", base_angle_deg=0.0,
                      arm1=ArmCommand(mode="off"), arm2=ArmCommand(mode="off")), s)
    s = Sensors(**{**s.__dict__, "base_pose_I": np.array([0.0, 0.0, 0.01]), "base_rate_I": np.array([0.0, 0.0, -0.002])})
    u = ctl(s)
    assert u.tau_B == pytest.approx(-100.0 * 0.01 - 1000.0 * -0.002, rel=1e-15)
    assert u.tau_m.tolist() == [0.0] * 6
    s = Sensors(**{**s.__dict__, "base_rate_I": np.array([0.0, 0.0, 0.5])})
    assert ctl(s).tau_B == -P.actuators.torque_max


def test_jacobian_transpose_at_a_chosen_error_eq_14():
    """An arm held at its entry pose, the end effector measured δ = (1 mm, −2 mm) off and the
    joints at rest: τ = −J_EEᵀ K_p (δ, 0) with J_EE the rigid model's at the joint angles."""
    ctl = _controller()
    s = random_sensors(0.0)
    s = Sensors(**{**s.__dict__, "joint_rates": np.zeros(6)})
    ctl.start(s)
    ctl.enter(Segment(name="hold", duration=1.0), s)
    c, sn = math.cos(s.base_pose_I[2]), math.sin(s.base_pose_I[2])
    delta_B = np.array([1e-3, -2e-3])
    ee = s.ee_pos_I.copy()
    ee[0] += np.array([[c, -sn], [sn, c]]) @ delta_B
    u = ctl(Sensors(**{**s.__dict__, "ee_pos_I": ee}))
    jac = ArmModel(P, 1).jacobian(s.joint_angles[:3])
    assert u.tau_m[:3] == pytest.approx(-jac.T @ (np.array([3000.0, 2500.0, 900.0]) * [*delta_B, 0.0]), rel=1e-9)
    assert np.max(np.abs(u.tau_m[3:])) < 1e-9


# ---------------------------------------------------------------------------------------
# the runner's supervisor
# ---------------------------------------------------------------------------------------
def test_supervisor_and_capture_gap_are_the_numpy_formulas():
    rho = np.array([-0.35, -0.2])
    for n in range(2000):
        s = random_sensors(0.0, grasp=(n % 2, 1))
        lever = rot(s.target_pose_I[2]) @ rho
        p = s.target_pose_I[:2] + lever
        v = s.target_rate_I[:2] + s.target_rate_I[2] * np.array([-lever[1], lever[0]])
        arm = 1 + n % 2
        ok, gap, rel = runner.if_conditions(s, arm, rho, 0.05, 0.01)
        # the positions are ≲ 6 m, the velocities ≲ 0.1 m/s: the scale of their terms
        assert_roundoff([gap, rel], [np.linalg.norm(s.ee_pos_I[arm - 1] - p), np.linalg.norm(s.ee_vel_I[arm - 1] - v)],
                        [6.0, 0.1])
        assert ok == (gap < 0.05 and rel < 0.01)
        assert_roundoff(runner.capture_gap_B(s, arm, rho), rot(s.base_pose_I[2]).T @ (s.ee_pos_I[arm - 1] - p), 6.0)
        assert_roundoff(np.concatenate(runner.capture_point(s, rho)), np.concatenate([p, v]), [6.0, 6.0, 0.1, 0.1])
        out = np.zeros(4)
        ck.supervise(s.target_pose_I, s.target_rate_I, s.ee_pos_I, s.ee_vel_I, s.wrist_angles, s.grasp_state, 0,
                     rho, 0.05, out)
        assert out[:2].tolist() == [float(bool(s.grasp_state[k]) and abs(s.wrist_angles[k]) > 0.05) for k in range(2)]
        assert math.isnan(out[2]) and math.isnan(out[3])
