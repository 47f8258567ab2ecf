"""Comparison of two engines' runs of the same case, observable by observable.

Both engines are driven by the same sampled-data loop, so their samples fall on the same
times; every comparison is sample by sample.  Two kinds:

**Case checks** (`rsmcheck check`, `tests/crosscheck`): the case file's `[compare]` table is
the single source of what is compared and how closely.  Each entry names an observable, a
tolerance *in the observable's unit* (SI, radians), a `why` sentence and a metric:

    max_abs   max_t max_c |a(t)_c − b(t)_c|                      (default)
    rms       max_c sqrt(mean_t (a(t)_c − b(t)_c)²)
    final     max_c |a(T)_c − b(T)_c| at the last sample
    growth    |σ_a − σ_b| [1/s], σ the exponential growth rate of ‖·‖_∞ in the entry's
              `window` [t0, t1] (`growth_rate`): for a loop that is meant to be unstable,
              where the amplitude is seeded by the ripple's phase and then amplified as
              e^{σt}, so differences of the signal itself say nothing (docs/cases.md)

`max_abs` and `rms` may take a `window` too: then only the samples t0 ≤ t ≤ t1 count, for
an interval the case's why says the engines can be held to (docs/records.md, p1_transport at full length: a swing
whose stiff stop contacts the two engines reach at instants a fraction of a second apart).

(a: the other engine, b: the reference; c runs over the components of the observable).
The margin is tolerance / error: > 1 passes, and says how much room is left.

*The sample at a constraint switch.*  A grasp's reaction force is a Lagrange multiplier:
at a capture or release the reference's (axially rigid links) jumps to the new constraint
set's value at once, Exudyn's (finite EA) is continuous and reaches it within the axial
wave's transit — the two engines show the two one-sided limits of one quantity there
(docs/physics.md §4.2, item 4).  `max_abs` and `rms` of the observables in `MULTIPLIERS`
therefore leave out the samples at a switch, every other sample (the next one included)
is compared, and the difference at the switch is reported on its own (`Check.at_switches`).

*Samples between the engines' instants of one event.*  Some observables change definition
at an event: `capture_gap_B` is measured to the designated point of the running segment
(a new segment, a new point), a reaction force exists between a capture and a release.
When the two engines reach the same event at instants a few control periods apart (a
chained flight: each engine captures when its own hand reaches the point), a sample
between the two instants compares two different quantities — in the full mission the
regrasp segment starts 17 ms apart and the one sample between compares a 2 mm grasp offset
with a 0.25 m approach gap.  `max_abs` and `rms` of the observables in `MODE_EVENTS` leave
those samples out and report them (`Check.between_events`), provided the engines report the
same sequence of those events and each pair of instants is at most `EVENT_SKEW_MAX` apart;
otherwise every sample is compared, so a missing, extra or late event shows as a difference.

**Relative differences** (`compare_runs`: rigid equivalence, convergence studies): the
difference in units of the observable's size in the reference run,

    error = max_t max_c |a(t)_c − b(t)_c| / scale,
    scale = max(max_t ‖b(t)‖_∞, floor),

`floor` keeps an observable that is zero in the reference (a reaction force with the grasp
off, momentum of a system at rest) from turning round-off into an infinite relative
error; the floors are physical sizes, listed in `SCALE_FLOORS` with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np

from rsmcheck.core.cases import METRICS  # noqa: F401  (the metrics a [compare] entry may ask for)
from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import NAMES, OBSERVABLES
from rsmcheck.core.plugins import default_engines, departure_allowances, plugins, refined_options
from rsmcheck.core.tolerances import PairTolerance, pair_tolerance
from rsmcheck.orchestration.runs import Job, expected_wall, get_runs, run_engine
from rsmcheck.core.store import EngineRun
from rsmcheck.core.store import json_number as _finite  # JSON has no inf/NaN: inf → "inf", NaN → null


#: observables that are Lagrange multipliers of the grasp constraints, and the events that
#: switch those constraints: at a switch sample they are one-sided limits that depend on
#: the model class (module docstring), so that sample is reported and not compared
MULTIPLIERS = ("reaction_forces_I",)
CONSTRAINT_SWITCHES = ("capture", "release")

#: observables whose definition changes at an event, and those events (module docstring)
MODE_EVENTS: dict[str, tuple[str, ...]] = {
    "capture_gap_B": ("segment", "capture", "release"),  # the designated point of the segment
    "reaction_forces_I": CONSTRAINT_SWITCHES,  # a multiplier exists while its grasp is closed
}
#: largest difference [s] between the engines' instants of one event whose samples in between
#: are left out of a `MODE_EVENTS` row.  A capture happens when the hand reaches its point,
#: approaching at ~1 mm/s (rel_speed_mps at capture, 0.95e-3); engines whose hands differ by
#: the ~2e-5 m their position rows allow reach it ~20 ms apart (measured: 17 ms in the full
#: mission, 0 stand-alone, where both detect it at the same control sample).  0.1 s is five
#: times that and one output period of the mission phases: a later event is a fault to see.
EVENT_SKEW_MAX = 0.1

#: number of equal blocks of the window whose maxima `growth_rate` fits
GROWTH_BLOCKS = 10

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
    "joint_frame_angles": 1e-3,
    "wrist_angles": 1e-3,
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


def _same_times(case: str, reference: EngineRun, other: EngineRun) -> np.ndarray:
    ta = np.asarray(reference.observables["time"], float)
    tb = np.asarray(other.observables["time"], float)
    if ta.shape != tb.shape or (ta.size and np.max(np.abs(ta - tb)) > 1e-9):
        raise ValueError(f"{case}: the runs are not sampled at the same times "
                         f"({ta.size} vs {tb.size} samples)")
    return ta


def _pair(reference: EngineRun, other: EngineRun, name: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    if name not in NAMES or name == "time":
        raise ValueError(f"no observable named {name!r}")
    b = np.asarray(reference.observables[name], float).reshape(n, -1)
    a = np.asarray(other.observables[name], float).reshape(n, -1)
    return a, b


def growth_rate(t: np.ndarray, x: np.ndarray, window: tuple[float, float]) -> float:
    """Exponential growth rate σ [1/s] of the envelope of `x` (samples × components) in
    `window`: the window is cut into `GROWTH_BLOCKS` equal closed blocks, and σ is the least-squares
    slope of ln(max over the block of ‖x(t)‖_∞) against the block centres.  Block maxima, not
    samples: an oscillation sampled below its frequency (the 92 Hz rotor mode at 10 Hz
    output) has a random phase at each sample, its maximum over a block of ≥ 10 samples is
    within a few per cent of the envelope."""
    t0, t1 = window
    edges = np.linspace(t0, t1, GROWTH_BLOCKS + 1)
    mags = np.max(np.abs(x.reshape(t.size, -1)), axis=1)
    centres, logs = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (t >= lo - 1e-9) & (t <= hi + 1e-9)  # closed: a sample on an edge is in both blocks
        if not np.any(sel):
            raise ValueError(f"growth window [{t0}, {t1}] s: no sample in [{lo:.6g}, {hi:.6g}] s")
        peak = float(np.max(mags[sel]))
        if not peak > 0.0:
            return float("nan")
        centres.append(0.5 * (lo + hi))
        logs.append(math.log(peak))
    return float(np.polyfit(centres, logs, 1)[0])


def switch_samples(t: np.ndarray, *runs: EngineRun) -> np.ndarray:
    """Indices of the samples `t` that fall on a constraint switch (capture or release) of
    any of `runs` (each engine detects its own captures)."""
    times = sorted({e.time for r in runs for e in r.events if e.kind in CONSTRAINT_SWITCHES})
    hits = [np.flatnonzero(np.abs(t - te) <= 1e-9 * max(1.0, abs(te))) for te in times]
    return np.unique(np.concatenate(hits)) if hits else np.zeros(0, int)


def in_window(t: np.ndarray, window: Sequence[float]) -> np.ndarray:
    """Mask of the samples t0 ≤ t ≤ t1 of `window` (closed, to 1e-9 s)."""
    return (t >= window[0] - 1e-9) & (t <= window[1] + 1e-9)


def between_events(t: np.ndarray, reference: EngineRun, other: EngineRun,
                   kinds: Sequence[str]) -> tuple[np.ndarray, float]:
    """(indices of the samples `t` that lie between the two runs' instants of one event of
    `kinds`, the largest such pair of instants apart [s]).  The runs' events of `kinds` are
    paired in order by kind and `Event.identity`; when the two sequences differ nothing is
    left out, nor between instants the same to 1e-9 s or more than `EVENT_SKEW_MAX` apart."""
    ev_a = [e for e in reference.events if e.kind in kinds]
    ev_b = [e for e in other.events if e.kind in kinds]
    if [(e.kind, e.identity) for e in ev_a] != [(e.kind, e.identity) for e in ev_b]:
        return np.zeros(0, int), 0.0
    hits, skew = [], 0.0
    for a, b in zip(ev_a, ev_b):
        lo, hi = sorted((a.time, b.time))
        if hi - lo <= 1e-9 * max(1.0, abs(hi)) or hi - lo > EVENT_SKEW_MAX:
            continue
        inside = np.flatnonzero((t >= lo - 1e-9) & (t <= hi + 1e-9))
        if inside.size:
            hits.append(inside)
            skew = max(skew, hi - lo)
    return (np.unique(np.concatenate(hits)) if hits else np.zeros(0, int)), skew


def difference(reference: EngineRun, other: EngineRun, name: str, metric: str = "max_abs",
               case: str = "", window: tuple[float, float] | None = None,
               skip: np.ndarray | None = None) -> tuple[float, float, int]:
    """(error, time of the worst sample, worst component) of observable `name` by `metric`,
    in the observable's unit (1/s for `growth`, which needs `window`).  `worst_time` is NaN
    for `rms` and `growth`.  `skip`: indices of samples that `max_abs` and `rms` leave out;
    `window`: for them, the interval [t0, t1] whose samples are compared."""
    t = _same_times(case, reference, other)
    a, b = _pair(reference, other, name, t.size)
    if metric in ("max_abs", "rms"):
        keep = np.ones(t.size, bool)
        if skip is not None and len(skip):
            keep[np.asarray(skip, int)] = False
        if window is not None:
            keep &= in_window(t, window)
            if not np.any(keep):
                raise ValueError(f"{case}: {name}: no sample in the window [{window[0]}, {window[1]}] s")
        t, a, b = t[keep], a[keep], b[keep]
    if metric == "growth":
        if window is None:
            raise ValueError("metric 'growth' needs a window [t0, t1]")
        d = abs(growth_rate(t, a, window) - growth_rate(t, b, window))
        return (d if math.isfinite(d) else float("inf")), float("nan"), 0
    d = np.abs(a - b)
    if not d.size:
        return 0.0, float("nan"), 0
    if not np.all(np.isfinite(d)):
        bad = np.argwhere(~np.isfinite(d))[0]
        return float("inf"), float(t[bad[0]]), int(bad[1])
    if metric == "max_abs":
        k = int(np.argmax(d))
        i, c = divmod(k, d.shape[1])
        return float(d.flat[k]), float(t[i]), c
    if metric == "rms":
        r = np.sqrt(np.mean(d**2, axis=0))
        c = int(np.argmax(r))
        return float(r[c]), float("nan"), c
    if metric == "final":
        c = int(np.argmax(d[-1]))
        return float(d[-1, c]), float(t[-1]), c
    raise ValueError(f"unknown metric {metric!r} (known: {', '.join(METRICS)})")


# ---------------------------------------------------------------------------------------
# case checks: the [compare] table of a case file
# ---------------------------------------------------------------------------------------
def metric_label(metric: str, window: Sequence[float] | None) -> str:
    """A [compare] entry's metric as people read it: 'rms', 'max_abs [0, 190] s'."""
    return metric if window is None else f"{metric} [{window[0]:g}, {window[1]:g}] s"


