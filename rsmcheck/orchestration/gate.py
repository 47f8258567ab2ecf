"""Regression gate: every case's short variant, per engine, against a stored golden run.

The engine-vs-engine check cannot see a change that moves both engines together (a
parameter, a controller, a case file, the initial-state solver), and its tolerances are
set by the engines' modelling differences.  The gate compares each engine with *itself*
as it was when the golden was blessed, at the level of reproducibility (docs/gate.md):

* A golden (`goldens/CASE.ENGINE.h5`) is an ordinary run file (rsmcheck.core.store) holding
  every observable at at most `MAX_SAMPLES` evenly strided samples of the short run, all
  events and phases, and as root attributes its provenance (case-file hash, the hash of
  the case's run inputs — `runs.run_inputs_hash`, without prose and [compare] rows —,
  parameter hash, commit, package versions, platform, when and why it was blessed) and
  its gate tolerance per observable (`gate_tol.NAME`).
* The gate tolerance is *measured* at bless time: the case is run a second time with every
  mass of the parameter set scaled by (1 + `PERTURBATION`), a change 10⁴ times double
  round-off that stands in for another machine or library build (different operation
  order, FMA contraction); the tolerance is `TOL_FACTOR` times the largest change this
  causes in the observable, and at least `REL_FLOOR` times its largest magnitude.  Each
  engine is run a third time with the tolerance behind its discrete decisions scaled by
  (1 + `STEP_PERTURBATION`): the reference's rtol (its step control's accept/reject
  decisions), Exudyn's absolute Newton tolerance (when its iterations stop).  Another
  machine's round-off can flip such a decision, after which the solution differs by
  integration error or by what Newton's tolerance leaves, not by round-off;
  `STEP_FACTOR` times the change of that run is the second lower bound of the tolerance.
* Each engine is also run on every other CPU's code path this machine can emulate
  (rsmcheck.orchestration.code_paths: OpenBLAS's kernel family, numpy's SIMD dispatch,
  libm's FMA variants and numba's target CPU, each set as another processor would set
  them); `PATH_FACTOR` times the largest change among those runs is the third lower bound.
* A run moved when any observable differs from the golden by more than its gate tolerance
  at any stored sample, when the events or phases differ, or when its time grid differs.
  A changed run input of the case file or parameter set is reported as such (the run then
  has no golden to be compared with, and is "inputs changed", exit 1 until blessed).
* A run also moved when it did more work than its golden: a counter of its solver (the
  reference's attempted steps, Exudyn's Newton iterations, …: each plug-in's
  `work_counters`) above the golden's by more than `WORK_TOL` and `WORK_SLACK`.  Work is counted, never timed: the
  counts of the same code repeat exactly on one machine and move by at most ~1 % under
  round-off, its wall time by several per cent from run to run.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import platform
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from rsmcheck.core.cases import list_cases, load_case
from rsmcheck.core.plugins import plugins, step_perturbed_settings
from rsmcheck.orchestration import code_paths
from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import NAMES
from rsmcheck.orchestration.runs import (GOLDEN_DIR, Job, expected_wall, get_runs, golden_path,  # noqa: F401
                                         goldens_dir, run_engine, run_inputs_hash, run_jobs)  # GOLDEN_DIR: re-exported
from rsmcheck.core.params import Params
from rsmcheck.core.store import EngineRun, git_commit, read_run, write_run, write_text

CHANGELOG = "CHANGELOG.md"
GOLDEN_SCHEMA = 1
#: samples kept per golden run (evenly strided, the last one always kept)
MAX_SAMPLES = 100
#: relative change of every mass used to measure reproducibility at bless time
PERTURBATION = 1e-12
#: gate tolerance = TOL_FACTOR × the change the perturbation causes ...
TOL_FACTOR = 10.0
#: ... and at least STEP_FACTOR × the change a relative change STEP_PERTURBATION of the
#: tolerance behind the engine's decisions causes (`step_perturbed_case`: the reference's rtol,
#: another step sequence; Exudyn's Newton atol, other stopping decisions).  Between two CPUs a
#: flipped accept/reject decision moved capture's reference reaction forces by 1.4e-6 N, 19 ×
#: a tolerance measured from the mass perturbation alone, and flipped Newton stops moved
#: release's Exudyn link deflection by 3.8e-11 m, 279 × (docs/gate.md) ...
STEP_PERTURBATION = 1e-3
STEP_FACTOR = 3.0
#: ... and at least PATH_FACTOR × the largest change among the runs on the other CPUs' code
#: paths this machine emulates (`code_paths.available`): one such run measures one other
#: machine, where round-off may flip other decisions than it did (as for STEP_FACTOR).
#: Without this bound release's Exudyn golden, blessed on an AMD EPYC, moved on an Intel
#: Xeon by 4.55 × its tolerance; OpenBLAS's Haswell kernels on the Xeon reproduce the
#: EPYC's run to the bit (docs/gate.md)
PATH_FACTOR = 3.0
#: ... and at least REL_FLOOR × the observable's largest magnitude (+ ABS_FLOOR)
REL_FLOOR = 1e-10
ABS_FLOOR = 1e-14
#: two events are the same when kind and identity (`Event.identity`) agree and times
#: within this [s]
EVENT_TIME_TOL = 1e-9
#: a run's work: each engine plug-in's `work_counters`, sums of the counters in its solver
#: settings (`EngineRun.solver`); a counter may exceed its golden's by WORK_TOL of it plus
#: WORK_SLACK: 4 × the largest spread that round-off causes (Exudyn's Newton iterations in
#: p1_transport, +1.25 % under the mass perturbation; the reference's attempted steps 0.7 %
#: under the step perturbation), and 3 × the ±1 by which a count of a few Jacobians moves
#: (docs/gate.md, "Work")
WORK_TOL = 0.05
WORK_SLACK = 3
_TOL = "gate_tol."
_DELTA = "gate_delta."
_DELTA_STEP = "gate_delta_step."
_DELTA_PATH = "gate_delta_path."  # + NAME: the largest over the paths; + PATH.NAME: each path's


@dataclass
class Golden:
    """A golden run as read back: the decimated run, where its samples were, provenance."""

    path: Path
    run: EngineRun
    index: np.ndarray  # sample indices of the full run that were kept
    n_full: int
    tolerances: dict[str, float]
    attrs: dict[str, Any]


@dataclass(frozen=True)
class Moved:
    """One observable of one run that left its gate tolerance."""

    observable: str
    change: float  # largest |new − golden| over the stored samples and components
    tolerance: float
    first_time: float  # first stored sample at which the tolerance is exceeded [s]
    component: int

    @property
    def ratio(self) -> float:
        return self.change / self.tolerance if self.tolerance > 0 else float("inf")


@dataclass(frozen=True)
class WorkChange:
    """One work counter of one run against its golden's."""

    counter: str  # its label (`WorkCounter.label` of the engine's plug-in)
    golden: int
    new: int

    @property
    def limit(self) -> int:
        """The most the gate accepts: golden × (1 + WORK_TOL) + WORK_SLACK."""
        return int(self.golden * (1.0 + WORK_TOL)) + WORK_SLACK

    @property
    def grew(self) -> bool:
        return self.new > self.limit

    @property
    def relative(self) -> float:
        """(new − golden) / golden (0 when both are 0)."""
        if self.golden == 0:
            return 0.0 if self.new == 0 else float("inf")
        return (self.new - self.golden) / self.golden

    @property
    def ratio(self) -> float:
        """The growth over the growth the gate accepts (> 1: more work; 0 for less work)."""
        return max(0, self.new - self.golden) / (self.limit - self.golden)

    def describe(self) -> str:
        return f"{self.counter} {_count(self.golden)} → {_count(self.new)} ({self.relative:+.2%})"


