"""The error budget of every [compare] row (`rsmcheck budget`, docs/cases.md §1).

A row's tolerance bounds the difference between two engines' runs of a case, by the row's
metric.  What that difference is made of is measured, each part by the row's own metric
(`compare.check_runs`: metric, window, the samples left out at a constraint switch or
between the engines' instants of one event):

    model difference        d(A, B)     the engines' runs at the case's settings, as
                                        `rsmcheck check` compares them
    A's integration error   d(A, A')    A' = A's run refined by its plug-in
    B's integration error   d(B, B')    (`refined_options`: the reference at rtol/10,
                                        Exudyn at half the step)
    budget = the sum,  margin = tolerance / budget

A is the first engine of the cross-check (the model under test), B each of the others.
The verdict of a row: "ok" when budget ≤ tolerance and margin ≤ `BLIND_MARGIN` (10);
"tight" when tolerance < budget (the tolerance does not cover what was measured: the
command exits 1); "blind" when margin > 10 (a change ten times what the engines and their
steps explain would pass unseen).  An engine whose plug-in declares no `refined_options`
has its integration error "not measured": the budget is then a lower bound, and says so.

d(X, X') estimates X's integration error only to a factor: at half the step a method of
order p has X's error ≈ 2^p/(2^p − 1) · d (2 for first order — generalized-α carries a held
input by O(h), docs/exudyn.md §4 —, 4/3 for second), an adaptive one at rtol/10 ≈ 10/9 · d
where its error follows rtol, less where stability, not accuracy, holds its steps; and a
run's round-off seeds what a loop amplifies.  Hence the suggested tolerance,
`SUGGEST_FACTOR` (3; `rsmcheck budget --factor K`, 1 ≤ K ≤ 10) × budget rounded up to two
significant figures (`Suggest`, `Budget.suggested_tolerance`): it covers the factor 2 and
leaves the margin 3 the verdict calls "ok".

A sequence (the mission) is budgeted by the rows its chained flight is checked by
(`sequence_budget_rows`, as the report's mission rows): each engine flies it at the phases'
settings and again with every phase refined at its own (`chain.fly`'s phase options).

The runs are jobs of `runs.run_jobs` (Dask, as every multi-run command): per case and
engine, one at the case's settings and one refined.  With a run folder (`rsmcheck budget
--runs DIR`) the runs at the case's settings are those of `rsmcheck check --out DIR` and of
the report: read from DIR when valid (`runs.reusable`), else made and stored there
(`runs.add_runs`), so that a budget and a check of the same code share them.  The refined
runs are not kept.  The document is written atomically (`write_document`); its cases are
merged into what the file holds, by variant.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import tempfile
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from rsmcheck.core.cases import Case, phase_cases
from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import OBSERVABLES
from rsmcheck.core.plugins import default_engines, plugin, refined_options, settings_of
from rsmcheck.core.store import EngineRun, git_commit, json_number, machine, write_json
from rsmcheck.orchestration import executor
from rsmcheck.orchestration.compare import check_runs, engine_pairs, not_checked, unit_of
from rsmcheck.orchestration.collect import phase_runs, phase_specs
from rsmcheck.orchestration.runs import (Job, Outcome, SequenceRun, add_runs, expected_wall, reusable, run_engine,
                                         run_jobs, run_sequence, source_digest)

#: above this margin (tolerance / budget) a row is "blind"
BLIND_MARGIN = 10.0
#: suggested tolerance = SUGGEST_FACTOR × budget, rounded up to SUGGEST_DIGITS significant figures
SUGGEST_FACTOR = 3.0
SUGGEST_DIGITS = 2
#: where the document goes by default, and what its `why` suggestions cite
DEFAULT_OUT = "docs/data/budget.json"
FORMAT = "rsmcheck-budget"
FORMAT_VERSION = 1
#: the rules, as the document states them (and the suggestion's, `Suggest.rule`)
RULES = {
    "model_difference": "d(first engine, other engine) at the case's settings, by the row's metric",
    "integration_error": "d(engine at the case's settings, engine refined by its plug-in's refined_options)",
    "budget": "model_difference + each engine's integration_error (a lower bound where one is not measured)",
    "margin": "tolerance / budget",
    "chained": ("a phase of a sequence's chained flight (rows SEQUENCE/PHASE): tolerance and model_difference "
                "include inherited (d0, the engines' difference at the phase's start); each integration_error "
                "is what the phase adds to integration_inherited; suggested_tolerance is the row's own, "
                "factor x (budget - inherited)"),
    "ok": f"budget <= tolerance and margin <= {BLIND_MARGIN:g}",
    "tight": "tolerance < budget",
    "blind": f"margin > {BLIND_MARGIN:g}",
}

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Suggest:
    """The rule of the suggested tolerances: `factor` × budget, rounded up to SUGGEST_DIGITS
    significant figures, from 1 (the budget itself) to BLIND_MARGIN (still "ok"); `source`,
    the document the suggested whys cite."""

    factor: float = SUGGEST_FACTOR
    source: str = DEFAULT_OUT

    def __post_init__(self):
        if not 1.0 <= self.factor <= BLIND_MARGIN:
            raise InputError("--factor", f"{self.factor:g}", f"must lie in [1, {BLIND_MARGIN:g}]: below 1 the "
                             f"suggested tolerance is tight, above {BLIND_MARGIN:g} blind")

    @property
    def rule(self) -> str:
        return f"{self.factor:g} x budget, rounded up to {SUGGEST_DIGITS} significant figures"


def round_up(x: float, digits: int = SUGGEST_DIGITS) -> float:
    """`x` > 0 rounded up to `digits` significant figures (0.2224 → 0.23, 3.0e-7 → 3.0e-7)."""
    exp = math.floor(math.log10(x)) - (digits - 1)
    mantissa = math.ceil(x / 10.0**exp * (1 - 1e-12))  # 0.75 / 1e-2 is 75.00000000000001
    return float(f"{mantissa}e{exp}")


def _g(x: float | None) -> str:
    """Two significant figures, both shown: 0.22, 0.010, 1.0e-07."""
    return "not measured" if x is None else f"{x:#.2g}"


@dataclass(frozen=True)
class Budget:
    """One [compare] row of one case and one pair of engines, with its measured budget."""

    case: str
    observable: str
    metric: str  # the metric with its window: 'growth [0.1, 0.2] s'
    engines: tuple[str, str]  # (the model under test, the other)
    tolerance: float
    model_difference: float
    #: engine → d(run, refined run); None: not measured (no refined_options, or it failed)
    integration_error: Mapping[str, float | None]
    why: str = ""  # the row's present why
    unit: str = ""
    #: a phase of a chained flight: d0, the difference the engines carry in, part of both the
    #: model difference and `tolerance` (the row's own tolerance + d0, as it is checked); the
    #: integration errors are then what each engine's step adds in the phase to the d0 between
    #: its run and its refined run (engine → that d0: `integration_inherited`)
    inherited: float = 0.0
    integration_inherited: Mapping[str, float] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return all(v is not None for v in self.integration_error.values())

    @property
    def budget(self) -> float:
        return self.model_difference + sum(v for v in self.integration_error.values() if v is not None)

    @property
    def margin(self) -> float:
        b = self.budget
        return self.tolerance / b if b > 0 else float("inf")

    @property
    def verdict(self) -> str:
        b = self.budget
        if not math.isfinite(b) or self.tolerance < b:
            return "tight"
        return "blind" if self.margin > BLIND_MARGIN else "ok"

    def suggested_tolerance(self, factor: float = SUGGEST_FACTOR) -> float | None:
        """factor × budget rounded up to SUGGEST_DIGITS significant figures; None when the
        budget is 0 or not finite (nothing to scale).  A chained row's is the row's own
        tolerance, to which its check adds d0: factor × (budget − d0), what the phase and the
        engines' steps add to what it inherits."""
        b = self.budget - self.inherited
        return round_up(factor * b) if 0 < b < math.inf else None

    def suggested_why(self, refinements: Mapping[str, str], factor: float = SUGGEST_FACTOR,
                      source: str = DEFAULT_OUT, run: str = "full run") -> str:
        """'Budget X m on the full run (docs/data/budget.json): model difference A, reference
        integration B (rtol/10), exudyn integration C (half step); tolerance 3 × budget.', the
        form a case file's why quotes (tests/cases/test_budget_quotes.py); `refinements`:
        engine → what its finer run refines; `run`: 'full run', 'short run', 'short chained
        flight' (`CaseBudget.run_label`)."""
        parts = [f"model difference {_g(self.model_difference)}"]
        for e, v in self.integration_error.items():
            how = f" ({refinements[e]})" if v is not None and refinements.get(e) else ""
            parts.append(f"{e} integration {_g(v)}{how}")
        bound = "" if self.complete else " (a lower bound)"
        head = f"Budget {_g(self.budget)}{self.unit}{bound} on the {run} ({source})"
        if self.inherited:
            return (f"{head}: {', '.join(parts)}, of which d0 = {_g(self.inherited)} inherited; "
                    f"tolerance {factor:g} × (budget − d0), checked against tolerance + d0.")
        return f"{head}: {', '.join(parts)}; tolerance {factor:g} × budget."

    def as_dict(self, refinements: Mapping[str, str] | None = None, suggest: Suggest = Suggest(),
                run: str = "full run") -> dict[str, Any]:
        tol = self.suggested_tolerance(suggest.factor)
        return {"case": self.case, "observable": self.observable, "metric": self.metric,
                "engines": list(self.engines), "tolerance": self.tolerance,
                "model_difference": json_number(self.model_difference),
                "integration_error": {e: None if v is None else json_number(v)
                                      for e, v in self.integration_error.items()},
                "budget": json_number(self.budget), "complete": self.complete,
                "margin": json_number(self.margin), "verdict": self.verdict,
                **({"inherited": json_number(self.inherited)} if self.inherited else {}),
                **({"integration_inherited": {e: json_number(v) for e, v in self.integration_inherited.items()}}
                   if self.integration_inherited else {}),
                "suggested_tolerance": tol,
                "suggested_why": None if tol is None else self.suggested_why(refinements or {}, suggest.factor,
                                                                             suggest.source, run),
                "why": self.why}


