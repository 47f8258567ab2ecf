"""Comparison of two engines' runs of the same case, observable by observable.

Both engines are driven by the same sampled-data loop, so their samples fall on the same
times; the comparison is sample by sample:

    error = max_t max_c |a(t)_c − b(t)_c| / scale,
    scale = max(max_t ‖b(t)‖_∞, floor)                (b: the reference run)

`floor` keeps an observable that is zero in the reference (a reaction force with the grasp
off, momentum of a system at rest) from turning round-off into an infinite relative
error; the floors are physical sizes, listed in `SCALE_FLOORS` with the reason.  The
margin is tolerance / error (> 1 passes).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from rsmcheck.observables import NAMES
from rsmcheck.store import EngineRun

#: smallest scale of each observable [SI]: the size below which a difference means nothing
SCALE_FLOORS: dict[str, float] = {
    "base_pose_I": 1e-3,  # 1 mm / 1 mrad
    "target_pose_B": 1e-3,
    "ee1_pos_B": 1e-3,
    "ee2_pos_B": 1e-3,
    "ee2_speed": 1e-4,  # 0.1 mm/s
    "capture_gap_B": 1e-4,
    "com_pos_B": 1e-4,
    "joint_angles": 1e-3,
    "motor_angles": 1e-3,
    "motor_torques": 1e-2,  # 0.01 N·m
    "base_torque": 1e-2,
    "link_deflection": 1e-7,  # 0.1 µm
    "target_attitude": 1e-3,
    "reaction_forces_I": 1e-2,  # 0.01 N
    "constraint_residual": 1e-6,  # 1 µm: residuals are compared against this floor
    "grasp_state": 1.0,
    "energy": 1e-3,  # 1 mJ
    "momentum_I": 1e-3,
    "altitude": 1.0,  # 1 m
    "target_rel_lvlh": 1e-3,
    "system_mass": 1e-3,
}


@dataclass(frozen=True)
class Comparison:
    case: str
    observable: str
    error: float
    tolerance: float
    scale: float
    worst_time: float
    worst_component: int

    @property
    def margin(self) -> float:
        return self.tolerance / self.error if self.error > 0 else float("inf")

    @property
    def passed(self) -> bool:
        return bool(self.error <= self.tolerance)

    def as_dict(self) -> dict:
        return {"case": self.case, "observable": self.observable, "error": self.error,
                "tolerance": self.tolerance, "margin": self.margin, "pass": self.passed,
                "scale": self.scale, "worst_time": self.worst_time,
                "worst_component": self.worst_component}


def compare_runs(case: str, reference: EngineRun, other: EngineRun,
                 tolerances: Mapping[str, float]) -> list[Comparison]:
    """Compare `other` against `reference` for every observable that has a tolerance."""
    ta = reference.observables["time"]
    tb = other.observables["time"]
    if ta.shape != tb.shape or np.max(np.abs(ta - tb)) > 1e-9:
        raise ValueError(f"{case}: the runs are not sampled at the same times "
                         f"({ta.size} vs {tb.size} samples)")
    rows = []
    for name, tol in tolerances.items():
        if name not in NAMES or name == "time":
            raise ValueError(f"{case}: no observable named {name!r}")
        b = np.asarray(reference.observables[name], float).reshape(ta.size, -1)
        a = np.asarray(other.observables[name], float).reshape(ta.size, -1)
        scale = max(float(np.max(np.abs(b))), SCALE_FLOORS[name])
        diff = np.abs(a - b)
        k = int(np.argmax(diff))
        i, c = divmod(k, diff.shape[1])
        rows.append(Comparison(case, name, float(diff.flat[k]) / scale, float(tol), scale, float(ta[i]), c))
    return rows
