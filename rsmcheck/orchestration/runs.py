"""Engine runs: the one producer and reader of runs, and the one worker pool.

Runs flow one way: engines → run files (rsmcheck.core.store) → `get_runs` → the comparisons.
`rsmcheck check` (through `compare.check_cases`), `rsmcheck gate` (`gate.gate`) and the
report (`collect.collect`) all ask `get_runs` for the runs of a list of cases, engines and
a variant (short or full):

* with a folder (`run_dir`, holding ``CASE.h5`` with every engine's run of the case), a
  stored run is reused when `read_stored` finds it valid for the current inputs — the
  same run inputs of the case file and, for a sequence, of its phases' files
  (`run_inputs_hash`: their content without prose and without [compare] rows, so that a
  restated tolerance is judged on the runs it restates), parameters (`param_hash`),
  variant (`short`), source code (`source_digest`: the modules runs are made by) and
  engine options; the missing ones are run, stored beside the valid ones, and read back,
  so that a fresh run and a reused one reach the comparison alike;
* without a folder every run is made and kept in memory (the gate: fresh runs only).

The work is done by `run_jobs`: independent jobs on a Dask cluster
(rsmcheck.orchestration.executor: by default one of this machine's, `workers` processes,
two by default; or the one `rsmcheck --scheduler ADDRESS` or $RSMCHECK_SCHEDULER names),
longest first (the wall time each golden recorded, `expected_wall`), a line per finished
job and a failed job named with its error; `workers=0` runs them in this process.  The report's Pinocchio and eigenfrequency jobs and the gate's perturbed
runs go through the same pool.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import pickle
import tempfile
import time
import tomllib
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from rsmcheck.core.cases import Case, phase_cases, sibling_case
from rsmcheck.core.errors import InputError, SimulationDiverged
from rsmcheck.orchestration import executor
from rsmcheck.orchestration.chain import PhaseOptions, run_mission
from rsmcheck.core.plugins import make_engine, plugins
from rsmcheck.driver.runner import run
from rsmcheck.core.store import EngineRun, read_run, write_run

ROOT = Path(__file__).resolve().parents[2]
#: the gate's golden runs (rsmcheck.orchestration.gate), one file per case and engine
GOLDEN_DIR = ROOT / "goldens"
#: environment variable naming another folder of goldens (`goldens_dir`)
GOLDENS_ENV = "RSMCHECK_GOLDENS_DIR"
#: the sources of rsmcheck that make a run what it is: the foundation, the driver and the
#: chaining of a sequence's phases (a folder ends in /).  The rest of rsmcheck orchestrates,
#: compares or reports: no run depends on it, and the verdict is recomputed from the runs
#: every time.  Every registered plug-in's package counts whole.
RUN_SOURCES = ("rsmcheck/__init__.py", "rsmcheck/core/", "rsmcheck/driver/",
               "rsmcheck/orchestration/__init__.py", "rsmcheck/orchestration/chain.py")
#: keys of a case file that explain or judge a run and do not change it: prose, and the
#: [compare] rows (a sequence's [short_compare] too), at any depth
NOT_RUN_INPUTS = frozenset({"why", "description", "gains", "compare", "short_compare"})

Progress = Callable[[str], None]


def source_digest(root: Path | None = None) -> str:
    """sha256 over the names and contents of the .py files that runs are made by: those of
    RUN_SOURCES and of every registered plug-in's package (a variant's: the package of its
    `source_module`, rsmcheck.core.derived), found under `root` where given,
    else where they are imported from: a run made by other code is not reused."""
    h = hashlib.sha256()
    packages = sorted({"rsmcheck", *((getattr(p, "source_module", None) or type(p).__module__).split(".")[0]
                                     for p in plugins().values())})
    for pkg in packages:
        folder = Path(root) / pkg if root is not None else _package_folder(pkg)
        files = sorted(folder.rglob("*.py")) if folder.is_dir() else [folder] if folder.is_file() else []
        for path in files:
            name = f"{pkg}/{path.relative_to(folder).as_posix()}"
            if pkg == "rsmcheck" and not in_run_sources(name):
                continue
            h.update(name.encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def in_run_sources(name: str) -> bool:
    """Whether rsmcheck's module `name` ("rsmcheck/core/cases.py") is one runs are made by."""
    return any(name.startswith(s) if s.endswith("/") else name == s for s in RUN_SOURCES)