class _Verdict:
    """margin = tolerance / error (> 1 passes) and pass, for rows with error and tolerance."""

    error: float
    tolerance: float

    @property
    def margin(self) -> float:
        return self.tolerance / self.error if self.error > 0 else float("inf")

    @property
    def passed(self) -> bool:
        return bool(self.error <= self.tolerance)


@dataclass(frozen=True)
class Check(_Verdict):
    """One row of `rsmcheck check`: one observable of one case, by the case's own rule."""

    case: str
    observable: str
    error: float
    tolerance: float
    metric: str = "max_abs"
    why: str = ""
    worst_time: float = float("nan")
    worst_component: int = 0
    reference_range: float = 0.0  # max_t ‖b(t)‖_∞: the size of the observable in the reference
    #: metric `growth`: σ [1/s] of each run, by engine
    growth_rates: Mapping[str, float] = field(default_factory=dict)
    #: (time, error) of the samples at a constraint switch, left out of the error (MULTIPLIERS)
    at_switches: tuple[tuple[float, float], ...] = ()
    #: (time, error) of the samples between the engines' instants of one event, left out of
    #: the error (MODE_EVENTS), and the largest such pair of instants apart [s]
    between_events: tuple[tuple[float, float], ...] = ()
    event_skew: float = 0.0
    #: a chained phase: the difference the engines carry into it, max_c |a_c(0) − b_c(0)|,
    #: already added to `tolerance` (see `check_runs`)
    inherited: float = 0.0
    #: the interval [s] the metric looked at (the case's `window`), None: the whole run
    window: tuple[float, float] | None = None
    #: the engines compared (the model under test, the other)
    engines: tuple[str, ...] = ()
    #: the row's tolerance for this pair and its parts (rsmcheck.core.tolerances)
    tolerance_parts: PairTolerance | None = None

    @property
    def metric_label(self) -> str:
        """The metric with its window, e.g. 'max_abs [0, 190] s'."""
        return metric_label(self.metric, self.window)

    def as_dict(self) -> dict[str, Any]:
        out = {"case": self.case, "observable": self.observable, "error": _finite(self.error),
               "tolerance": self.tolerance, "margin": _finite(self.margin), "pass": self.passed,
               "metric": self.metric, "why": self.why, "worst_time": _finite(self.worst_time),
               "worst_component": self.worst_component, "reference_range": _finite(self.reference_range)}
        if self.engines:
            out["engines"] = list(self.engines)
        if self.growth_rates:
            out["growth_rates"] = {k: _finite(v) for k, v in self.growth_rates.items()}
        if self.at_switches:
            out["at_switches"] = [{"time": ts, "error": _finite(e)} for ts, e in self.at_switches]
        if self.between_events:
            out["between_events"] = [{"time": ts, "error": _finite(e)} for ts, e in self.between_events]
            out["event_skew"] = self.event_skew
        if self.inherited:
            out["inherited"] = _finite(self.inherited)
        if self.window is not None:
            out["window"] = list(self.window)
        if self.tolerance_parts is not None:
            out["tolerance_parts"] = self.tolerance_parts.as_dict()
        return out

    def switch_note(self) -> str:
        """One line on the samples left out (at a switch, between events), or ''."""
        notes = []
        if self.at_switches:
            at = ", ".join(f"t = {ts:.6g} s: {e:.3g}" for ts, e in self.at_switches)
            notes.append(f"not compared at the constraint switch ({at}): one-sided limits, docs/physics.md §4.2")
        if self.between_events:
            at = ", ".join(f"t = {ts:.6g} s: {e:.3g}" for ts, e in self.between_events)
            notes.append(f"not compared between the engines' instants of one event, at most "
                         f"{self.event_skew * 1e3:.3g} ms apart ({at}): different quantities, docs/cases.md §6")
        return "; ".join(notes)


