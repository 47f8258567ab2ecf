"""Run and store everything the report shows, so that the report only renders.

`collect(folder)` fills one folder (default ``out/``):

===================  ===========================================================================
``runs/CASE.h5``     every stand-alone case, both engines (rsmcheck.core.store format)
``runs/mission.h5``  the mission, its phases chained (rsmcheck.orchestration.chain.run_mission), both engines
``pinocchio.json``   the rows of ``rsmcheck pinocchio --json`` (rigid modes 0 and 2)
``modes.json``       the rows of ``rsmcheck modes --json`` (link and coupled frequencies)
``integration.json`` engine → observable → its integration error on each case, measured by its
                     refined run, for the engines a case's rows do not record (a plug-in's:
                     rsmcheck.core.tolerances), as ``rsmcheck check`` measures them
``verdict.json``     every check: the cross-check rows of each case (the same rows, computed by
                     the same function, as ``rsmcheck check --json``), the rows of each mission
                     phase, each engine's gate result, the Pinocchio rows; with provenance
===================  ===========================================================================

The runs come from `rsmcheck.orchestration.runs.get_runs`, the producer `rsmcheck check`
and `rsmcheck gate` use too: a stored run is reused when its attributes say it was made
from the same run inputs of the case files (`run_inputs_hash`: without prose and [compare]
rows), the same parameters, the same variant (short or full), the same engine options and
the same source code (`source_digest`: the ``.py`` files runs are made by); otherwise it
is run again and stored.  The work — one engine on one case, one engine on the mission,
the Pinocchio checks, the eigenfrequencies — goes through the one worker pool (`runs.run_jobs`): two at a time, longest first (each
golden's recorded wall time), a line on the terminal as each ends.  The verdict is always
recomputed from the stored runs (a second, cheap pass, through `runs.read_stored`).
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from rsmcheck.core.cases import Case, list_cases, load_case, phase_cases
from rsmcheck.orchestration.compare import case_rows, check_runs, engine_pairs, integration_errors, refined_jobs
from rsmcheck.core.plugins import (available, default_engines, given_settings, plugin, plugin_distributions,
                                   with_capability)
from rsmcheck.orchestration.gate import compare_with_golden, golden_path, read_golden
from rsmcheck.orchestration.modes import modes_report
from rsmcheck.orchestration.runs import Job, get_runs, read_stored, run_inputs_hash, source_digest
from rsmcheck.core.store import EngineRun, Event, Phase, git_commit, package_versions, write_json

VERDICT = "verdict.json"
MODES = "modes.json"
INTEGRATION = "integration.json"
MISSION = "mission"
#: the folder of the run files, under the report's folder
RUNS = "runs"

Progress = Callable[[str], None]


def run_dir(folder: Path) -> Path:
    """Where `collect` keeps the run files of the report in `folder`: folder/runs/CASE.h5."""
    return Path(folder) / RUNS


# ---------------------------------------------------------------------------------------
# the report's jobs besides the runs (they share the pool of rsmcheck.orchestration.runs)
# ---------------------------------------------------------------------------------------
def rigid_rows(name: str) -> dict[str, Any]:
    """The rows of checking plug-in `name`'s rigid checks (rigid modes 0 and 2, both arms
    open): `rsmcheck pinocchio --json` for Pinocchio."""
    return {"checks": [r for n in (0, 2) for r in plugin(name).rigid_checks(n_modes=n, open_arms=(1, 2))],
            "checker": name}


def modes_rows() -> dict[str, Any]:
    """The rows of `rsmcheck modes --json`."""
    return modes_report()


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


def collect(folder: Path, short: bool = True, engines: Sequence[str] | None = None,
            case_names: Sequence[str] | None = None, progress: Progress | None = None,
            rerun: bool = False, workers: int = 2) -> Collected:
    """Run what is missing or out of date, store it in `folder`, write the verdict.  The
    runs come from `rsmcheck.orchestration.runs.get_runs` (reused when current, else run
    and stored in folder/runs/), the Pinocchio and eigenfrequency tables ride in the same
    pool; a report restricted to `case_names` leaves those robot-wide tables out."""
    cases = [load_case(n) for n in case_names] if case_names else [load_case(p) for p in list_cases()]
    engines = list(engines or default_engines())
    folder = Path(folder)
    digest = source_digest()
    t0 = time.monotonic()
    res = Collected(folder, cases, short, engines)
    # the robot-wide tables (rigid checks, eigenfrequencies: a minute and a half of the two
    # engines' linearisations) come with the whole report, not with one restricted to cases
    jobs = [(f"{n}.json", rigid_rows, (n,)) for n in with_capability("rigid_checks") if available(n)]
    jobs.append((MODES, modes_rows, ()))
    extra = [Job(name.removesuffix(".json"), fn, args) for name, fn, args in jobs
             if not case_names and (rerun or not _stored_current(folder / name, digest))]
    # the refined runs of the engines whose errors the case files do not record, unless
    # their measured errors are stored for this code and these case files
    singles = [c for c in cases if not c.phases and c.variant(short).has_initial]
    stored = {} if rerun else _measured(folder, digest, short, singles)
    refine = [j for j in refined_jobs(singles, short, engines)
              if j.key[1] not in stored.get(j.key[0], {}).get("engines", {})]
    got = get_runs(cases, engines, short, run_dir(folder), rerun=rerun, progress=progress, workers=workers,
                   extra=[*extra, *refine])
    res.reused = got.reused
    res.failures = got.failures
    by_name = {c.name: c for c in singles}
    for job in refine:
        name, e = job.key
        entry = stored.setdefault(name, {"inputs": run_inputs_hash(by_name[name]), "engines": {}, "failed": {}})
        oc = got.extra[job]
        if oc.error is not None:
            res.failures[f"{name} / {e} refined"] = oc.error_text
            entry["failed"][e] = f"its refined run failed: {oc.error_text}"
        elif e in got.runs.get(name, {}):
            entry["engines"].update(integration_errors(by_name[name].variant(short), got.runs[name], {e: oc.value}))
    if refine:
        write_json(folder / INTEGRATION, {"source_digest": digest, "short": short, "cases": stored})
    for job, outcome in got.extra.items():
        if job in refine:
            continue
        if outcome.error is not None:
            res.failures[job.label] = outcome.error_text
        else:
            write_json(folder / f"{job.label}.json", {**outcome.value, "source_digest": digest})
    res.wall_s = time.monotonic() - t0
    write_json(folder / VERDICT, verdict(res, digest))
    return res


def _measured(folder: Path, digest: str, short: bool, cases: Sequence[Case]) -> dict[str, dict[str, Any]]:
    """case → {"inputs": its run_inputs_hash, "engines": engine → observable → integration
    error, "failed": engine → why not measured}, as `collect` stored them in
    folder/integration.json: only for this code, this variant and cases whose run inputs
    are unchanged ({} where there is none)."""
    try:
        doc = json.loads((Path(folder) / INTEGRATION).read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    if not isinstance(doc, dict) or doc.get("source_digest") != digest or doc.get("short") != short:
        return {}
    current = {c.name: run_inputs_hash(c) for c in cases}
    return {name: entry for name, entry in dict(doc.get("cases", {})).items()
            if isinstance(entry, dict) and entry.get("inputs") == current.get(name)}


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
    phases = phase_cases(mission, short)
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


def case_checks(case: Case, short: bool, runs: dict[str, EngineRun],
                engines: Sequence[str] | None = None, measured: dict[str, dict[str, float]] | None = None,
                missing: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """The rows of `rsmcheck check --json` for one case, from its stored runs: the same
    function (`compare.case_rows`) on the same runs (`runs.read_stored`), the first of
    `engines` (default: the default engines) against each other; `measured`: the engines'
    integration errors stored by `collect`, `missing`: why one was not measured."""
    return [r.as_dict() for r in case_rows(case, short, runs, engines, measured, missing)]


def phase_specs(mission: Case, short: bool, phase: Case) -> tuple:
    """The rows a phase is checked by in the chained flight: its own [compare] table, with
    the rows the sequence file replaces ([compare.PHASE.OBSERVABLE])."""
    replaced = {s.observable: s for s in mission.variant(short).phase_compare.get(phase.name, ())}
    return tuple(replaced.get(s.observable, s) for s in phase.compare)


def mission_checks(mission: Case, short: bool, runs: dict[str, EngineRun],
                   engines: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Each phase of the chained mission checked by its own tolerances plus the difference
    the engines carry into it (`rsmcheck.orchestration.compare.check_runs(chained=True)`); rows named
    "mission/PHASE"."""
    engines = [e for e in (engines or default_engines()) if e in runs]
    if len(engines) < 2:
        return []
    rows = []
    for first, other in engine_pairs(engines):
        for (ph, _, a), (_, _, b) in zip(phase_runs(mission, short, runs[first]), phase_runs(mission, short, runs[other])):
            for r in check_runs(ph, a, b, chained=True, specs=phase_specs(mission, short, ph)):
                d = r.as_dict()
                d["case"] = f"{mission.name}/{ph.name}"
                d["engines"] = [first, other]
                rows.append(d)
    return rows


