"""Shared engine runs for every test that needs a case's run as `rsmcheck run` makes it.

Every (case, engine) run is done once per session, in a pool of two worker processes
(the engines are independent: two cores halve the wall time), whichever tests use it: the
feature and mission tests (tests/cases), the cross-check (tests/crosscheck/test_cases.py)
and the gate (tests/crosscheck/test_gate.py) read the same runs.  As soon as collection is
finished every run the collected tests will need is submitted, in collection order; each
test then waits only for its own runs.  A test declares them with
`pytest.mark.engine_runs((case, engine, short, options), ...)`.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, Callable

import pytest

ENGINES = ("reference", "exudyn")


def _job(engine: str, case_name: str, short: bool, options: dict[str, Any]):
    """One engine run in a worker process: (EngineRun, wall seconds)."""
    import time

    from cases.loader import load_case
    from rsmcheck.compare import _run_one

    case = load_case(case_name).variant(short)
    duration = options.pop("duration", None) or case.duration
    t0 = time.monotonic()
    try:
        run = _run_one(engine, case, duration, options)
    except Exception as exc:  # noqa: BLE001 — not every exception pickles: send the text
        return None, f"{type(exc).__name__}: {exc}"
    return run, time.monotonic() - t0


class RunPool:
    """Runs keyed by (case, engine, options); computed in the background, on demand."""

    def __init__(self, workers: int = 2):
        self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
        self.futures: dict[tuple, Future] = {}

    @staticmethod
    def key(case: str, engine: str, short: bool = True, **options) -> tuple:
        return (case, engine, short, tuple(sorted(options.items())))

    def submit(self, case: str, engine: str, short: bool = True, **options) -> Future:
        k = self.key(case, engine, short, **options)
        if k not in self.futures:
            self.futures[k] = self.pool.submit(_job, engine, case, short, dict(options))
        return self.futures[k]

    def get(self, case: str, engine: str, short: bool = True, **options):
        run, info = self.submit(case, engine, short, **options).result()
        if run is None:
            raise RuntimeError(f"{engine} run of {case} ({'short' if short else 'full'}, {options}) failed: {info}")
        return run

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)


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


def pytest_configure(config):
    config.addinivalue_line("markers", "engine_runs(*jobs): (case, engine, short, options) runs a test needs")


POOL = pytest.StashKey[RunPool]()


def pytest_collection_finish(session):
    jobs = _wanted(session.items)
    if jobs and not session.config.option.collectonly:
        pool = session.config.stash[POOL] = RunPool()
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
