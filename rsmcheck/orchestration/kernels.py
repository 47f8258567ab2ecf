"""Fill the compiled-kernel cache once, in parallel, before the runs that need it.

An engine with numba kernels compiles them at its first call and keeps them in the cache
(rsmcheck.core.jit); the reference model's integrators each inline its whole right-hand
side, so a fresh tree spends minutes in LLVM before its first step.  Every process that
meets a kernel before the cache holds it compiles it again: a pool of two workers and the
process that feeds them, started together on a fresh tree, compile the same kernels three
times over.  `compile_kernels` runs each engine's `kernel_runs` first (a plug-in's optional
capability: groups of short runs that between them reach its kernels), one group per
worker, so that the cache is whole before anything else starts and every later process
only reads it.

A group runs in one process, in order, so that its later runs find what its first one
compiled; the groups are the parallel part.  An engine's first group reaches the kernels
its default settings use (every case runs on them); later groups reach options that no
case sets by default (the reference's implicit integrators, which share the right-hand
side but not their own loops): `groups=1` compiles only what the cases need.  Each run is
`RUN_S` of its case's short variant: enough for a few samples, events included where the
case starts with them (a held target, the orbit, a motion programme).  When a group has
run, a marker in the cache folder says so (`MARKER`), and `compile_kernels(...,
again=False)` leaves it alone: an unchanged tree costs nothing the second time.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

from rsmcheck.core import jit
from rsmcheck.core.cases import load_case
from rsmcheck.core.plugins import kernel_runs
from rsmcheck.orchestration.runs import Job, Progress, run_engine, run_jobs

#: how long each run of a group flies [s]: ten control periods of 1 ms
RUN_S = 0.01
#: the file, in the kernel cache's folder, that says an engine's group (counted from 1) has run
MARKER = ".compiled-{engine}-{group}"


def _marker(engine: str, group: int):
    return jit.cache_dir() / MARKER.format(engine=engine, group=group)


def compiled(engine: str, groups: int | None = None) -> bool:
    """Whether the cache of this tree holds `engine`'s kernels: its first `groups` groups
    (None: all) have run."""
    n = len(kernel_runs(engine))
    return all(_marker(engine, i).exists() for i in range(1, min(n, groups or n) + 1))


def mark(engine: str, group: int) -> None:
    """Record that `engine`'s group `group` (from 1) has run on this tree's cache."""
    _marker(engine, group).parent.mkdir(parents=True, exist_ok=True)
    _marker(engine, group).write_text("")


def _compile_group(engine: str, runs: Sequence[tuple[str, Mapping[str, Any]]]) -> int:
    """Fly `engine` on each (case, options) of `runs` for RUN_S, in this process; the
    number of runs."""
    for case_name, options in runs:
        case = load_case(case_name).variant(True)
        run_engine(engine, dataclasses.replace(case, duration=min(RUN_S, case.duration)), options)
    return len(runs)


def compile_jobs(engines: Sequence[str], groups: int | None = None, again: bool = True) -> list[Job]:
    """One job per group of each engine's `kernel_runs` (none for an engine without): the
    first `groups` of each (None: all); `again=False`: only the groups not marked.  Each
    job's key is (engine, group number from 1)."""
    jobs = []
    for engine in engines:
        for i, group in enumerate(kernel_runs(engine)[:groups], 1):
            if again or not _marker(engine, i).exists():
                cases = ", ".join(dict.fromkeys(c for c, _ in group))
                jobs.append(Job(f"{engine} kernels {i} ({cases})", _compile_group, (engine, tuple(group)),
                                expected_s=float(len(group)), key=(engine, i)))
    return jobs


def compile_kernels(engines: Sequence[str], workers: int = 2, progress: Progress | None = None,
                    again: bool = True, groups: int | None = None) -> dict[str, float]:
    """Run the compile jobs of `engines` (`compile_jobs`) on `workers` processes and mark
    each group that ran; {job label: wall s}.  A run that fails raises its error (a kernel
    that does not compile is a fault in the code, not something to find later in the
    middle of a test) after the groups that ran are marked."""
    out, error = {}, None
    for job, outcome in run_jobs(compile_jobs(engines, groups, again), progress, workers).items():
        if outcome.error is not None:
            error = error or outcome.error
            continue
        mark(*job.key)
        out[job.label] = outcome.wall_s
    if error is not None:
        raise error
    return out
