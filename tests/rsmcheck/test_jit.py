"""The compiled kernels' cache is keyed to the sources (rsmcheck/core/jit.py): numba checks
only the file that defines a function, so a kernel that calls another module's would run
stale code after that module changed."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from rsmcheck.core import jit


def test_the_key_changes_with_any_source_file_and_only_then(tmp_path, monkeypatch):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "sub" / "b.py").write_text("y = 2\n")
    monkeypatch.setattr(jit, "_package_dirs", lambda: [pkg])
    k0 = jit.source_key()
    assert jit.source_key() == k0
    (pkg / "sub" / "b.py").write_text("y = 3\n")  # a module the first one may inline
    k1 = jit.source_key()
    assert k1 != k0
    (pkg / "sub" / "b.py").write_text("y = 2\n")
    assert jit.source_key() == k0


@pytest.mark.skipif(bool(os.environ.get("NUMBA_CACHE_DIR")), reason="the user's NUMBA_CACHE_DIR is left alone")
def test_the_engines_compile_into_the_keyed_folder():
    code = ("import reference_model, numba; from rsmcheck.core import jit; "
            "print(numba.config.CACHE_DIR == str(jit.cache_root() / jit.source_key()))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"


def test_only_packages_that_import_numba_enter_the_key(tmp_path):
    """A plug-in that drives another package's engine (no numba import of its own) holds no
    kernel: installing it must not recompile every kernel; one that imports numba does."""
    driver = tmp_path / "driver_only"
    driver.mkdir()
    (driver / "plugin.py").write_text('"""Drives the reference (numba-compiled) model."""\nrequires = ("numba",)\n')
    kernels = tmp_path / "with_kernels"
    kernels.mkdir()
    (kernels / "k.py").write_text("import math\nfrom numba import njit\n")
    assert not jit._compiles(driver) and jit._compiles(kernels)
    for pkg in ("reference_model", "exudyn_model"):  # the in-tree engines hold kernels
        assert jit._compiles(jit.Path(jit.__file__).resolve().parents[2] / pkg)
