"""A [compare] row's tolerance for one pair of engines, from the row's budget in parts
(docs/cases.md §1).

A case file states a row's tolerance for the pair of engines its budget was measured on,
and the budget's parts: the `allowance` and each of the two engines' own integration
error (`errors`).  Any pair (A, B) is judged by its own parts, scaled by the row's margin
factor:

    budget(A, B)    = allowance + ε_A + ε_B + δ_A + δ_B
    tolerance(A, B) = k · budget(A, B),    k = tolerance / budget(P, Q)

* allowance — what the paper's physics lets two faithful engines differ by on this row
  (the links' axial compliance, the static shapes' truncation: docs/physics.md §9), the
  same for every pair; it is measured as the model difference of the pair (P, Q) the
  case file names, the engines that differ by exactly those departures;
* ε_X — engine X's own discretisation and integration error on this run, by the row's
  metric: the case file's where it was recorded (P and Q in `errors`, any other engine in
  `engine_errors`, both from `rsmcheck budget`), else d(X, X refined) measured
  now by X's plug-in's `refined_options`, else — a plug-in without one — taken as 0, and
  the row says so;
* δ_X — an allowance for engine X's own listed departures (its plug-in's optional
  `departures`: a soft constraint, say), added to X's pairs only;
* k — the row's margin over its budget, tolerance / budget(P, Q): the case file's
  judgement of how much room the measured budget needs, not a budget of its own.

So an engine is judged by the physics' allowance, its own error and its partner's, never by
its own measured difference (that would pass any engine) nor by another engine's error.
The pair (P, Q) itself gets the stated tolerance exactly (its allowance, measured on it,
holds its own engines' departures already).  A row without a budget (a 0/1 flag, a bound
by definition: a rule row) has the same tolerance for every pair, and so has every row of
a chained flight's phase, where no engine's own error is measured.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping


#: why an engine's error is not measured, when nothing else is said
NO_REFINEMENT = "no refined_options"


@dataclass(frozen=True)
class EngineError:
    """One engine's own error on a row: `value` in the row's unit and where it comes from."""

    engine: str
    value: float
    #: "recorded" (the case file), "measured" (refined now), "not measured" (taken as 0)
    source: str
    #: what the refinement refines ("rtol/10, h ≤ Δt/2"), for a measured or recorded value;
    #: for one not measured, why ("no refined_options", "its refined run failed: …")
    how: str = ""

    def text(self) -> str:
        if self.source == "not measured":
            return f"{self.engine} integration not measured ({self.how or NO_REFINEMENT}: taken as 0)"
        how = f", {self.how}" if self.how else ""
        return f"{self.engine} integration {self.value:#.2g} ({self.source}{how})"


@dataclass(frozen=True)
class PairTolerance:
    """A row's tolerance for `pair` (engine under test, the other) and its parts."""

    pair: tuple[str, str]
    tolerance: float
    #: None: a rule row (the same tolerance for every pair)
    allowance: float | None = None
    errors: tuple[EngineError, ...] = ()
    #: (engine, δ, why) of the pair's engines' own departures
    departures: tuple[tuple[str, float, str], ...] = ()
    #: k = stated tolerance / stated budget
    factor: float = 1.0
    #: the pair the case file states the tolerance for (its `errors`' engines)
    stated_pair: tuple[str, ...] = ()
    #: why every pair gets the stated tolerance where the parts cannot be applied ('' else)
    note: str = ""

    @property
    def budget(self) -> float | None:
        if self.allowance is None:
            return None
        return self.allowance + sum(e.value for e in self.errors) + sum(d for _, d, _ in self.departures)

    @property
    def stated(self) -> bool:
        """The tolerance the case file states: a rule row, or the pair the budget was measured
        on (whose allowance, measured on it, holds its engines' departures already)."""
        return self.allowance is None or set(self.pair) == set(self.stated_pair)

    def why(self, unit: str = "") -> str:
        """The parts as a sentence, naming the pair (for a pair the case file does not state)."""
        a, b = self.pair
        if self.allowance is None:
            return f"{a} against {b}: {self.note or 'a rule row, the same tolerance for every pair'}"
        parts = [f"allowance {self.allowance:#.2g} (the modelling differences the paper's physics admits, "
                 f"measured as the {'–'.join(self.stated_pair)} model difference)"]
        parts += [e.text() for e in self.errors]
        parts += [f"{e} departure {d:#.2g} ({why})" for e, d, why in self.departures]
        return (f"{a} against {b}: budget {self.budget:#.2g}{unit} = " + " + ".join(parts)
                + f"; tolerance {self.factor:.3g} × budget, the row's margin over the "
                  f"{'–'.join(self.stated_pair)} budget.")

    def formula(self) -> str:
        """'3.48 × (allowance 3.2e-08 + reference 7.0e-10 + mine 6.1e-10 measured)': how the
        tolerance of a pair the case file does not state is made."""
        if self.allowance is None:
            return self.note or "a rule row: the same for every pair"
        terms = [f"allowance {self.allowance:#.2g}"]
        terms += [f"{e.engine} not measured (0)" if e.source == "not measured" else
                  f"{e.engine} {e.value:#.2g}" + (" measured" if e.source == "measured" else "") for e in self.errors]
        terms += [f"{e} departure {d:#.2g}" for e, d, _ in self.departures]
        return f"{self.factor:.3g} × ({' + '.join(terms)})"

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"pair": list(self.pair), "tolerance": self.tolerance, "stated": self.stated}
        if self.note:
            out["note"] = self.note
        if self.allowance is not None:
            out.update({"allowance": self.allowance, "factor": self.factor, "budget": self.budget,
                        "stated_pair": list(self.stated_pair),
                        "errors": {e.engine: {"value": e.value, "source": e.source, **({"how": e.how} if e.how else {})}
                                   for e in self.errors}})
        if self.departures:
            out["departures"] = {e: {"value": d, "why": why} for e, d, why in self.departures}
        return out


