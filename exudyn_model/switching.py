"""Capture and release in the Exudyn model (docs/physics.md §4.2, §4.4; docs/exudyn.md §1):
the grasp joint and the wrist bistop switched by `activeConnector`, the terminal link's
frame redefined by switching its prismatic constraint (PP: chord, PF: mass-orthogonal
axis), and the velocities projected on the active constraints (plastic impact).  The
reference's mirror is `reference_model/switching.py`.

Functions of the built model (`build.ExudynModel`) and the run's state
(`state.EngineState`): they change the state (grasps, grasp points, bases), the mbs's
connectors and velocities, and restart the integrator through the engine's stepper.
"""

from __future__ import annotations

import math

import numpy as np

from exudyn_model.build import PF, PP
from exudyn_model.observe import end_effectors
from exudyn_model.state import EngineState, coordinates
from rsmcheck.core.errors import SimulationDiverged
from rsmcheck.core.geometry import rot


def capture(model, state: EngineState, stepper, cf, arm: int) -> dict[str, float]:
    """Switch grasp `arm` (1, 2) on at the current sample: the terminal link to PP, the
    grasp point where the end effector is, the grasp joint and the wrist bistop on, the
    plastic impact (by `cf`, the model's `reactions.ConstraintForces`), a restart."""
    stepper.pause()
    k = arm - 1
    info = switch_basis(model, state, 3 * k + 2, PP)
    q, v = coordinates(model, state)
    rE, _ = end_effectors(model, q, v)
    XT = q[model.index.i_target]
    state.rho_G[k] = rot(XT[2]).T @ (rE[k] - XT[:2])
    mbs = model.mbs
    mbs.SetMarkerParameter(model.grasp_markers[k], "localPosition", [*state.rho_G[k], 0.0])
    mbs.SetObjectParameter(model.grasp_joints[k], "activeConnector", True)
    mbs.SetObjectParameter(model.bistops[k], "activeConnector", True)
    state.grasp_on[k] = 1
    info["impact_loss_J"] = plastic_impact(model, cf, stepper.name, state.t)
    stepper.restart()
    return info


def release(model, state: EngineState, stepper, cf, arm: int) -> dict[str, float]:
    """Switch grasp `arm` off: the grasp joint and the wrist bistop off, the terminal link
    to PF, the plastic impact, a restart."""
    stepper.pause()
    k = arm - 1
    mbs = model.mbs
    mbs.SetObjectParameter(model.grasp_joints[k], "activeConnector", False)
    mbs.SetObjectParameter(model.bistops[k], "activeConnector", False)
    state.grasp_on[k] = 0
    info = switch_basis(model, state, 3 * k + 2, PF)
    info["impact_loss_J"] = plastic_impact(model, cf, stepper.name, state.t)
    stepper.restart()
    return info


def switch_basis(model, state: EngineState, i: int, new: str) -> dict[str, float]:
    """Redefine the frame of terminal link i (docs/physics.md §4.4): the frame body turns
    by δ to the chord (PP) or to the mass-orthogonal axis (PF); the beam, the pins and
    the rotor do not move, so θ_J3 jumps by δ and there is no projection residual.  The
    frame body keeps its angular velocity: the caller's `plastic_impact` brings it to
    the new axis's rate, coupling J_extra to the system by internal impulses
    (physics.md §2.3, momentum conserved).  The integrator must be paused."""
    it = model.links[i]
    if it.rigid or state.basis[i] == new:
        state.basis[i] = new
        return {"delta_rad": 0.0, "residual_m": 0.0, "residual_mps": 0.0}
    q, v = coordinates(model, state)
    qi = q[it.coords]
    R = qi[0:2]
    if new == PP:
        d = qi[-4:-2] - R
    else:
        d = first_moment(model, qi)
    theta_new = math.atan2(d[1], d[0])
    j = model.index.i_frame[i]
    th_old = q[j]
    delta = math.remainder(theta_new - th_old, 2 * math.pi)
    mbs = model.mbs
    sd = mbs.systemData
    qc, vc = np.asarray(sd.GetODE2Coordinates()), np.asarray(sd.GetODE2Coordinates_t())
    qc[j] += delta
    # P = R + (L/I_0) ∫ρξ(r − R)dξ tied to the beam in PF, parked at its reference in PP
    # (build.py): its coordinates are placed where the new constraints hold
    ip = it.p_coords
    if new == PF:
        scale = model.params.link.length / model.I0
        qc[ip] = R + scale * d - model.index.q_ref[ip]
        vc[ip] = v[it.coords][0:2] + scale * first_moment(model, v[it.coords])
    else:
        qc[ip] = 0.0
        vc[ip] = 0.0
    sd.SetODE2Coordinates(qc)
    sd.SetODE2Coordinates_t(vc)
    mbs.SetObjectParameter(it.pp_joint, "activeConnector", new == PP)
    mbs.SetObjectParameter(it.pf_joint, "activeConnector", new == PF)
    mbs.SetObjectParameter(it.p_tie, "activeConnector", new == PF)
    for park in it.p_park:
        mbs.SetObjectParameter(park, "activeConnector", new == PP)
    state.basis[i] = new
    return {"delta_rad": float(delta), "residual_m": 0.0, "residual_mps": 0.0}


def first_moment(model, qi: np.ndarray) -> np.ndarray:
    """∫ρξ(r − R)dξ of a beam from its coordinates qi (or the same of ṙ from its
    velocities): the direction of the PF axis (docs/physics.md §2.1) [kg·m²]."""
    return model.moment @ qi - 0.5 * model.params.link.mass * model.params.link.length * qi[0:2]


def plastic_impact(model, cf, name: str = "exudyn", t: float = math.nan) -> float:
    """Mass-weighted projection of the velocities on the active constraints
    (docs/physics.md §4.2, and §2.3 at a basis switch): [M Gᵀ; G 0][v⁺; μ] = [M v; 0].
    Returns the energy lost.  `name`, `t`: the engine's and the time, for the error."""
    # M and the constraint Jacobian at the current state from Exudyn's own functions, by
    # the separate static solver object `cf` (exudyn_model.reactions: the integrator's own
    # matrices are factorised sparse and must not be disturbed; that helper also keeps
    # the system state that the static solver's initialisation would overwrite)
    mbs = model.mbs
    M = cf.mass_matrix()
    J = cf.constraint_jacobian()
    n2 = cf.n2
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(J))):
        raise SimulationDiverged(name, t, "?", "mass matrix / constraint Jacobian at a capture or release", float("nan"))
    G = J[n2:, :n2]  # AE rows (no ODE1 coordinates)
    G = G[np.any(G != 0.0, axis=1)]
    v = np.asarray(mbs.systemData.GetODE2Coordinates_t())
    nc = G.shape[0]
    K = np.block([[M, G.T], [G, np.zeros((nc, nc))]])
    sol = np.linalg.lstsq(K, np.concatenate([M @ v, np.zeros(nc)]), rcond=None)[0]
    vp = sol[:n2]
    mbs.systemData.SetODE2Coordinates_t(vp)
    return float(0.5 * v @ M @ v - 0.5 * vp @ M @ vp)
