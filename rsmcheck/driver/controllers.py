"""Controllers: one implementation, used by every engine (docs/physics.md §6, paper Sect. 3).

A controller maps the `Sensors` of one sample to the `Inputs` held until the next one and
applies the saturations of Tables 3–4 (|τ_B| ≤ 12 N·m, |τ_m| ≤ 80 N·m).  The laws:

* base attitude, eq. (13):   τ_B = −k_p,B (θ_B − θ_B^des) − k_d,B (θ̇_B − θ̇_B^des)
* arms, eq. (14):            τ_m,j = −K_p,j J_EE,jᵀ e_EE,j − K_d,j r_j
  with r the link-side joint rates ψ̇_J (the end-section encoders) or their first-order
  low-pass (`rate_filter_hz`); e_EE = (x − x_des, y − y_des, φ − φ_des): end-effector
  position in the base frame (about the base COM) and terminal-link attitude
  φ = ψ_J1 + ψ_J2 + ψ_J3 relative to the base.  J_EE (3×3) comes from the controller's **own rigid kinematic model** of the arm
  (`ArmModel`: mount point and link lengths from `Params`, links straight) — a controller
  knows its nominal geometry, not the deflected shape.  The position in e_EE is either the
  measured end effector (`feedback = "measured"`, default: the deflected tip, as a camera
  or a grapple sensor sees it) or the rigid model's tip from the joint angles
  (`feedback = "kinematic"`).

Desired conditions are fixed (hold, freeze) or quintic moves (`rsmcheck.core.trajectories`).
The programme (which arm does what, when) is a sequence of segments of the case file, run
by `ProgrammeController` together with `rsmcheck.driver.runner`.

The laws run compiled at every sample (`rsmcheck.driver.control_kernels.programme_inputs`):
the classes here hold the configuration and the programme, and describe the references to
the kernel as rows of numbers (`ArmReference.row`).  The Python formulas below (`measure`,
`base_pd`, `jacobian_transpose`, the references' `__call__`, `retrograde_attitude`) state
the same equations; the kernel reproduces them to the bit (tests/rsmcheck/test_control_kernels.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from rsmcheck.core.cases import ControllerSpec
from rsmcheck.core.programme import ArmCommand, Segment
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.geometry import arm_jacobian, arm_pins, rot
from rsmcheck.core.params import Params
from rsmcheck.core.trajectories import Quintic, quintic
from rsmcheck.driver import control_kernels as ck

Controller = Callable[[Sensors], Inputs]


def saturate(inputs: Inputs, params: Params) -> Inputs:
    """Clip τ_m to ±τ_m,max (Table 4) and τ_B to ±τ_B,max (Table 3)."""
    tm = params.motor.torque_max
    tb = params.actuators.torque_max
    return Inputs(tau_m=np.minimum(np.maximum(inputs.tau_m, -tm), tm),
                  tau_B=min(max(float(inputs.tau_B), -tb), tb), thrust=inputs.thrust)


def wrap_near(angle: float, reference: float) -> float:
    """`angle` + 2πk closest to `reference`."""
    return angle + 2.0 * math.pi * round((reference - angle) / (2.0 * math.pi))


# ---------------------------------------------------------------------------------------
# The controller's internal model
# ---------------------------------------------------------------------------------------
class ArmModel:
    """Rigid kinematic model of arm `arm` in the base frame (the controller's own model).

    Links are straight segments of length L between pins; the first pin is the mount point.
    `pose(q)` = (x, y, φ) of the end effector (distal pin of link 3) and terminal-link
    attitude, `jacobian(q)` = ∂(x, y, φ)/∂(θ_J1, θ_J2, θ_J3).
    """

    def __init__(self, params: Params, arm: int):
        self.arm = arm
        self.mount_x, self.mount_y = (float(c) for c in params.geometry.mount_B(arm))
        self.length = params.link.length

    def pins_list(self, q) -> list[tuple[float, float]]:
        """The four pins (mount, elbows, end effector) as (x, y) floats, base frame (plain
        arithmetic: called every control sample)."""
        return arm_pins(self.mount_x, self.mount_y, 0.0, self.length, q)

    def pins(self, q) -> np.ndarray:
        """The four pins, base frame, rows."""
        return np.array(self.pins_list(q))

    def pose(self, q) -> np.ndarray:
        x, y = self.pins_list(q)[3]
        return np.array([x, y, float(q[0]) + float(q[1]) + float(q[2])])

    def jacobian(self, q) -> np.ndarray:
        """Column s: ∂(x, y, φ)/∂θ_Js = (−(e − p_s)_y, (e − p_s)_x, 1), e the end effector."""
        return arm_jacobian(self.pins_list(q), attitude=True)

    def inverse(self, goal, guess, tol: float = 1e-12, iterations: int = 100) -> np.ndarray:
        """Joint angles reaching pose `goal` = (x, y, φ) (Newton from `guess`)."""
        q = np.asarray(guess, float).copy()
        goal = np.asarray(goal, float)
        for _ in range(iterations):
            err = goal - self.pose(q)
            if np.linalg.norm(err) < tol:
                return q
            q = q + np.linalg.lstsq(self.jacobian(q), err, rcond=None)[0]
        raise ValueError(f"arm {self.arm}: pose {goal} not reachable (residual {np.linalg.norm(err):.3g})")


# ---------------------------------------------------------------------------------------
# The two control laws
# ---------------------------------------------------------------------------------------
def base_pd(theta: float, rate: float, theta_des: float, rate_des: float, kp: float, kd: float) -> float:
    """Eq. (13), before saturation."""
    return -kp * (theta - theta_des) - kd * (rate - rate_des)


def jacobian_transpose(pins, error, joint_rates, kp, kd) -> list[float]:
    """Eq. (14), before saturation: τ = −J_EEᵀ K_p e_EE − K_d θ̇_J (K_p applied to e, K_d to
    θ̇), J_EE of the rigid arm whose four pins are `pins` (`ArmModel.pins`): its column s is
    ∂(x, y, φ)/∂θ_Js = (−(e − p_s)_y, (e − p_s)_x, 1), e = pins[3] the end effector.  On
    floats (every control sample): τ_s = (e − p_s)_y K_p,x e_x − (e − p_s)_x K_p,y e_y
    − K_p,φ e_φ − K_d,s θ̇_s."""
    ex, ey = pins[3][0], pins[3][1]
    fx, fy, fphi = kp[0] * error[0], kp[1] * error[1], kp[2] * error[2]
    return [(ey - pins[s][1]) * fx - (ex - pins[s][0]) * fy - fphi - kd[s] * joint_rates[s] for s in range(3)]


@dataclass(frozen=True)
class Measured:
    """What the programme uses, derived from `Sensors` (base frame, about the base COM)."""

    ee_B: np.ndarray  # (2, 3): x, y, φ of each end effector
    target_B: np.ndarray  # x, y, θ of the target COM
    target_rate_B: np.ndarray  # ẋ, ẏ, θ̇ relative to the base, in base axes


def measure(s: Sensors, arms: tuple[ArmModel, ArmModel], feedback: str) -> Measured:
    """The sensors in the base frame about the base COM (plain float arithmetic: this runs
    at every control sample).  With c, s of θ_B, a vector d of inertial axes is
    Aᵀ(θ_B) d = (c d_x + s d_y, −s d_x + c d_y)."""
    xb, yb, th = s.base_pose_I.tolist()
    c, sn = math.cos(th), math.sin(th)
    q = s.joint_angles.tolist()
    ee = np.empty((2, 3))
    for k in range(2):
        qk = q[3 * k:3 * k + 3]
        if feedback == "kinematic":
            ee[k] = arms[k].pose(qk)
        else:
            ex, ey = s.ee_pos_I[k].tolist()
            dx, dy = ex - xb, ey - yb
            ee[k] = (c * dx + sn * dy, -sn * dx + c * dy, qk[0] + qk[1] + qk[2])
    xt, yt, tht = s.target_pose_I.tolist()
    dx, dy = xt - xb, yt - yb
    tgt = np.array([c * dx + sn * dy, -sn * dx + c * dy, tht - th])
    vbx, vby, om = s.base_rate_I.tolist()
    vtx, vty, omt = s.target_rate_I.tolist()
    # relative velocity of the target COM seen from the turning base: ṙ_T − ṙ_B − θ̇_B S d
    dvx = vtx - vbx + om * dy
    dvy = vty - vby - om * dx
    rate = np.array([c * dvx + sn * dvy, -sn * dvx + c * dvy, omt - om])
    return Measured(ee, tgt, rate)


# ---------------------------------------------------------------------------------------
# Reference generators for one arm
# ---------------------------------------------------------------------------------------
class ArmReference:
    """Desired (x, y, φ) of one end effector as a function of time and measurements."""

    def __call__(self, t: float, m: Measured) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def goal(self) -> np.ndarray | None:
        """Where this reference ends (held by a following "hold"), None if it moves with
        the target."""
        return None

    def row(self) -> list[float]:  # pragma: no cover - interface
        """The reference for the compiled controller: kind (`control_kernels.REF_*`) and
        parameters, in the layout of `control_kernels._desired`."""
        raise NotImplementedError


class Fixed(ArmReference):
    def __init__(self, pose):
        self.pose = np.asarray(pose, float).copy()

    def __call__(self, t, m):
        return self.pose

    def goal(self):
        return self.pose

    def row(self):
        return [ck.REF_FIXED, *self.pose.tolist()]


class Move(ArmReference):
    """Quintic from the pose at entry to `goal` over `duration` s, then hold."""

    def __init__(self, start, goal, t0, duration):
        self.q = Quintic(start, goal, t0, duration)

    def __call__(self, t, m):
        return self.q(t)

    def goal(self):
        return self.q.p1

    def row(self):
        return [ck.REF_MOVE, *_quintic_row(self.q)]


class Approach(ArmReference):
    """Quintic blend from the entry pose onto a point of the target (which may move):
    desired = p0 + s(t)·(p_point(t) − p0); attitude quintic to `phi` (or held)."""

    def __init__(self, start, point_T, phi_goal, t0, duration):
        self.start = np.asarray(start, float).copy()
        self.point_T = np.asarray(point_T, float).copy()  # target frame about the COM
        self.phi = Quintic([start[2]], [start[2] if phi_goal is None else phi_goal], t0, duration)
        self.t0, self.duration = t0, duration

    def point_B(self, m: Measured) -> np.ndarray:
        return m.target_B[:2] + rot(m.target_B[2]) @ self.point_T

    def __call__(self, t, m):
        s, _, _ = quintic(t, self.t0, self.duration)
        p = self.start[:2] + s * (self.point_B(m) - self.start[:2])
        return np.array([p[0], p[1], self.phi(t)[0]])

    def row(self):
        return [ck.REF_APPROACH, *self.start.tolist(), *self.point_T.tolist(), float(self.phi.p1[0]),
                float(self.t0), float(self.duration)]


class Held(ArmReference):
    """End effector of an arm that holds the target, following a desired target pose
    (x, y, θ in the base frame, a callable of t): p = r_T + A(θ_T) ρ, φ = θ_T − ψ0."""

    def __init__(self, target_ref: Callable[[float], np.ndarray], rho_T, psi0: float):
        self.target_ref = target_ref
        self.rho = np.asarray(rho_T, float).copy()
        self.psi0 = psi0

    def __call__(self, t, m):
        return self._ee(self.target_ref(t))

    def _ee(self, x):
        p = x[:2] + rot(x[2]) @ self.rho
        return np.array([p[0], p[1], x[2] - self.psi0])

    def goal(self):
        final = getattr(self.target_ref, "final_pose", None)
        return self._ee(final()) if final is not None else None

    def row(self):
        target = self.target_ref
        if isinstance(target, ComAlignment):
            target = target.move if target.move is not None else target.pose
        if isinstance(target, Quintic):
            path = [ck.TARGET_QUINTIC, *_quintic_row(target)]
        else:
            path = [ck.TARGET_FIXED, *np.asarray(target, float).tolist(), 0.0, 0.0, 0.0, 0.0, 0.0]
        return [ck.REF_HELD, *path, *self.rho.tolist(), float(self.psi0)]


def _quintic_row(q: Quintic) -> list[float]:
    """p0 (3), p1 (3), t0, T of a quintic move."""
    return [*q.p0.tolist(), *q.p1.tolist(), float(q.t0), float(q.duration)]


# ---------------------------------------------------------------------------------------
# Composite controller
# ---------------------------------------------------------------------------------------
class ProgrammeController:
    """Base PD (eq. 13) + Jacobian transpose (eq. 14) per arm, driven by segments.

    The runner calls `enter(segment, sensors)` at the first sample of each segment and
    `captured(arm, sensors)` after a grasp closes; `__call__(sensors)` returns the inputs.
    """

    def __init__(self, spec: ControllerSpec, params: Params, period: float):
        self.spec = spec
        self.period = period
        self.params = params
        self.arms = (ArmModel(params, 1), ArmModel(params, 2))
        self.kp = (tuple(map(float, spec.arm1.kp)), tuple(map(float, spec.arm2.kp)))
        self.kd = (tuple(map(float, spec.arm1.kd)), tuple(map(float, spec.arm2.kd)))
        self.refs: list[ArmReference | None] = [None, None]
        self.open_loop = [np.zeros(3), np.zeros(3)]
        self.base_mode = "hold"
        self.base_goal = 0.0
        self.thrust = 0.0
        self.frozen: Measured | None = None
        self.frozen_base = 0.0
        self.segment: Segment | None = None
        self.com_align: "ComAlignment | None" = None
        self.log: list[tuple[float, str, str]] = []  # events for the runner (time, kind, detail)
        # what the compiled laws read (control_kernels): the constants and the base mode
        # (`law`), the references (`refs_table`, rewritten by `_describe` when they change), the
        # rate filter's state (`filt`: last sample time, NaN before the first; the joint-rate
        # estimate used by eq. 14) and the inputs (`out`)
        law = np.zeros(ck.LAW_SIZE)
        for k, arm in enumerate(self.arms):
            law[ck.L_MOUNT + 2 * k:ck.L_MOUNT + 2 * k + 2] = arm.mount_x, arm.mount_y
            law[ck.L_KP + 3 * k:ck.L_KP + 3 * k + 3] = self.kp[k]
            law[ck.L_KD + 3 * k:ck.L_KD + 3 * k + 3] = self.kd[k]
        law[ck.L_LENGTH] = params.link.length
        law[ck.L_BASE_KP], law[ck.L_BASE_KD] = spec.base.kp, spec.base.kd
        law[ck.L_MU] = params.orbit.mu
        law[ck.L_TAU_M_MAX], law[ck.L_TAU_B_MAX] = params.motor.torque_max, params.actuators.torque_max
        law[ck.L_KINEMATIC] = 1.0 if spec.feedback == "kinematic" else 0.0
        law[ck.L_FILTER_HZ] = spec.rate_filter_hz
        law[ck.L_PERIOD] = period
        self.law = law
        self.refs_table = np.zeros((2, ck.REF_SIZE))
        self.filt = np.full(7, math.nan)
        self.filt[1:] = 0.0
        self.out = np.zeros(7)
        self._describe()

    @property
    def rates(self) -> np.ndarray:
        """The joint-rate estimate used by eq. (14) (the rate filter's output)."""
        return self.filt[1:]

    def _describe(self) -> None:
        """Write the references and the base mode into the compiled law's arrays."""
        for k, ref in enumerate(self.refs):
            row = [ck.REF_OPEN, *self.open_loop[k].tolist()] if ref is None else ref.row()
            self.refs_table[k] = 0.0
            self.refs_table[k, :len(row)] = row
        self.law[ck.L_BASE_MODE] = {"off": ck.BASE_OFF, "retrograde": ck.BASE_RETROGRADE}.get(self.base_mode,
                                                                                             ck.BASE_GOAL)
        self.law[ck.L_BASE_GOAL] = self.base_goal

    # ---- programme ------------------------------------------------------------------
    def start(self, s: Sensors) -> None:
        """First sample of the case: remember the configuration for `freeze`."""
        self.frozen = measure(s, self.arms, self.spec.feedback)
        self.frozen_base = float(s.base_pose_I[2])
        self.filt[1:] = s.joint_rates

    def enter(self, seg: Segment, s: Sensors) -> None:
        self.segment = seg
        m = measure(s, self.arms, self.spec.feedback)
        t0 = s.time
        self.thrust = self.params.actuators.thrust if seg.thrust else 0.0
        self.base_mode = seg.base
        if seg.base == "hold":
            self.base_goal = float(s.base_pose_I[2])
        elif seg.base == "freeze":
            self.base_goal = self.frozen_base
        elif seg.base == "angle":
            self.base_goal = math.radians(seg.base_angle_deg)
        self.com_align = None
        target_ref = None
        if seg.target is not None:
            if seg.target.mode == "move":
                goal = np.array([seg.target.to[0], seg.target.to[1], math.radians(seg.target.to[2])])
                goal[2] = wrap_near(goal[2], m.target_B[2])
                tq = Quintic(m.target_B, goal, t0, seg.target.time or seg.duration)
                target_ref = tq
            elif seg.target.mode == "push":
                d = np.array([seg.target.by[0], seg.target.by[1], 0.0])
                tq = Quintic(m.target_B, m.target_B + d, t0, seg.target.time or seg.duration)
                target_ref = tq
            elif seg.target.mode == "com_align":
                self.com_align = ComAlignment(m.target_B, seg.target, t0, self.params)
                target_ref = self.com_align
        for k, cmd in enumerate((seg.arm1, seg.arm2)):
            self.refs[k] = self._reference(k, cmd, m, t0, seg, target_ref)
            self.open_loop[k] = np.array(cmd.torques if cmd.mode == "torque" else (0.0, 0.0, 0.0), float)
        self._describe()

    def _reference(self, k: int, cmd: ArmCommand, m: Measured, t0: float, seg: Segment,
                   target_ref) -> ArmReference | None:
        mode = cmd.mode
        if mode in ("off", "torque"):
            return None
        if mode == "hold":
            # finish the last commanded motion (a move, or a carry after a release) and stay
            # at its goal; after anything else (an approach, no reference) stay where it is
            prev = self.refs[k]
            if prev is not None and prev.goal() is not None:
                return prev
            return Fixed(m.ee_B[k])
        if mode == "freeze":
            assert self.frozen is not None
            return Fixed(self.frozen.ee_B[k])
        if mode == "move":
            goal = np.array([cmd.to[0], cmd.to[1], math.radians(cmd.to[2])])
            goal[2] = wrap_near(goal[2], m.ee_B[k, 2])
            return Move(m.ee_B[k], goal, t0, cmd.time or seg.duration)
        if mode == "approach":
            point = np.asarray(cmd.point_T, float)
            phi = None if cmd.phi_deg is None else wrap_near(math.radians(cmd.phi_deg), m.ee_B[k, 2])
            return Approach(m.ee_B[k], point, phi, t0, cmd.time or seg.duration)
        if mode == "carry":
            # the end effector follows the target's desired pose at its current held point
            rho = rot(m.target_B[2]).T @ (m.ee_B[k, :2] - m.target_B[:2])
            psi0 = m.target_B[2] - m.ee_B[k, 2]
            return Held(target_ref, rho, psi0)
        raise ValueError(f"unknown arm mode {mode!r}")  # pragma: no cover - the loader checks

    def captured(self, arm: int, s: Sensors) -> None:
        """A grasp closed: the capturing arm holds where it is (until the next segment)."""
        m = measure(s, self.arms, self.spec.feedback)
        self.refs[arm - 1] = Fixed(m.ee_B[arm - 1])
        self._describe()

    # ---- the laws ---------------------------------------------------------------------
    def __call__(self, s: Sensors) -> Inputs:
        """Eqs. (13)–(14) with the references of the segment, the rate filter and the
        saturations, compiled (`control_kernels.programme_inputs`)."""
        t = s.time
        if self.com_align is not None:
            note = self.com_align.update(t, s)
            if note:
                self.log.append((t, "com_align", note))
                self._describe()  # a new move of the target
        out = self.out
        ck.programme_inputs(t, s.base_pose_I, s.base_rate_I, s.joint_angles, s.joint_rates, s.ee_pos_I,
                            s.target_pose_I, s.orbit_r_I, s.orbit_v_I, self.law, self.refs_table, self.filt, out)
        return Inputs(tau_m=out[:6].copy(), tau_B=float(out[6]), thrust=self.thrust)


def retrograde_attitude(r, v, mu: float) -> tuple[float, float]:
    """Attitude whose +x points against the orbital velocity, and its rate (Kepler motion):
    θ = atan2(−v), θ̇ = (v × a)/|v|² with a = −μ r/|r|³."""
    rx, ry = np.asarray(r, float).tolist()
    vx, vy = np.asarray(v, float).tolist()
    if vx == 0.0 and vy == 0.0:
        return 0.0, 0.0
    rn3 = math.hypot(rx, ry) ** 3
    ax, ay = -mu * rx / rn3, -mu * ry / rn3
    return math.atan2(-vy, -vx), (vx * ay - vy * ax) / (vx * vx + vy * vy)


class ComAlignment:
    """The iterative COM alignment of Sect. 5.3 as a desired target pose (base frame).

    The apogee motor's thrust passes through the base COM along +x_B, so the system COM
    must lie on the base x-axis (com_pos_B[1] = 0).  Each iteration: read com_pos_B[1]
    (after the previous move has settled), move the target across the thrust axis by
    Δy = −gain·y_COM with a quintic of `step_time` s, wait `settle_time` s.  The first gain
    is the controller's rigid estimate m_sys / (m_T + 3 m_link) (the target and roughly one
    arm's worth of links move with it); later iterations use the secant of the measured
    response.  Stops when |y_COM| < `tolerance`.
    """

    def __init__(self, start_B, spec, t0: float, params: Params):
        self.pose = np.asarray(start_B, float).copy()
        self.spec = spec
        self.t_next = t0
        m_sys = params.base.mass + params.target.mass + 6 * params.link.mass
        self.gain = m_sys / (params.target.mass + 3 * params.link.mass)
        self.move: Quintic | None = None
        self.last: tuple[float, float] | None = None  # (offset applied, y measured before)
        self.offset = 0.0
        self.iterations = 0
        self.done = False

    def update(self, t: float, s: Sensors) -> str:
        if self.done or t + 1e-12 < self.t_next:
            return ""
        y = float(s.com_pos_B[1])
        note = ""
        if self.last is not None:
            dy_applied, y_before = self.last
            if abs(y - y_before) > 1e-9 and abs(dy_applied) > 1e-12:
                measured_gain = dy_applied / (y - y_before)
                if 0.2 * self.gain < measured_gain < 5.0 * self.gain:
                    self.gain = measured_gain
        if abs(y) < self.spec.tolerance or self.iterations >= self.spec.max_iterations:
            self.done = True
            return f"iterations={self.iterations} com_y={y:.6g}"
        step = -self.gain * y
        start = self.pose + np.array([0.0, self.offset, 0.0])
        self.offset += step
        self.move = Quintic(start, self.pose + np.array([0.0, self.offset, 0.0]), t, self.spec.step_time)
        self.last = (step, y)
        self.iterations += 1
        self.t_next = t + self.spec.step_time + self.spec.settle_time
        note = f"iteration={self.iterations} com_y={y:.6g} step={step:.6g} gain={self.gain:.4g}"
        return note

    def __call__(self, t: float) -> np.ndarray:
        if self.move is None:
            return self.pose
        return self.move(t)

    def final_pose(self) -> np.ndarray:
        return self.pose + np.array([0.0, self.offset, 0.0])


@dataclass(frozen=True)
class HeldTorques:
    """Open-loop torques (controller kind "constant"): τ_m held from t = 0 and brought in
    over `ramp_time` T [s] by the smooth step f(t) = (1 − cos(πt/T))/2 (zero rate at both
    ends), plus a sine from t = 0, clipped to the motors' limits:

        τ_m(t) = sat( f(t) τ_m,held + A sin(2π f_s t) ),   τ_B(t) = f(t) τ_B,held

    Why a ramp: the joints are all but undamped (Table 4: C_m = 0.002 N·m·s/rad on
    K_m = 4e4 N·m/rad, B_m = 0.12 kg·m²), so a step rings the rotor mode at the full static
    load for the whole run; the ramp leaves a ringing of order (π/ωT)² of it (1.2e-4 at
    T = 0.5 s, ω = 578 rad/s).
    """

    held: Inputs
    ramp_time: float = 0.0
    sine_amplitude: np.ndarray | None = None  # A [N·m] per motor; None: no sine
    sine_frequency_hz: float = 0.0
    params: Params | None = None  # the limits the sum is clipped to (with a sine)

    def __call__(self, s: Sensors) -> Inputs:
        f = 1.0
        if s.time < self.ramp_time:
            f = 0.5 * (1.0 - math.cos(math.pi * s.time / self.ramp_time))
        out = Inputs(tau_m=f * self.held.tau_m, tau_B=f * self.held.tau_B, thrust=0.0)
        if self.sine_amplitude is None:
            return out
        tau = out.tau_m + self.sine_amplitude * math.sin(2.0 * math.pi * self.sine_frequency_hz * s.time)
        return saturate(Inputs(tau_m=tau, tau_B=out.tau_B, thrust=0.0), self.params)


def make_controller(spec: ControllerSpec, params: Params, period: float = 1e-3):
    """The controller a case names; `period` is the control period (the rate filter's)."""
    if spec.kind == "none":
        return lambda s: Inputs()
    if spec.kind == "constant":
        held = saturate(Inputs(tau_m=np.array(spec.motor_torques, float), tau_B=spec.base_torque), params)
        sine = np.array(spec.sine_amplitude, float)
        if not np.any(sine) or spec.sine_frequency_hz == 0.0:
            return HeldTorques(held, spec.ramp_time)
        return HeldTorques(held, spec.ramp_time, sine, spec.sine_frequency_hz, params)
    if spec.kind == "programme":
        return ProgrammeController(spec, params, period)
    raise ValueError(f"unknown controller kind {spec.kind!r}")