def run_inputs_hash(case: Case) -> str:
    """SHA-256 of what in the case files makes the runs of `case` what they are: its file's
    parsed content without NOT_RUN_INPUTS, and for a sequence each phase's file's too (both
    variants' phases, by name).  Read from the files, so a base case and its variants hash
    alike."""
    def content(path: str | Path) -> Any:
        with open(path, "rb") as f:
            return strip(tomllib.load(f))

    def strip(x: Any) -> Any:
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if k not in NOT_RUN_INPUTS}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x

    data: dict[str, Any] = {"case": content(case.path)}
    if case.phases:
        names = sorted({*case.variant(False).phases, *case.variant(True).phases})
        data["phases"] = {n: content(sibling_case(n, Path(case.path))) for n in names}
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


def _package_folder(package: str) -> Path:
    """The folder of `package`, or the file of a module that is not a package."""
    spec = importlib.util.find_spec(package)
    if spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations)))
    return Path(spec.origin)


def goldens_dir() -> Path:
    """The folder of the goldens: $RSMCHECK_GOLDENS_DIR where it is set (a user's own
    cases, a test's temporary folder), else goldens/ beside the rsmcheck package."""
    return Path(os.environ.get(GOLDENS_ENV) or GOLDEN_DIR)


def golden_path(case_name: str, engine: str, root: Path | None = None) -> Path:
    """Where the gate keeps the golden run of `case_name` in `engine` (in `root`, else in
    `goldens_dir()`)."""
    return Path(goldens_dir() if root is None else root) / f"{case_name}.{engine}.h5"


def expected_wall(case: Case, engine: str) -> float:
    """The wall time the case's golden recorded for `engine` [s] (0 without one; a sequence:
    the sum over its phases).  Only orders the jobs, longest first."""
    if case.phases:
        return sum(expected_wall(phase, engine) for phase in phase_cases(case, True))
    path = golden_path(case.name, engine)
    try:
        return float(read_run(path)[0][engine].solver.get("wall_s", 0.0)) if path.exists() else 0.0
    except (OSError, InputError, KeyError):
        return 0.0


# ---------------------------------------------------------------------------------------
# the worker pool
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Job:
    """One piece of work: `fn(*args)` (a module-level function: it is sent to a worker by
    name), `label` for the progress line, `expected_s` to order the jobs (longest first),
    `key` for the caller to find what it asked for.  Jobs compare by identity."""

    label: str
    fn: Callable[..., Any]
    args: tuple = ()
    expected_s: float = 0.0
    key: Any = None


@dataclass
class Outcome:
    """A job's result, or the exception it raised (`error`), and its wall seconds."""

    value: Any = None
    error: BaseException | None = None
    wall_s: float = 0.0

    @property
    def error_text(self) -> str:
        return _error_line(self.error) if self.error is not None else ""


def _error_line(exc: BaseException) -> str:
    """'Type: message (note) …' of an exception, on one line."""
    notes = "".join(f" ({n})" for n in getattr(exc, "__notes__", ()))
    return f"{type(exc).__name__}: {exc}{notes}"


def _call(fn: Callable[..., Any], args: tuple) -> Outcome:
    """`fn(*args)` timed; an exception is returned, as itself when it pickles (rsmcheck's
    errors do: a bad input stays an InputError), else as a RuntimeError with its text.
    The traceback does not cross the process boundary, so an exception that is not one of
    rsmcheck's own (a fault in the code, not in the input or the simulation) takes the
    place it was raised at as a note: a bare `StopIteration` says nothing."""
    t0 = time.monotonic()
    try:
        return Outcome(fn(*args), None, time.monotonic() - t0)
    except Exception as exc:  # noqa: BLE001 — the caller decides what a failure means
        if not isinstance(exc, (InputError, SimulationDiverged)) and exc.__traceback__ is not None:
            frame = traceback.extract_tb(exc.__traceback__)[-1]
            exc.add_note(f"raised at {frame.filename}:{frame.lineno} in {frame.name}")
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:  # noqa: BLE001
            exc = RuntimeError(_error_line(exc))
        exc.__traceback__ = None
        return Outcome(None, exc, time.monotonic() - t0)