def _percent(relative: float) -> str:
    """A relative change in per cent with two significant digits, never in exponent form
    (+0.0029, −0.29, +13, +100)."""
    p = 100.0 * relative
    return f"{p:+.0f}" if abs(p) >= 10.0 else f"{p:+.2g}"


def _count(n: int) -> str:
    """An integer with thin groups of three digits (108 789)."""
    return f"{n:,}".replace(",", " ")


@dataclass
class GateResult:
    """The gate's verdict on one (case, engine)."""

    case: str
    engine: str
    inputs_changed: list[str] = field(default_factory=list)  # case file / parameters
    moved: list[Moved] = field(default_factory=list)
    structure: list[str] = field(default_factory=list)  # time grid, events, phases
    largest_ratio: float = 0.0  # max change / tolerance over all observables
    work: list[WorkChange] = field(default_factory=list)  # every work counter both runs have

    @property
    def more_work(self) -> list[WorkChange]:
        """The work counters above their limit."""
        return [w for w in self.work if w.grew]

    @property
    def work_ratio(self) -> float:
        """The largest growth of a work counter over the growth the gate accepts."""
        return max((w.ratio for w in self.work), default=0.0)

    @property
    def unchanged(self) -> bool:
        return not (self.inputs_changed or self.moved or self.structure or self.more_work)

    def work_summary(self) -> str:
        """A few words: which work counters changed against the golden, by how much."""
        if not self.work:
            return "no work counters in the golden"
        changed = [w for w in self.work if w.new != w.golden]
        if not changed:
            return "work as blessed"
        return ("work " + ", ".join(f"{w.counter} {_percent(w.relative)} %" for w in changed)
                + f" (limit +{WORK_TOL:.0%} + {WORK_SLACK})")

    def as_dict(self) -> dict[str, Any]:
        return {"case": self.case, "engine": self.engine, "unchanged": self.unchanged,
                "inputs_changed": self.inputs_changed, "structure": self.structure,
                "largest_ratio": self.largest_ratio,
                "moved": [{**dataclasses.asdict(m), "ratio": m.ratio} for m in self.moved],
                "work": [{**dataclasses.asdict(w), "limit": w.limit, "relative": w.relative, "grew": w.grew,
                          "text": w.describe()} for w in self.work],
                "work_ratio": self.work_ratio, "work_summary": self.work_summary()}


