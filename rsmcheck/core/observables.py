"""The observable schema (docs/observables.md): what every engine writes, as data.

Each observable is one row of the table in docs/observables.md (generated from this
module and tested against it): a name, the shape of one time sample, its unit and what it
means.  An engine's result is a mapping name -> array whose first axis is the time sample;
`check_observables` is the one place that decides whether such a mapping is complete and
well formed (it is used by the HDF5 store before writing and after reading).

Conventions (docs/observables.md): SI units, radians.  Suffix `_B`: expressed in the base
body frame, relative to the base COM.  Suffix `_I`: inertial axes (positions relative to
the co-moving reference point).  Arm 1 comes before arm 2, and within an arm the joints
and links go from the base outward.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np


@dataclass(frozen=True)
class ObservableSpec:
    """One row of the observables table (docs/observables.md).  `shape` is the shape of one
    time sample (() for a scalar)."""

    name: str
    shape: tuple[int, ...]
    unit: str
    meaning: str

    @property
    def size(self) -> int:
        """Number of scalar components per time sample."""
        return int(np.prod(self.shape, dtype=int))


OBSERVABLES: tuple[ObservableSpec, ...] = (
    ObservableSpec("time", (), "s", "simulation time"),
    ObservableSpec(
        "base_pose_I", (3,), "m, m, rad",
        "base COM x, y (relative to the co-moving reference point) and attitude θ_B",
    ),
    ObservableSpec(
        "target_pose_B", (3,), "m, m, rad",
        "target COM position and attitude relative to the base",
    ),
    ObservableSpec("ee1_pos_B", (2,), "m", "end-effector 1 position (paper Figs. 7, 8)"),
    ObservableSpec("ee2_pos_B", (2,), "m", "end-effector 2 position (paper Figs. 7, 8)"),
    ObservableSpec("ee2_speed", (), "m/s", "absolute speed of end effector 2 (Fig. 6)"),
    ObservableSpec(
        "capture_gap_B", (2,), "m", "end effector minus designated capture point (Fig. 10)"
    ),
    ObservableSpec("com_pos_B", (2,), "m", "system COM (Fig. 12)"),
    ObservableSpec(
        "joint_angles", (6,), "rad",
        "ψ_J, section-relative: child's proximal end section relative to the parent's distal "
        "one, what a link-side joint encoder reads (docs/physics.md §3.3); arm 1 then arm 2, "
        "base outward",
    ),
    ObservableSpec(
        "joint_frame_angles", (6,), "rad",
        "θ_J, between link frames (the coordinate of Y, docs/physics.md §1)",
    ),
    ObservableSpec(
        "wrist_angles", (2,), "rad",
        "ψ_w = θ_T − distal section angle of the terminal link, arm 1 then arm 2 (the bistop's "
        "angle, docs/physics.md §4.3; reported also while the arm holds nothing)",
    ),
    ObservableSpec("motor_angles", (6,), "rad", "θ_m, arm 1 then arm 2, base outward"),
    ObservableSpec(
        "motor_torques", (6,), "N·m", "applied τ_m after saturation (Fig. 14)"
    ),
    ObservableSpec("base_torque", (), "N·m", "applied τ_B after saturation"),
    ObservableSpec(
        "link_deflection", (6,), "m",
        "elastic transverse displacement at mid-span relative to the link frame (Fig. 15)",
    ),
    ObservableSpec("target_attitude", (), "rad", "target attitude θ_T, inertial (Fig. 9)"),
    ObservableSpec(
        "reaction_forces_I", (4,), "N",
        "R_cl, inertial components (Fig. 4), grasp 1 x, y then grasp 2 x, y; "
        "0 where a grasp is off",
    ),
    ObservableSpec(
        "constraint_residual", (4,), "m",
        "φ_T of eq. (8), grasp 1 x, y then grasp 2 x, y",
    ),
    ObservableSpec("grasp_state", (2,), "1", "1 where arm k holds the target, else 0"),
    ObservableSpec(
        "energy", (3,), "J",
        "kinetic, elastic (links + joint springs), gravitational",
    ),
    ObservableSpec(
        "momentum_I", (3,), "kg·m/s, kg·m/s, kg·m²/s",
        "linear x, y and angular momentum about the reference point",
    ),
    ObservableSpec(
        "altitude", (), "m", "altitude of the system COM above R_E (Fig. 16)"
    ),
    ObservableSpec(
        "target_rel_lvlh", (2,), "m",
        "target COM relative to the base in the base's LVLH frame (Fig. 17)",
    ),
    ObservableSpec("system_mass", (), "kg", "total mass (propellant consumption)"),
)

BY_NAME: dict[str, ObservableSpec] = {spec.name: spec for spec in OBSERVABLES}
"""The rows of `OBSERVABLES` by name."""

NAMES: tuple[str, ...] = tuple(spec.name for spec in OBSERVABLES)
"""Observable names in the schema's order (`time` first)."""