def run_jobs(jobs: Sequence[Job], progress: Progress | None = None, workers: int = 2) -> dict[Job, Outcome]:
    """Run `jobs`, longest first, on a Dask cluster (`executor`: this machine's, `workers`
    processes, or the one --scheduler / $RSMCHECK_SCHEDULER names; 0: one after the other
    in this process); {job: outcome}.  `progress(text)` gets a line per finished job: how
    many are done, the time since the start, the job and its wall time or its error (a job
    Dask could not run, e.g. one whose workers kept dying: KilledWorker)."""
    out: dict[Job, Outcome] = {}
    if not jobs:
        return out
    order = sorted(jobs, key=lambda j: -j.expected_s)  # stable: equal ones keep their order
    t0 = time.monotonic()

    def done(n: int, job: Job, outcome: Outcome) -> None:
        out[job] = outcome
        if progress:
            status = f"FAILED: {outcome.error_text}" if outcome.error is not None else f"{outcome.wall_s:.0f} s"
            progress(f"[{n}/{len(jobs)}, {time.monotonic() - t0:.0f} s] {job.label}: {status}")

    if workers <= 0:
        for n, job in enumerate(order, 1):
            done(n, job, _call(job.fn, job.args))
        return out
    tasks = [(_call, (job.fn, job.args)) for job in order]
    for n, (i, outcome, exc) in enumerate(executor.completed(tasks, workers, source_digest), 1):
        done(n, order[i], outcome if exc is None else Outcome(None, exc, 0.0))
    return out


# ---------------------------------------------------------------------------------------
# what a job runs
# ---------------------------------------------------------------------------------------
def run_engine(engine: str, case: Case, options: Mapping[str, Any] | None = None) -> EngineRun:
    """Run one engine on `case` (the variant to run) for its duration.  A bad engine option
    value becomes an InputError naming the options (exit 2 on the command line)."""
    options = dict(options or {})
    try:
        return run(make_engine(engine, case, **options), case, case.duration)
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        raise InputError("--option", ",".join(f"{engine}:{k}={v}" for k, v in options.items()) or engine,
                         str(exc)) from None


@dataclass
class SequenceRun:
    """A sequence case's flight in one engine, and each phase's own run (phase name → run)."""

    run: EngineRun
    phases: dict[str, EngineRun]


def run_sequence(engine: str, case: Case, short: bool, workdir: str,
                 options: Mapping[str, Any] | None = None,
                 phase_options: PhaseOptions | None = None) -> SequenceRun:
    """Fly `case` (a sequence, the base case) in `engine`, its phases chained
    (rsmcheck.orchestration.chain.run_mission, into `workdir`); every phase's engine takes
    `options` and what `phase_options(phase variant)` gives."""
    out = Path(workdir) / f"{case.name}.{engine}"
    phases: dict[str, dict[str, EngineRun]] = {}
    runs, _ = read_run(run_mission(case.variant(short), [engine], short, out,
                                   options={engine: dict(options or {})} if options else None,
                                   phase_runs=phases,
                                   phase_options={engine: phase_options} if phase_options else None))
    return SequenceRun(runs[engine], {p: r[engine] for p, r in phases.items()})


# ---------------------------------------------------------------------------------------
# run files: the one reader and writer of stored runs
# ---------------------------------------------------------------------------------------
def run_path(run_dir: Path, case: Case) -> Path:
    return Path(run_dir) / f"{case.name}.h5"


def _options_attr(options: Mapping[str, Mapping[str, Any]]) -> str:
    return json.dumps({e: dict(o) for e, o in options.items()}, sort_keys=True)


