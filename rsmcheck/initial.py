"""Initial conditions shared by the engines: body poses and rates from a case's spec.

This is input geometry, not dynamics: the links start undeformed (rigid, zero
amplitudes), so the poses follow from the parameters by plane trigonometry.  The target's
pose follows from the holding arm and the wrist angle ψ = θ_T − θ_3 (docs/physics.md
§4.3).  When both arms hold the target, arm 2's joint angles and rates are solved so that
its end effector sits on (and moves with) grasp point 2: least-norm Newton on the three
joint angles from the case's values as first guess.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cases.loader import Case
from rsmcheck.errors import InputError
from rsmcheck.params import Params


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


def _rot(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def rigid_arm(params: Params, base_pose, base_rate, angles, rates, arm: int):
    """End effector position, velocity, terminal frame angle and rate, and the 2×3 Jacobian
    of the end effector w.r.t. the arm's joint angles, for undeformed links."""
    L = params.link.length
    th = base_pose[2]
    om = base_rate[2]
    p = np.asarray(base_pose[:2], float) + _rot(th) @ np.asarray(params.geometry.mount_B(arm))
    v = np.asarray(base_rate[:2], float) + om * np.array([-(p - base_pose[:2])[1], (p - base_pose[:2])[0]])
    pins = []
    for s in range(3):
        pins.append(p.copy())
        th = th + angles[s]
        om = om + rates[s]
        d = L * np.array([math.cos(th), math.sin(th)])
        p = p + d
        v = v + om * np.array([-d[1], d[0]])
    # column s: ∂r_EE/∂θ_Js = e_z × (r_EE − r_pin,s)
    jac = np.array([[-(p - c)[1], (p - c)[0]] for c in pins]).T
    return p, v, th, om, jac


def build_initial(case: Case, params: Params | None = None) -> InitialConfiguration:
    params = params or case.params
    spec = case.initial
    geo = params.geometry
    base_pose = np.array(spec.base_pose, float)
    base_rate = np.array(spec.base_rate, float)
    q = np.radians(np.array(spec.joint_angles_deg, float))
    qd = np.array(spec.joint_rates, float)
    grasp = np.array(spec.grasp, dtype=np.int64)
    rho_G = np.array([geo.grasp_T(1), geo.grasp_T(2)], float)

    if grasp.any():
        k = 0 if grasp[0] else 1
        p, v, th3, om3, _ = rigid_arm(params, base_pose, base_rate, q[3 * k:3 * k + 3], qd[3 * k:3 * k + 3], k + 1)
        thT = th3 + math.radians(spec.wrist_angle_deg)
        omT = om3
        rT = p - _rot(thT) @ rho_G[k]
        lever = rT - p
        vT = v + omT * np.array([-lever[1], lever[0]])
        target_pose = np.array([rT[0], rT[1], thT])
        target_rate = np.array([vT[0], vT[1], omT])
        if grasp[0] and grasp[1]:
            q[3:6], qd[3:6] = _close_arm2(params, base_pose, base_rate, q[3:6], target_pose, target_rate, rho_G[1], case.path)
    else:
        target_pose = np.array(spec.target_pose, float)
        target_rate = np.array(spec.target_rate, float)

    orbit_r = np.zeros(2)
    orbit_v = np.zeros(2)
    if case.orbit:
        r0 = params.orbit.earth_radius + params.orbit.altitude_initial
        orbit_r = np.array([r0, 0.0])
        orbit_v = np.array([0.0, math.sqrt(params.orbit.mu / r0)])
    return InitialConfiguration(base_pose, base_rate, q, qd, target_pose, target_rate, grasp, rho_G,
                                orbit_r, orbit_v)


def _close_arm2(params, base_pose, base_rate, guess, target_pose, target_rate, rho2, where):
    """Joint angles/rates of arm 2 that put its end effector on grasp point 2 (least norm)."""
    goal = target_pose[:2] + _rot(target_pose[2]) @ rho2
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