def unit_of(observable: str, metric: str) -> str:
    """The unit a row's figures are in, with a leading space, for its `why` ('' for a mixed
    one: "m, m, rad")."""
    if metric == "growth":
        return "/s"
    unit = next((o.unit for o in OBSERVABLES if o.name == observable), "")
    return "" if "," in unit or not unit else f" {unit}"


def refinement_texts(engines: Sequence[str]) -> dict[str, str]:
    """engine → what its plug-in's refinement refines ("rtol/10, h ≤ Δt/2"; '' unknown)."""
    found = plugins()
    return {e: str(getattr(found.get(e), "refinement", "") or "") for e in engines}


def check_runs(case, reference: EngineRun, other: EngineRun, chained: bool = False,
               specs: Sequence[Any] | None = None,
               measured: Mapping[str, Mapping[str, float]] | None = None,
               missing: Mapping[str, str] | None = None) -> list[Check]:
    """Every entry of `case.compare` (a `rsmcheck.core.cases.Case`, the variant that was run), or
    of `specs` in its place, each with its tolerance for the pair (`reference.engine`,
    `other.engine`) (`rsmcheck.core.tolerances.pair_tolerance`): `measured`, engine →
    observable → that engine's integration error measured now (`integration_errors`), for
    the engines a row does not record (`missing`: engine → why its error was not
    measured); the engines' own departures from their plug-ins.  The why of a row whose
    tolerance the case file states is the file's; any other pair's shows its parts.

    `chained`: the runs are a phase of a chained flight, each engine starting from its own
    end state of the previous phase, so the engines start the phase apart by
    d0 = max_c |a_c(0) − b_c(0)|.  Where the phase's dynamics carry or reduce a difference
    (positions held or steered by the controllers), |a − b| ≤ d0 + (what the phase adds),
    so a max_abs or rms row is checked against tolerance + d0 (d0 is in the row as
    `inherited`); a row whose difference the phase amplifies needs its own tolerance in the
    sequence file (docs/cases.md §6)."""
    rows = []
    t = _same_times(case.name, reference, other)
    switches = switch_samples(t, reference, other)
    pair = (reference.engine, other.engine)
    departures = {e: departure_allowances(e, case) for e in pair}
    refinements = refinement_texts(pair)
    for spec in (case.compare if specs is None else specs):
        pt = pair_tolerance(spec, pair, {e: (measured or {}).get(e, {}).get(spec.observable) for e in pair},
                            {e: departures[e][spec.observable] for e in pair if spec.observable in departures[e]},
                            refinements, missing, chained)
        why = spec.why if pt.stated else pt.why(unit_of(spec.observable, spec.metric))
        a, b = _pair(reference, other, spec.observable, t.size)
        sampled = spec.metric in ("max_abs", "rms")
        at_switch = switches if spec.observable in MULTIPLIERS and sampled else np.zeros(0, int)
        between, skew = (between_events(t, reference, other, MODE_EVENTS[spec.observable])
                         if spec.observable in MODE_EVENTS and sampled else (np.zeros(0, int), 0.0))
        if spec.window is not None:  # only what the row looks at is left out, or listed
            inside = np.flatnonzero(in_window(t, spec.window))
            at_switch, between = np.intersect1d(at_switch, inside), np.intersect1d(between, inside)
        between = np.setdiff1d(between, at_switch)
        skew = skew if between.size else 0.0
        skip = np.union1d(at_switch, between).astype(int)
        if not np.all(np.isfinite(a[skip] - b[skip])):
            at_switch = between = skip = np.zeros(0, int)  # a blow-up there is a failure, not a limit
            skew = 0.0
        err, tw, c = difference(reference, other, spec.observable, spec.metric, case.name, spec.window, skip)
        rates = ({reference.engine: growth_rate(t, b, spec.window), other.engine: growth_rate(t, a, spec.window)}
                 if spec.metric == "growth" else {})
        at = tuple((float(t[i]), float(np.max(np.abs(a[i] - b[i])))) for i in at_switch)
        btw = tuple((float(t[i]), float(np.max(np.abs(a[i] - b[i])))) for i in between)
        d0 = float(np.max(np.abs(a[0] - b[0]))) if chained and sampled and t.size else 0.0
        rows.append(Check(case.name, spec.observable, err, pt.tolerance + d0, spec.metric, why,
                          tw, c, float(np.max(np.abs(b))) if b.size else 0.0, rates, at, btw, skew, d0,
                          spec.window, pair, pt))
    return rows


