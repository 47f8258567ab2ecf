"""The robot's coupled frequencies from MuJoCo's own linearisation: at rest in a case's
initial configuration, undamped, M (`mj_fullM`, with the rotor armature and the frame
tendons), K the central difference of MuJoCo's passive forces (bending hinges, joint
springs), on the null space of the active grasps' Jacobians (rigid grasps)."""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import eigh, null_space

from rsmcheck.core.cases import Case, at_rest


def coupled_frequencies(case: Case, n: int = 6, f_min: float = 1.0, **engine_options) -> np.ndarray:
    """The first `n` eigenfrequencies [Hz] above `f_min` of the robot of `case` at rest."""
    import mujoco

    from mujoco_model.engine import MujocoEngine
    from mujoco_model.switching import _jacobians

    e = MujocoEngine(at_rest(case), **engine_options)
    m, d = e.mm.model, e.d
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)
    M = e.mass_matrix()
    q0 = d.qpos.copy()
    K = np.zeros((m.nv, m.nv))
    eps = 1e-7
    for j in range(m.nv):
        for sign in (1.0, -1.0):
            d.qpos[:] = q0
            d.qpos[j] += sign * eps
            mujoco.mj_forward(m, d)
            K[:, j] -= sign * d.qfrc_passive / (2 * eps)
    d.qpos[:] = q0
    mujoco.mj_forward(m, d)
    G = _jacobians(e, [k for k in range(2) if e.state.grasp_on[k]])
    Z = null_space(G) if G.shape[0] else np.eye(m.nv)
    lam = eigh(Z.T @ (0.5 * (K + K.T)) @ Z, Z.T @ M @ Z, eigvals_only=True)
    f = np.sqrt(np.clip(lam, 0.0, None)) / (2 * math.pi)
    return f[f > f_min][:n]
