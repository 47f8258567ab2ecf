"""The other CPUs' code paths the gate's bless measures its tolerances on
(rsmcheck.orchestration.code_paths, docs/gate.md): which ones a CPU can run, that their
environment reaches a fresh interpreter and changes what OpenBLAS, numpy, libm and numba
compute there, and that a run on a path comes back whole (or says why not)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError
from rsmcheck.orchestration import code_paths as cp
from rsmcheck.orchestration.runs import run_engine

ALL = {f: True for f in ("SSE42", "AVX2", "FMA3", "AVX512F", "AVX512CD", "AVX512BW", "AVX512DQ", "AVX512VL")}


def test_a_path_runs_only_where_the_cpu_has_its_features():
    names = lambda feats: [p.name for p in cp.available(feats)]  # noqa: E731
    assert names(ALL) == ["x86-64-v4", "x86-64-v3", "x86-64-v2", "blas-1-thread"]
    assert names({**ALL, "AVX512BW": False}) == ["x86-64-v3", "x86-64-v2", "blas-1-thread"]  # an AVX2 CPU
    assert names({"SSE42": True}) == ["x86-64-v2", "blas-1-thread"]
    assert names({}) == ["blas-1-thread"]  # not x86: the thread count alone
    assert all(cp.runnable(p) for p in cp.available())


# what a child reports: numpy's enabled dispatch groups, numba's target CPU, and digests of
# the bits of products numpy leaves to OpenBLAS (A(a)ᵀ v, SkylakeX's kernels fuse them,
# Haswell's do not) and of libm's sin and exp (FMA and plain variants)
PROBE = """
import hashlib, json, math, numpy as np, numba.core.config as nc
from numpy._core._multiarray_umath import __cpu_features__ as f, __cpu_dispatch__ as d
rng = np.random.default_rng(3)
blas = hashlib.sha1()
for a, x, y in rng.normal(0.0, 3.0, (4000, 3)):
    A = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    blas.update((A.T @ np.array([x, y])).tobytes())
libm = hashlib.sha1(np.array([(math.sin(v), math.exp(v / 10)) for v in rng.uniform(-40, 40, 50000)]).tobytes())
print(json.dumps({"dispatch": [k for k in d if f.get(k)], "numba_cpu": nc.CPU_NAME,
                  "blas": blas.hexdigest(), "libm": libm.hexdigest()}))
"""


def _probe(env: dict[str, str]) -> dict:
    import os

    out = subprocess.run([sys.executable, "-c", PROBE], env={**os.environ, **env}, capture_output=True, text=True,
                         timeout=120, check=True)
    return json.loads(out.stdout)


def test_each_path_changes_what_the_libraries_compute():
    host = _probe({})
    got = {p.name: _probe(dict(p.env)) for p in cp.available()}
    for p in cp.available():
        assert got[p.name]["numba_cpu"] == p.env.get("NUMBA_CPU_NAME"), p.name
        off = p.env.get("NPY_DISABLE_CPU_FEATURES", "").split()
        assert not set(off) & set(got[p.name]["dispatch"]), p.name
    assert got["blas-1-thread"] == host  # the same CPU's code, one BLAS thread
    if "x86-64-v2" in got and cp.cpu_features().get("FMA3"):
        assert got["x86-64-v2"]["libm"] != host["libm"]  # libm's plain variants, not its FMA ones
    emulated = [got[n]["blas"] for n in ("x86-64-v4", "x86-64-v3", "x86-64-v2") if n in got]
    if len(emulated) >= 2:
        assert len(set(emulated)) >= 2  # OpenBLAS's kernel families round differently


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    path = tmp_path_factory.mktemp("paths") / "spin.toml"
    path.write_text('name = "spin"\ndescription = "a free robot that spins for 20 ms"\nduration = 0.02\n'
                    '[initial]\nbase_rate = [0.0, 0.0, 0.05]\n[solver]\ncontrol_period = 1e-3\n'
                    'output_period = 1e-3\n')
    return load_case(path).variant(True)


def test_a_run_on_a_path_comes_back_whole(tiny):
    """On the host's own code with one BLAS thread the run is the in-process one to the bit
    (the tiny case's products are too small for OpenBLAS to thread), with its solver's
    counters; a failure in the child is one line naming the engine and the path."""
    path = next(p for p in cp.CODE_PATHS if p.name == "blas-1-thread")
    there, here = cp.run_on_path(path, "reference", tiny), run_engine("reference", tiny)
    assert there.engine == "reference" and there.solver["steps"] == here.solver["steps"]
    for name, value in here.observables.items():
        assert np.array_equal(np.asarray(there.observables[name]), np.asarray(value), equal_nan=True), name
    with pytest.raises(RuntimeError, match=r"nosuchengine on code path blas-1-thread: exit 1: .*nosuchengine"):
        cp.run_on_path(path, "nosuchengine", tiny)


def test_bless_refuses_a_path_this_cpu_cannot_run(monkeypatch):
    from rsmcheck import cli

    monkeypatch.setattr(cp, "cpu_features", lambda: {"SSE42": True})
    with pytest.raises(InputError, match="x86-64-v3.*cannot run it.*AVX2, FMA3"):
        cli._code_paths("x86-64-v3")
    assert [p.name for p in cli._code_paths("x86-64-v2,blas-1-thread")] == ["x86-64-v2", "blas-1-thread"]
    assert cli._code_paths("none") == [] and cli._code_paths(None) is None
