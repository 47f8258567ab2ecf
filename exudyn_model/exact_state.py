"""The exact state of a run of the Exudyn model, for phase chaining
(rsmcheck.orchestration.chain): what `ExudynEngine.export_state` gives and
`ExudynEngine.import_state` takes, as functions of the built model
(`build.ExudynModel`) and the run's state (`state.EngineState`).
"""

from __future__ import annotations

import numpy as np

from exudyn_model.build import PP
from exudyn_model.state import EngineState, coordinates


def export_state(name: str, model, state: EngineState) -> dict:
    """Everything needed to continue this run in a new engine of the same model: absolute
    ODE2 coordinates and velocities (with the link deformation), the bistop data
    coordinates, grasp flags, held points, terminal-link bases."""
    q, v = coordinates(model, state)
    i_base = model.index.i_base
    return {"engine": name, "rigid": model.rigid, "n_elements": model.n_elements,
            "q": q.copy(), "v": v.copy(), "data": np.asarray(model.mbs.systemData.GetDataCoordinates(), float),
            "grasp_on": state.grasp_on.copy(), "rho_G": state.rho_G.copy(),
            "basis": list(state.basis), "base_pose": q[i_base].copy(),
            "base_rate": v[i_base].copy()}


def import_state(name: str, model, state: EngineState, stepper, exact: dict, base_start: tuple) -> None:
    """Continue from `export_state()` of an engine of the same model (same links, element
    count, grasps and bases: the model is built from the rigid part of the same end
    state).  A shift of O between the phases (placing O on the orbit at the system COM,
    rsmcheck.orchestration.chain) moves every position coordinate by the base's shift
    (`base_start`: the base's pose and rate this model was built at).  An exact state of
    another model size is not used: the run starts from the rigid end state."""
    q_new, v_new = coordinates(model, state)
    same = (exact.get("engine") == name and bool(exact.get("rigid")) == model.rigid
            and int(exact.get("n_elements", -1)) == model.n_elements
            and len(exact.get("q", ())) == len(q_new)
            and list(exact.get("grasp_on", ())) == list(state.grasp_on)
            and list(exact.get("basis", ())) == list(state.basis))
    if not same:
        return
    shift = base_start[0][:2] - np.asarray(exact["base_pose"], float)[:2]
    shift_v = base_start[1][:2] - np.asarray(exact["base_rate"], float)[:2]
    q = np.asarray(exact["q"], float)
    v = np.asarray(exact["v"], float)
    for i in position_coordinates(model.mbs):
        q[i] += shift
        v[i] += shift_v
    q_ref = model.index.q_ref
    for i, it in enumerate(model.links):  # a PP link's P stays parked at this model's reference (build.py)
        if it.p_node is not None and state.basis[i] == PP:
            q[it.p_coords], v[it.p_coords] = q_ref[it.p_coords], 0.0
    sd = model.mbs.systemData
    sd.SetODE2Coordinates(q - q_ref)
    sd.SetODE2Coordinates_t(v)
    sd.SetDataCoordinates(np.asarray(exact["data"], float))
    state.rho_G = np.asarray(exact["rho_G"], float).copy()
    for k in range(2):
        model.mbs.SetMarkerParameter(model.grasp_markers[k], "localPosition", [*state.rho_G[k], 0.0])
    state.start_label = "exact end state"
    stepper.restart()


def position_coordinates(mbs) -> list[np.ndarray]:
    """Global ODE2 indices (x, y) of every node position (rigid-body and ANCF nodes)."""
    out = []
    for n in range(mbs.systemData.NumberOfNodes()):
        if mbs.GetNode(n)["nodeType"] in ("RigidBody2D", "Point2DSlope1"):
            out.append(mbs.GetNodeODE2Index(n) + np.arange(2))
    return out