def pair_tolerance(spec: Any, pair: tuple[str, str], measured: Mapping[str, float | None] | None = None,
                   departures: Mapping[str, tuple[float, str]] | None = None,
                   refinements: Mapping[str, str] | None = None, missing: Mapping[str, str] | None = None,
                   chained: bool = False) -> PairTolerance:
    """The tolerance of [compare] row `spec` (`rsmcheck.core.cases.CompareSpec`) for `pair`.

    `measured`: engine → its integration error on this row, d(X, X refined), for engines
    the row does not record (None or absent: not measured, for the reason `missing` gives,
    else "no refined_options"); `departures`: engine → (δ, why), its plug-in's allowance on
    this row; `refinements`: engine → what its refinement refines.  `chained`: a phase of a
    chained flight, where no engine's own error is measured: every pair gets the stated
    tolerance, and the row says so."""
    measured, departures, refinements, missing = measured or {}, departures or {}, refinements or {}, missing or {}
    stated = spec.allowance + sum(spec.errors.values()) if spec.allowance is not None else 0.0
    if spec.allowance is None or not stated > 0.0:
        return PairTolerance(tuple(pair), float(spec.tolerance))
    if chained:
        return PairTolerance(tuple(pair), float(spec.tolerance),
                             note="a phase of a chained flight, where the engines' own errors are not measured: "
                                  "the tolerance the phase's file states, for every pair")
    errors = []
    for e in dict.fromkeys(pair):
        if e in spec.errors:
            errors.append(EngineError(e, float(spec.errors[e]), "recorded", refinements.get(e, "")))
        elif e in spec.engine_errors:
            errors.append(EngineError(e, float(spec.engine_errors[e]), "recorded", refinements.get(e, "")))
        elif measured.get(e) is not None:
            errors.append(EngineError(e, float(measured[e]), "measured", refinements.get(e, "")))
        else:
            errors.append(EngineError(e, 0.0, "not measured", missing.get(e, NO_REFINEMENT)))
    deps = tuple((e, float(departures[e][0]), departures[e][1]) for e in dict.fromkeys(pair) if e in departures)
    k = float(spec.tolerance) / stated
    out = PairTolerance(tuple(pair), 0.0, float(spec.allowance), tuple(errors), deps, k, tuple(spec.errors))
    # the stated pair: the case file's figure itself, not k · budget rounded back
    tol = float(spec.tolerance) if out.stated else k * out.budget
    return PairTolerance(out.pair, tol, out.allowance, out.errors, out.departures if not out.stated else (), k,
                         out.stated_pair)
