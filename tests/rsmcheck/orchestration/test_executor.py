"""rsmcheck.orchestration.executor: `run_jobs` on Dask gives the serial results to the bit,
runs longest first with a line per job and a failed job named, survives a worker killed
in the middle of a job on a real scheduler started with Dask's own command line, and an
unreachable scheduler is one line and exit 2 before anything runs (docs/cluster.md)."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import rsmcheck.orchestration.runs as runs_mod
from rsmcheck.cli import main
from rsmcheck.core.cases import load_case
from rsmcheck.orchestration import executor
from rsmcheck.orchestration.runs import Job, run_engine, run_jobs

ROOT = Path(__file__).resolve().parents[3]
if str(ROOT) not in sys.path:  # plain `pytest`: the workers import the helpers by name
    sys.path.insert(0, str(ROOT))
from tests.rsmcheck.orchestration import dask_jobs  # noqa: E402


def _tenth_of_a_second(engine: str):
    return dataclasses.replace(load_case("free_drift").variant(True), duration=0.1)


def _same_run(a, b) -> bool:
    return (a.observables.keys() == b.observables.keys() and a.events == b.events
            and all(np.array_equal(a.observables[k], b.observables[k], equal_nan=True) for k in a.observables))


def test_the_cluster_gives_the_serial_results_to_the_bit():
    jobs = [Job(f"noise {s}", dask_jobs.noise, (s,), float(s)) for s in range(4)]
    engine = Job("free_drift 0.1 s / reference", run_engine, ("reference", _tenth_of_a_second("reference")))
    jobs.append(engine)
    serial, spread = run_jobs(jobs, workers=0), run_jobs(jobs, workers=2)
    assert all(serial[j].error is None and spread[j].error is None for j in jobs)
    for j in jobs[:-1]:
        assert np.array_equal(serial[j].value, spread[j].value), j.label
    assert _same_run(serial[engine].value, spread[engine].value)
    assert not np.array_equal(serial[jobs[0]].value, serial[jobs[1]].value)  # the comparison can fail


def test_longest_first_a_line_per_job_and_a_failed_job_named():
    """One worker: the jobs start in the order of their priority, longest first."""
    jobs = [Job("short", dask_jobs.started_at, (0.05,), 1.0), Job("long", dask_jobs.started_at, (0.05,), 5.0),
            Job("bad", abs, ("x",), 2.0), Job("middle", dask_jobs.started_at, (0.05,), 3.0)]
    lines: list[str] = []
    done = run_jobs(jobs, lines.append, workers=1)
    labels = [line.split("] ")[1].split(":")[0] for line in lines]
    assert labels == ["long", "middle", "bad", "short"], lines
    assert [line.split("]")[0] for line in lines] == [f"[{n}/4, " + line.split(", ")[1].split("]")[0]
                                                      for n, line in enumerate(lines, 1)]
    assert "bad: FAILED: TypeError" in lines[2] and isinstance(done[jobs[2]].error, TypeError)
    assert done[jobs[1]].value < done[jobs[3]].value < done[jobs[0]].value  # started in that order


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _until(condition, seconds: float, what: str):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"not within {seconds:g} s: {what}")


def test_a_worker_killed_in_the_middle_of_a_job_on_a_real_scheduler(tmp_path, monkeypatch):
    """`dask scheduler` and two `dask worker` processes (one process, one thread each, no
    nanny to restart them) on 127.0.0.1; the jobs go there through RSMCHECK_SCHEDULER.  The
    worker running the engine job is killed (SIGKILL) while it runs: the job runs again on
    the other worker and gives the serial run to the bit; nothing is left half written."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    sched_file, marks = tmp_path / "scheduler.json", tmp_path / "marks"
    marks.mkdir()
    procs: list[subprocess.Popen] = []

    def dask(*args: str, log: str) -> subprocess.Popen:
        with open(tmp_path / log, "w") as out:
            procs.append(subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=out, stderr=subprocess.STDOUT,
                                          env=env, cwd=tmp_path, start_new_session=True))
        return procs[-1]

    try:
        dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file),
             log="scheduler.log")
        _until(lambda: sched_file.is_file() and json.loads(sched_file.read_text() or "{}").get("address"), 60,
               "the scheduler file")
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        for n in (1, 2):
            dask("worker", "--scheduler-file", str(sched_file), "--nworkers", "1", "--nthreads", "1", "--no-nanny",
                 "--host", "127.0.0.1", "--no-dashboard", "--memory-limit", "0", "--death-timeout", "60",
                 log=f"worker{n}.log")
        from distributed import Client

        with Client(address, timeout=10, set_as_default=False) as watcher:
            watcher.wait_for_workers(2, timeout=60)
        case = _tenth_of_a_second("reference")
        jobs = [Job("engine, killed once", dask_jobs.marked, (str(marks), 3.0, run_engine, "reference", case), 2.0),
                Job("noise", dask_jobs.noise, (7,), 1.0)]
        monkeypatch.setenv(executor.SCHEDULER_ENV, address)
        lines: list[str] = []
        result: dict = {}
        runner = threading.Thread(target=lambda: result.update(run_jobs(jobs, lines.append, workers=2)), daemon=True)
        runner.start()
        first = int(_until(lambda: next(iter(p.name for p in marks.iterdir() if not p.name.startswith(".")), None),
                           60, "the engine job to start"))
        os.kill(first, signal.SIGKILL)
        runner.join(120)
        assert not runner.is_alive(), "run_jobs did not return within 120 s of the kill"
        pids = sorted(int(p.name) for p in marks.iterdir())
        assert len(pids) == 2 and first in pids, pids  # run again, in the other worker
        worker_pids = {p.pid for p in procs[1:]}
        assert set(pids) == worker_pids
        assert [p.pid for p in procs[1:] if p.poll() is not None] == [first]
        assert len(lines) == 2 and all("FAILED" not in line for line in lines), lines
        assert result[jobs[0]].error is None and result[jobs[1]].error is None
        assert _same_run(result[jobs[0]].value, run_engine("reference", case))
        assert np.array_equal(result[jobs[1]].value, dask_jobs.noise(7))
        left = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())
        assert left == sorted(["scheduler.json", "scheduler.log", "worker1.log", "worker2.log",
                               *(f"marks/{p}" for p in pids)]), left  # no partial file anywhere
    finally:
        executor.close()
        for p in procs:
            if p.poll() is None:
                p.kill()
        for p in procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                pass


