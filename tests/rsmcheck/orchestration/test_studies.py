"""rsmcheck.orchestration.studies: the refinement study's grid, its records and its command line."""

from __future__ import annotations

import json
import math

import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.orchestration.studies import _exudyn_grid, _integrator_grid, integrator_study, main, refinement_study


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


def test_integrator_grid_reads_integrator_and_rtol():
    assert _integrator_grid("dopri5:1e-7,imex:1e-8") == [("dopri5", 1e-7), ("imex", 1e-8)]


@pytest.mark.parametrize("text", ["dopri5", "rk4:1e-7", "imex:x", "imex:0", "imex:nan"])
def test_integrator_grid_rejects_bad_items(text):
    with pytest.raises(Exception, match="INTEGRATOR:RTOL|the integrator is"):
        _integrator_grid(text)


def test_integrator_study_measures_each_rtol_against_the_tight_solution(tmp_path):
    """p1_rigid_gains' short variant (0.2 s): the tight Dormand–Prince solution against
    itself is exact, a looser rtol leaves a larger error than a tighter one on every
    [compare] row, and the record is complete JSON with steps per control sample.  (The
    study's other integrators compile for minutes: `test_integrator_study_takes_imex`.)"""
    out = tmp_path / "integrators.json"
    doc = integrator_study("p1_rigid_gains", [("dopri5", 1e-10), ("dopri5", 1e-6), ("dopri5", 1e-8)], out=out)
    rows = [c.observable for c in load_case("p1_rigid_gains").short.compare]
    exact, loose, tight = doc["runs"]
    assert set(exact["error"]) == set(rows)
    assert all(v == 0.0 for v in exact["error"].values())  # the same integrator at the same rtol
    assert all(loose["error"][o] > tight["error"][o] > 0.0 for o in rows), (loose["error"], tight["error"])
    assert exact["steps_per_sample"] >= 1.0 and tight["rejected_per_sample"] >= 0.0
    assert json.loads(out.read_text())["runs"][2]["rtol"] == 1e-8


@pytest.mark.study
def test_integrator_study_takes_imex(tmp_path):
    """The same study with the IMEX pair at rtol 1e-8: between the loose and the tight run."""
    doc = integrator_study("p1_rigid_gains", [("dopri5", 1e-10), ("dopri5", 1e-6), ("imex", 1e-8)],
                           out=tmp_path / "integrators.json")
    rows = [c.observable for c in load_case("p1_rigid_gains").short.compare]
    exact, loose, imex = doc["runs"]
    assert all(loose["error"][o] > imex["error"][o] > 0.0 for o in rows), (loose["error"], imex["error"])
    assert doc["runs"][2]["integrator"] == "imex"
