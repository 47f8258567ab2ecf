"""rsmcheck.orchestration.studies: the refinement study's grid, its records and its command line."""

from __future__ import annotations

import json
import math

import pytest

from rsmcheck.cases import load_case
from rsmcheck.orchestration.studies import _exudyn_grid, main, refinement_study


def test_exudyn_grid_reads_substeps_and_axial_stiffness():
    assert _exudyn_grid("32:1e5,256:1e6") == [(32, 1e5), (256, 1e6)]


@pytest.mark.parametrize("text", ["32", "x:1e5", "0:1e5", "32:-1", "32:nan"])
def test_exudyn_grid_rejects_bad_items(text):
    with pytest.raises(Exception, match="SUBSTEPS:EA/EI|must be"):
        _exudyn_grid(text)


def test_bad_case_is_one_line_and_exit_2(capsys):
    assert main(["refinement", "no_such_case"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no_such_case" in err


def test_bad_grid_is_a_usage_error():
    with pytest.raises(SystemExit) as exc:
        main(["refinement", "motor_step", "--exudyn", "256"])
    assert exc.value.code == 2


@pytest.mark.crosscheck
def test_refinement_study_records_every_compare_row(tmp_path):
    """flex_arm_step's short variant, 1 mode against Exudyn at 2 steps per period with two
    axial stiffnesses: every [compare] row of the case gets a finite error per pair, the
    EA/EI is really applied (the two Exudyn runs differ) and the file is complete JSON."""
    out = tmp_path / "refinement.json"
    doc = refinement_study("flex_arm_step", [1], [(2, 1e4), (2, 1e5)], out=out)
    assert set(doc["errors"]) == {"1,2,10000", "1,2,100000"}
    rows = doc["errors"]["1,2,10000"]
    compared = {row.observable for row in load_case("flex_arm_step").variant(short=True).compare}
    assert set(rows) == set(doc["tolerances"]) == compared
    assert {"link_deflection", "joint_angles", "ee2_pos_B", "momentum_I"} <= compared
    assert all(math.isfinite(e) and e > 0 for e in rows.values())
    assert doc["errors"]["1,2,10000"] != doc["errors"]["1,2,100000"]
    assert json.loads(out.read_text())["errors"] == doc["errors"]
