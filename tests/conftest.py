"""Shared engine runs for every test that needs a case's run as `rsmcheck run` makes it.

Every (case, engine) run is done once per session, in a pool of two worker processes
(the engines are independent: two cores halve the wall time), whichever tests use it: the
feature and mission tests (tests/cases), the cross-check (tests/crosscheck/test_cases.py)
and the gate (tests/crosscheck/test_gate.py) read the same runs.  As soon as collection is
finished every run the collected tests will need is submitted, in collection order; each
test then waits only for its own runs.  A test declares them with
`pytest.mark.engine_runs((case, engine, short, options), ...)`.

A sequence case (the mission) is a job too: it runs through `rsmcheck.orchestration.chain.run_case` into
a folder of the session and comes back as a `SequenceRun` (the run, the file's attributes,
the folder with its end states).  Jobs start longest first (the wall time each golden
recorded, goldens/; a sequence: the sum of its phases'), so that no long run starts last
while the other core has nothing left to do; the tests that read pool runs are collected
last, so that the main process meanwhile runs everything else.  Before the pool starts,
the engines' kernels are compiled once, on both cores (`_compile_kernels`).
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import shutil
import site
import tempfile
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import pytest

ENGINES = ("reference", "exudyn")
ROOT = Path(__file__).resolve().parent.parent


@dataclass
class SequenceRun:
    """A sequence case's run as `rsmcheck run` writes it: the engine's run over all phases,
    the run file's root attributes, the folder with the file and its end states."""

    run: Any
    attrs: dict
    out_dir: Path


def _job(engine: str, case_name: str, short: bool, options: dict[str, Any], workdir: str):
    """One engine run in a worker process: (EngineRun or SequenceRun, wall seconds)."""
    import time

    from rsmcheck.core.cases import load_case
    from rsmcheck.orchestration.chain import run_case
    from rsmcheck.orchestration.runs import run_engine
    from rsmcheck.core.store import read_run

    case = load_case(case_name)
    t0 = time.monotonic()
    try:
        if case.phases:
            out = Path(workdir) / f"{case_name}.{engine}"
            runs, attrs = read_run(run_case(case, [engine], short, out_dir=out))
            return SequenceRun(runs[engine], attrs, out), time.monotonic() - t0
        case = case.variant(short)
        duration = options.pop("duration", None)
        if duration:
            case = dataclasses.replace(case, duration=duration)
        run = run_engine(engine, case, options)
    except Exception as exc:  # noqa: BLE001 — not every exception pickles: send the text
        return None, f"{type(exc).__name__}: {exc}"
    return run, time.monotonic() - t0


def expected_wall(case_name: str, engine: str) -> float:
    """The wall time the case's golden recorded for `engine` (rsmcheck.orchestration.runs); 0 for a
    case that does not load (the tests themselves report on it).  Only orders the jobs."""
    from rsmcheck.core.cases import load_case
    from rsmcheck.orchestration.runs import expected_wall as recorded
    from rsmcheck.core.errors import InputError

    try:
        return recorded(load_case(case_name), engine)
    except InputError:
        return 0.0


class RunPool:
    """Runs keyed by (case, engine, options); computed in the background, on demand."""

    def __init__(self, workers: int = 2):
        # the workers unpickle `_job` as tests.conftest._job: the repository root must be on
        # their path also when pytest was started as `pytest` (not `python -m pytest`)
        self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=site.addsitedir, initargs=(str(ROOT),))
        self.futures: dict[tuple, Future] = {}
        self.workdir = tempfile.mkdtemp(prefix="rsmcheck-runs-")

    @staticmethod
    def key(case: str, engine: str, short: bool = True, **options) -> tuple:
        return (case, engine, short, tuple(sorted(options.items())))

    def submit(self, case: str, engine: str, short: bool = True, **options) -> Future:
        k = self.key(case, engine, short, **options)
        if k not in self.futures:
            self.futures[k] = self.pool.submit(_job, engine, case, short, dict(options), self.workdir)
        return self.futures[k]

    def get(self, case: str, engine: str, short: bool = True, **options):
        run, info = self.submit(case, engine, short, **options).result()
        if run is None:
            raise RuntimeError(f"{engine} run of {case} ({'short' if short else 'full'}, {options}) failed: {info}")
        return run

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)
        shutil.rmtree(self.workdir, ignore_errors=True)


