"""Index tables of the built Exudyn model: the global ODE2 indices of the coordinates the
engine reads (base, target, link frames, hubs, rotors, each link's beam or body, the point
P of a PF axis), the sensors' rows gathered in one index array, and the link coordinates
stacked with the matrix of their first mass moments.  Made once by
`exudyn_model.build.build_model` after `Assemble`; they do not change during a run.
"""

from __future__ import annotations

import contextlib
import io
import sys
from dataclasses import dataclass

import numpy as np

sys.exudynFast = True  # the engine's build: import order must not matter
# exudyn announces the fast build on stdout: keep it out of `--json` output
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu  # noqa: E402


@dataclass(frozen=True)
class IndexTables:
    """Global ODE2 indices (into q, q̇ of the whole mbs)."""

    i_base: np.ndarray  # base x, y, θ_B
    i_target: np.ndarray  # target x, y, θ_T
    i_frame: np.ndarray  # (6,) each link's frame angle θ_i
    i_hub_prox: np.ndarray  # (6,) rotation of each link's proximal end section
    i_hub_dist: np.ndarray  # (6,) the same, distal
    i_rotor: np.ndarray  # (6,) θ_m
    hub_parent: np.ndarray  # (6,) each joint's parent section (the base's θ for a first joint)
    frame_parent: np.ndarray  # (6,) each joint's parent frame (the base's θ for a first joint)
    wrist_hub: np.ndarray  # (2,) each terminal link's distal section
    ee: np.ndarray | None  # (2, 2) the end effectors' x, y (flexible: tip nodes), rigid: None
    sensor_rows: np.ndarray  # every coordinate the sensors read, in one gather per sample
    sensor_at: dict  # name → slice of `sensor_rows` (base, target, rotor, hub_prox, ...)
    q_ref: np.ndarray  # the reference configuration (Exudyn's coordinates are relative to it)
    link_coords: np.ndarray  # every link's coordinates, stacked
    link_first: np.ndarray  # ∫ρ r dξ of every link as one matrix on `link_coords`


def index_tables(model) -> IndexTables:
    """The tables of an assembled `ExudynModel`; also gives each link item its `coords`
    (and a terminal flexible link its `p_coords`)."""
    mbs = model.mbs
    idx = mbs.GetNodeODE2Index
    i_base = idx(model.base_node) + np.arange(3)
    i_target = idx(model.target_node) + np.arange(3)
    i_frame = np.array([idx(it.frame_node) + 2 for it in model.links])
    i_hub_prox = np.array([idx(it.prox_hub) + 2 for it in model.links])
    i_hub_dist = np.array([idx(it.dist_hub) + 2 for it in model.links])
    i_rotor = np.array([idx(n) for n in model.rotor_nodes])
    for it in model.links:
        if it.rigid:
            it.coords = idx(it.frame_node) + np.arange(3)
        else:
            it.coords = np.concatenate([idx(n) + np.arange(4) for n in it.nodes])
        if it.p_node is not None:
            it.p_coords = idx(it.p_node) + np.arange(2)
    # the sensors' pairs (`observe.Observer.sensors`): each joint's parent hub and parent
    # frame (the base's θ for the first joint of an arm), each wrist's terminal distal hub,
    # the end effectors' x, y (the tip nodes of flexible terminal links; rigid: None)
    i_thB = i_base[2]
    hub_parent = np.array([i_thB, *i_hub_dist[:2], i_thB, *i_hub_dist[3:5]])
    frame_parent = np.array([i_thB, *i_frame[:2], i_thB, *i_frame[3:5]])
    wrist_hub = i_hub_dist[[2, 5]]
    ee = None if model.rigid else np.array([model.links[2].coords[-4:-2], model.links[5].coords[-4:-2]])
    # all of them in one gather per sample: `sensor_rows`, and where each group lies in it
    # (`sensor_at`, name → slice)
    groups = {"base": i_base, "target": i_target, "rotor": i_rotor,
              "hub_prox": i_hub_prox, "hub_parent": hub_parent, "frame": i_frame,
              "frame_parent": frame_parent, "wrist_hub": wrist_hub}
    if not model.rigid:
        groups["ee"] = ee.reshape(-1)
    ends = np.cumsum([len(g) for g in groups.values()])
    sensor_at = {name: slice(int(e) - len(g), int(e)) for (name, g), e in zip(groups.items(), ends)}
    sensor_rows = np.concatenate(list(groups.values())).astype(np.int64)
    q_ref = np.asarray(mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference))
    # ∫ρ r dξ of every link as one matrix on the stacked link coordinates
    p = model.params
    link_coords = np.concatenate([it.coords for it in model.links])
    blocks = [np.hstack([p.link.mass * np.eye(2), np.zeros((2, 1))]) if it.rigid else model.first
              for it in model.links]
    return IndexTables(i_base=i_base, i_target=i_target, i_frame=i_frame, i_hub_prox=i_hub_prox,
                       i_hub_dist=i_hub_dist, i_rotor=i_rotor, hub_parent=hub_parent, frame_parent=frame_parent,
                       wrist_hub=wrist_hub, ee=ee, sensor_rows=sensor_rows, sensor_at=sensor_at, q_ref=q_ref,
                       link_coords=link_coords, link_first=np.hstack(blocks))
