"""rsmcheck bench on Dask (rsmcheck.orchestration.bench.run_all): one run per worker at a
time (the worker resource executor.BENCH_RESOURCE), each run with the machine it ran on, the
table saying when the runs ran on more than one machine, a failed run still named, and
`--scheduler` reaching bench (docs/cluster.md).  The runs are a stub process of 0.4 s, not
an engine: what is tested is the dispatch, not the timing."""

from __future__ import annotations

import socket

import pytest

from rsmcheck.cli import main
from rsmcheck.core.store import machine
from rsmcheck.orchestration import executor
from rsmcheck.orchestration.bench import run_all, runs_machines_note, table
from rsmcheck.orchestration.bench_diff import compare
from rsmcheck.orchestration.runs import source_digest

#: a bench process in 0.4 s: the run's record with when it started and ended; case "bad"
#: fails with "boom" on its last line of stderr, as a failed engine run does
STUB = r"""
import json, sys, time
start = time.time()
if sys.argv[1] == "bad":
    sys.exit("boom")
time.sleep(0.4)
print(json.dumps({"case": sys.argv[1], "engine": sys.argv[2], "variant": "short" if sys.argv[3] == "1" else "full",
                  "wall_s": 0.4, "sim_s": 1.0, "peak_mb": 1.0, "start": start, "end": time.time()}))
"""


def _apart(a: dict, b: dict) -> bool:
    return a["end"] <= b["start"] or b["end"] <= a["start"]


@pytest.fixture
def two_thread_worker(monkeypatch):
    """One in-process Dask worker with two threads and one unit of the bench resource,
    named as the cluster to use (as --scheduler does)."""
    from distributed import LocalCluster

    monkeypatch.delenv(executor.SCHEDULER_ENV, raising=False)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=":0",
                      resources={executor.BENCH_RESOURCE: 1}) as cluster:
        executor.use_scheduler(cluster.scheduler_address)
        try:
            yield cluster.scheduler_address
        finally:
            executor.use_scheduler(None)
            executor.close()


def test_one_bench_run_per_worker_at_a_time(two_thread_worker):
    """Two runs on a worker with two threads never overlap: each takes the worker's one unit
    of the bench resource.  The same two tasks without the resource do overlap there (the
    check can fail)."""
    work = [("a", "reference", "short"), ("b", "exudyn", "short")]
    lines: list[str] = []
    runs = run_all(work, 1, lambda r: lines.append(r["case"]), script=STUB)
    assert [(r["case"], r["engine"], r["variant"]) for r in runs] == work  # in the order listed
    assert all("error" not in r for r in runs), runs
    assert _apart(*runs), runs
    assert sorted(lines) == ["a", "b"]
    from rsmcheck.orchestration.bench import bench_run

    free = {i: value for i, value, _ in executor.completed([(bench_run, (*w, STUB)) for w in work], 1, source_digest)}
    assert not _apart(free[0], free[1]), free  # without the resource the two threads run both at once


def test_a_run_dask_could_not_run_is_a_failed_run_named(two_thread_worker):
    """A task that raises on the worker (here: no script) is a failed run with the error."""
    runs = run_all([("a", "reference", "short")], 1, script=None)  # type: ignore[arg-type]
    assert runs[0]["error"].startswith("TypeError") and runs[0]["wall_s"] != runs[0]["wall_s"], runs
    assert "FAILED a reference short: TypeError" in table({"engines": ["reference"], "runs": runs})


def test_local_workers_one_run_at_a_time_each_with_its_machine_and_a_failed_run_named(monkeypatch):
    """The default: a local cluster of `--jobs` workers (here 1).  Every run, the failed one
    too, carries the machine it ran on; the failed one is named under the table."""
    monkeypatch.delenv(executor.SCHEDULER_ENV, raising=False)
    executor.use_scheduler(None)
    work = [("a", "reference", "short"), ("bad", "reference", "short"), ("b", "reference", "short")]
    runs = run_all(work, 1, script=STUB)
    assert [r["case"] for r in runs] == ["a", "bad", "b"]
    assert _apart(runs[0], runs[2]), runs
    here = machine()
    assert all(r["machine"]["cpu"] == here["cpu"] and r["machine"]["logical_cpus"] == here["logical_cpus"]
               for r in runs), runs
    assert runs[1]["error"] == "boom" and "error" not in runs[0]
    text = table({"engines": ["reference"], "runs": runs, "machine": here})
    assert text.splitlines()[-1] == "FAILED bad reference short: boom"
    assert text.splitlines()[1] == ""  # all on this machine: no note