def _margin_text(x: float) -> str:
    return "inf" if x == float("inf") else f"{x:.3g}" if x >= 0.01 else f"{x:.2e}"


def row_lines(rows: Sequence[Check], pair_headers: bool = False, threshold: str = "tolerance",
              every_formula: bool = False) -> list[str]:
    """Rows as `rsmcheck check` and `rsmcheck judge` print them: a header, a line per row
    (error, `threshold`, margin, verdict), how a tolerance not stated in the case file is made
    (every one with `every_formula`), the samples left out; `pair_headers`: a line naming the
    pair before each pair's rows."""
    out = [f"  {'observable':20s} {'metric':8s} {'error':>10s} {threshold:>10s} {'margin':>8s}  result"]
    for i, r in enumerate(rows):
        if pair_headers and (i == 0 or rows[i - 1].engines != r.engines):
            out.append(f"  {r.engines[0]} against {r.engines[1]}:")
        out.append(f"  {r.observable:20s} {r.metric_label:8s} {r.error:10.3e} {r.tolerance:10.3e} "
                   f"{_margin_text(r.margin):>8s}  "
                   + ("pass" if r.passed else f"FAIL (worst at t = {r.worst_time:.4g} s, component {r.worst_component})"))
        if r.tolerance_parts is not None and (every_formula or not r.tolerance_parts.stated):
            out.append(f"  {'':20s} {threshold} = {r.tolerance_parts.formula()}")
        if r.switch_note():
            out.append(f"  {'':20s} {r.switch_note()}")
    return out