def check_observables(data: Mapping[str, np.ndarray], where: str) -> int:
    """Check that `data` holds exactly the observables of docs/observables.md, well formed.

    Every name of `OBSERVABLES` must be present and no other; each array is numeric with
    shape (n, *spec.shape) for one common number of samples n >= 1; every value is
    finite; `time` does not decrease (equal times are allowed: the states just before and
    after an event); `grasp_state` holds only 0 and 1.

    Returns n.  Raises ValueError "<where>: observable '<name>': <what is wrong>".
    """

    def fail(name: str, reason: str) -> ValueError:
        return ValueError(f"{where}: observable '{name}': {reason}")

    unknown = sorted(set(data) - set(BY_NAME))
    if unknown:
        raise fail(unknown[0], f"unknown name (docs/observables.md has no such observable; "
                               f"{len(unknown)} unknown: {', '.join(unknown)})")
    missing = [name for name in NAMES if name not in data]
    if missing:
        raise fail(missing[0], f"missing ({len(missing)} missing: {', '.join(missing)})")

    n_samples: int | None = None
    for spec in OBSERVABLES:
        array = np.asarray(data[spec.name])
        if array.dtype.kind not in "biuf":
            raise fail(spec.name, f"must be numeric, got dtype {array.dtype}")
        if array.ndim != 1 + len(spec.shape):
            expected = ", ".join(["n_samples", *map(str, spec.shape)])
            raise fail(spec.name, f"expected shape ({expected}), got {array.shape}")
        if tuple(array.shape[1:]) != spec.shape:
            raise fail(
                spec.name,
                f"expected per-sample shape {spec.shape}, got {tuple(array.shape[1:])} "
                f"(array shape {array.shape})",
            )
        n = array.shape[0]
        if n_samples is None:
            if n < 1:
                raise fail(spec.name, "has no samples")
            n_samples = n
        elif n != n_samples:
            raise fail(
                spec.name,
                f"has {n} samples, '{OBSERVABLES[0].name}' has {n_samples}",
            )
        finite = np.isfinite(array)
        if not finite.all():
            bad = np.argwhere(~finite)[0]
            raise fail(
                spec.name,
                f"non-finite value {array[tuple(bad)]} at index {tuple(int(i) for i in bad)}",
            )
        if spec.name == "time" and n > 1:
            steps = np.diff(array)
            if (steps < 0).any():
                i = int(np.argmax(steps < 0))
                raise fail(
                    spec.name,
                    f"decreases at sample {i + 1} ({array[i]!r} -> {array[i + 1]!r})",
                )
        if spec.name == "grasp_state":
            off = (array != 0) & (array != 1)
            if off.any():
                bad = np.argwhere(off)[0]
                raise fail(
                    spec.name,
                    f"must be 0 or 1, got {array[tuple(bad)]} at index "
                    f"{tuple(int(i) for i in bad)}",
                )
    assert n_samples is not None
    return n_samples


def allocate(n_samples: int) -> dict[str, np.ndarray]:
    """Zero-filled float64 arrays of the right shapes for `n_samples` samples.

    Engines fill these in place; the result passes `check_observables` once `time`
    does not decrease (all zeros does).
    """
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    return {spec.name: np.zeros((n_samples, *spec.shape)) for spec in OBSERVABLES}