def _machine(cpu: str) -> dict:
    return {"cpu": cpu, "logical_cpus": 2, "memory_gib": 8.0, "system": "Linux", "python": "3.11.7"}


def _run(case: str, engine: str, m: dict | None, wall: float = 1.0) -> dict:
    r = {"case": case, "engine": engine, "variant": "short", "wall_s": wall, "sim_s": 1.0, "peak_mb": 1.0,
         "solver": {"steps": 100}}
    return dict(r, machine=m) if m else r


def test_runs_from_two_machines_are_flagged_in_one_line():
    a, b = _machine("AMD EPYC (family 25)"), _machine("Intel Xeon (family 6)")
    doc = {"engines": ["reference", "exudyn"], "machine": a,
           "runs": [_run("x", "reference", a), _run("x", "exudyn", b), _run("y", "reference", a)]}
    lines = table(doc).splitlines()
    assert lines[0].startswith("machine: AMD EPYC (family 25)")
    assert lines[1].startswith("runs ran on 2 machines (2 on AMD EPYC (family 25), 2 logical CPUs; "
                               "1 on Intel Xeon (family 6)") and lines[2] == "", lines[:3]
    assert runs_machines_note(dict(doc, runs=[_run("x", "reference", a)])) == ""
    assert runs_machines_note(dict(doc, runs=[_run("x", "reference", None)])) == ""  # an older document
    assert runs_machines_note(dict(doc, runs=[_run("x", "reference", b)])).startswith(
        "runs ran on another machine: Intel Xeon (family 6)")
    assert "1 not recorded" in runs_machines_note(dict(doc, runs=[_run("x", "reference", b), _run("y", "x", None)]))


def test_the_baseline_compares_wall_times_run_by_run():
    """The documents' machines alike, but one run ran on another machine: its wall ratio is
    left out, the other's kept; a document without per-run machines compares as before."""
    a, b = _machine("AMD EPYC (family 25)"), _machine("Intel Xeon (family 6)")
    base = {"machine": a, "runs": [_run("x", "reference", None, 2.0), _run("x", "exudyn", None, 2.0)]}
    doc = {"machine": a, "runs": [_run("x", "reference", a), _run("x", "exudyn", b)]}
    cmp = compare(doc, base)
    assert [r["wall_ratio"] for r in cmp["rows"]] == [0.5, None] and not cmp["same_machine"]
    old = compare({"machine": a, "runs": [_run("x", "reference", None)]}, base)
    assert old["same_machine"] and old["rows"][0]["wall_ratio"] == 0.5


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_scheduler_reaches_bench_before_or_after_it(monkeypatch, capsys):
    """`rsmcheck --scheduler A bench …` and `rsmcheck bench --scheduler A …`: an address
    where nothing answers is one line and exit 2, before any run."""
    monkeypatch.delenv(executor.SCHEDULER_ENV, raising=False)
    monkeypatch.setattr(executor, "CONNECT_TIMEOUT_S", 1.0)
    address = f"tcp://127.0.0.1:{_free_port()}"
    assert main(["--scheduler", address, "bench", "--cases", "free_drift", "--engines", "reference"]) == 2
    assert main(["bench", "--cases", "free_drift", f"--scheduler={address}", "--engines", "reference"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and all(e.startswith("rsmcheck: --scheduler: ") and address in e for e in err), err
    assert executor.scheduler_address() is None


def test_a_cluster_without_the_bench_resource_is_one_line(monkeypatch, capsys):
    """Workers started without `--resources bench=1` would never take a bench run: one line,
    exit 2, instead of waiting for ever."""
    from distributed import LocalCluster

    monkeypatch.delenv(executor.SCHEDULER_ENV, raising=False)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        try:
            assert main(["bench", "--scheduler", cluster.scheduler_address, "--cases", "free_drift",
                         "--engines", "reference"]) == 2
        finally:
            executor.close()
    err = capsys.readouterr().err
    assert "no worker has the resource bench=1" in err and err.count("rsmcheck:") == 1, err