def budget_rows(variant: Case, runs: Mapping[str, EngineRun], refined: Mapping[str, EngineRun | None],
                engines: Sequence[str], specs: Sequence[Any] | None = None, chained: bool = False) -> list[Budget]:
    """The budget of every [compare] row of `variant` (the case variant that was run; or of
    `specs` in its place) for each pair of `engines` (the first against each other,
    `compare.engine_pairs`), from each engine's run at the case's settings (`runs`) and
    refined (`refined`; an engine absent or None there: its integration error is not
    measured).  Every figure is the row's own metric through `compare.check_runs` (with
    `chained`, a phase of a chained flight: the tolerance plus the difference the engines
    carry in), so the model difference is the error `rsmcheck check` or the report's
    mission rows report."""
    integration: dict[str, list[Any] | None] = {}
    for e in engines:
        fine = refined.get(e)
        integration[e] = None if fine is None else check_runs(variant, runs[e], fine, chained, specs)
    # each pair's tolerance takes the integration errors measured here for the engines a
    # row does not record (rsmcheck.core.tolerances)
    measured = {e: {r.observable: max(r.error - r.inherited, 0.0) for r in rows}
                for e, rows in integration.items() if rows is not None}
    out = []
    for a, b in engine_pairs(list(engines)):
        for i, row in enumerate(check_runs(variant, runs[a], runs[b], chained, specs, measured)):
            # chained: what each engine's step adds in the phase to the d0 between its run and its
            # refined run, as the model difference is d0 plus what the phase adds
            ie = {e: None if integration[e] is None else max(integration[e][i].error - integration[e][i].inherited,
                                                             0.0) for e in (a, b)}
            carried = {e: integration[e][i].inherited for e in (a, b) if integration[e] is not None and chained}
            out.append(Budget(variant.name, row.observable, row.metric_label, (a, b), row.tolerance, row.error,
                              ie, row.why, unit_of(row.observable, row.metric), row.inherited, carried))
    return out


