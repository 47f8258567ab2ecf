"""Capture, release, the terminal link's basis switch and the plastic impact
(docs/physics.md §4.2, §4.4), on the MuJoCo model.

* The held point is the target's point under the end effector at the capture (the hold
  site is moved there), and the grasp's `connect` equality is switched on (`eq_active`).
* The impact is not left to the soft constraint (which absorbs it only partly): the
  velocities are projected in Python, with MuJoCo's mass matrix and the grasps' Jacobians
  (`mj_jacSite`): [M⁺ Gᵀ; G 0][q̇⁺; μ] = [M⁻ q̇⁻; 0].  M⁻, M⁺ differ by the frame tendon
  of the switched link (J_extra on the new frame): the generalised momentum is kept, so
  the switch's impulse is internal (docs/physics.md §4.4).  Positions do not move: the
  pieces are the material; only the frame the observables read changes.
"""

from __future__ import annotations

import numpy as np

from rsmcheck.core.geometry import rot


def _jacobians(engine, arms) -> np.ndarray:
    """(2·len(arms), nv): x, y rows of ∂(end effector − held point)/∂q per arm."""
    mj, m, d, ix = engine._mj, engine.mm.model, engine.d, engine.mm.index
    rows = []
    for k in arms:
        ja, jb = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mj.mj_jacSite(m, d, ja, None, int(ix.tip_site[k]))
        mj.mj_jacSite(m, d, jb, None, int(ix.hold_site[k]))
        rows.append((ja - jb)[:2])
    return np.concatenate(rows) if rows else np.zeros((0, m.nv))


def _kinematics(engine) -> None:
    engine._mj.mj_forward(engine.mm.model, engine.d)
    engine._fresh = True


def _project(engine, M_old: np.ndarray, basis_new: list) -> float:
    """q̇ onto the active grasps with the generalised momentum kept; the links' bases
    switched to `basis_new` (M⁺).  Returns the kinetic energy lost [J]."""
    d = engine.d
    v = d.qvel.copy()
    engine.set_basis(basis_new)
    _kinematics(engine)
    M_new = engine.mass_matrix()
    arms = [k for k in range(2) if engine.state.grasp_on[k]]
    G = _jacobians(engine, arms)
    nv, nc = len(v), G.shape[0]
    A = np.zeros((nv + nc, nv + nc))
    A[:nv, :nv] = M_new
    A[:nv, nv:] = G.T
    A[nv:, :nv] = G
    rhs = np.concatenate([M_old @ v, np.zeros(nc)])
    vp = np.linalg.solve(A, rhs)[:nv]
    d.qvel[:] = vp
    _kinematics(engine)
    return float(0.5 * v @ M_old @ v - 0.5 * vp @ M_new @ vp)


def _frame_angle(engine, k: int) -> float:
    return float(engine.observer.kin().frame[k, 2])


def _switch(engine, k: int, on: bool) -> dict[str, float]:
    """Grasp k on (its terminal link then pinned–pinned) or off (pinned–free): the equality
    switched, the velocities projected from the mass matrix before the switch."""
    st, d, ix = engine.state, engine.d, engine.mm.index
    before = _frame_angle(engine, k)
    M_old = engine.mass_matrix()
    st.grasp_on[k] = int(on)
    d.eq_active[ix.grasp_eq[k]] = int(on)
    basis = list(st.basis)
    basis[3 * k + 2] = "PP" if on else "PF"
    loss = _project(engine, M_old, basis)
    return {"delta_rad": _frame_angle(engine, k) - before, "residual_m": 0.0, "residual_mps": 0.0,
            "impact_loss_J": loss}


def capture(engine, arm: int) -> dict[str, float]:
    st, d, ix = engine.state, engine.d, engine.mm.index
    k = arm - 1
    _kinematics(engine)
    rE = d.site_xpos[ix.tip_site[k], :2].copy()
    XT = d.qpos[ix.target].copy()
    st.rho_G[k] = rot(XT[2]).T @ (rE - XT[:2])
    engine.mm.model.site_pos[ix.hold_site[k], :2] = st.rho_G[k]
    return _switch(engine, k, True)


def release(engine, arm: int) -> dict[str, float]:
    _kinematics(engine)
    return _switch(engine, arm - 1, False)


def grasp_forces(engine) -> np.ndarray:
    """R_cl: the force on the target at each held point (inertial x, y; 0 where a grasp is
    off), from the `connect` rows of MuJoCo's constraint forces: the equality's residual is
    end effector − held point, so its force acts +f on the arm and −f on the target."""
    mj, d, ix = engine._mj, engine.d, engine.mm.index
    out = np.zeros(4)
    eq_type = int(mj.mjtConstraint.mjCNSTR_EQUALITY)
    n = int(d.nefc)
    types, ids, forces = d.efc_type[:n], d.efc_id[:n], d.efc_force[:n]
    for k in range(2):
        if not engine.state.grasp_on[k]:
            continue
        rows = np.flatnonzero((types == eq_type) & (ids == ix.grasp_eq[k]))
        out[2 * k:2 * k + 2] = -forces[rows[:2]]
    return out