#: per test item: the runs it needs, [(case, engine, short, options)], registered by the
#: test modules through `pytest.mark.engine_runs(...)`
def _wanted(items) -> list[tuple]:
    out = []
    for item in items:
        for m in item.iter_markers("engine_runs"):
            for job in m.args:
                if job not in out:
                    out.append(job)
    return out


def pytest_collection_modifyitems(session, config, items):
    """Tests that read pool runs go last (in their own order): while the pool works through
    its queue, longest first, the main process runs everything that needs no pool run,
    instead of waiting at the first test whose run is queued behind the long ones."""
    items.sort(key=lambda item: item.get_closest_marker("engine_runs") is not None)


def pytest_configure(config):
    config.addinivalue_line("markers", "engine_runs(*jobs): (case, engine, short, options) runs a test needs")


POOL = pytest.StashKey[RunPool]()


def _compile_kernels(session) -> None:
    """Fill the kernel cache before the pool and this process start (rsmcheck.orchestration.
    kernels): on a fresh tree both workers and this process would each compile the same
    kernels; a tree whose cache is whole skips it."""
    from rsmcheck.core.plugins import available
    from rsmcheck.orchestration import executor
    from rsmcheck.orchestration.kernels import compile_kernels

    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    write = (lambda line: reporter.write_line(f"compiling the kernels once: {line}")) if reporter else None
    compile_kernels([e for e in ENGINES if available(e)], 2, write, again=False)
    executor.close_local()


def pytest_collection_finish(session):
    jobs = _wanted(session.items)
    if jobs and not session.config.option.collectonly:
        _compile_kernels(session)
        pool = session.config.stash[POOL] = RunPool()
        jobs.sort(key=lambda job: -expected_wall(job[0], job[1]))  # longest first (stable)
        for case, engine, short, options in jobs:
            pool.submit(case, engine, short, **dict(options))


def pytest_sessionfinish(session):
    pool = session.config.stash.get(POOL, None)
    if pool is not None:
        pool.close()


@pytest.fixture(scope="session")
def run_pool(request) -> Callable[..., Any]:
    stash = request.config.stash
    if POOL not in stash:  # a test that declared no engine_runs: runs on demand
        stash[POOL] = RunPool()
    return stash[POOL]


@pytest.fixture
def chromium() -> str:
    """Debian's headless Chromium for the browser tests: skipped where it is missing, except
    when RSMCHECK_REQUIRE_BROWSER=1 (`.ci/run` sets it and installs Chromium): then failed."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        if os.environ.get("RSMCHECK_REQUIRE_BROWSER") == "1":
            pytest.fail("Chromium is required (RSMCHECK_REQUIRE_BROWSER=1) but not installed: apt-get install chromium")
        pytest.skip("Chromium not installed (apt-get install chromium); .ci/run installs it")
    return exe


@pytest.fixture
def render_stored(tmp_path) -> Callable[[Mapping[str, Any]], str]:
    """The report page of a stored folder without runs (free_drift's section only), with
    `documents` (file name → JSON document) as its docs/data: the page's text."""
    def render_page(documents: Mapping[str, Any]) -> str:
        from rsmcheck.report.build import render

        (tmp_path / "verdict.json").write_text(json.dumps({"checks": [], "mission": [], "gate": [], "rigid": {},
                                                           "provenance": {"short": True}}))
        data = tmp_path / "data"
        data.mkdir(exist_ok=True)
        for old in data.glob("*.json"):
            old.unlink()
        for name, doc in documents.items():
            (data / name).write_text(json.dumps(doc))
        return render(tmp_path, tmp_path / "page.html", ["free_drift"], data_dir=data).read_text(encoding="utf-8")
    return render_page