def sequence_budget_rows(sequence: Case, short: bool, runs: Mapping[str, EngineRun],
                         refined: Mapping[str, EngineRun | None], engines: Sequence[str]) -> list[Budget]:
    """The budget of every row a sequence's chained flight is checked by, as the report's
    mission rows (`collect.mission_checks`): each phase cut from the flights
    (`collect.phase_runs`), by its own rows and those the sequence file replaces
    (`collect.phase_specs`), chained.  `runs`, `refined`: engine → the whole flight at the
    phases' settings and refined (each phase by its plug-in's `refined_options`); rows
    named "SEQUENCE/PHASE"."""
    cut = {e: phase_runs(sequence, short, r) for e, r in runs.items()}
    cut_fine = {e: None if r is None else phase_runs(sequence, short, r) for e, r in refined.items()}
    out = []
    for k, (phase, _, _) in enumerate(cut[engines[0]]):
        pieces = {e: cut[e][k][2] for e in engines}
        fine = {e: None if cut_fine.get(e) is None else cut_fine[e][k][2] for e in engines}
        out += [replace(b, case=f"{sequence.name}/{phase.name}")
                for b in budget_rows(phase, pieces, fine, engines, phase_specs(sequence, short, phase), chained=True)]
    return out


def _not_budgeted(case: Case, short: bool) -> str:
    """Why `case` has no rows to budget ('' when it has): as `compare.not_checked`, but a
    sequence is budgeted by its phases' rows in the chained flight."""
    if not case.phases:
        return not_checked(case, short)
    return "" if any(phase.compare for phase in phase_cases(case, short)) else "no phase has [compare] rows"