def engine_pairs(engines: Sequence[str]) -> list[tuple[str, str]]:
    """The pairs a cross-check compares: the first engine (the model under test) against
    each of the others."""
    return [(engines[0], other) for other in engines[1:]]


def needs_error(variant, engine: str) -> bool:
    """Whether a budgeted row of `variant` does not record `engine`'s own integration error
    (so that judging it needs its refined run)."""
    return any(s.allowance is not None and engine not in s.errors and engine not in s.engine_errors
               for s in variant.compare)


def integration_errors(variant, runs: Mapping[str, EngineRun],
                       refined: Mapping[str, EngineRun | None]) -> dict[str, dict[str, float]]:
    """engine → observable → d(run, refined run) by each row of `variant` (its own metric,
    window and left-out samples): the integration error of each engine that has a refined run."""
    return {e: {r.observable: r.error for r in check_runs(variant, runs[e], fine)}
            for e, fine in refined.items() if fine is not None and e in runs}


def case_rows(case, short: bool, runs: Mapping[str, EngineRun], engines: Sequence[str] | None = None,
              measured: Mapping[str, Mapping[str, float]] | None = None,
              missing: Mapping[str, str] | None = None) -> list[Check]:
    """The cross-check rows of one stand-alone case from its runs (engine → run): its
    [compare] table applied to each pair of `engines` (default: the default engines,
    rsmcheck.core.plugins.default_engines) of the variant (`short`), each with the pair's
    tolerance; `measured`: engine → observable → its integration error measured by its
    refined run (`integration_errors`), where a row does not record it (`needs_error`);
    `missing`: engine → why it was not measured.
    The one place both `rsmcheck check` and the report's verdict
    (rsmcheck.orchestration.collect) compute them; [] for a sequence, a case without a table
    or a missing engine."""
    variant = case.variant(short)
    engines = list(engines or default_engines())
    if case.phases or not variant.compare or not set(engines) <= set(runs):
        return []
    return [r for a, b in engine_pairs(engines)
            for r in check_runs(variant, runs[a], runs[b], measured=measured, missing=missing)]


