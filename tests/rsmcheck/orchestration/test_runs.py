"""rsmcheck.orchestration.runs: the one producer of runs (`get_runs`) reuses a stored run
only when it was made from the same run inputs of the case files, parameters, variant,
engine options and source code (the modules runs are made by), runs (and stores) the rest; the one pool (`run_jobs`) runs longest first and
names a failed job; `rsmcheck check` and the report's verdict give the same rows from the
same runs."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
import pickle

import numpy as np
import pytest

import rsmcheck.orchestration.runs as runs_mod
from rsmcheck.core.cases import load_case
from rsmcheck.cli import main
from rsmcheck.core.observables import allocate
from rsmcheck.core.plugins import default_engines

ENGINES = default_engines()
from rsmcheck.orchestration.runs import (Job, SequenceRun, get_runs, read_stored, run_jobs, run_path, source_digest,
                                         store_runs)
from rsmcheck.core.store import EngineRun, dumps_json


def _synthetic(engine: str, case, value: float = 0.0) -> EngineRun:
    obs = allocate(3)
    obs["time"] = np.linspace(0.0, case.duration, 3)
    obs["energy"][...] = value
    return EngineRun(engine, obs, solver={"wall_s": 0.5})


@pytest.fixture(autouse=True)
def fixed_digest(monkeypatch):
    """The source digest of this tree, held still: the sources may be edited while a test
    runs, and a run stored by other code is (rightly) not reused."""
    digest = source_digest()
    monkeypatch.setattr(runs_mod, "source_digest", lambda root=None: digest)
    return digest


@pytest.fixture
def fake_runs(monkeypatch):
    """`run_engine` replaced by a synthetic run; the calls it got, as (case, engine, options)."""
    calls = []

    def fake(engine, case, options=None):
        calls.append((case.name, engine, dict(options or {})))
        return _synthetic(engine, case, float(len(calls)))

    monkeypatch.setattr(runs_mod, "run_engine", fake)
    return calls


def test_a_stored_run_is_reused_only_for_the_same_case_params_variant_options_and_code(tmp_path, fake_runs,
                                                                                          monkeypatch):
    case = load_case("free_drift")

    def get(c=case, short=True, **kw):
        return get_runs([c], ["reference"], short, tmp_path, workers=0, **kw)

    first = get()
    assert len(fake_runs) == 1 and first.reused == [] and run_path(tmp_path, case).is_file()
    again = get()
    assert len(fake_runs) == 1 and again.reused == ["free_drift"]  # read, not run
    assert np.array_equal(again.runs["free_drift"]["reference"].observables["energy"],
                          first.runs["free_drift"]["reference"].observables["energy"])

    get(short=False)  # another variant: run, and stored in its place
    assert len(fake_runs) == 2
    get()  # so the short one is out of date now
    assert len(fake_runs) == 3
    edited = tmp_path / "cases" / "free_drift.toml"  # a run input of the case file changed
    edited.parent.mkdir()
    edited.write_text(Path(case.path).read_text().replace(f"duration = {case.raw['duration']}",
                                                          f"duration = {case.raw['duration'] + 1}", 1))
    get(dataclasses.replace(case, path=str(edited)))
    assert len(fake_runs) == 4
    get()
    assert len(fake_runs) == 5
    from rsmcheck.orchestration.gate import perturbed_case

    get(perturbed_case(case))  # the parameters changed
    assert len(fake_runs) == 6
    get()
    assert len(fake_runs) == 7
    get(options={"reference": {"n_modes": 2}})  # other engine options
    get(options={"reference": {"n_modes": 2}})
    assert fake_runs[-1] == ("free_drift", "reference", {"n_modes": 2}) and len(fake_runs) == 8
    get()
    assert len(fake_runs) == 9
    get(rerun=True)
    assert len(fake_runs) == 10
    monkeypatch.setattr(runs_mod, "source_digest", lambda root=None: "0" * 64)  # other code
    get()
    assert len(fake_runs) == 11
    assert get().reused == ["free_drift"] and len(fake_runs) == 11


def test_a_restated_tolerance_or_reason_keeps_the_runs_a_phase_change_drops_the_sequence(tmp_path, fake_runs):
    """The run inputs leave out prose and [compare] rows; a sequence's include its phases'."""
    case = load_case("wrist_bistop")
    get_runs([case], ["reference"], True, tmp_path, workers=0)
    text = Path(case.path).read_text()
    tol = case.raw["compare"][case.compare[0].observable]["tolerance"]
    assert f"tolerance = {tol}" in text and 'description = "' in text
    restated = tmp_path / "restated" / "wrist_bistop.toml"
    restated.parent.mkdir()
    restated.write_text(text.replace(f"tolerance = {tol}", f"tolerance = {2 * tol}", 1)
                        .replace('description = "', 'description = "Reworded. ', 1) + "# a comment\n")
    assert get_runs([load_case(restated)], ["reference"], True, tmp_path, workers=0).reused == ["wrist_bistop"]
    assert len(fake_runs) == 1
    mission = load_case("mission")
    before = runs_mod.run_inputs_hash(mission)
    phase = load_case(mission.phases[1])
    copy = tmp_path / "cases"
    copy.mkdir()
    for p in {*mission.variant(False).phases, *mission.variant(True).phases, mission.name}:
        (copy / f"{p}.toml").write_text(Path(load_case(p).path).read_text())
    moved = load_case(copy / "mission.toml")
    assert runs_mod.run_inputs_hash(moved) == before  # the same files elsewhere: the same inputs
    text = (copy / f"{phase.name}.toml").read_text()
    (copy / f"{phase.name}.toml").write_text(text.replace(f"duration = {phase.raw['duration']}",
                                                          f"duration = {phase.raw['duration'] + 1}", 1))
    assert runs_mod.run_inputs_hash(load_case(copy / "mission.toml")) != before


def test_the_source_digest_covers_every_module_of_rsmcheck_a_run_imports():
    """RUN_SOURCES must hold what making a run (a case in every engine, a chained sequence)
    loads of rsmcheck: a module left out would let a run made by other code be reused."""
    import subprocess
    import sys

    code = ("import pathlib, sys\n"
            "import rsmcheck\n"
            "from rsmcheck.core.cases import load_case\n"
            "from rsmcheck.core.plugins import default_engines, make_engine\n"
            "from rsmcheck.driver.runner import run\n"
            "import rsmcheck.orchestration.chain\n"
            "case = load_case('free_drift').variant(True)\n"
            "for e in default_engines():\n"
            "    run(make_engine(e, case), case, 0.002)\n"
            "root = pathlib.Path(rsmcheck.__file__).parents[1]\n"
            "for name, m in sorted(sys.modules.items()):\n"
            "    if name.split('.')[0] == 'rsmcheck':\n"
            "        print(pathlib.Path(m.__file__).relative_to(root).as_posix())\n")
    files = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert "rsmcheck/driver/runner.py" in files and "rsmcheck/orchestration/chain.py" in files
    assert [f for f in files if not runs_mod.in_run_sources(f)] == []


def test_only_the_missing_engines_run_and_the_valid_ones_stay_in_the_file(tmp_path, fake_runs):
    case = load_case("free_drift")
    get_runs([case], ["reference"], True, tmp_path, workers=0)
    got = get_runs([case], ENGINES, True, tmp_path, workers=0)
    assert [c[1] for c in fake_runs] == ["reference", "exudyn"]
    assert list(got.runs["free_drift"]) == list(ENGINES)
    stored, options = read_stored(run_path(tmp_path, case), case, True)
    assert set(stored) == set(ENGINES) and options == {"reference": {}, "exudyn": {}}
    assert get_runs([case], ["exudyn"], True, tmp_path, workers=0).reused == ["free_drift"]
    assert len(fake_runs) == 2


def test_a_failed_run_is_named_and_the_others_are_stored(tmp_path, monkeypatch):
    def flaky(engine, case, options=None):
        if engine == "exudyn":
            raise RuntimeError("boom")
        return _synthetic(engine, case)

    monkeypatch.setattr(runs_mod, "run_engine", flaky)
    case = load_case("free_drift")
    lines = []
    got = get_runs([case], ENGINES, True, tmp_path, workers=0, progress=lines.append)
    assert list(got.failures) == ["free_drift / exudyn"]
    text = got.failures["free_drift / exudyn"]  # a fault in the code: where it was raised
    assert text.startswith("RuntimeError: boom (raised at ") and text.endswith(" in flaky)"), text
    assert list(got.runs["free_drift"]) == ["reference"]
    assert any("free_drift / exudyn: FAILED: RuntimeError: boom" in line for line in lines)
    assert list(read_stored(run_path(tmp_path, case), case, True)[0]) == ["reference"]


def test_without_a_folder_every_run_is_made_and_nothing_is_stored(tmp_path, fake_runs, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = load_case("free_drift")
    for _ in range(2):
        got = get_runs([case, case], ["reference"], True, workers=0)  # named twice: run once
        assert got.reused == [] and list(got.runs) == ["free_drift"]
    assert len(fake_runs) == 2 and not list(tmp_path.iterdir())


def test_a_sequences_first_phase_is_cut_from_its_flight(tmp_path, fake_runs, monkeypatch):
    mission, first = load_case("mission"), load_case("p2_capture_regrasp")
    flights = []

    def fly(engine, case, short, workdir, options=None):
        flights.append((case.name, engine))
        return SequenceRun(_synthetic(engine, case.variant(short), 7.0),
                           {p: _synthetic(engine, load_case(p).variant(short), 3.0) for p in case.variant(short).phases})

    monkeypatch.setattr(runs_mod, "run_sequence", fly)
    got = get_runs([first, mission], ["reference"], True, tmp_path, workers=0)
    assert flights == [("mission", "reference")] and fake_runs == []  # p2 was not run on its own
    assert got.runs["p2_capture_regrasp"]["reference"].observables["energy"][0, 0] == 3.0
    assert got.runs["mission"]["reference"].observables["energy"][0, 0] == 7.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mission.h5", "p2_capture_regrasp.h5"]


def test_the_pool_runs_longest_first_and_names_a_failed_job():
    jobs = [Job("short", abs, (-4,), 1.0), Job("long", abs, (-9,), 5.0), Job("bad", abs, ("x",), 2.0)]
    lines = []
    done = run_jobs(jobs, lines.append, workers=0)
    assert [line.split("] ")[1].split(":")[0] for line in lines] == ["long", "bad", "short"]
    assert done[jobs[0]].value == 4 and done[jobs[1]].value == 9
    assert isinstance(done[jobs[2]].error, TypeError) and "bad: FAILED: TypeError" in lines[1]
    spawned = run_jobs(jobs, workers=2)  # the same in worker processes
    assert spawned[jobs[1]].value == 9 and isinstance(spawned[jobs[2]].error, TypeError)


def test_a_real_short_run_is_stored_and_read_back_unchanged(tmp_path):
    """free_drift short with the reference engine (seconds): the run read back from its file
    is the run, and a second call reads it instead of running."""
    case = load_case("free_drift")
    first = get_runs([case], ["reference"], True, tmp_path, workers=0)
    assert first.reused == [] and first.wall_s[("free_drift", "reference")] > 0
    again = get_runs([case], ["reference"], True, tmp_path, workers=0)
    assert again.reused == ["free_drift"] and again.wall_s == {}
    a, b = first.runs["free_drift"]["reference"], again.runs["free_drift"]["reference"]
    for name, values in a.observables.items():
        assert np.array_equal(values, b.observables[name], equal_nan=True), name
    assert a.events == b.events and a.phases == b.phases


@pytest.mark.engine_runs(("p1_rigid_gains", "reference", True, ()), ("p1_rigid_gains", "exudyn", True, ()))
def test_check_and_the_report_give_the_same_rows_from_the_same_runs(run_pool, tmp_path, capsys, monkeypatch,
                                                                     fixed_digest):
    """The runs stored once; `rsmcheck check --out` reads them (nothing runs) and its rows
    are the report's verdict rows, and those of the runs kept in memory."""
    from rsmcheck.orchestration.collect import Collected, run_dir, verdict
    from rsmcheck.orchestration.compare import case_rows

    case = load_case("p1_rigid_gains")
    pair = {e: run_pool.get(case.name, e) for e in ENGINES}
    store_runs(run_dir(tmp_path), case, True, pair)

    def no_run(*args, **kw):
        raise AssertionError("a stored, current run was run again")

    monkeypatch.setattr(runs_mod, "run_engine", no_run)
    assert main(["check", case.name, "--short", "--json", "--serial", "--out", str(run_dir(tmp_path))]) == 0
    checked = json.loads(capsys.readouterr().out)["checks"]
    reported = verdict(Collected(tmp_path, [case], True, list(ENGINES)), fixed_digest)["checks"]
    in_memory = [r.as_dict() for r in case_rows(case, True, pair)]
    assert checked and checked == json.loads(dumps_json(reported)) == json.loads(dumps_json(in_memory))


def _next_of_nothing():
    return next(iter(()))


def test_a_fault_in_the_code_is_named_with_the_place_it_was_raised_at():
    """The traceback stays in the worker; a bare `StopIteration` (e.g. an engine option taken
    from three Nones) would say nothing of where.  The exception carries the
    file, line and function as a note, through pickling, and the progress line shows it;
    rsmcheck's own errors (their messages name the input or the time) get none."""
    job = Job("broken", _next_of_nothing, (), 1.0)
    lines = []
    err = run_jobs([job], lines.append, workers=0)[job].error
    assert isinstance(err, StopIteration)
    note = f"raised at {__file__}:"
    assert any(n.startswith(note) and n.endswith("in _next_of_nothing") for n in err.__notes__)
    assert pickle.loads(pickle.dumps(err)).__notes__ == err.__notes__
    assert "in _next_of_nothing" in lines[0]
    bad = Job("bad input", load_case, ("no_such_case",), 1.0)
    assert not getattr(run_jobs([bad], workers=0)[bad].error, "__notes__", None)
