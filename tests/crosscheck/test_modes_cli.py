"""`rsmcheck modes --json` (docs/commands.md): link frequencies analytic / reference / Exudyn /
MuJoCo and the coupled frequencies of four configurations, each engine against the reference."""

from __future__ import annotations

import importlib.util
import json

import pytest

from rsmcheck.cli import main

ENGINES = ("reference", "exudyn") + (("mujoco",) if importlib.util.find_spec("mujoco") else ())


@pytest.fixture(scope="module")
def modes():
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["modes", "--json", "--engines", ",".join(ENGINES)])
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


@pytest.mark.crosscheck
@pytest.mark.skipif("mujoco" not in ENGINES, reason="the mujoco extra is not installed")
def test_mujoco_columns(modes):
    """MuJoCo's segment chains (docs/mujoco.md) at the default N = 8: below Euler–Bernoulli by
    the finite-segment error (≤ 4.1e-4 measured on PF f2, fourth order in 1/N), within 5e-4 of
    Table 2 as printed; the robot's coupled modes within 1.5e-3 of the reference's (measured
    ≤ 9.1e-4: N = 8's second-order error of ≈ 4.6e-4 on the first six modes against N = 32,
    plus the reference's modal truncation ≤ 3e-4)."""
    for r in modes["links"]:
        assert -5e-4 < r["mujoco_hz"] / r["analytic_hz"] - 1 < 0, r
        assert abs(r["mujoco_hz"] / r["table2_hz"] - 1) < 5e-4, r
    for r in modes["arms"]:
        assert r["against"] == "reference" and abs(r["mujoco_rel"]) < 1.5e-3, r
        assert r["exudyn_rel"] == pytest.approx(r["exudyn_hz"] / r["reference_hz"] - 1, rel=1e-12)
