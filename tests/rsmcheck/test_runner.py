"""rsmcheck.runner: what the sampled-data loop writes into its events."""

from __future__ import annotations

from rsmcheck.runner import _detail
from rsmcheck.store import Event


def test_an_exact_zero_is_a_measured_value_not_an_identity():
    """Exudyn's basis switch has no projection residual (exactly 0), the reference's has
    round-off: the two engines' captures must still be the same event (docs/cases.md §6)."""
    exact = Event(1.0, "capture", _detail(2, {"residual_m": 0.0, "gap_m": 0.0019995}))
    rounded = Event(1.0, "capture", _detail(2, {"residual_m": 6.17e-14, "gap_m": 0.00199953}))
    assert exact.detail == "arm=2 residual_m=0.00000 gap_m=0.00199950"
    assert exact.identity == rounded.identity == "arm=2 residual_m gap_m"
