"""Plane geometry shared by the driver, the engines' inputs and outputs, and the report.

* `rot(a)`: the rotation matrix A(a) (components in a frame turned by `a` → outer frame);
* the rigid three-link arm (straight links of equal length from a mount point):
  `arm_pins` (mount, elbows, end effector), `arm_jacobian` (∂ end effector / ∂ joint
  angles) and `rigid_arm` (the same in inertial axes on a moving base, with velocities).

These serve inputs (initial configurations, the controllers' own kinematic model) and
outputs (observables, chained end states, drawings).  Each engine still builds its own
model of the flexible links, and the compiled kernels of reference_model/kinematics.py keep
their own inline arithmetic.  Plain float arithmetic where a controller calls it at every
control sample.
"""

from __future__ import annotations

import math

import numpy as np


def rot(a: float) -> np.ndarray:
    """A(a) = [[cos a, −sin a], [sin a, cos a]]."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def arm_pins(x: float, y: float, theta: float, length: float, angles) -> list[tuple[float, float]]:
    """The four pins of a rigid three-link arm as (x, y) floats: the mount at (x, y), then
    the distal pin of link s at the angle θ + angles[0] + … + angles[s] (relative joint
    angles, `theta` the angle of the frame the mount is attached to); the last pin is the
    end effector."""
    out = [(x, y)]
    for s in range(3):
        theta += float(angles[s])
        x += length * math.cos(theta)
        y += length * math.sin(theta)
        out.append((x, y))
    return out


def arm_jacobian(pins: list[tuple[float, float]], attitude: bool = False) -> np.ndarray:
    """∂(x, y)/∂(θ_J1, θ_J2, θ_J3) of the end effector e = pins[3]: column s is
    e_z × (e − p_s) = (−(e − p_s)_y, (e − p_s)_x).  With `attitude`, a third row of ones:
    ∂φ/∂θ_Js of the terminal-link attitude φ = θ_J1 + θ_J2 + θ_J3."""
    ex, ey = pins[3]
    rows = [[-(ey - pins[0][1]), -(ey - pins[1][1]), -(ey - pins[2][1])],
            [ex - pins[0][0], ex - pins[1][0], ex - pins[2][0]]]
    if attitude:
        rows.append([1.0, 1.0, 1.0])
    return np.array(rows)


def rigid_arm(params, base_pose, base_rate, angles, rates, arm: int):
    """End effector position, velocity, terminal frame angle and rate, and the 2×3 Jacobian
    of the end effector w.r.t. the arm's joint angles, for undeformed links of arm `arm`
    (1, 2) on a base at `base_pose` (x, y, θ_B) moving with `base_rate`; inertial axes."""
    L = params.link.length
    th = base_pose[2]
    om = base_rate[2]
    p = np.asarray(base_pose[:2], float) + rot(th) @ np.asarray(params.geometry.mount_B(arm))
    v = np.asarray(base_rate[:2], float) + om * np.array([-(p - base_pose[:2])[1], (p - base_pose[:2])[0]])
    pins = arm_pins(float(p[0]), float(p[1]), th, L, angles)
    for s in range(3):
        th = th + angles[s]
        om = om + rates[s]
        d = L * np.array([math.cos(th), math.sin(th)])
        v = v + om * np.array([-d[1], d[0]])
    return np.array(pins[3]), v, th, om, arm_jacobian(pins)
