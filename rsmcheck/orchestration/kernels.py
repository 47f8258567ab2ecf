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
compiled; the groups are the parallel part (the reference's: the explicit integrator and
the implicit ones, which share the right-hand side but not their own loops).  Each run is
`RUN_S` of its case's short variant: enough for a few samples, events included where the
case starts with them (a held target, the orbit, a motion programme).  When all of an
engine's groups have run, a marker in the cache folder says so (`MARKER`), and
`compile_kernels(..., again=False)` leaves that engine alone: an unchanged tree costs
nothing the second time.
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
#: the file, in the kernel cache's folder, that says an engine's groups have all run
MARKER = ".compiled-{engine}"


def compiled(engine: str) -> bool:
    """Whether the cache of this tree holds `engine`'s kernels (its groups all ran)."""
    return (jit.cache_dir() / MARKER.format(engine=engine)).exists()


def _compile_group(engine: str, runs: Sequence[tuple[str, Mapping[str, Any]]]) -> int:
    """Fly `engine` on each (case, options) of `runs` for RUN_S, in this process; the
    number of runs."""
    for case_name, options in runs:
        case = load_case(case_name).variant(True)
        run_engine(engine, dataclasses.replace(case, duration=min(RUN_S, case.duration)), options)
    return len(runs)


def compile_jobs(engines: Sequence[str]) -> list[Job]:
    """One job per group of each engine's `kernel_runs` (none for an engine without)."""
    jobs = []
    for engine in engines:
        for i, group in enumerate(kernel_runs(engine), 1):
            cases = ", ".join(dict.fromkeys(c for c, _ in group))
            jobs.append(Job(f"{engine} kernels {i} ({cases})", _compile_group, (engine, tuple(group)),
                            expected_s=float(len(group))))
    return jobs


def compile_kernels(engines: Sequence[str], workers: int = 2, progress: Progress | None = None,
                    again: bool = True) -> dict[str, float]:
    """Run the compile jobs of `engines` on `workers` processes, then mark each engine
    compiled; {job label: wall s}.  `again=False`: skip the engines already marked.  A run
    that fails raises its error (a kernel that does not compile is a fault in the code,
    not something to find later in the middle of a test) and marks nothing."""
    engines = [e for e in engines if again or not compiled(e)]
    out = {}
    for job, outcome in run_jobs(compile_jobs(engines), progress, workers).items():
        if outcome.error is not None:
            raise outcome.error
        out[job.label] = outcome.wall_s
    folder = jit.cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    for engine in engines:
        (folder / MARKER.format(engine=engine)).write_text("")
    return out