def test_an_unreachable_scheduler_is_one_line_and_exit_2_before_anything_runs(monkeypatch, capsys):
    def no_run(*args, **kw):
        raise AssertionError("a job ran")

    monkeypatch.setattr(runs_mod, "run_engine", no_run)
    monkeypatch.setattr(executor, "CONNECT_TIMEOUT_S", 1.0)
    address = f"tcp://127.0.0.1:{_free_port()}"  # nothing listens there
    t0 = time.monotonic()
    assert main(["--scheduler", address, "check", "free_drift", "--short"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and address in err and err.startswith("rsmcheck: --scheduler: "), err
    monkeypatch.setenv(executor.SCHEDULER_ENV, address)  # the variable, and the option after the command
    assert main(["gate", "free_drift"]) == 2
    assert main(["check", "free_drift", "--short", "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and err.count(address) == 2, err
    assert time.monotonic() - t0 < 30
    assert executor.scheduler_address() == address  # --scheduler does not outlive its command


THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MALLOC_TRIM_THRESHOLD_")


def test_the_local_workers_run_in_this_process_s_environment(monkeypatch):
    """Dask's nannies set OMP/MKL/OpenBLAS threads to 1 for their workers unless told not
    to; in release that moved Exudyn's run by 3 Newton iterations (observables 4e-15 apart):
    the local cluster's workers see the thread variables as this process does, so that
    their runs equal the serial ones to the bit."""
    monkeypatch.setenv("OMP_NUM_THREADS", "2")  # a value Dask would overwrite with 1
    executor.close_local()
    try:
        job = Job("environment", dask_jobs.environment, (THREAD_VARIABLES,))
        remote = run_jobs([job], workers=1)[job]
        assert remote.error is None, remote.error_text
        assert remote.value == {n: os.environ.get(n) for n in THREAD_VARIABLES}
        assert os.environ.get("OMP_NUM_THREADS") == "2"  # this process's own left as it was
    finally:
        executor.close_local()
