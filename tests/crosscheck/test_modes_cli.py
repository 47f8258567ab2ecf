"""`rsmcheck modes --json` (docs/commands.md): link frequencies analytic / reference / Exudyn and the
coupled frequencies of four configurations, reference vs Exudyn."""

from __future__ import annotations

import json

import pytest

from rsmcheck.cli import main


@pytest.fixture(scope="module")
def modes():
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["modes", "--json"])
    assert code == 0
    return json.loads(buf.getvalue())


@pytest.mark.crosscheck
def test_link_rows(modes):
    rows = modes["links"]
    assert [(r["basis"], r["mode"]) for r in rows] == [("PP", 1), ("PP", 2), ("PF", 1), ("PF", 2)]
    for r in rows:
        assert {"basis", "mode", "analytic_hz", "reference_hz", "exudyn_hz"} <= set(r)
        assert abs(r["reference_hz"] / r["analytic_hz"] - 1) < 1e-9  # exact modes, quadrature to round-off
        assert 0 < r["exudyn_hz"] / r["analytic_hz"] - 1 < 5e-4  # 8 cubic elements: stiffer, < 0.05 %
        assert abs(r["analytic_hz"] / r["table2_hz"] - 1) < 2e-4  # Table 2 as printed


@pytest.mark.crosscheck
def test_arm_rows(modes):
    rows = modes["arms"]
    configs = {r["configuration"] for r in rows}
    assert {"open", "closed", "free_arms", "stretched_closed"} <= configs
    for r in rows:
        assert {"configuration", "mode", "reference_hz", "exudyn_hz"} <= set(r)
        # known differences: modal truncation (≤ 0.03 %) and the FE axial compliance (≤ 0.15 %)
        assert abs(r["exudyn_hz"] / r["reference_hz"] - 1) < 2e-3, r
