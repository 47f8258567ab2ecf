"""Fixtures of the case tests."""

from __future__ import annotations

import pytest

from rsmcheck.core.cases import load_case


@pytest.fixture
def short_run(run_pool):
    """name → (case variant, EngineRun) of the --short variant, reference engine, from the
    session's run pool (tests/conftest.py: the runs the cross-check and the gate read).
    A test declares the runs it reads with `pytest.mark.engine_runs`."""
    return lambda name: (load_case(name).variant(True), run_pool.get(name, "reference"))