def read_stored(path: Path, case: Case, short: bool,
                digest: str | None = None) -> tuple[dict[str, EngineRun], dict[str, dict[str, Any]]]:
    """The runs `path` holds that were made from this case's run inputs (`run_inputs_hash`),
    parameters, variant and source code (`digest`, default `source_digest()`), and each
    one's engine options: ({engine: run}, {engine: options}); ({}, {}) when the file is missing, unreadable or
    was made from other inputs."""
    path = Path(path)
    if not path.is_file():
        return {}, {}
    try:
        runs, attrs = read_run(path)
    except (OSError, InputError):
        return {}, {}
    if not (attrs.get("run_inputs_hash") == run_inputs_hash(case) and attrs.get("param_hash") == case.params.digest()
            and bool(attrs.get("short")) == bool(short)
            and attrs.get("source_digest") == (digest or source_digest())):
        return {}, {}
    try:
        stored_options = json.loads(attrs.get("engine_options", "{}"))
    except (TypeError, json.JSONDecodeError):
        return {}, {}
    return runs, {e: dict(stored_options.get(e, {})) for e in runs}


def store_runs(run_dir: Path, case: Case, short: bool, runs: Mapping[str, EngineRun], digest: str | None = None,
               options: Mapping[str, Mapping[str, Any]] | None = None) -> Path:
    """Write `runs` (engine → run) of `case` to run_dir/CASE.h5 with what makes them valid:
    case file and run-input hashes, parameter hash, variant, source digest, each engine's
    options."""
    order = [e for e in plugins() if e in runs] + [e for e in runs if e not in plugins()]
    return write_run(run_path(run_dir, case), {e: runs[e] for e in order}, case_name=case.name,
                     case_hash=case.file_hash, param_hash=case.params.digest(),
                     extra_attrs={"short": bool(short), "run_inputs_hash": run_inputs_hash(case),
                                  "source_digest": digest or source_digest(),
                                  "engine_options": _options_attr({e: (options or {}).get(e, {}) for e in order})})


def reusable(run_dir: Path, case: Case, short: bool, options: Mapping[str, Mapping[str, Any]],
             digest: str | None = None) -> dict[str, EngineRun]:
    """The runs stored in `run_dir` for `case` that are valid now (`read_stored`) and were
    made with the engine options asked for: `options`, engine → options, names the engines."""
    stored, made_with = read_stored(run_path(run_dir, case), case, short, digest)
    return {e: stored[e] for e in options if e in stored and made_with[e] == dict(options[e])}


def add_runs(run_dir: Path, case: Case, short: bool, new: Mapping[str, EngineRun],
             options: Mapping[str, Mapping[str, Any]], digest: str | None = None) -> dict[str, EngineRun]:
    """Store the `new` runs of `case` beside what its file holds that is still valid (other
    engines, other options), and read back the valid runs with `options` (`reusable`)."""
    kept, made_with = read_stored(run_path(run_dir, case), case, short, digest)
    store_runs(run_dir, case, short, {**kept, **new}, digest, {**made_with, **{e: options[e] for e in new}})
    return reusable(run_dir, case, short, options, digest)


# ---------------------------------------------------------------------------------------
# the producer
# ---------------------------------------------------------------------------------------
@dataclass
class RunSet:
    """What `get_runs` returns: case name → engine → run, and how it was obtained."""

    runs: dict[str, dict[str, EngineRun]] = field(default_factory=dict)
    #: (case, engine) → the exception its job raised
    errors: dict[tuple[str, str], BaseException] = field(default_factory=dict)
    #: cases whose runs were all read from their stored file
    reused: list[str] = field(default_factory=list)
    #: (case, engine) → wall seconds of the job that made the run (absent: reused)
    wall_s: dict[tuple[str, str], float] = field(default_factory=dict)
    #: the outcomes of the caller's `extra` jobs
    extra: dict[Job, Outcome] = field(default_factory=dict)

    @property
    def failures(self) -> dict[str, str]:
        """'case / engine' → error text, for every run that could not be made (with the
        place a fault in the code was raised at, as in the progress lines)."""
        return {f"{c} / {e}": _error_line(x) for (c, e), x in self.errors.items()}


