"""Index tables of the built Exudyn model: the global ODE2 indices of the coordinates the
engine reads (base, target, link frames, hubs, rotors, each link's beam or body, the point
P of a PF axis), how each sensor is read from them (one compiled gather), and the link coordinates
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


#: the sensors' places in the buffer `observe.Observer.sensors` fills at every sample (name →
#: slice; `ee_pos_I`, `ee_vel_I` row by row); the last two, the COM in base axes, are computed
SENSOR_LAYOUT = {"base_pose_I": slice(0, 3), "base_rate_I": slice(3, 6), "joint_angles": slice(6, 12),
                 "joint_rates": slice(12, 18), "joint_frame_angles": slice(18, 24),
                 "joint_frame_rates": slice(24, 30), "wrist_angles": slice(30, 32), "motor_angles": slice(32, 38),
                 "motor_rates": slice(38, 44), "ee_pos_I": slice(44, 48), "ee_vel_I": slice(48, 52),
                 "target_pose_I": slice(52, 55), "target_rate_I": slice(55, 58), "com_pos_B": slice(58, 60)}
SENSOR_SIZE = 60


def sensor_table(i_base, i_target, i_rotor, i_hub_prox, hub_parent, i_frame, frame_parent, wrist_hub,
                 ee) -> np.ndarray:
    """Row j = (0: q, 1: q̇; i; k): sensor j of `SENSOR_LAYOUT` is x[i] − x[k] (a joint: its
    proximal hub or frame minus its parent's; a wrist: θ_T minus the terminal distal hub),
    or x[i] for k = −1.  The end effectors' rows read the tip nodes of flexible links; a
    rigid model's (`ee` None) are placeholders, overwritten by `observe.end_effectors`."""
    rows: list[tuple[int, int, int]] = []

    def add(src, a, b=None):
        rows.extend((src, int(i), -1 if b is None else int(k)) for i, k in zip(a, a if b is None else b))

    for src in (0, 1):
        add(src, i_base)
    for parent_of, items in ((hub_parent, i_hub_prox), (frame_parent, i_frame)):
        for src in (0, 1):
            add(src, items, parent_of)
    add(0, [i_target[2]] * 2, wrist_hub)
    for src in (0, 1):
        add(src, i_rotor)
    tips = np.zeros(4, dtype=np.int64) if ee is None else np.asarray(ee).reshape(-1)
    for src in (0, 1):
        add(src, tips)
    for src in (0, 1):
        add(src, i_target)
    table = np.array(rows, dtype=np.int64)
    assert len(table) == SENSOR_SIZE - 2
    return table


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
    sensor_table: np.ndarray  # (SENSOR_SIZE − 2, 3): how each sensor is read (`sensor_table`)
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
    # all of them in one compiled gather per sample (`observe.gather_sensors`)
    table = sensor_table(i_base, i_target, i_rotor, i_hub_prox, hub_parent, i_frame, frame_parent, wrist_hub, ee)
    q_ref = np.asarray(mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference))
    # ∫ρ r dξ of every link as one matrix on the stacked link coordinates
    p = model.params
    link_coords = np.concatenate([it.coords for it in model.links])
    blocks = [np.hstack([p.link.mass * np.eye(2), np.zeros((2, 1))]) if it.rigid else model.first
              for it in model.links]
    return IndexTables(i_base=i_base, i_target=i_target, i_frame=i_frame, i_hub_prox=i_hub_prox,
                       i_hub_dist=i_hub_dist, i_rotor=i_rotor, hub_parent=hub_parent, frame_parent=frame_parent,
                       wrist_hub=wrist_hub, ee=ee, sensor_table=table, q_ref=q_ref,
                       link_coords=link_coords, link_first=np.hstack(blocks))
