"""The executor behind `rsmcheck.orchestration.runs.run_jobs`: Dask.distributed.

`run_jobs` orders the jobs and prints the progress; this module only hands them to a
dask.distributed Client and gives back each one's result as it finishes:

* by default to a LocalCluster of this machine (`workers` processes, one thread each:
  one process per core, nothing to start).  Starting one costs ≈ 1.5 s (start + stop,
  2 workers, 2 cores), and its workers import the engines again at their first job, so
  one cluster is kept per process and reused by the next call (closed at exit).  It is
  started again when the number of workers, the environment, the working folder or
  `sys.path` changed since: a spawned worker sees those as they were when it started
  (the ProcessPoolExecutor this replaces saw them as they were at each call);
* to an existing cluster when an address is given (`rsmcheck --scheduler ADDRESS`, or
  the environment variable RSMCHECK_SCHEDULER): `connect` checks before anything runs
  that a scheduler answers there within CONNECT_TIMEOUT_S, that it has a worker, and
  that every worker runs this very code (`runs.source_digest`), else one line, exit 2.

The jobs are submitted longest first, each with a priority that says so to the scheduler.
`rsmcheck bench` sends its runs the same way, each asking for one unit of the worker
resource BENCH_RESOURCE (`resources=`, Dask's worker resources): a worker runs one of them
at a time whatever its threads, and only workers that have the resource take them (the
local cluster's all do; an existing cluster's are started with `dask worker --resources
bench=1`, and `completed` says so in one line, exit 2, when none has it).

A worker that dies (killed, out of memory) takes its job back to the scheduler, which runs
it again on another worker (Dask's `distributed.scheduler.allowed-failures`, 3 by
default, after which the job fails with KilledWorker and is reported like any failure).
Jobs return their values and write nothing the parent reads, so a job cut short leaves
nothing behind (the parent writes the run files, atomically: `store.write_run`).
"""

from __future__ import annotations

import atexit
import logging
import os
import sys
import uuid
from typing import Any, Callable, Iterator, Sequence

from rsmcheck.core.errors import InputError

# `distributed` is imported where it is used: at the top it would add ≈ 0.7 s to every
# command, `rsmcheck --help` included (tests/test_layers.py, DEFERRED_ALLOWED)

#: the environment variable naming a Dask scheduler (as --scheduler does)
SCHEDULER_ENV = "RSMCHECK_SCHEDULER"
#: how long a scheduler may take to answer, and to show a worker [s]
CONNECT_TIMEOUT_S = 5.0
#: the worker resource a `rsmcheck bench` run takes one unit of: one run per worker at a
#: time (each worker of the local cluster has one unit; `dask worker --resources bench=1`)
BENCH_RESOURCE = "bench"

_local: dict[str, Any] = {}  # "key", "cluster", "client": the one LocalCluster of this process
_remote: dict[str, Any] = {}  # address → Client
_scheduler: str | None = None  # set by --scheduler (`use_scheduler`)


def scheduler_address() -> str | None:
    """The scheduler to use: --scheduler, else $RSMCHECK_SCHEDULER, else None (local)."""
    return _scheduler or os.environ.get(SCHEDULER_ENV, "").strip() or None


def use_scheduler(address: str | None) -> None:
    """Use the scheduler at `address` (None: back to $RSMCHECK_SCHEDULER or local)."""
    global _scheduler
    _scheduler = address.strip() if address else None


def describe(workers: int) -> str:
    """Where `run_jobs(…, workers)` runs its jobs, for the progress line."""
    if workers <= 0:
        return "in this process"
    address = scheduler_address()
    return f"on the Dask cluster at {address}" if address else f"on {workers} processes"


def _quiet() -> None:
    """Dask's own logging to errors only: its info and warnings (a worker restarted, a
    connection closed at shutdown) are not the suite's output."""
    logging.getLogger("distributed").setLevel(logging.ERROR)


def connect(address: str, digest: Callable[[], str]) -> Any:
    """The Client of the scheduler at `address` (one per address and process); an
    InputError (one line, exit 2) when none answers within CONNECT_TIMEOUT_S, when it has
    no worker by then, or when a worker runs other code than this process: `digest()`
    (`runs.source_digest`, passed in: runs imports this module) differs there."""
    if address in _remote:
        return _remote[address]
    _quiet()
    from distributed import Client

    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError("--scheduler", address, f"no Dask scheduler answers there within "
                         f"{CONNECT_TIMEOUT_S:g} s ({type(exc).__name__})") from None
    try:
        client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
    except (TimeoutError, OSError):
        client.close()
        raise InputError("--scheduler", address, f"the scheduler has no worker (waited {CONNECT_TIMEOUT_S:g} s)")
    mine = digest()
    theirs = client.run(digest)
    other = sorted(w for w, d in theirs.items() if d != mine)
    if other:
        client.close()
        raise InputError("--scheduler", address, f"worker(s) {', '.join(other)} run other rsmcheck or engine "
                         "code than this one (source digest); start them from the same checkout")
    _remote[address] = client
    return client


