"""Run and store everything the report shows, so that the report only renders.

`collect(folder)` fills one folder (default ``out/``):

===================  ===========================================================================
``runs/CASE.h5``     every stand-alone case, both engines (rsmcheck.store format)
``runs/mission.h5``  the mission, its phases chained (rsmcheck.orchestration.chain.run_mission), both engines
``pinocchio.json``   the rows of ``rsmcheck pinocchio --json`` (rigid modes 0 and 2)
``modes.json``       the rows of ``rsmcheck modes --json`` (link and coupled frequencies)
``verdict.json``     every check: the cross-check rows of each case (the same rows, computed by
                     the same function, as ``rsmcheck check --json``), the rows of each mission
                     phase, each engine's gate result, the Pinocchio rows; with provenance
===================  ===========================================================================

The work is a list of independent jobs — one engine on one case, one engine on the mission,
the Pinocchio checks, the eigenfrequencies — run two at a time in worker processes, longest
first (each golden's recorded wall time), with a line on the terminal as each ends.

A stored run is reused when its attributes say it was made from the same case file, the
same parameters, the same variant (short or full) and the same source code
(`source_digest`: every ``.py`` file of the packages); otherwise it is run again.  The
verdict is always recomputed from the stored runs (a second, cheap pass).
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import platform
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from rsmcheck.cases import Case, list_cases, load_case, sibling_case
from rsmcheck.orchestration.compare import check_runs
from rsmcheck.orchestration.engines import ENGINES
from rsmcheck.errors import InputError
from rsmcheck.store import EngineRun, Event, Phase, git_commit, package_versions, read_run, write_json, write_run

#: the packages whose sources make a run what it is
SOURCE_PACKAGES = ("rsmcheck", "reference_model", "exudyn_model", "pinocchio_check")
#: modules of rsmcheck that orchestrate, compare or report: no run depends on them (the
#: verdict is recomputed from the runs every time)
NOT_IN_RUNS = ("rsmcheck/cli.py", "rsmcheck/orchestration/collect.py", "rsmcheck/orchestration/bench.py",
               "rsmcheck/orchestration/studies.py", "rsmcheck/orchestration/faults.py",
               "rsmcheck/orchestration/gate.py", "rsmcheck/orchestration/compare.py")
VERDICT = "verdict.json"
PINOCCHIO = "pinocchio.json"
MODES = "modes.json"
MISSION = "mission"

Progress = Callable[[str], None]


def source_digest(root: Path | None = None) -> str:
    """sha256 over the names and contents of the .py files of SOURCE_PACKAGES that runs
    depend on (all but NOT_IN_RUNS): a run made by other code is not reused."""
    root = root or Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for pkg in SOURCE_PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            name = path.relative_to(root).as_posix()
            if name in NOT_IN_RUNS:
                continue
            h.update(name.encode())
            h.update(path.read_bytes())
    return h.hexdigest()


# ---------------------------------------------------------------------------------------
# jobs (each runs in a worker process)
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Job:
    """One piece of work: `kind` "run" (an engine on a case or the mission), "pinocchio"
    or "modes"."""

    kind: str
    case: str = ""
    engine: str = ""
    short: bool = True

    @property
    def label(self) -> str:
        return f"{self.case} / {self.engine}" if self.kind == "run" else self.kind


@dataclass
class MissionResult:
    """A mission job's result: the flight, and each phase's own run (phase name → run)."""

    run: EngineRun
    phases: dict[str, EngineRun]


def _do_job(job: Job, workdir: str) -> tuple[Any, float]:
    """(result, wall seconds); a failed job returns its error text as the result."""
    t0 = time.monotonic()
    try:
        if job.kind == "pinocchio":
            from pinocchio_check.compare import run_checks

            rows = [r for n in (0, 2) for r in run_checks(n_modes=n, open_arms=(1, 2))]
            return {"checks": rows}, time.monotonic() - t0
        if job.kind == "modes":
            from rsmcheck.orchestration.modes import modes_report

            return modes_report(), time.monotonic() - t0
        case = load_case(job.case)
        if case.phases:
            from rsmcheck.orchestration.chain import run_mission

            out = Path(workdir) / f"{job.case}.{job.engine}"
            phases: dict[str, dict[str, EngineRun]] = {}
            runs, _ = read_run(run_mission(case.variant(job.short), [job.engine], job.short, out,
                                           phase_runs=phases))
            return MissionResult(runs[job.engine], {p: r[job.engine] for p, r in phases.items()}), \
                time.monotonic() - t0
        from rsmcheck.orchestration.compare import _run_one

        variant = case.variant(job.short)
        return _run_one(job.engine, variant, variant.duration, {}), time.monotonic() - t0
    except Exception as exc:  # noqa: BLE001 — not every exception pickles: send its text
        return f"{type(exc).__name__}: {exc}", time.monotonic() - t0


def expected_wall(case: Case, engine: str) -> float:
    """The wall time the case's golden recorded for `engine` [s] (0 without one; a sequence:
    the sum over its phases).  Only orders the jobs, longest first."""
    from rsmcheck.orchestration.gate import golden_path

    if case.phases:
        return sum(expected_wall(load_case(sibling_case(p, Path(case.path))), engine)
                   for p in case.variant(True).phases)
    path = golden_path(case.name, engine)
    try:
        return float(read_run(path)[0][engine].solver.get("wall_s", 0.0)) if path.exists() else 0.0
    except (OSError, InputError, KeyError):
        return 0.0


def run_jobs(jobs: Sequence[Job], workdir: Path, progress: Progress | None, workers: int = 2) -> dict[Job, Any]:
    """Run `jobs` `workers` at a time; {job: result or error text}."""
    out: dict[Job, Any] = {}
    if not jobs:
        return out
    t0 = time.monotonic()
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = {pool.submit(_do_job, job, str(workdir)): job for job in jobs}
        for n, fut in enumerate(as_completed(futures), 1):
            job = futures[fut]
            result, wall = fut.result()
            out[job] = result
            if progress:
                status = "FAILED: " + result if isinstance(result, str) else f"{wall:.0f} s"
                progress(f"[{n}/{len(jobs)}, {time.monotonic() - t0:.0f} s] {job.label}: {status}")
    return out


# ---------------------------------------------------------------------------------------
# what is stored, and whether it is current
# ---------------------------------------------------------------------------------------
def _current(path: Path, case: Case, engines: Sequence[str], short: bool, digest: str) -> bool:
    """True when `path` holds runs of every engine made from this case file, parameters,
    variant and source code."""
    if not path.is_file():
        return False
    try:
        runs, attrs = read_run(path)
    except (OSError, InputError):
        return False
    return (all(e in runs for e in engines) and attrs.get("case_hash") == case.file_hash
            and attrs.get("param_hash") == case.params.digest() and bool(attrs.get("short")) == bool(short)
            and attrs.get("source_digest") == digest)


@dataclass
class Collected:
    """What `collect` stored: the folder, the cases, and the failed jobs (label → error)."""

    folder: Path
    cases: list[Case]
    short: bool
    engines: list[str]
    failures: dict[str, str] = field(default_factory=dict)
    wall_s: float = 0.0
    reused: list[str] = field(default_factory=list)


def collect(folder: Path, short: bool = True, engines: Sequence[str] = ENGINES,
            case_names: Sequence[str] | None = None, progress: Progress | None = None,
            rerun: bool = False, workers: int = 2) -> Collected:
    """Run what is missing or out of date, store it in `folder`, write the verdict."""
    cases = [load_case(n) for n in case_names] if case_names else [load_case(p) for p in list_cases()]
    engines = list(engines)
    folder = Path(folder)
    run_dir = folder / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    digest = source_digest()
    t0 = time.monotonic()
    res = Collected(folder, cases, short, engines)
    jobs: list[Job] = []
    for case in cases:
        if not rerun and _current(run_dir / f"{case.name}.h5", case, engines, short, digest):
            res.reused.append(case.name)
            continue
        jobs += [Job("run", case.name, e, short) for e in engines]
    # A sequence's first phase starts from its own [initial]: the flight's first piece is
    # that case's run, made by the same calls; it is taken from the flight, not run twice.
    from_flight = {load_case(j.case).variant(short).phases[0]: j.case for j in jobs
                   if j.kind == "run" and load_case(j.case).phases}
    jobs = [j for j in jobs if j.case not in from_flight]
    jobs.sort(key=lambda j: -expected_wall(load_case(j.case), j.engine))
    for name in (PINOCCHIO, MODES):
        if rerun or not _stored_current(folder / name, digest):
            jobs.append(Job(name.removesuffix(".json")))
    if progress:
        progress(f"{len(jobs)} jobs on {workers} processes"
                 + (f"; stored runs reused: {', '.join(res.reused)}" if res.reused else ""))
    with tempfile.TemporaryDirectory(prefix="rsmcheck-collect-") as tmp:
        results = run_jobs(jobs, Path(tmp), progress, workers)
    by_case: dict[str, dict[str, EngineRun]] = {}
    for job, result in results.items():
        if isinstance(result, str):
            res.failures[job.label] = result
        elif isinstance(result, MissionResult):
            by_case.setdefault(job.case, {})[job.engine] = result.run
            for phase, mission in from_flight.items():
                if mission == job.case:
                    by_case.setdefault(phase, {})[job.engine] = result.phases[phase]
        elif job.kind == "run":
            by_case.setdefault(job.case, {})[job.engine] = result
        else:
            write_json(folder / f"{job.kind}.json", {**result, "source_digest": digest})
    for case in cases:
        runs = by_case.get(case.name, {})
        if len(runs) == len(engines):
            store_runs(folder, case, short, runs, digest)
    res.wall_s = time.monotonic() - t0
    write_json(folder / VERDICT, verdict(res, digest))
    return res


def store_runs(folder: Path, case: Case, short: bool, runs: dict[str, EngineRun], digest: str | None = None) -> Path:
    """Write `runs` (engine → run) of `case` where `collect` keeps them: folder/runs/CASE.h5."""
    (Path(folder) / "runs").mkdir(parents=True, exist_ok=True)
    return write_run(Path(folder) / "runs" / f"{case.name}.h5", runs, case_name=case.name,
                     case_hash=case.file_hash, param_hash=case.params.digest(),
                     extra_attrs={"short": bool(short), "source_digest": digest or source_digest()})


def _stored_current(path: Path, digest: str) -> bool:
    try:
        return json.loads(path.read_text()).get("source_digest") == digest
    except (OSError, json.JSONDecodeError, AttributeError):
        return False


# ---------------------------------------------------------------------------------------
# the verdict: every check row, from the stored runs
# ---------------------------------------------------------------------------------------
def phase_runs(mission: Case, short: bool, run: EngineRun) -> list[tuple[Case, float, EngineRun]]:
    """The mission run cut into its phases: (the phase case's variant, its start time in the
    mission, the phase's run on phase-local time), in order.

    `rsmcheck.orchestration.chain.run_mission` concatenates the phases' runs, each from its own t = 0: the
    last sample of one phase and the first of the next have the same mission time, and each
    belongs to its own phase."""
    variant = mission.variant(short)
    phases = [load_case(sibling_case(p, Path(mission.path))).variant(short) for p in variant.phases]
    t = np.asarray(run.observables["time"], float)
    first = [0]
    t_start = 0.0
    for ph in phases[:-1]:
        t_start += ph.duration
        # the last sample at t_start opens the next phase
        first.append(int(np.searchsorted(t, t_start + 1e-9 * max(1.0, t_start), side="right")) - 1)
    first.append(t.size)
    out = []
    t_start = 0.0
    for k, ph in enumerate(phases):
        i0, i1 = first[k], first[k + 1]
        t_end = t_start + ph.duration
        last = k == len(phases) - 1

        def inside(time: float) -> bool:
            return t_start - 1e-9 <= time and (last or time < t_end - 1e-9)

        obs = {key: (v[i0:i1] - t_start if key == "time" else v[i0:i1]) for key, v in run.observables.items()}
        events = [Event(e.time - t_start, e.kind, e.detail) for e in run.events if inside(e.time)]
        segments = [Phase(p.name, p.t_start - t_start, p.t_end - t_start) for p in run.phases if inside(p.t_start)]
        out.append((ph, t_start, EngineRun(run.engine, obs, events, segments, run.solver, run.versions)))
        t_start = t_end
    return out


def case_checks(case: Case, short: bool, runs: dict[str, EngineRun]) -> list[dict[str, Any]]:
    """The rows of `rsmcheck check --json` for one case, from its stored runs."""
    variant = case.variant(short)
    if case.phases or not variant.compare or not {"reference", "exudyn"} <= set(runs):
        return []
    return [r.as_dict() for r in check_runs(variant, runs["reference"], runs["exudyn"])]


def phase_specs(mission: Case, short: bool, phase: Case) -> tuple:
    """The rows a phase is checked by in the chained flight: its own [compare] table, with
    the rows the sequence file replaces ([compare.PHASE.OBSERVABLE])."""
    replaced = {s.observable: s for s in mission.variant(short).phase_compare.get(phase.name, ())}
    return tuple(replaced.get(s.observable, s) for s in phase.compare)


def mission_checks(mission: Case, short: bool, runs: dict[str, EngineRun]) -> list[dict[str, Any]]:
    """Each phase of the chained mission checked by its own tolerances plus the difference
    the engines carry into it (`rsmcheck.orchestration.compare.check_runs(chained=True)`); rows named
    "mission/PHASE"."""
    if not {"reference", "exudyn"} <= set(runs):
        return []
    rows = []
    ref = phase_runs(mission, short, runs["reference"])
    exu = phase_runs(mission, short, runs["exudyn"])
    for (ph, _, a), (_, _, b) in zip(ref, exu):
        for r in check_runs(ph, a, b, chained=True, specs=phase_specs(mission, short, ph)):
            d = r.as_dict()
            d["case"] = f"{mission.name}/{ph.name}"
            rows.append(d)
    return rows


def gate_rows(case: Case, runs: dict[str, EngineRun]) -> list[dict[str, Any]]:
    """Each engine's short run of `case` against its golden (rsmcheck.orchestration.gate)."""
    from rsmcheck.orchestration.gate import compare_with_golden, golden_path, read_golden

    rows = []
    for engine, run in runs.items():
        path = golden_path(case.name, engine)
        if not path.exists():
            rows.append({"case": case.name, "engine": engine, "unchanged": False,
                         "inputs_changed": [f"no golden {path.name}"], "structure": [], "moved": [],
                         "largest_ratio": None})
            continue
        rows.append(compare_with_golden(case.variant(True), run, read_golden(path, engine)).as_dict())
    return rows


def provenance(res: Collected, digest: str) -> dict[str, Any]:
    """Where the results come from: commit, versions, platform, solver settings, date."""
    commit, dirty = git_commit()
    settings = {}
    for case in res.cases:
        v = case.variant(res.short)
        settings[case.name] = {"control_period_s": v.solver.control_period, "output_period_s": v.solver.output_period,
                               "reference": {"integrator": v.solver.integrator, "rtol": v.solver.rtol,
                                             **dict(v.reference)},
                               "exudyn": dict(v.exudyn)}
    return {
        "commit": commit, "modified": dirty, "source_digest": digest,
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": {"python": platform.python_version(),
                     **package_versions("rsmcheck", "exudyn", "pin", "numpy", "numba", "scipy", "h5py", "plotly")},
        "platform": f"{platform.system()} {platform.release()} {platform.machine()}, {os.cpu_count()} CPUs",
        "short": res.short, "engines": res.engines, "settings": settings, "collect_wall_s": res.wall_s,
        "failures": res.failures, "reused": res.reused,
    }


def verdict(res: Collected, digest: str) -> dict[str, Any]:
    """Every check row from what is stored in `res.folder`."""
    checks, mission, gates = [], [], []
    for case in res.cases:
        path = res.folder / "runs" / f"{case.name}.h5"
        if not path.is_file():
            continue
        runs, _ = read_run(path)
        if case.phases:
            mission += mission_checks(case, res.short, runs)
            continue
        checks += case_checks(case, res.short, runs)
        if res.short:
            gates += gate_rows(case, runs)
    pin_path = res.folder / PINOCCHIO
    pin = json.loads(pin_path.read_text())["checks"] if pin_path.is_file() else []
    return {"checks": checks, "mission": mission, "gate": gates, "pinocchio": pin,
            "provenance": provenance(res, digest)}