def gate_rows(case: Case, runs: dict[str, EngineRun]) -> list[dict[str, Any]]:
    """Each engine's short run of `case` against its golden (rsmcheck.orchestration.gate)."""
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
                               **given_settings(v.engine_settings)}
    return {
        "commit": commit, "modified": dirty, "source_digest": digest,
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": {"python": platform.python_version(),
                     **package_versions("rsmcheck", *plugin_distributions(), "numpy", "numba", "scipy", "h5py",
                                        "plotly")},
        "platform": f"{platform.system()} {platform.release()} {platform.machine()}, {os.cpu_count()} CPUs",
        "short": res.short, "engines": res.engines, "settings": settings, "collect_wall_s": res.wall_s,
        "failures": res.failures, "reused": res.reused,
    }


def verdict(res: Collected, digest: str) -> dict[str, Any]:
    """Every check row from the runs stored in `res.folder` that are current (read by
    `rsmcheck.orchestration.runs.read_stored`, the reader `rsmcheck check --out` uses)."""
    checks, mission, gates = [], [], []
    measured = _measured(res.folder, digest, res.short, [c for c in res.cases if not c.phases])
    for case in res.cases:
        runs, _ = read_stored(run_dir(res.folder) / f"{case.name}.h5", case, res.short, digest)
        if not runs:
            continue
        if case.phases:
            mission += mission_checks(case, res.short, runs, res.engines)
            continue
        entry = measured.get(case.name, {})
        checks += case_checks(case, res.short, runs, res.engines, entry.get("engines"), entry.get("failed"))
        if res.short:
            gates += gate_rows(case, runs)
    rigid = {}
    for n in with_capability("rigid_checks"):
        path = res.folder / f"{n}.json"
        rigid[n] = json.loads(path.read_text())["checks"] if _stored_current(path, digest) else []
    return {"checks": checks, "mission": mission, "gate": gates, "rigid": rigid,
            "provenance": provenance(res, digest)}