def local_client(workers: int) -> Any:
    """The Client of this process's LocalCluster with `workers` worker processes (started,
    or started again when what a spawned worker inherits changed)."""
    if _local.get("key") == _inherited(workers):
        return _local["client"]
    close_local()
    _quiet()
    from distributed import Client, LocalCluster

    import dask

    env = dict(os.environ)
    # the workers inherit this process's environment unchanged, as the runs made in this
    # process do: Dask's nannies would set OMP_NUM_THREADS, MKL_NUM_THREADS,
    # OPENBLAS_NUM_THREADS = 1 and MALLOC_TRIM_THRESHOLD_, and with them release's Exudyn
    # run took 16 146 Newton iterations instead of 16 143 (observables 4e-15 apart):
    # the runs would no longer equal the serial ones to the bit
    with dask.config.set({"distributed.nanny.pre-spawn-environ": {}}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                               memory_limit=0, silence_logs=logging.ERROR, resources={BENCH_RESOURCE: 1})
    client = Client(cluster, set_as_default=False)
    # whatever Dask still sets here for its workers stays out of this process's other
    # children (a test's subprocess, a fault's copy)
    for name in set(os.environ) - set(env):
        del os.environ[name]
    os.environ.update(env)
    # (its scheduler also puts its scratch folder on sys.path: the key is taken after)
    _local.update(key=_inherited(workers), cluster=cluster, client=client)
    return client


def _inherited(workers: int) -> tuple:
    """What a spawned worker takes from this process when it starts."""
    return workers, tuple(sorted(os.environ.items())), os.getcwd(), tuple(sys.path)


def close_local() -> None:
    if _local:
        _local.pop("client").close()
        _local.pop("cluster").close()
        _local.clear()


def close() -> None:
    """Close the local cluster and the clients of this process (also done at exit)."""
    close_local()
    for client in _remote.values():
        client.close()
    _remote.clear()


atexit.register(close)


def require_resources(client: Any, address: str, resources: dict[str, float]) -> None:
    """An InputError (one line, exit 2) when no worker of the cluster at `address` has
    `resources`: the tasks asking for them would wait for ever."""
    have = [w.get("resources") or {} for w in client.scheduler_info(n_workers=-1)["workers"].values()]
    if not any(all(r.get(k, 0) >= v for k, v in resources.items()) for r in have):
        need = ",".join(f"{k}={v:g}" for k, v in resources.items())
        raise InputError("--scheduler", address, f"no worker has the resource {need} these tasks need: "
                         f"start them with `dask worker … --resources {need}` (docs/cluster.md)")


def completed(tasks: Sequence[tuple[Callable[..., Any], tuple]], workers: int,
              digest: Callable[[], str],
              resources: dict[str, float] | None = None) -> Iterator[tuple[int, Any, BaseException | None]]:
    """Run `fn(*args)` for each of `tasks` (in this order of priority: the first first) on
    the cluster; (index, value, None) for each as it finishes, or (index, None, exception)
    when Dask could not run it (a job that kept killing its workers: KilledWorker).
    `digest`: see `connect`.  `resources`: what each task takes of its worker's resources
    (Dask's worker resources, e.g. {BENCH_RESOURCE: 1}); on an existing cluster some
    worker must have them (`require_resources`)."""
    from distributed import as_completed

    address = scheduler_address()
    client = connect(address, digest) if address else local_client(workers)
    if address and resources:
        require_resources(client, address, resources)
    tag = uuid.uuid4().hex[:12]
    futures = {client.submit(fn, *args, key=f"rsmcheck-{tag}-{i}", priority=len(tasks) - i, pure=False,
                             resources=resources): i
               for i, (fn, args) in enumerate(tasks)}
    try:
        for fut in as_completed(futures, loop=client.loop):
            try:
                yield futures[fut], fut.result(), None
            except Exception as exc:  # noqa: BLE001 — reported as the job's failure
                yield futures[fut], None, exc
    finally:
        client.cancel(list(futures))