# ---------------------------------------------------------------------------------------
# golden files
# ---------------------------------------------------------------------------------------
def kept_samples(n_full: int, max_samples: int = MAX_SAMPLES) -> np.ndarray:
    """Indices kept in a golden: every `stride`-th sample and the last one."""
    if n_full < 1:
        raise ValueError("a run needs at least one sample")
    stride = max(1, -(-n_full // max_samples))
    idx = np.arange(0, n_full, stride)
    if idx[-1] != n_full - 1:
        idx = np.append(idx, n_full - 1)
    return idx


def at_samples(run: EngineRun, index: np.ndarray) -> EngineRun:
    """`run` with every observable at the sample indices `index` (events, phases kept)."""
    return dataclasses.replace(run, observables={k: np.asarray(v)[index] for k, v in run.observables.items()})


def scales(run: EngineRun) -> dict[str, float]:
    """Largest finite magnitude of each observable (the size a relative floor refers to)."""
    out = {}
    for name in NAMES:
        x = np.asarray(run.observables[name], float)
        fin = x[np.isfinite(x)]
        out[name] = float(np.max(np.abs(fin))) if fin.size else 0.0
    return out


def differences(run: EngineRun, golden_run: EngineRun, index: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per observable: (|new − golden| at the stored samples, per sample and component
    flattened to (samples, components)); a NaN on one side only is an infinite change."""
    out = {}
    for name in NAMES:
        a = np.asarray(run.observables[name], float)[index].reshape(len(index), -1)
        b = np.asarray(golden_run.observables[name], float).reshape(len(index), -1)
        d = np.abs(a - b)
        both_nan = np.isnan(a) & np.isnan(b)
        d[both_nan] = 0.0
        d[np.isnan(d)] = np.inf
        out[name] = (d, np.asarray(golden_run.observables["time"], float))
    return out


@dataclass
class Measured:
    """What bless measures per observable: the gate tolerance and the change each kind of
    perturbed run caused against the nominal run (the masses, the decisions' tolerance,
    each emulated code path; `path` is the largest over the paths).  Without a
    step-perturbed run `step` is None; without code-path runs `per_path` is empty and
    `path` zero."""

    tolerance: dict[str, float]
    mass: dict[str, float]
    step: dict[str, float] | None
    path: dict[str, float]
    per_path: dict[str, dict[str, float]]


def _largest_changes(other: EngineRun, nominal: EngineRun, what: str) -> dict[str, float]:
    """Per observable the largest |other − nominal| over all samples."""
    n = len(nominal.observables["time"])
    if len(other.observables["time"]) != n:
        raise RuntimeError(f"the {what} run has another time grid than the nominal one: the case is not "
                           "reproducible at round-off level (an event moved by a sample)")
    out = {}
    for name, (d, _) in differences(other, nominal, np.arange(n)).items():
        out[name] = float(np.max(d)) if d.size else 0.0
        if not np.isfinite(out[name]):
            raise RuntimeError(f"{name}: the {what} run is NaN where the nominal one is not")
    return out


def measured_tolerances(nominal: EngineRun, perturbed: EngineRun, stepped: EngineRun | None = None,
                        paths: dict[str, EngineRun] | None = None) -> Measured:
    """The gate tolerance of every observable from the nominal run, the mass-perturbed one,
    the step-perturbed one (`step_perturbed_case`; None: no such run, its changes 0) and the
    runs on other CPUs' code paths (`code_paths`; name → run):

        tolerance = max(TOL_FACTOR × mass change, STEP_FACTOR × step change,
                        PATH_FACTOR × largest code-path change, REL_FLOOR × |value|max + ABS_FLOOR)."""
    mass = _largest_changes(perturbed, nominal, "mass-perturbed")
    step = _largest_changes(stepped, nominal, "step-perturbed") if stepped is not None else None
    per_path = {p: _largest_changes(r, nominal, f"code path {p}") for p, r in (paths or {}).items()}
    path = {name: max((d[name] for d in per_path.values()), default=0.0) for name in NAMES}
    size = scales(nominal)
    tol = {name: max(TOL_FACTOR * mass[name], STEP_FACTOR * (step[name] if step else 0.0), PATH_FACTOR * path[name],
                     REL_FLOOR * size[name] + ABS_FLOOR) for name in NAMES}
    return Measured(tol, mass, step, path, per_path)


def write_golden(path: Path, case, run: EngineRun, measured: Measured, reason: str) -> Path:
    """Write the decimated `run` of the short variant of `case` with its provenance and
    what bless measured (`measured_tolerances`)."""
    n_full = len(run.observables["time"])
    idx = kept_samples(n_full)
    small = at_samples(run, idx)
    extra: dict[str, Any] = {
        "golden_schema": GOLDEN_SCHEMA, "short": True, "n_full": n_full, "max_samples": MAX_SAMPLES,
        "reason": reason, "blessed_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "platform": platform.platform(), "machine": platform.machine(), "cpu": cpu_name(),
        "perturbation": PERTURBATION, "tol_factor": TOL_FACTOR, "rel_floor": REL_FLOOR,
        "step_perturbation": STEP_PERTURBATION if measured.step is not None else 0.0, "step_factor": STEP_FACTOR,
        "path_factor": PATH_FACTOR, "code_paths": ",".join(measured.per_path),
        "run_inputs_hash": run_inputs_hash(case),
    }
    extra.update({_TOL + k: float(v) for k, v in measured.tolerance.items()})
    extra.update({_DELTA + k: float(v) for k, v in measured.mass.items()})
    extra.update({_DELTA_STEP + k: float(v) for k, v in (measured.step or {}).items()})
    if measured.per_path:
        extra.update({_DELTA_PATH + k: float(v) for k, v in measured.path.items()})
        for p, deltas in measured.per_path.items():
            extra.update({f"{_DELTA_PATH}{p}.{k}": float(v) for k, v in deltas.items()})
    return write_run(path, {run.engine: small}, case_name=case.name, case_hash=case.file_hash,
                     param_hash=case.params.digest(), extra_attrs=extra, compress=True)


def cpu_name() -> str:
    """This processor's model name (/proc/cpuinfo), else the platform's word for it."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def read_golden(path: Path, engine: str) -> Golden:
    """Read a golden; a missing, corrupt or foreign file is an InputError (exit 2)."""
    where = str(path)
    if not Path(path).exists():
        raise InputError(where, "file", "no golden for this case and engine: bless it first "
                                        "(rsmcheck bless CASE --reason TEXT)")
    try:
        runs, attrs = read_run(path)
    except FileNotFoundError:
        raise InputError(where, "file", "no such golden") from None
    if attrs.get("golden_schema") != GOLDEN_SCHEMA:
        raise InputError(where, "golden_schema", f"{attrs.get('golden_schema')!r} is not a golden of schema "
                                                 f"{GOLDEN_SCHEMA}: re-bless it")
    if engine not in runs:
        raise InputError(where, engine, f"the golden holds {', '.join(runs)}, not {engine}")
    try:
        n_full = int(attrs["n_full"])
        tol = {name: float(attrs[_TOL + name]) for name in NAMES}
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(where, "attributes", f"missing or malformed gate attribute ({exc})") from None
    idx = kept_samples(n_full, int(attrs.get("max_samples", MAX_SAMPLES)))
    run = runs[engine]
    if len(run.observables["time"]) != len(idx):
        raise InputError(where, "time", f"{len(run.observables['time'])} samples stored, "
                                        f"{len(idx)} expected from n_full = {n_full}")
    return Golden(Path(path), run, idx, n_full, tol, attrs)


# ---------------------------------------------------------------------------------------
# comparing
# ---------------------------------------------------------------------------------------
def _events(run: EngineRun) -> list[tuple[str, str, float]]:
    return [(e.kind, e.identity, e.time) for e in run.events]


def work_changes(run: EngineRun, golden_run: EngineRun) -> list[WorkChange]:
    """Each work counter of the run's engine plug-in (`work_counters`) that both runs'
    solver settings hold (a golden blessed before a counter existed is not compared on it)."""
    out = []
    counters = plugins()[run.engine].work_counters if run.engine in plugins() else ()
    for c in counters:
        if all(k in run.solver and k in golden_run.solver for k in c.keys):
            out.append(WorkChange(c.label, sum(int(golden_run.solver[k]) for k in c.keys),
                                  sum(int(run.solver[k]) for k in c.keys)))
    return out


def compare_with_golden(case, run: EngineRun, golden: Golden) -> GateResult:
    """The gate's verdict on `run` (of `case`'s short variant) against `golden`."""
    res = GateResult(case.name, run.engine, work=work_changes(run, golden.run))
    inputs = run_inputs_hash(case)
    if golden.attrs.get("run_inputs_hash") != inputs:
        res.inputs_changed.append(f"case file {case.path} changed since the golden was blessed "
                                  f"(run inputs, without prose and [compare] rows: "
                                  f"{str(golden.attrs.get('run_inputs_hash'))[:12]} → {inputs[:12]})")
    if golden.attrs.get("param_hash") != case.params.digest():
        res.inputs_changed.append(f"parameter set changed since the golden was blessed "
                                  f"({str(golden.attrs.get('param_hash'))[:12]} → {case.params.digest()[:12]})")
    t_new = np.asarray(run.observables["time"], float)
    if len(t_new) != golden.n_full or not np.array_equal(t_new[golden.index], golden.run.observables["time"]):
        res.structure.append(f"time grid: {len(t_new)} samples to {t_new[-1]:g} s, golden "
                             f"{golden.n_full} to {golden.run.observables['time'][-1]:g} s")
        return res
    ev_new, ev_old = _events(run), _events(golden.run)
    if [e[:2] for e in ev_new] != [e[:2] for e in ev_old]:
        if [e[0] for e in ev_new] != [e[0] for e in ev_old]:
            res.structure.append(f"events: {[e[0] for e in ev_old]} → {[e[0] for e in ev_new]}")
        else:  # the same kinds: say which event's identity changed
            (kind, new, t1), (_, old, _) = next((a, b) for a, b in zip(ev_new, ev_old) if a[1] != b[1])
            res.structure.append(f"event '{kind}' at {t1:.9g} s: '{old}' → '{new}'")
    else:
        for (kind, _, t1), (_, _, t0) in zip(ev_new, ev_old):
            if abs(t1 - t0) > EVENT_TIME_TOL:
                res.structure.append(f"event '{kind}' at {t0:.9g} s → {t1:.9g} s")
    if [(p.name, p.t_start, p.t_end) for p in run.phases] != [(p.name, p.t_start, p.t_end) for p in golden.run.phases]:
        res.structure.append("phases: " + ", ".join(f"{p.name} [{p.t_start:g}, {p.t_end:g}]" for p in run.phases))
    for name, (d, t) in differences(run, golden.run, golden.index).items():
        tol = golden.tolerances[name]
        worst = float(np.max(d)) if d.size else 0.0
        res.largest_ratio = max(res.largest_ratio, worst / tol if tol > 0 else (np.inf if worst > 0 else 0.0))
        if worst > tol:
            first = int(np.argwhere(d > tol)[0][0])
            comp = int(np.unravel_index(np.argmax(d), d.shape)[1])
            res.moved.append(Moved(name, worst, tol, float(t[first]), comp))
    return res


# ---------------------------------------------------------------------------------------
# blessing
# ---------------------------------------------------------------------------------------
def perturbed_case(case):
    """`case` with every mass of its parameters scaled by (1 + PERTURBATION)."""
    values = case.params.to_dict()
    for section in ("base", "target", "link"):
        values[section]["mass"] *= 1.0 + PERTURBATION
    return dataclasses.replace(case, params=Params.from_overrides(values, "<perturbation>"))


def step_perturbed_case(case):
    """`case` with the tolerance behind each engine's discrete decisions scaled by
    (1 + STEP_PERTURBATION), at the same accuracy (each plug-in's `step_perturbed`: the
    reference's relative tolerance, another sequence of accepted and rejected steps;
    Exudyn's absolute Newton tolerance, other steps where the iteration stops)."""
    return dataclasses.replace(case, engine_settings=step_perturbed_settings(case.engine_settings,
                                                                             1.0 + STEP_PERTURBATION))


def summarize_change(old: Golden | None, new_run: EngineRun, case) -> list[str]:
    """Lines for the changelog: what moved between the old golden and the new run."""
    if old is None:
        return ["new golden"]
    lines = []
    res = compare_with_golden(case, new_run, old)
    lines += res.inputs_changed + res.structure
    for m in res.moved:
        lines.append(f"{m.observable}: changed by {m.change:.3e} (gate tolerance {m.tolerance:.3e}; "
                     f"first at t = {m.first_time:.4g} s)")
    # the work, where it moved by more than the gate accepts either way (less work is
    # recorded too: the next gate compares with it)
    lines += [f"work: {w.describe()}" for w in res.work
              if w.grew or w.new < w.golden - (w.limit - w.golden)]
    if not lines:
        lines.append(f"unchanged (largest change {res.largest_ratio:.2g} × its gate tolerance)")
    return lines


def append_changelog(root: Path, reason: str, entries: Iterable[tuple[str, str, list[str]]]) -> Path:
    """Prepend one bless entry (newest first) to goldens/CHANGELOG.md, atomically."""
    path = Path(root) / CHANGELOG
    head = "# Golden changelog\n\nOne entry per `rsmcheck bless`, newest first.\n\n"
    old = path.read_text() if path.exists() else head
    body = old[len(head):] if old.startswith(head) else old
    commit, dirty = git_commit()
    when = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    lines = [f"## {when} — {reason}", "", f"Commit {commit}" + (" (with uncommitted changes)" if dirty == "yes" else "")
             + f"; platform {platform.platform()}.", ""]
    for case, engine, what in entries:
        lines.append(f"- **{case} / {engine}**: " + "; ".join(what))
    text = head + "\n".join(lines) + "\n\n" + body
    return write_text(path, text)


# ---------------------------------------------------------------------------------------
# running: the fresh runs from rsmcheck.orchestration.runs (its producer and its pool)
# ---------------------------------------------------------------------------------------
def gated_cases() -> list:
    """The cases with goldens: every stand-alone case (sequences are gated phase by phase)."""
    return [c for c in (load_case(p) for p in list_cases()) if not c.phases and c.variant(True).has_initial]


def gate(cases: list, engines: list[str], root: Path | None = None, progress=None) -> list[GateResult]:
    """Run the short variant of every case in every engine (fresh runs, nothing stored:
    `runs.get_runs` without a folder) and compare with its golden.  Every golden is read
    (and a bad one reported, InputError) before anything runs."""
    variants = [c.variant(True) for c in cases]
    goldens = {(v.name, e): read_golden(golden_path(v.name, e, root), e) for v in variants for e in engines}
    got = get_runs(cases, engines, True, None, progress=progress)
    for error in got.errors.values():
        raise error
    return [compare_with_golden(v, got.runs[v.name][e], goldens[(v.name, e)]) for v in variants for e in engines]


def bless(cases: list, engines: list[str], reason: str, root: Path | None = None, progress=None,
          paths: list | None = None) -> list[tuple[str, str, list[str]]]:
    """Re-run and rewrite the goldens of `cases` and prepend what moved to the changelog (in
    `root`, else in `goldens_dir()`).  Each engine runs each case's short variant nominally,
    with the masses perturbed, with its decisions' tolerance perturbed, and on every code
    path of `paths` (default: every other CPU's this one can emulate,
    `code_paths.available()`); the gate tolerances are measured from them."""
    root = goldens_dir() if root is None else Path(root)
    if not reason or not reason.strip():
        raise InputError("bless", "--reason", "a bless needs a reason (what changed and why the new results are right)")
    paths = code_paths.available() if paths is None else list(paths)
    variants = [c.variant(True) for c in cases]
    kinds = {"nominal": lambda v: v, "perturbed": perturbed_case, "step-perturbed": step_perturbed_case}
    jobs = [Job(f"{v.name} / {e}" + (f" ({k})" if k != "nominal" else ""), run_engine,
                (e, make(v)), expected_wall(v, e), (v.name, e, k))
            for v in variants for e in engines for k, make in kinds.items()]
    jobs += [Job(f"{v.name} / {e} (code path {p.name})", code_paths.run_on_path, (p, e, v), expected_wall(v, e),
                 (v.name, e, p.name)) for v in variants for e in engines for p in paths]
    done = run_jobs(jobs, progress)  # the one pool; a failed job raises once all have ended
    for job in jobs:
        if done[job].error is not None:
            raise done[job].error
    runs = {job.key: done[job].value for job in jobs}
    entries = []
    for v in variants:
        for e in engines:
            path = golden_path(v.name, e, root)
            try:
                old = read_golden(path, e) if path.exists() else None
            except InputError:
                old = None
            nominal = runs[(v.name, e, "nominal")]
            measured = measured_tolerances(nominal, runs[(v.name, e, "perturbed")], runs[(v.name, e, "step-perturbed")],
                                           {p.name: runs[(v.name, e, p.name)] for p in paths})
            what = summarize_change(old, nominal, v) if old is not None else ["new golden"]
            write_golden(path, v, nominal, measured, reason.strip())
            entries.append((v.name, e, what))
    append_changelog(root, reason.strip(), entries)
    return entries


def tolerance_table(cases: list, engines: list[str], root: Path | None = None) -> list[dict[str, Any]]:
    """Per (case, engine, observable): the gate tolerance, the changes the mass and the step
    perturbation and the code paths caused (the largest and each path's; NaN for a golden
    blessed without that run), which of them sets the tolerance, and the observable's
    largest magnitude, as stored in the goldens."""
    rows = []
    nan = float("nan")
    for c in cases:
        for e in engines:
            g = read_golden(golden_path(c.name, e, root), e)
            size = scales(g.run)
            names = [p for p in str(g.attrs.get("code_paths", "")).split(",") if p]
            for name in NAMES:
                row = {"case": c.name, "engine": e, "observable": name, "tolerance": g.tolerances[name],
                       "perturbation_change": float(g.attrs.get(_DELTA + name, nan)),
                       "step_change": float(g.attrs.get(_DELTA_STEP + name, nan)),
                       "path_change": float(g.attrs.get(_DELTA_PATH + name, nan)),
                       "paths": {p: float(g.attrs.get(f"{_DELTA_PATH}{p}.{name}", nan)) for p in names},
                       "largest_value": size[name]}
                row["set_by"] = _setter(row)
                rows.append(row)
    return rows


def _setter(row: dict[str, Any]) -> str:
    """Which bound sets a tolerance-table row's tolerance ('masses', 'decisions', 'code
    paths', 'floor')."""
    bounds = {"masses": TOL_FACTOR * row["perturbation_change"], "decisions": STEP_FACTOR * row["step_change"],
              "code paths": PATH_FACTOR * row["path_change"]}
    bounds = {k: v for k, v in bounds.items() if np.isfinite(v)}
    kind = max(bounds, key=bounds.get, default="floor")
    return kind if kind != "floor" and bounds[kind] >= row["tolerance"] * (1 - 1e-12) else "floor"
