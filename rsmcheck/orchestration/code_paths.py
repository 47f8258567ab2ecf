"""Other CPUs' code paths, emulated on this machine: the third kind of bless run of the gate.

The same wheels compute differently on another CPU because three libraries choose their
code at run time from the processor they find:

* OpenBLAS (numpy's BLAS) picks a kernel family per CPU (`OPENBLAS_CORETYPE`: SkylakeX on
  an AVX-512 Xeon, Haswell on AMD Zen and on Intel client cores, older ones without FMA);
  its products round differently from one family to the next;
* numpy dispatches its SIMD loops per CPU feature group (`NPY_DISABLE_CPU_FEATURES` turns
  groups off);
* glibc's libm picks FMA or plain variants of sin, cos, exp, pow… (`GLIBC_TUNABLES`
  `glibc.cpu.hwcaps` masks features), and numba compiles for the host CPU
  (`NUMBA_CPU_NAME`).

Each `CodePath` below is one class of machine as these four see it, set through their
environment variables in a fresh interpreter (they are read once, at load time).  A path
runs only where this CPU can execute it (`runnable`: AVX-512 kernels on a CPU without
AVX-512 would stop at an illegal instruction).  `run_on_path` runs one engine on one case
in such an interpreter and returns its run; the gate's bless takes the largest change of
these runs against the nominal one as a measured bound of what another CPU does
(rsmcheck.orchestration.gate, docs/gate.md).
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from numpy._core._multiarray_umath import __cpu_features__

from rsmcheck.core.store import EngineRun
from rsmcheck.orchestration.runs import run_engine


@dataclass(frozen=True)
class CodePath:
    """One machine class: its name, the environment that selects its code in OpenBLAS,
    numpy, libm and numba, and the CPU features (numpy's names) it needs to run here."""

    name: str
    env: Mapping[str, str]
    needs: tuple[str, ...]
    machine: str  # which processors compute this way

    def describe(self) -> str:
        return f"{self.name} ({self.machine}): " + " ".join(f"{k}={v}" for k, v in self.env.items())


#: the numpy dispatch groups above the x86-64-v2 baseline of the wheels
_NPY_ABOVE_V2 = "X86_V3 X86_V4 AVX512_ICL AVX512_SPR"
_NPY_ABOVE_V3 = "X86_V4 AVX512_ICL AVX512_SPR"

CODE_PATHS: tuple[CodePath, ...] = (
    CodePath("x86-64-v4", {"OPENBLAS_CORETYPE": "SkylakeX", "NPY_DISABLE_CPU_FEATURES": "AVX512_SPR",
                           "NUMBA_CPU_NAME": "skylake-avx512"},
             ("AVX512F", "AVX512CD", "AVX512BW", "AVX512DQ", "AVX512VL"),
             "AVX-512 without FP16: Intel Xeon Skylake-SP to Ice Lake, AMD Zen 4 and 5"),
    CodePath("x86-64-v3", {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": _NPY_ABOVE_V3,
                           "NUMBA_CPU_NAME": "haswell"},
             ("AVX2", "FMA3"), "AVX2 and FMA: AMD Zen 1–3, Intel Haswell and client cores"),
    CodePath("x86-64-v2", {"OPENBLAS_CORETYPE": "Nehalem", "NPY_DISABLE_CPU_FEATURES": _NPY_ABOVE_V2,
                           "NUMBA_CPU_NAME": "nehalem", "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX,-AVX2,-FMA,-FMA4"},
             ("SSE42",), "SSE4.2 without AVX or FMA: old servers, minimal virtual CPUs"),
    CodePath("blas-1-thread", {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}, (),
             "this CPU with a single-threaded BLAS (a Dask nanny's default)"),
)


def cpu_features() -> dict[str, bool]:
    """This CPU's features by numpy's names (AVX512F, FMA3, …)."""
    return dict(__cpu_features__)


def runnable(path: CodePath, features: Mapping[str, bool] | None = None) -> bool:
    """Whether this CPU executes `path`'s code (it has every feature the path needs)."""
    have = cpu_features() if features is None else features
    return all(have.get(f, False) for f in path.needs)


def available(features: Mapping[str, bool] | None = None) -> list[CodePath]:
    """The code paths this CPU can run, in `CODE_PATHS`' order."""
    return [p for p in CODE_PATHS if runnable(p, features)]


def run_on_path(path: CodePath, engine: str, case: Any) -> EngineRun:
    """`engine` on `case` (the variant to run) in a fresh interpreter whose environment
    selects `path`'s code; its run.  A failure there is a RuntimeError with the child's
    last line of error output."""
    with tempfile.TemporaryDirectory(prefix="rsmcheck-path-") as tmp:
        job, out = Path(tmp) / "job.pkl", Path(tmp) / "run.pkl"
        job.write_bytes(pickle.dumps((engine, case)))
        env = {**os.environ, **path.env}
        proc = subprocess.run([sys.executable, "-m", __name__, str(job), str(out)], env=env,
                              capture_output=True, text=True)
        if proc.returncode != 0 or not out.exists():
            last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            raise RuntimeError(f"{engine} on code path {path.name}: exit {proc.returncode}: {last}")
        return pickle.loads(out.read_bytes())


def _child(job: str, out: str) -> None:
    engine, case = pickle.loads(Path(job).read_bytes())
    Path(out).write_bytes(pickle.dumps(run_engine(engine, case)))


if __name__ == "__main__":
    _child(sys.argv[1], sys.argv[2])