def refined_runs(outcomes: Mapping[Job, Any]) -> tuple[dict[str, dict[str, EngineRun]], dict[str, BaseException]]:
    """The outcomes of `refined_jobs`: (case → engine → refined run, case → the first error)."""
    runs: dict[str, dict[str, EngineRun]] = {}
    errors: dict[str, BaseException] = {}
    for job, oc in outcomes.items():
        if oc.error is not None:
            errors.setdefault(job.key[0], oc.error)
        else:
            runs.setdefault(job.key[0], {})[job.key[1]] = oc.value
    return runs, errors


def refined_jobs(cases: Sequence[Any], short: bool, engines: Sequence[str],
                 options: Mapping[str, Mapping[str, Any]] | None = None) -> list[Job]:
    """The refined runs a check needs: of each engine whose error some budgeted row of a
    case does not record, and whose plug-in declares `refined_options`; job key
    (case, engine)."""
    jobs = []
    for case in cases:
        variant = case.variant(short)
        for e in engines:
            opts = refined_options(e, variant) if needs_error(variant, e) else None
            if opts is not None:
                how = refinement_texts([e])[e] or ", ".join(f"{k}={v}" for k, v in opts.items())
                jobs.append(Job(f"{case.name} / {e} refined ({how}): its own integration error", run_engine,
                                (e, variant, {**dict((options or {}).get(e, {})), **opts}),
                                2.0 * expected_wall(case, e), (case.name, e)))
    return jobs


def not_checked(case, short: bool) -> str:
    """Why `rsmcheck check` compares nothing for `case` ('' when it compares): a sequence
    (its phases are checked one by one) or no [compare] table.  A case that only chains
    from another's end state is an InputError: a check needs both engines at one state."""
    variant = case.variant(short)
    if case.phases:
        return f"a sequence of phases: check its phases ({', '.join(case.phases)}) one by one"
    if not variant.compare:
        return "no [compare] table in the case file: nothing is compared"
    if not variant.has_initial:
        raise InputError(variant.path, "initial", f"the case only chains from '{variant.start_from}': "
                         "a check needs a stand-alone [initial] (both engines from the same state)")
    return ""


