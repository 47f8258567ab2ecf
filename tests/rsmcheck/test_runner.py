"""rsmcheck.driver.runner: what the sampled-data loop writes into its events."""

from __future__ import annotations

import pytest

from rsmcheck.driver.runner import _detail
from rsmcheck.core.store import Event


def test_an_exact_zero_is_a_measured_value_not_an_identity():
    """Exudyn's basis switch has no projection residual (exactly 0), the reference's has
    round-off: the two engines' captures must still be the same event (docs/cases.md §6)."""
    exact = Event(1.0, "capture", _detail(2, {"residual_m": 0.0, "gap_m": 0.0019995}))
    rounded = Event(1.0, "capture", _detail(2, {"residual_m": 6.17e-14, "gap_m": 0.00199953}))
    assert exact.detail == "arm=2 residual_m=0.00000 gap_m=0.00199950"
    assert exact.identity == rounded.identity == "arm=2 residual_m gap_m"


def test_a_run_reports_where_its_wall_time_went():
    """The per-sample calls the runner times (`SPLIT`) and the engine's own integrator time
    (`wall_integrator_s`, part of `advance`) add up to no more than the run's wall time, and
    `rsmcheck bench` turns them into µs per control sample that sum to it."""
    from reference_model.engine import ReferenceEngine
    from rsmcheck.core.cases import load_case
    from rsmcheck.orchestration.bench import SPLIT_KEYS, per_sample_us
    from rsmcheck.driver.runner import SPLIT, run

    case = load_case("free_drift")
    solver = run(ReferenceEngine(case), case, 0.05).solver
    assert solver["samples"] == 50
    parts = [solver[f"wall_{p}_s"] for p in SPLIT]
    assert all(p > 0.0 for p in parts) and sum(parts) <= solver["wall_s"]
    assert 0.0 < solver["wall_integrator_s"] <= solver["wall_advance_s"]
    us = per_sample_us({k: solver[k] for k in SPLIT_KEYS})
    assert sum(us.values()) * 50 * 1e-6 == pytest.approx(solver["wall_s"], rel=1e-12)
    assert us["runner"] >= 0.0 and us["engine"] >= 0.0
