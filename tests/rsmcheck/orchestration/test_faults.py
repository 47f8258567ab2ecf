"""The fault list of `make faults` (rsmcheck.orchestration.faults) stays applicable as the code changes:
every fault's text occurs exactly once where it says, the faults cover the reference, the
Exudyn model and the shared inputs, and one control fault changes no arithmetic."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

import rsmcheck.orchestration.faults as faults
from rsmcheck.orchestration.faults import ROOT, _failed_tests, apply, catalogue, revert

ITEMS = catalogue()
FAULTS = [i.fault for i in ITEMS]


def test_every_fault_applies_exactly_once():
    for f in FAULTS:
        text = (ROOT / f.path).read_text()
        assert text.count(f.old) == 1, f"{f.name}: {f.old!r} occurs {text.count(f.old)} times in {f.path}"
        assert f.old != f.new and f.what.strip()


def test_the_faults_cover_every_layer_and_one_control():
    layers = [i.layer for i in ITEMS]
    assert sum(layer != "none" for layer in layers) >= 15
    assert {"reference", "exudyn", "shared"} <= set(layers)
    assert layers.count("none") == 1
    assert len({f.name for f in FAULTS}) == len(FAULTS)


def test_apply_and_revert_on_a_copy(tmp_path):
    f = FAULTS[0]
    dest = tmp_path / f.path
    dest.parent.mkdir(parents=True)
    dest.write_text((ROOT / f.path).read_text())
    apply(f, tmp_path)
    assert f.new in dest.read_text() and f.old not in dest.read_text()
    revert(f, ROOT, tmp_path)
    assert dest.read_text() == Path(ROOT / f.path).read_text()


def test_every_run_in_the_copy_starts_from_an_empty_numba_cache(tmp_path, monkeypatch):
    """numba keys a cached function on its own file, not on the files it calls: a cache kept
    from an unfaulted run hid faults of core.py's `rhs` behind the cached integrator."""
    stale = tmp_path / ".numba_cache" / "reference_model_x" / "stepping.dp5.nbi"
    stale.parent.mkdir(parents=True)
    stale.write_text("compiled against the unfaulted core")
    seen = {}

    def fake_run(cmd, cwd, env, **kw):
        seen.update(cmd=cmd, cwd=cwd, cache=env["NUMBA_CACHE_DIR"], path=env["PYTHONPATH"],
                    cache_left=Path(env["NUMBA_CACHE_DIR"]).exists())
        return subprocess.CompletedProcess(cmd, 0, "{}", "")

    monkeypatch.setattr(faults.subprocess, "run", fake_run)
    faults._in_copy(tmp_path, "probe", FAULTS[0].name)
    assert seen["cache"] == str(tmp_path / ".numba_cache") and not seen["cache_left"]
    assert seen["path"] == str(tmp_path) and seen["cwd"] == tmp_path and seen["cmd"][-2:] == ["probe", FAULTS[0].name]


def test_failed_analytic_tests_are_named(tmp_path):
    """The `analytic` column lists the tests that fail, by name; a pytest that could not run
    them is an error, not a clean result."""
    f = tmp_path / "test_probe_sample.py"
    f.write_text("def test_holds():\n    assert 1 + 1 == 2\n\n\ndef test_broken():\n    assert 1 + 1 == 3\n")
    assert _failed_tests((str(f),)) == ["test_broken"]
    with pytest.raises(RuntimeError, match="did not run"):
        _failed_tests((str(tmp_path / "no_such_file.py"),))
