"""One link of the finite-segment model alone, and its bending frequencies from MuJoCo's own
mass matrix, passive stiffness and pin Jacobian (`rsmcheck modes`, tests).

The link hangs on a hinge at the world origin (its proximal pin).  PF: nothing else.  PP:
the distal pin is held by the rigid constraint on the null space of its Jacobian (MuJoCo's
`mj_jacSite`), so the frequencies are those of the segment chain itself, free of the soft
constraint's compliance.  M is `mj_fullM` (with the link frame's J_extra on its tendon),
K the finite difference of `qfrc_passive` (the hinge springs), at the straight link.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import eigh, null_space

from mujoco_model.build import N_SEGMENTS_DEFAULT, frame_inertia, frame_weights, piece_bounds, piece_rotary_inertia
from rsmcheck.core.params import Params


def link_xml(p: Params, n: int, basis: str) -> str:
    """A single link on a hinge at the world origin, its pieces and hinges as in the robot
    (build.model_xml), with the frame tendon of `basis` carrying J_extra."""
    lk = p.link
    ell = lk.length / n
    bounds = piece_bounds(lk.length, n)
    out = ['<mujoco><compiler angle="radian"/><option gravity="0 0 0"><flag contact="disable"/></option>',
           "<worldbody>"]
    for q in range(n + 1):
        a, b = bounds[q]
        if q == 0:
            out.append('<body name="p0"><joint name="pin" type="hinge" axis="0 0 1"/>')
        else:
            out.append(f'<body name="p{q}" pos="{(ell / 2 if q == 1 else ell)!r} 0 0">'
                       f'<joint name="b{q - 1}" type="hinge" axis="0 0 1" stiffness="{lk.ei / ell!r}"/>')
        m, length = float(lk.rho_a * (b - a)), float(b - a)
        j = piece_rotary_inertia(m, length)
        out.append(f'<inertial pos="{length / 2!r} 0 0" mass="{m!r}" diaginertia="{j / 2!r} {j / 2!r} {j!r}"/>')
    out.append(f'<site name="tip" pos="{ell / 2!r} 0 0"/>' + "</body>" * (n + 1))
    w = frame_weights(lk.length, n, basis)
    parts = '<joint joint="pin" coef="1"/>' + "".join(f'<joint joint="b{q}" coef="{float(w[q])!r}"/>' for q in range(n))
    out.append(f'</worldbody><tendon><fixed name="frame" armature="{frame_inertia(p, n)!r}">{parts}</fixed></tendon>'
               "</mujoco>")
    return "".join(out)


def link_matrices(p: Params, n: int, basis: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, K, G) of one link at rest: MuJoCo's mass matrix, the finite-difference stiffness
    of its passive forces, and the distal pin's Jacobian (2 × nv; empty for PF)."""
    import mujoco

    m = mujoco.MjModel.from_xml_string(link_xml(p, n, basis))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    K = np.zeros((m.nv, m.nv))
    eps = 1e-7
    for j in range(m.nv):
        for sign in (1.0, -1.0):
            d.qpos[:] = 0.0
            d.qpos[j] = sign * eps
            mujoco.mj_forward(m, d)
            K[:, j] -= sign * d.qfrc_passive / (2 * eps)
    d.qpos[:] = 0.0
    mujoco.mj_forward(m, d)
    jacp = np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jacp, None, m.site("tip").id)
    G = jacp[:2] if basis == "PP" else np.zeros((0, m.nv))
    return M, 0.5 * (K + K.T), G


def link_frequencies(params: Params, basis: str, n_segments: int | None = None, n: int = 2) -> np.ndarray:
    """The first `n` bending frequencies [Hz] of one link in `basis` ("PP": pinned at both
    ends, "PF": pinned-free), from MuJoCo's M, K and pin Jacobian (module doc)."""
    M, K, G = link_matrices(params, n_segments or N_SEGMENTS_DEFAULT, basis)
    Z = null_space(G) if G.shape[0] else np.eye(M.shape[0])
    lam = eigh(Z.T @ K @ Z, Z.T @ M @ Z, eigvals_only=True)
    f = np.sqrt(np.clip(lam, 0.0, None)) / (2 * math.pi)
    return f[f > 1e-3 * max(f.max(), 1.0)][:n]