def _refined_options(engine: str, case: Case, short: bool) -> dict[str, Any] | None:
    """The options of `engine`'s refined run of `case`: its plug-in's `refined_options` of
    the variant; of a sequence, phase name → those of each phase (None: not declared)."""
    if not case.phases:
        return refined_options(engine, case.variant(short))
    per_phase = {ph.name: refined_options(engine, ph) for ph in phase_cases(case, short)}
    return None if any(o is None for o in per_phase.values()) else per_phase


def _job(engine: str, case: Case, short: bool, workdir: str,
         refined: Mapping[str, Any] | None) -> tuple[Callable[..., Any], tuple]:
    """The call of one budget run, at the case's settings or (`refined`, `_refined_options`)
    refined: a stand-alone case through `runs.run_engine`, a sequence flown through
    `runs.run_sequence`, each phase refined at its own settings."""
    if not case.phases:
        return run_engine, (engine, case.variant(short), dict(refined or {}))
    return run_sequence, (engine, case, short, workdir, {}, partial(refined_options, engine) if refined else None)


def _options_text(opts: Mapping[str, Any]) -> str:
    """'rtol=1e-09, h_max=0.0005'; a sequence's per-phase options by phase only where they differ."""
    def flat(o: Mapping[str, Any]) -> str:
        return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in o.items())
    if opts and all(isinstance(v, Mapping) for v in opts.values()):
        texts = {p: flat(o) for p, o in opts.items()}
        if len(set(texts.values())) == 1:
            return next(iter(texts.values())) + " in every phase"
        return "; ".join(f"{p}: {t}" for p, t in texts.items())
    return flat(opts)