def get_runs(cases: Sequence[Case], engines: Sequence[str], short: bool, run_dir: Path | None = None, *,
             rerun: bool = False, options: Mapping[str, Mapping[str, Any]] | None = None,
             progress: Progress | None = None, workers: int = 2, extra: Sequence[Job] = ()) -> RunSet:
    """The runs of `cases` (base cases; their short variants with `short`) in `engines`.

    With `run_dir`, the valid stored runs are read (`read_stored`: same case file,
    parameters, variant, source code and engine options) unless `rerun`, the others are
    run, stored there beside the valid ones and read back.  Without, everything is run and
    kept in memory.  `options`: engine → constructor options.  A sequence case is flown
    with its phases chained; its first phase, when asked for too, is cut from the flight
    instead of being run twice (the same calls make it).  `extra` jobs share the pool.
    A job that fails leaves its run out (`RunSet.errors`); the others go on."""
    cases = list({c.name: c for c in cases}.values())  # a case named twice is run once
    engines = list(engines)
    options = {e: dict((options or {}).get(e, {})) for e in engines}
    digest = source_digest() if run_dir is not None else None
    res = RunSet()
    missing: dict[str, list[str]] = {}
    for case in cases:
        have = {} if run_dir is None or rerun else reusable(run_dir, case, short, options, digest)
        res.runs[case.name] = have
        missing[case.name] = [e for e in engines if e not in have]
        if not missing[case.name]:
            res.reused.append(case.name)
    by_name = {c.name: c for c in cases}
    from_flight: dict[tuple[str, str], str] = {}  # (first phase, engine) → sequence
    for case in cases:
        if case.phases:
            first = case.variant(short).phases[0]
            for e in missing[case.name]:
                if first in by_name and e in missing[first]:
                    from_flight[(first, e)] = case.name
    with tempfile.TemporaryDirectory(prefix="rsmcheck-runs-") as workdir:
        jobs = []
        for case in cases:
            for e in missing[case.name]:
                if (case.name, e) in from_flight:
                    continue
                fn, args = ((run_sequence, (e, case, short, workdir, options[e])) if case.phases
                            else (run_engine, (e, case.variant(short), options[e])))
                jobs.append(Job(f"{case.name} / {e}", fn, args, expected_wall(case, e), (case.name, e)))
        if progress and (jobs or extra):
            progress(f"{len(jobs) + len(extra)} jobs " + executor.describe(workers)
                     + (f"; stored runs reused: {', '.join(res.reused)}" if res.reused else ""))
        outcomes = run_jobs([*jobs, *extra], progress, workers)
    fresh: dict[str, dict[str, EngineRun]] = {}
    for job in jobs:
        oc = outcomes[job]
        name, e = job.key
        if oc.error is not None:
            res.errors[(name, e)] = oc.error
            continue
        res.wall_s[(name, e)] = oc.wall_s
        if isinstance(oc.value, SequenceRun):
            fresh.setdefault(name, {})[e] = oc.value.run
            for (phase, pe), seq in from_flight.items():
                if seq == name and pe == e:
                    fresh.setdefault(phase, {})[e] = oc.value.phases[phase]
        else:
            fresh.setdefault(name, {})[e] = oc.value
    for (phase, e), seq in from_flight.items():
        if (seq, e) in res.errors:
            res.errors[(phase, e)] = res.errors[(seq, e)]
    res.extra = {job: outcomes[job] for job in extra}
    for case in cases:
        new = fresh.get(case.name, {})
        if not new:
            continue
        if run_dir is None:
            res.runs[case.name].update(new)
            continue
        res.runs[case.name] = add_runs(run_dir, case, short, new, options, digest)
    res.runs = {c.name: {e: res.runs[c.name][e] for e in engines if e in res.runs[c.name]} for c in cases}
    return res
