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
last, so that the main process meanwhile runs everything else.  The pool's first jobs
compile the engines' kernels once (each engine's first `kernel_runs` group, what the cases'
default settings reach: rsmcheck.orchestration.kernels); an engine's runs are queued when its
group is done, so that a worker never compiles what another is compiling, while the other
worker already flies an engine that is ready.  The main process waits for every group
before its first test (`RunPool.wait_compiled`).
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import shutil
import site
import tempfile
import threading
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
    """Runs keyed by (case, engine, options); computed in the background, on demand.  An
    engine whose kernels are being compiled (`compile`) has its runs queued when that is done."""

    def __init__(self, workers: int = 2):
        # the workers unpickle `_job` as tests.conftest._job: the repository root must be on
        # their path also when pytest was started as `pytest` (not `python -m pytest`)
        self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=site.addsitedir, initargs=(str(ROOT),))
        self.futures: dict[tuple, Future] = {}
        self.compiling: dict[str, list[Future]] = {}  # engine → its compile jobs
        self.waiting: dict[str, list[tuple[tuple, Future]]] = {}  # engine → (job key, placeholder)
        self.lock = threading.Lock()
        self.workdir = tempfile.mkdtemp(prefix="rsmcheck-runs-")

    def compile(self, engines) -> None:
        """Submit the first `kernel_runs` group of each engine not compiled on this tree; a
        thread per engine marks it when done and then queues the runs that waited for it."""
        from rsmcheck.orchestration import kernels

        for job in kernels.compile_jobs(engines, groups=1, again=False):
            engine, group = job.key
            future = self.pool.submit(job.fn, *job.args)
            self.compiling.setdefault(engine, []).append(future)
            threading.Thread(target=self._release, args=(engine, group, future), daemon=True).start()

    def _release(self, engine: str, group: int, future: Future) -> None:
        from rsmcheck.orchestration import kernels

        try:
            future.result()
            kernels.mark(engine, group)
        except Exception:  # noqa: BLE001 — wait_compiled raises it; the runs then fail on their own
            pass
        finally:
            with self.lock:
                self.compiling.pop(engine, None)
                waiting = self.waiting.pop(engine, [])
            for key, placeholder in waiting:
                self._chain(self._submit_now(key), placeholder)

    def wait_compiled(self) -> None:
        """Block until every compile job is done; raise the first one's error."""
        for futures in list(self.compiling.values()):
            for future in futures:
                future.result()

    @staticmethod
    def _chain(source: Future, target: Future) -> None:
        def copy(f: Future) -> None:
            if f.exception() is not None:
                target.set_exception(f.exception())
            else:
                target.set_result(f.result())

        source.add_done_callback(copy)

    def _submit_now(self, k: tuple) -> Future:
        case, engine, short, options = k
        return self.pool.submit(_job, engine, case, short, dict(options), self.workdir)

    @staticmethod
    def key(case: str, engine: str, short: bool = True, **options) -> tuple:
        return (case, engine, short, tuple(sorted(options.items())))

    def submit(self, case: str, engine: str, short: bool = True, **options) -> Future:
        k = self.key(case, engine, short, **options)
        with self.lock:
            if k not in self.futures:
                if engine in self.compiling:
                    self.futures[k] = Future()
                    self.waiting.setdefault(engine, []).append((k, self.futures[k]))
                else:
                    self.futures[k] = self._submit_now(k)
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


def pytest_collection_finish(session):
    jobs = _wanted(session.items)
    if jobs and not session.config.option.collectonly:
        from rsmcheck.core.plugins import available

        pool = session.config.stash[POOL] = RunPool()
        pool.compile([e for e in ENGINES if available(e)])
        jobs.sort(key=lambda job: -expected_wall(job[0], job[1]))  # longest first (stable)
        for case, engine, short, options in jobs:
            pool.submit(case, engine, short, **dict(options))
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter and pool.compiling:
            reporter.write_line("compiling the kernels of " + ", ".join(pool.compiling) + " once, in the pool")
        pool.wait_compiled()


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
