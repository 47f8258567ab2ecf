"""Initial conditions shared by the engines: body poses and rates from a case's spec.

This is input geometry, not dynamics: the links start undeformed (rigid, zero
amplitudes), so the poses follow from the parameters by plane trigonometry.  The target's
pose follows from the holding arm and the wrist angle ψ = θ_T − θ_3 (docs/physics.md
§4.3), its rotation rate from the arm's terminal link and the wrist rate ψ̇.  When both
arms hold the target, arm 2's joint angles and rates are solved so that its end effector
sits on (and moves with) grasp point 2: least-norm Newton on the three joint angles from
the case's values as first guess.

A run that continues from the stored end state of another case (a `StartState`, handed to
the engine beside the case by `rsmcheck.orchestration.chain`; the case itself only names
its predecessor) takes every pose, rate, motor angle, held point, orbit state and the
propellant used from the state's common rigid part instead (links undeformed: the rigid
part is what every engine can start from; an engine's own exact state is restored on top
by `rsmcheck.core.plugins.make_engine`).

Orbit (docs/physics.md §5): with `[orbit] enabled`, the co-moving point O is put on a
circular orbit of the case's altitude.  `centre_on_com` (default) shifts all positions
and velocities so that O is the system COM and moves with it (the COM is then on the
circular orbit); `align = "retrograde"` picks the orbit phase at which the orbital
velocity points along −x_B, so that a burn along +x_B starts aligned (Sect. 5.3).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rsmcheck.core.cases import Case
from rsmcheck.core.errors import InputError
from rsmcheck.core.geometry import rigid_arm, rot
from rsmcheck.core.params import Params


@dataclass(frozen=True)
class InitialConfiguration:
    base_pose: np.ndarray  # x, y, θ_B (relative to O)
    base_rate: np.ndarray
    joint_angles: np.ndarray  # 6
    joint_rates: np.ndarray
    target_pose: np.ndarray  # x_T, y_T, θ_T
    target_rate: np.ndarray
    grasp: np.ndarray  # 2 ints
    rho_G: np.ndarray  # (2, 2) held points, target frame about the COM
    orbit_r: np.ndarray  # O from Earth's centre (zeros when no orbit)
    orbit_v: np.ndarray
    motor_angles: np.ndarray | None = None  # None: at the joint angles (springs relaxed)
    motor_rates: np.ndarray | None = None  # None: at the joint rates
    m_used: float = 0.0  # propellant already burnt [kg]


@dataclass(frozen=True)
class StartState:
    """The end state of a previous run that a run continues from (rsmcheck.orchestration.chain).

    rigid: the common rigid part every engine understands (chain.RIGID_KEYS: poses, rates,
           joint and frame angles, motor angles, held points, orbit state, propellant used,
           COM position and velocity);
    exact: the engine's own exact state (`Engine.export_state()`), None if there is none.
    """

    rigid: Mapping[str, Any]
    exact: Mapping[str, Any] | None = None


def build_initial(case: Case, params: Params | None = None, start: StartState | None = None) -> InitialConfiguration:
    """The initial configuration of a run of `case`: from `start` (its rigid part) when the
    run continues another, else from the case's [initial]."""
    params = params or case.params
    if start is not None:
        return _from_state(case, params, start.rigid)
    if not case.has_initial:
        raise InputError(case.path, "initial", f"the case starts from the end state of "
                         f"'{case.start_from}' and has no [initial] of its own: run it chained")
    spec = case.initial
    geo = params.geometry
    base_pose = np.array(spec.base_pose, float)
    base_rate = np.array(spec.base_rate, float)
    q = np.radians(np.array(spec.joint_angles_deg, float))
    qd = np.array(spec.joint_rates, float)
    grasp = np.array(spec.grasp, dtype=np.int64)
    if spec.held_points is not None:
        rho_G = np.array(spec.held_points, float)
    else:
        rho_G = np.array([geo.grasp_T(1), geo.grasp_T(2)], float)

    if grasp.any():
        k = 0 if grasp[0] else 1
        p, v, th3, om3, _ = rigid_arm(params, base_pose, base_rate, q[3 * k:3 * k + 3], qd[3 * k:3 * k + 3], k + 1)
        thT = th3 + math.radians(spec.wrist_angle_deg)
        omT = om3 + spec.wrist_rate
        rT = p - rot(thT) @ rho_G[k]
        lever = rT - p
        vT = v + omT * np.array([-lever[1], lever[0]])
        target_pose = np.array([rT[0], rT[1], thT])
        target_rate = np.array([vT[0], vT[1], omT])
        if grasp[0] and grasp[1]:
            q[3:6], qd[3:6] = _close_arm2(params, base_pose, base_rate, q[3:6], target_pose, target_rate, rho_G[1], case.path)
    else:
        target_pose = np.array(spec.target_pose, float)
        target_rate = np.array(spec.target_rate, float)

    init = InitialConfiguration(base_pose, base_rate, q, qd, target_pose, target_rate, grasp, rho_G,
                                np.zeros(2), np.zeros(2))
    if case.orbit:
        com, vcom = rigid_com(params, init)
        init = place_on_orbit(case, params, init, com, vcom)
    return init