@dataclass
class CaseCheck:
    """The result of checking one case: its rows, or why there are none (`skipped`), or
    the error that stopped one of its runs (`error`)."""

    case: str
    rows: list[Check] = field(default_factory=list)
    skipped: str = ""  # non-empty: nothing compared, and why
    runs: dict[str, EngineRun] = field(default_factory=dict)
    duration: float = 0.0
    wall_s: dict[str, float] = field(default_factory=dict)
    error: BaseException | None = None

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.rows)


def check_cases(cases: Sequence[Any], short: bool, options: Mapping[str, Mapping[str, Any]] | None = None,
                run_dir=None, *, rerun: bool = False, workers: int = 2, progress=None,
                engines: Sequence[str] | None = None) -> list[CaseCheck]:
    """`rsmcheck check`: the runs of `engines` (default: the default engines) from
    `rsmcheck.orchestration.runs.get_runs`
    (stored in and reused from `run_dir` when given, else made in memory), each case's
    rows by `case_rows`.  Every case is looked at before anything runs (`not_checked`); a
    case without rows is returned with `skipped` set and nothing run: it is not a pass."""
    skipped = {c.name: not_checked(c, short) for c in cases}
    todo = [c for c in cases if not skipped[c.name]]
    engines = list(engines or default_engines())
    extra = refined_jobs(todo, short, engines, options)
    got = get_runs(todo, engines, short, run_dir, rerun=rerun, options=options,
                   progress=progress, workers=workers, extra=extra)
    refined, refined_errors = refined_runs(got.extra)
    out = []
    for case in cases:
        if skipped[case.name]:
            out.append(CaseCheck(case.name, skipped=skipped[case.name]))
            continue
        errors = [x for (c, _), x in got.errors.items() if c == case.name]
        if case.name in refined_errors:
            errors.append(refined_errors[case.name])
        runs = got.runs[case.name]
        res = CaseCheck(case.name, runs=runs, duration=case.variant(short).duration,
                        error=errors[0] if errors else None)
        if res.error is None:
            measured = integration_errors(case.variant(short), runs, refined.get(case.name, {}))
            res.rows = case_rows(case, short, runs, engines, measured)
            res.wall_s = {e: float(r.solver.get("wall_s", float("nan"))) for e, r in runs.items()}
            res.wall_s["total"] = sum(got.wall_s.get((case.name, e), 0.0) for e in runs)
        out.append(res)
    return out


# ---------------------------------------------------------------------------------------
# relative differences: every observable, in units of its size
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Comparison(_Verdict):
    case: str
    observable: str
    error: float
    tolerance: float
    scale: float
    worst_time: float
    worst_component: int

    def as_dict(self) -> dict:
        return {"case": self.case, "observable": self.observable, "error": self.error,
                "tolerance": self.tolerance, "margin": self.margin, "pass": self.passed,
                "scale": self.scale, "worst_time": self.worst_time,
                "worst_component": self.worst_component}


def compare_runs(case: str, reference: EngineRun, other: EngineRun,
                 tolerances: Mapping[str, float], t_from: float | None = None) -> list[Comparison]:
    """Compare `other` against `reference` for every observable that has a tolerance, in
    units of the observable's size (scale above).  `t_from`: only samples at t ≥ t_from."""
    ta = _same_times(case, reference, other)
    sel = np.ones(ta.size, bool) if t_from is None else ta >= t_from - 1e-12
    rows = []
    for name, tol in tolerances.items():
        if name not in NAMES or name == "time":
            raise ValueError(f"{case}: no observable named {name!r}")
        a, b = _pair(reference, other, name, ta.size)
        a, b, t = a[sel], b[sel], ta[sel]
        scale = max(float(np.max(np.abs(b))) if b.size else 0.0, SCALE_FLOORS[name])
        diff = np.abs(a - b)
        k = int(np.argmax(diff))
        i, c = divmod(k, diff.shape[1])
        rows.append(Comparison(case, name, float(diff.flat[k]) / scale, float(tol), scale, float(t[i]), c))
    return rows


def relative_errors(case: str, reference: EngineRun, other: EngineRun,
                    names: Sequence[str] | None = None) -> dict[str, float]:
    """{observable: relative error} for every observable (or `names`)."""
    names = names or [n for n in NAMES if n != "time"]
    return {r.observable: r.error for r in compare_runs(case, reference, other, {n: 1.0 for n in names})}