# ---------------------------------------------------------------------------------------
# the runs
# ---------------------------------------------------------------------------------------
@dataclass
class CaseBudget:
    """One case's budget: its rows, the runs they were measured from, or why there are none."""

    case: Case  # the base case (its file, for --apply)
    short: bool
    rows: list[Budget] = field(default_factory=list)
    skipped: str = ""  # non-empty: no [compare] row, and why
    engines: tuple[str, ...] = ()
    #: engine → {"case": run record, "refined": run record or None}
    runs: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: engines whose plug-in declares no refined_options
    not_measured: tuple[str, ...] = ()
    #: 'engine' or 'engine refined' → error text of a run that could not be made
    failures: dict[str, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.case.name

    @property
    def variant(self) -> Case:
        return self.case.variant(self.short)

    @property
    def run_label(self) -> str:
        """What a suggested why says it was measured on: 'short run', 'full chained flight'…"""
        return f"{'short' if self.short else 'full'} {'chained flight' if self.case.phases else 'run'}"

    def refinements(self) -> dict[str, str]:
        return {e: str(getattr(plugin(e), "refinement", "") or "") for e in self.engines}


def _record(engine: str, variant: Case, options: Mapping[str, Any], run: EngineRun | None,
            wall_s: float, refinement: str = "", reused: bool = False) -> dict[str, Any]:
    """What the document says of one run: its option overrides, the case's settings of the
    engine, what the engine resolved and counted (`EngineRun.solver`), its wall time, and
    whether it was read from the run folder."""
    out: dict[str, Any] = {"options": dict(options), "case_settings": settings_of(variant, engine).given()}
    if refinement:
        out["refinement"] = refinement
    if reused:
        out["reused"] = True
    if run is not None:
        out["solver"] = dict(run.solver)
        out["job_wall_s"] = wall_s
    return out


def measure(cases: Sequence[Case], short: bool, engines: Sequence[str] | None = None,
            progress: Progress | None = None, workers: int = 2, run_dir: Path | None = None) -> list[CaseBudget]:
    """Each case's budget: every engine (default: the default engines) run at the case's
    settings and refined by its plug-in, all of them jobs of one `run_jobs` call (Dask,
    `workers` local processes or the --scheduler's cluster; 0: in this process).  With
    `run_dir`, the runs at the case's settings are read from there when valid and stored
    there when made.  A case without [compare] rows is returned with `skipped` set and
    nothing run."""
    engines = list(engines or default_engines())
    out = [CaseBudget(c, short, skipped=_not_budgeted(c, short), engines=tuple(engines)) for c in cases]
    todo = [cb for cb in out if not cb.skipped]
    fine = {(cb.name, e): _refined_options(e, cb.case, short) for cb in todo for e in engines}
    digest = source_digest() if run_dir is not None else None
    at_settings = {e: {} for e in engines}
    stored = {cb.name: reusable(run_dir, cb.case, short, at_settings, digest) if run_dir is not None else {}
              for cb in todo}
    with tempfile.TemporaryDirectory(prefix="rsmcheck-budget-") as workdir:
        jobs = []
        for cb in todo:
            cb.not_measured = tuple(e for e in engines if fine[(cb.name, e)] is None)
            for e in engines:
                wall = expected_wall(cb.case, e)
                if e not in stored[cb.name]:
                    jobs.append(Job(f"{cb.name} / {e} at the case's settings", *_job(e, cb.case, short, workdir, None),
                                    wall, (cb.name, e, False)))
                opts = fine[(cb.name, e)]
                if opts is not None:
                    jobs.append(Job(f"{cb.name} / {e} refined ({_options_text(opts)}: {plugin(e).refinement})",
                                    *_job(e, cb.case, short, workdir, opts), 2 * wall, (cb.name, e, True)))
        reused = [f"{name} / {e}" for name, have in stored.items() for e in have]
        if progress and jobs:
            progress(f"{len(jobs)} runs " + executor.describe(workers)
                     + (f"; stored runs reused: {', '.join(reused)}" if reused else ""))
        outcomes = run_jobs(jobs, progress, workers)
    got = {job.key: _whole(outcomes[job]) for job in jobs}
    for cb in todo:
        runs: dict[str, EngineRun] = dict(stored[cb.name])
        walls = {e: float(r.solver.get("wall_s", math.nan)) for e, r in runs.items()}
        refined = {e: got.get((cb.name, e, True)) for e in engines}
        for e in engines:
            base = got.get((cb.name, e, False))
            if base is not None and base.error is not None:
                cb.failures[e] = base.error_text
            elif base is not None:
                runs[e], walls[e] = base.value, base.wall_s
            if refined[e] is not None and refined[e].error is not None:
                cb.failures[f"{e} refined"] = refined[e].error_text
        new = {e: runs[e] for e in runs if e not in stored[cb.name]}
        if run_dir is not None and new:  # compared as read back, as `get_runs` gives them
            runs.update({e: r for e, r in add_runs(run_dir, cb.case, short, new, at_settings, digest).items()
                         if e in new})
        fine_runs = {e: oc.value if oc is not None and oc.error is None else None for e, oc in refined.items()}
        for e in engines:
            oc = refined[e]
            cb.runs[e] = {"case": _record(e, cb.variant, {}, runs.get(e), walls.get(e, math.nan),
                                          reused=e in stored[cb.name]),
                          "refined": None if oc is None else _record(
                              e, cb.variant, fine[(cb.name, e)], fine_runs[e], oc.wall_s, plugin(e).refinement)}
        if len(runs) == len(engines):
            cb.rows = (sequence_budget_rows(cb.case, short, runs, fine_runs, engines) if cb.case.phases
                       else budget_rows(cb.variant, runs, fine_runs, engines))
    return out


def _whole(outcome: Outcome) -> Outcome:
    """A sequence's outcome with the whole flight as its value (`runs.SequenceRun.run`), as
    it is stored and cut into phases."""
    if outcome.error is None and isinstance(outcome.value, SequenceRun):
        return replace(outcome, value=outcome.value.run)
    return outcome


# ---------------------------------------------------------------------------------------
# the document
# ---------------------------------------------------------------------------------------
def variant_key(short: bool) -> str:
    return "short" if short else "full"


def read_document(path: Path) -> dict[str, Any]:
    """The budget document at `path` (an empty one when there is none), checked before
    anything runs: a file that is not one is an InputError, not overwritten."""
    path = Path(path)
    if not path.exists():
        return {}
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(str(path), "--out", f"exists and is not a budget document ({exc}); "
                         "choose another file") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(str(path), "--out", f"exists and is not a budget document (format {FORMAT!r}); "
                         "choose another file")
    return doc


def case_entry(cb: CaseBudget, suggest: Suggest = Suggest()) -> dict[str, Any]:
    """One case's part of the document: rows (with their suggestions by `suggest`), runs,
    where and from what code."""
    commit, dirty = git_commit()
    refinements = cb.refinements()
    return {"case": cb.name, "variant": variant_key(cb.short), "duration_s": cb.variant.duration,
            "engines": list(cb.engines),
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "git_commit": commit, "git_dirty": dirty, "machine": machine(),
            "scheduler": executor.scheduler_address(),
            "refinements": {e: r or None for e, r in refinements.items()},
            "not_measured": list(cb.not_measured), "failures": dict(cb.failures),
            "suggested_tolerance": suggest.rule,
            "runs": cb.runs, "rows": [r.as_dict(refinements, suggest, cb.run_label) for r in cb.rows]}


def document(results: Sequence[CaseBudget], short: bool, previous: Mapping[str, Any] | None = None,
             suggest: Suggest = Suggest()) -> dict[str, Any]:
    """The budget document: `previous` (`read_document`) with the cases of `results`
    replaced in their variant ("short" or "full"); the other cases kept as they were."""
    variants = {k: dict(v) for k, v in dict((previous or {}).get("variants", {})).items()}
    mine = variants.setdefault(variant_key(short), {})
    for cb in results:
        if not cb.skipped:
            mine[cb.name] = case_entry(cb, suggest)
    variants[variant_key(short)] = dict(sorted(mine.items()))
    return {"format": FORMAT, "format_version": FORMAT_VERSION, "rules": RULES,
            "variants": dict(sorted(variants.items()))}


def write_document(path: Path, doc: Mapping[str, Any]) -> Path:
    """`doc` as strict JSON at `path`, atomically (`store.write_json`)."""
    return write_json(path, doc)


# ---------------------------------------------------------------------------------------
# what people read
# ---------------------------------------------------------------------------------------
def _e(x: float | None) -> str:
    if x is None:
        return "n/m"
    return "inf" if x == math.inf else f"{x:.2e}"


def table_lines(cb: CaseBudget) -> list[str]:
    """A case's rows as a table, one block per pair of engines."""
    v = cb.variant
    head = f"{cb.name} ({variant_key(cb.short)}, {v.duration:g} s)"
    if cb.skipped:
        return [f"{cb.name}: NOT BUDGETED: {cb.skipped}"]
    lines = [head]
    for what, text in cb.failures.items():
        lines.append(f"  {what}: FAILED: {text}")
    pairs: list[tuple[str, str]] = []
    for r in cb.rows:
        if r.engines not in pairs:
            pairs.append(r.engines)
    labels = [r.observable if r.case == cb.name else f"{r.case.split('/', 1)[1]}: {r.observable}" for r in cb.rows]
    w = max([18, *map(len, labels)])
    for a, b in pairs:
        lines.append(f"  {a} against {b}: model difference d({a}, {b}); integration error of X: d(X, X refined)")
        lines.append(f"  {'observable':{w}s} {'metric':20s} {'tolerance':>9s} {'model':>9s} {a[:9]:>9s} {b[:9]:>9s} "
                     f"{'budget':>9s} {'margin':>7s}  verdict")
        for r, label in ((r, label) for r, label in zip(cb.rows, labels) if r.engines == (a, b)):
            m = r.margin
            lines.append(f"  {label:{w}s} {r.metric:20s} {r.tolerance:9.2e} {_e(r.model_difference):>9s} "
                         f"{_e(r.integration_error[a]):>9s} {_e(r.integration_error[b]):>9s} {_e(r.budget):>9s} "
                         f"{'inf' if m == math.inf else f'{m:.3g}':>7s}  {r.verdict}"
                         + ("" if r.complete else " (lower bound)"))
    return lines


def suggestion_lines(cb: CaseBudget, suggest: Suggest = Suggest()) -> list[str]:
    """Each row's suggested tolerance and why (`Budget.suggested_tolerance`, `suggested_why`)."""
    refinements = cb.refinements()
    lines = []
    for r in cb.rows:
        tol = r.suggested_tolerance(suggest.factor)
        pair = f" ({r.engines[0]} against {r.engines[1]})" if len(cb.engines) > 2 else ""
        if tol is None:
            lines.append(f"  {r.case} {r.observable}{pair}: no suggestion (budget {_e(r.budget)})")
            continue
        lines.append(f"  {r.case} {r.observable}{pair}: tolerance {r.tolerance - r.inherited:.2g} -> {tol:.2g}"
                     + (f" (checked against it + d0 = {r.inherited:.2g})" if r.inherited else ""))
        lines.append(f"      why = \"{r.suggested_why(refinements, suggest.factor, suggest.source, cb.run_label)}\"")
    return lines


def suggestions(cb: CaseBudget, suggest: Suggest = Suggest()) -> dict[str, dict[str, Any]]:
    """observable → the row's new values that `--apply` may write: tolerance, why and the
    budget's parts (allowance: the model difference; errors: each engine's integration
    error, rsmcheck.core.tolerances), of a case whose runs all ran, one pair of engines,
    every part of the budget measured and not zero; none of a sequence (its phase rows are
    written by hand, docs/cases.md §6)."""
    if cb.failures or len(cb.engines) != 2 or cb.case.phases:
        return {}
    refinements = cb.refinements()
    return {r.observable: {"tolerance": tol, "allowance": r.model_difference,
                           "errors": {e: v for e, v in r.integration_error.items()},
                           "why": r.suggested_why(refinements, suggest.factor, suggest.source, cb.run_label)}
            for r in cb.rows
            if r.complete and (tol := r.suggested_tolerance(suggest.factor)) is not None}


def engine_error_rows(cb: CaseBudget) -> dict[str, dict[str, Any]]:
    """observable → {"engine_errors": …} that `--apply` writes for a pair other than the one
    the case file states: the own integration error of each engine outside the row's stated
    pair, measured here, merged with the engines the row records already; only budgeted rows
    of a stand-alone case whose runs all ran (the tolerance, the allowance and the stated
    errors stay the case file's)."""
    if cb.failures or cb.case.phases:
        return {}
    stated = {s.observable: s for s in cb.case.variant(cb.short).compare if s.allowance is not None}
    out = {}
    for r in cb.rows:
        spec = stated.get(r.observable)
        if spec is None:
            continue
        new = {e: float(v) for e, v in r.integration_error.items() if e not in spec.errors and v is not None}
        if new:
            out[r.observable] = {"engine_errors": {**dict(spec.engine_errors), **new}}
    return out


def summary(results: Sequence[CaseBudget]) -> str:
    """'7 rows: 4 ok, 1 tight, 2 blind', and what was not measured or failed."""
    rows = [r for cb in results for r in cb.rows]
    counts = {v: sum(r.verdict == v for r in rows) for v in ("ok", "tight", "blind")}
    text = f"{len(rows)} rows: " + ", ".join(f"{n} {v}" for v, n in counts.items())
    missing = sorted({e for cb in results for e in cb.not_measured})
    if missing:
        text += (f"; integration error of {', '.join(missing)} not measured (no refined_options in its "
                 "plug-in): those budgets are lower bounds")
    failed = [f"{cb.name} / {what}" for cb in results for what in cb.failures]
    if failed:
        text += f"; runs that failed: {', '.join(failed)}"
    return text