def _from_state(case: Case, params: Params, st) -> InitialConfiguration:
    """The common rigid part of a stored end state (rsmcheck.orchestration.chain.RIGID_KEYS).

    The links start undeformed, placed by the joint angles between their frames θ_J; every
    joint spring keeps its twist θ_m − ψ_J (the rotor angles are shifted by θ_J − ψ_J, the
    bend the links had at their end sections), so the joints carry on with their torques."""
    a = lambda k: np.array(st[k], float)  # noqa: E731
    bend = a("joint_frame_angles") - a("joint_angles")
    bend_rate = a("joint_frame_rates") - a("joint_rates")
    init = InitialConfiguration(
        base_pose=a("base_pose"), base_rate=a("base_rate"), joint_angles=a("joint_frame_angles"),
        joint_rates=a("joint_frame_rates"), target_pose=a("target_pose"), target_rate=a("target_rate"),
        grasp=np.array(st["grasp"], dtype=np.int64), rho_G=a("held_points"),
        orbit_r=a("orbit_r"), orbit_v=a("orbit_v"), motor_angles=a("motor_angles") + bend,
        motor_rates=a("motor_rates") + bend_rate, m_used=float(st["m_used"]))
    if case.orbit and not np.any(init.orbit_r):
        init = place_on_orbit(case, params, init, a("com_I"), a("com_vel_I"))
    return init


def rigid_com(params: Params, init: InitialConfiguration) -> tuple[np.ndarray, np.ndarray]:
    """System COM and its velocity (relative to O) for straight links."""
    mB = params.base.mass - init.m_used
    mL = params.link.mass
    mT = params.target.mass
    s = mB * init.base_pose[:2] + mT * init.target_pose[:2]
    v = mB * init.base_rate[:2] + mT * init.target_rate[:2]
    L = params.link.length
    for arm in (1, 2):
        k = 3 * (arm - 1)
        th = init.base_pose[2]
        om = init.base_rate[2]
        p = init.base_pose[:2] + rot(th) @ np.asarray(params.geometry.mount_B(arm), float)
        pv = init.base_rate[:2] + om * _perp(p - init.base_pose[:2])
        for j in range(3):
            th += init.joint_angles[k + j]
            om += init.joint_rates[k + j]
            half = 0.5 * L * np.array([math.cos(th), math.sin(th)])
            s = s + mL * (p + half)
            v = v + mL * (pv + om * _perp(half))
            p = p + 2.0 * half
            pv = pv + om * _perp(2.0 * half)
    m = mB + mT + 6 * mL
    return s / m, v / m


def _perp(d: np.ndarray) -> np.ndarray:
    return np.array([-d[1], d[0]])


def orbit_start(case: Case, params: Params, theta_B: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity of a circular orbit at the case's altitude, phased by `align`."""
    h = case.orbit_spec.altitude if case.orbit_spec.altitude is not None else params.orbit.altitude_initial
    r0 = params.orbit.earth_radius + h
    if case.orbit_spec.align == "retrograde":
        r_hat = np.array([-math.sin(theta_B), math.cos(theta_B)])
    else:
        r_hat = np.array([1.0, 0.0])
    v_hat = _perp(r_hat)  # counter-clockwise (prograde, equatorial)
    return r0 * r_hat, math.sqrt(params.orbit.mu / r0) * v_hat


def place_on_orbit(case: Case, params: Params, init: InitialConfiguration, com: np.ndarray,
                   vcom: np.ndarray) -> InitialConfiguration:
    """Put O on the case's circular orbit; with centre_on_com, O := system COM first."""
    shift = np.zeros(2)
    vshift = np.zeros(2)
    if case.orbit_spec.centre_on_com:
        shift, vshift = np.asarray(com, float), np.asarray(vcom, float)
    r, v = orbit_start(case, params, float(init.base_pose[2]))
    bp, bv, tp, tv = (init.base_pose.copy(), init.base_rate.copy(), init.target_pose.copy(),
                      init.target_rate.copy())
    bp[:2] -= shift
    tp[:2] -= shift
    bv[:2] -= vshift
    tv[:2] -= vshift
    return dataclasses.replace(init, base_pose=bp, base_rate=bv, target_pose=tp, target_rate=tv,
                               orbit_r=r, orbit_v=v)


def _close_arm2(params, base_pose, base_rate, guess, target_pose, target_rate, rho2, where):
    """Joint angles/rates of arm 2 that put its end effector on grasp point 2 (least norm)."""
    goal = target_pose[:2] + rot(target_pose[2]) @ rho2
    lever = goal - target_pose[:2]
    goal_v = target_rate[:2] + target_rate[2] * np.array([-lever[1], lever[0]])
    a = np.array(guess, float)
    for _ in range(50):
        p, _, _, _, jac = rigid_arm(params, base_pose, base_rate, a, np.zeros(3), 2)
        err = goal - p
        if np.linalg.norm(err) < 1e-13:
            break
        a = a + np.linalg.pinv(jac) @ err
    else:
        raise InputError(where, "initial.joint_angles_deg",
                         f"arm 2 cannot reach grasp point 2 (gap {np.linalg.norm(err):.3g} m)")
    _, v0, _, _, jac = rigid_arm(params, base_pose, base_rate, a, np.zeros(3), 2)
    rates = np.linalg.pinv(jac) @ (goal_v - v0)
    _, v, _, _, _ = rigid_arm(params, base_pose, base_rate, a, rates, 2)
    if np.linalg.norm(v - goal_v) > 1e-9:
        raise InputError(where, "initial.joint_rates", "arm 2 cannot follow grasp point 2 (singular arm)")
    return a, rates
