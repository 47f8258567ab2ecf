"""The MuJoCo engine's settings of a case: its table [mujoco] (docs/cases.md §1).  Pure data
and validation: it imports no MuJoCo, so that a case file can be read without it."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping

from rsmcheck.core.schema import choice, engine_table, integer, number


@dataclass(frozen=True)
class MujocoSettings:
    """A case's settings of the MuJoCo engine; None = the engine's default
    (mujoco_model/engine.py).  `why` is the study behind them (required with any)."""

    n_segments: int | None = None  # rigid segments per link
    timestep: float | None = None  # MuJoCo's fixed step [s]
    integrator: str | None = None  # "rk4" | "implicitfast"
    why: str = ""

    def given(self) -> dict[str, Any]:
        """The settings the case file gives (None = not given), without `why`."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) is not None and f.name != "why"}


def parse(tables: Mapping[str, Mapping[str, Any]], solver: Mapping[str, Any], where: str,
          key: Callable[[str], str]) -> MujocoSettings:
    """[mujoco]: the engine's segments and step for this case, with the reason (a study)."""
    w = where
    t = engine_table(w, key("mujoco"), tables.get("mujoco", {}), {
        "n_segments": lambda k, x: integer(w, k, x, 2, 64),
        "timestep": lambda k, x: number(w, k, x, 0.0, lo_open=True, hi=1e-3),
        "integrator": lambda k, x: choice(w, k, x, ("rk4", "implicitfast")),
    }, needs_why=("n_segments", "timestep", "integrator"))
    return MujocoSettings(**t)
