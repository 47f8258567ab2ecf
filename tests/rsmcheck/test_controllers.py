"""The controllers of Sect. 3 on their own: the rigid arm model, eqs. (13)–(14), the
saturations, quintic trajectories, retrograde pointing, the rate filter and the COM
alignment iteration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsmcheck.core.cases import ArmGains, BaseGains, ControllerSpec
from rsmcheck.core.programme import Segment, TargetCommand
from rsmcheck.driver.controllers import (
    ArmModel,
    ComAlignment,
    ProgrammeController,
    base_pd,
    jacobian_transpose,
    make_controller,
    retrograde_attitude,
    saturate,
    wrap_near,
)
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.params import Params
from rsmcheck.core.trajectories import PEAK_ACCEL, PEAK_SPEED, Quintic, quintic

P = Params()


def sensors(q=None, qd=None, t=0.0, base=(0.0, 0.0, 0.0), com=(3.0, 0.0), target=(5.65, 0.1, 0.0),
            orbit_r=(0.0, 0.0), orbit_v=(0.0, 0.0)) -> Sensors:
    q = np.radians([60.0, -120.0, 60.0, -60.0, 120.0, -60.0]) if q is None else np.asarray(q, float)
    qd = np.zeros(6) if qd is None else np.asarray(qd, float)
    ee = np.array([ArmModel(P, 1).pose(q[:3])[:2], ArmModel(P, 2).pose(q[3:])[:2]])
    c, s = math.cos(base[2]), math.sin(base[2])
    rot = np.array([[c, -s], [s, c]])
    return Sensors(time=t, base_pose_I=np.array(base, float), base_rate_I=np.zeros(3), joint_angles=q,
                   joint_rates=qd, joint_frame_angles=q.copy(), joint_frame_rates=qd.copy(),
                   motor_angles=q.copy(), motor_rates=qd.copy(), wrist_angles=np.zeros(2),
                   ee_pos_I=np.array([base[:2] + rot @ e for e in ee]), ee_vel_I=np.zeros((2, 2)),
                   target_pose_I=np.array(target, float), target_rate_I=np.zeros(3),
                   com_pos_B=np.array(com, float), grasp_state=np.array([1, 0]), system_mass=918.94,
                   orbit_r_I=np.array(orbit_r, float), orbit_v_I=np.array(orbit_v, float))


def test_arm_model_forward_kinematics_of_the_nominal_z():
    arm = ArmModel(P, 1)
    pose = arm.pose(np.radians([60.0, -120.0, 60.0]))
    assert pose == pytest.approx([4.0, 0.6, 0.0], abs=1e-12)
    arm2 = ArmModel(P, 2)
    assert arm2.pose(np.radians([-60.0, 120.0, -60.0])) == pytest.approx([4.0, -0.6, 0.0], abs=1e-12)


@pytest.mark.parametrize("arm", [1, 2])
def test_arm_jacobian_matches_finite_differences(arm):
    model = ArmModel(P, arm)
    q = np.array([0.3, -1.1, 0.7])
    jac = model.jacobian(q)
    h = 1e-6
    fd = np.column_stack([(model.pose(q + h * e) - model.pose(q - h * e)) / (2 * h) for e in np.eye(3)])
    assert jac == pytest.approx(fd, abs=1e-8)


def test_arm_inverse_kinematics_round_trip():
    model = ArmModel(P, 1)
    q = model.inverse([3.9, 0.8, 0.2], np.radians([60, -120, 60]))
    assert model.pose(q) == pytest.approx([3.9, 0.8, 0.2], abs=1e-10)
    with pytest.raises(ValueError):
        model.inverse([9.0, 0.0, 0.0], np.zeros(3))  # beyond the 4.5 m reach


def test_base_pd_is_eq_13():
    assert base_pd(0.1, 0.02, 0.0, 0.0, 100.0, 1000.0) == pytest.approx(-10.0 - 20.0)
    assert base_pd(0.0, 0.01, 0.0, 0.01, 100.0, 1000.0) == pytest.approx(0.0)


def test_jacobian_transpose_pulls_towards_the_desired_pose():
    """Eq. (14): the torques do negative work on the error (an EE spring towards the goal)."""
    model = ArmModel(P, 1)
    q = np.radians([60.0, -120.0, 60.0])
    jac = model.jacobian(q)
    e = np.array([0.01, -0.02, 0.005])
    kp = np.array([1000.0, 1000.0, 1000.0])
    tau = np.array(jacobian_transpose(model.pins(q), e, np.zeros(3), kp, np.zeros(3)))
    assert tau == pytest.approx(-jac.T @ (kp * e), rel=1e-14)
    # a small joint step along τ reduces the error
    dq = 1e-4 * tau / np.linalg.norm(tau)
    e_new = e + jac @ dq
    assert np.linalg.norm(kp * e_new) < np.linalg.norm(kp * e)
    tau_d = jacobian_transpose(model.pins(q), np.zeros(3), np.array([0.1, 0.0, -0.2]), kp, np.array([10.0, 10.0, 5.0]))
    assert tau_d == pytest.approx([-1.0, 0.0, 1.0])


def test_saturation_of_tables_3_and_4():
    u = saturate(Inputs(tau_m=np.array([100.0, -100.0, 5.0, 0.0, 80.0, -81.0]), tau_B=-50.0, thrust=180.0), P)
    assert u.tau_m.tolist() == [80.0, -80.0, 5.0, 0.0, 80.0, -80.0]
    assert u.tau_B == -12.0 and u.thrust == 180.0


def test_held_torques_step_and_ramp():
    step = make_controller(ControllerSpec(kind="constant", motor_torques=(100.0, 0, 0, 0, 0, -5.0), base_torque=3.0), P)
    u = step(sensors(t=0.0))
    assert u.tau_m.tolist() == [80.0, 0, 0, 0, 0, -5.0] and u.tau_B == 3.0 and u.thrust == 0.0  # saturated
    ramp = make_controller(ControllerSpec(kind="constant", motor_torques=(10.0, 0, 0, 0, 0, -5.0), base_torque=3.0,
                                          ramp_time=0.5), P)
    assert ramp(sensors(t=0.0)).tau_m.tolist() == [0.0] * 6 and ramp(sensors(t=0.0)).tau_B == 0.0
    half = ramp(sensors(t=0.25))
    assert half.tau_m[0] == pytest.approx(5.0) and half.tau_m[5] == pytest.approx(-2.5) and half.tau_B == pytest.approx(1.5)
    assert ramp(sensors(t=0.5)).tau_m[0] == 10.0 and ramp(sensors(t=7.0)).tau_m[0] == 10.0
    # smooth: zero slope at both ends (finite differences over 1 ms)
    assert ramp(sensors(t=1e-3)).tau_m[0] < 1e-3 and 10.0 - ramp(sensors(t=0.499)).tau_m[0] < 1e-3
    ramp(sensors(t=0.1)).tau_m[0] = 99.0  # the held torques are not shared with a caller
    assert ramp(sensors(t=0.6)).tau_m[0] == 10.0


def test_held_torques_with_a_sine_are_clipped_to_the_motor_limits():
    spec = ControllerSpec(kind="constant", motor_torques=(10.0, 0, 0, 0, 0, 70.0), base_torque=2.0, ramp_time=0.5,
                          sine_amplitude=(4.0, 0, 0, 0, 0, 20.0), sine_frequency_hz=2.0)
    ctrl = make_controller(spec, P)
    # t = 1/8 s: the sine at its crest (2 Hz), the ramp at (1 − cos(π/4))/2
    f = 0.5 * (1.0 - math.cos(math.pi * 0.125 / 0.5))
    u = ctrl(sensors(t=0.125))
    assert u.tau_m[0] == pytest.approx(10.0 * f + 4.0) and u.tau_B == pytest.approx(2.0 * f)
    # t = 0.625 s: ramp done, sine at its crest again: 70 + 20 clipped to Table 4's 80 N·m
    u = ctrl(sensors(t=0.625))
    assert u.tau_m[0] == pytest.approx(14.0) and u.tau_m[5] == 80.0
    assert ctrl(sensors(t=0.0)).tau_m.tolist() == [0.0] * 6  # sine and ramp both start at zero


def test_quintic_is_rest_to_rest():
    assert quintic(0.0, 0.0, 10.0) == (0.0, 0.0, 0.0)
    assert quintic(10.0, 0.0, 10.0) == (1.0, 0.0, 0.0)
    s, ds, dds = quintic(5.0, 0.0, 10.0)
    assert s == pytest.approx(0.5) and ds == pytest.approx(PEAK_SPEED / 10.0) and dds == pytest.approx(0.0)
    t = np.linspace(0, 10, 10001)
    acc = np.array([quintic(x, 0.0, 10.0)[2] for x in t])
    assert np.max(acc) == pytest.approx(PEAK_ACCEL / 100.0, rel=1e-4)
    q = Quintic([0.0, 1.0], [2.0, -1.0], 1.0, 4.0)
    assert q(0.0).tolist() == [0.0, 1.0] and q(9.0).tolist() == [2.0, -1.0]
    assert q.velocity(3.0) == pytest.approx([2.0 * PEAK_SPEED / 4.0, -2.0 * PEAK_SPEED / 4.0])
    assert q.done(5.0) and not q.done(4.9)


def test_wrap_near():
    assert wrap_near(-3.1, 3.1) == pytest.approx(-3.1 + 2 * math.pi)
    assert wrap_near(0.2, 0.0) == 0.2


def test_retrograde_attitude_points_against_the_velocity_and_turns_with_the_orbit():
    mu = P.orbit.mu
    r = 7.078e6
    v = math.sqrt(mu / r)
    th, rate = retrograde_attitude(np.array([r, 0.0]), np.array([0.0, v]), mu)
    assert th == pytest.approx(-math.pi / 2)
    assert rate == pytest.approx(v / r)  # the orbit's angular rate on a circle


def _spec(kp=(1000.0, 1000.0, 1000.0), kd=(100.0, 100.0, 50.0), fc=0.0):
    return ControllerSpec(kind="programme", gains="test", base=BaseGains(100.0, 1000.0),
                          arm1=ArmGains(kp, kd), arm2=ArmGains(kp, kd), rate_filter_hz=fc)


def test_programme_hold_gives_zero_torque_at_rest_and_restores_a_displacement():
    ctl = make_controller(_spec(), P, 1e-3)
    assert isinstance(ctl, ProgrammeController)
    s0 = sensors()
    ctl.start(s0)
    ctl.enter(Segment(name="hold", duration=10.0), s0)
    u = ctl(s0)
    assert np.max(np.abs(u.tau_m)) < 1e-9 and abs(u.tau_B) < 1e-12 and u.thrust == 0.0
    q = np.radians([60.0, -120.0, 60.0, -60.0, 120.0, -60.0])
    q[1] += 0.01
    u = ctl(sensors(q=q))
    model = ArmModel(P, 1)
    e = model.pose(q[:3]) - model.pose(np.radians([60.0, -120.0, 60.0]))
    assert u.tau_m[:3] == pytest.approx(-model.jacobian(q[:3]).T @ (1000.0 * e), rel=1e-9)
    assert np.all(u.tau_m[3:] == 0.0)


def test_rate_filter_lags_a_step_in_the_joint_rate():
    ctl = make_controller(_spec(kp=(0.0, 0.0, 0.0), fc=1.0), P, 1e-3)
    s0 = sensors()
    ctl.start(s0)
    ctl.enter(Segment(name="hold", duration=10.0), s0)
    qd = np.array([0.1, 0, 0, 0, 0, 0])
    taus = [ctl(sensors(qd=qd, t=k * 1e-3)).tau_m[0] for k in range(1, 160)]
    alpha = 1 - math.exp(-2 * math.pi * 1e-3)
    assert taus[0] == pytest.approx(-100.0 * 0.1 * alpha)
    # after one time constant (1/2π s ≈ 159 samples) the estimate is ~63 % of the step
    assert taus[-1] == pytest.approx(-100.0 * 0.1 * (1 - (1 - alpha) ** 159))
    assert -10.0 * 0.7 < taus[-1] < -10.0 * 0.55


def test_thrust_segment_and_freeze():
    ctl = make_controller(_spec(), P, 1e-3)
    s0 = sensors()
    ctl.start(s0)
    q = np.radians([61.0, -120.0, 60.0, -60.0, 120.0, -60.0])
    from rsmcheck.core.programme import ArmCommand

    ctl.enter(Segment(name="burn", duration=10.0, thrust=True, arm1=ArmCommand(mode="freeze"),
                      arm2=ArmCommand(mode="hold")), sensors(q=q))
    u = ctl(sensors(q=q))
    assert u.thrust == P.actuators.thrust
    assert np.linalg.norm(u.tau_m[:3]) > 1.0  # arm 1 goes back to the pose at the case start
    assert np.max(np.abs(u.tau_m[3:])) < 1e-9  # arm 2 holds where it entered


def test_com_alignment_converges_on_a_linear_plant():
    """Sect. 5.3 iteration on a plant whose COM responds to the target offset with a gain
    different from the controller's rigid estimate: converges in a few iterations."""
    spec = TargetCommand(mode="com_align", tolerance=1e-4, step_time=10.0, settle_time=5.0, max_iterations=10)
    align = ComAlignment(np.array([6.6, 0.1, 0.0]), spec, 0.0, P)
    y0, true_gain = 0.043, 0.7 / align.gain  # COM moves 0.7 × the estimated sensitivity
    t = 0.0
    notes = []
    while t < 200.0 and not align.done:
        offset = align(t)[1] - 0.1
        note = align.update(t, sensors(t=t, com=(3.0, y0 + true_gain * offset)))
        if note:
            notes.append(note)
        t += 0.5
    assert align.done
    assert abs(y0 + true_gain * (align(t)[1] - 0.1)) < 1e-4
    assert align.iterations <= 5
    assert notes[-1].startswith("iterations=")
