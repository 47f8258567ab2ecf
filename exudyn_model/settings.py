"""The Exudyn engine's settings of a case: its table [exudyn] (docs/cases.md §1).  Pure data
and validation: it imports no Exudyn, so that a case file can be read where Exudyn is not
installed."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping

from rsmcheck.core.schema import choice, engine_table, flag, integer, number


@dataclass(frozen=True)
class ExudynSettings:
    """A case's settings of the Exudyn engine; None = the engine's default
    (exudyn_model/engine.py).  `why` is the study behind them (required with any)."""

    substeps: int | None = None  # generalized-α steps per control period
    n_elements: int | None = None  # ANCF elements per link
    constraints: str | None = None  # "index3" | "index2"
    restart_threshold: float | None = None  # input jump (fraction of its limit) restarting
    newton_atol: float | None = None  # absolute Newton tolerance [N]
    jacobian_per_step: bool | None = None  # a new Newton Jacobian at every step
    why: str = ""
    #: factor on the absolute Newton tolerance, whichever it is (None: 1): the gate's decision
    #: perturbation (`ExudynPlugin.step_perturbed`), never a case file's
    newton_atol_scale: float | None = None

    def given(self) -> dict[str, Any]:
        """The settings the case file gives (None = not given), without `why`: a run's
        provenance."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) is not None and f.name != "why"}


def parse(tables: Mapping[str, Mapping[str, Any]], solver: Mapping[str, Any], where: str,
          key: Callable[[str], str]) -> ExudynSettings:
    """[exudyn]: the engine's step and mesh for this case, with the reason (a study)."""
    w = where
    t = engine_table(w, key("exudyn"), tables.get("exudyn", {}), {
        "substeps": lambda k, x: integer(w, k, x, 1, 4096),
        "n_elements": lambda k, x: integer(w, k, x, 1, 64),
        "constraints": lambda k, x: choice(w, k, x, ("index3", "index2")),
        "restart_threshold": lambda k, x: number(w, k, x, 0.0, hi=1.0),
        "newton_atol": lambda k, x: number(w, k, x, 0.0, lo_open=True, hi=1.0),
        "jacobian_per_step": lambda k, x: flag(w, k, x),
    }, needs_why=("substeps", "n_elements", "constraints", "restart_threshold", "newton_atol",
                  "jacobian_per_step"))
    return ExudynSettings(**t)
