"""The reference engine's settings of a case: its table [reference] and the keys `rtol` and
`integrator` of the shared [solver] table (docs/cases.md §1).  Pure data and validation: it
imports no numba, so that reading a case file does not compile the model."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping

from rsmcheck.core.errors import InputError
from rsmcheck.core.schema import choice, engine_table, flag, number

#: the integrators (reference_model/stepper.py)
INTEGRATORS = ("dopri5", "trbdf2", "imex")
#: how the static correction shapes enter (reference_model/build.py STATIC_SHAPES)
STATIC_SHAPES = ("condensed", "explicit", "off")
#: eigenmodes per link unless a case says otherwise (the paper's two)
N_MODES_DEFAULT = (2,) * 6


@dataclass(frozen=True)
class ReferenceSettings:
    """A case's settings of the reference engine; None = the engine's default
    (reference_model/engine.py).  `why` is the study behind them (required with h_max or
    quiet_integrator)."""

    n_modes: tuple[int, ...] = N_MODES_DEFAULT  # eigenmodes per link, arm 1 then arm 2
    #: static correction shapes (docs/physics.md §2.4): "condensed", "explicit", "off", or a
    #: flag (true: condensed, false: off)
    static_modes: bool | str | None = None
    h_max: float | None = None  # largest integration step [s]
    #: the integrator of the control intervals longer than [solver] control_period (the
    #: quiet segments' own control_period, docs/physics.md §7); None: `integrator`
    quiet_integrator: str | None = None
    why: str = ""
    #: from [solver]: the relative tolerance of every integrator, and the integrator of the
    #: control intervals
    rtol: float = 1e-9
    integrator: str = "dopri5"

    def given(self) -> dict[str, Any]:
        """What a run's provenance records: the integrator and its tolerance, and the
        [reference] settings the case gives (n_modes and `why` aside)."""
        out = {"integrator": self.integrator, "rtol": self.rtol}
        out.update({f.name: getattr(self, f.name) for f in fields(self)
                    if f.name not in ("n_modes", "why", "rtol", "integrator") and getattr(self, f.name) is not None})
        return out


def parse(tables: Mapping[str, Mapping[str, Any]], solver: Mapping[str, Any], where: str,
          key: Callable[[str], str]) -> ReferenceSettings:
    """[reference] (modes per link, the largest step, the quiet segments' integrator, each
    numerical setting with the study behind it) and [solver] rtol, integrator."""
    w = where
    t = engine_table(w, key("reference"), tables.get("reference", {}), {
        "n_modes": lambda k, x: _modes(w, k, x),
        "static_modes": lambda k, x: flag(w, k, x) if isinstance(x, bool) else choice(w, k, x, STATIC_SHAPES),
        "h_max": lambda k, x: number(w, k, x, 0.0, lo_open=True, hi=1.0),
        "quiet_integrator": lambda k, x: choice(w, k, x, INTEGRATORS),
    }, needs_why=("h_max", "quiet_integrator"))
    s = key("solver")
    if "rtol" in solver:
        t["rtol"] = number(w, f"{s}.rtol", solver["rtol"], 0.0, lo_open=True)
        if t["rtol"] >= 1e-2:
            raise InputError(w, f"{s}.rtol", f"{t['rtol']} is too loose to mean anything (< 1e-2)")
    if "integrator" in solver:
        t["integrator"] = choice(w, f"{s}.integrator", solver["integrator"], INTEGRATORS)
    return ReferenceSettings(**t)


def _modes(where: str, key: str, v: Any) -> tuple[int, ...]:
    items = [v] * 6 if not isinstance(v, list) else v
    if len(items) != 6 or any(isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= 6 for x in items):
        raise InputError(where, key, "must be an integer 0..6 or a list of six")
    return tuple(items)
