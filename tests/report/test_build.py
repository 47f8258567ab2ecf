"""report.build: the stored engine studies as HTML tables."""

from __future__ import annotations

import json

from report.build import _studies_html


def _refinement(tmp_path, errors):
    doc = {"case": "motor_step", "duration": 1.0, "modes": [2, 4],
           "exudyn": [{"substeps": 256, "h": 1e-3 / 256, "axial_to_bending": 1e6}],
           "tolerances": {"motor_angles": 1e-6}, "errors": errors}
    (tmp_path / "refinement_motor_step.json").write_text(json.dumps(doc))
    return _studies_html(tmp_path)


def test_refinement_rows_mark_errors_above_the_tolerance(tmp_path):
    page = _refinement(tmp_path, {"2,256,1e+06": {"motor_angles": 3.06e-6},
                                  "4,256,1e+06": {"motor_angles": 4.17e-7}})
    assert "Refinement, motor_step" in page and "motor_angles (≤ 1e-06)" in page
    assert "<span class='fail'>3.06e-06</span>" in page
    assert "4.17e-07" in page and "<span class='fail'>4.17e-07" not in page


def test_a_missing_pair_is_shown_as_missing_and_red(tmp_path):
    page = _refinement(tmp_path, {"2,256,1e+06": {"motor_angles": 3.06e-6}})
    assert "<span class='fail'>–</span>" in page


def test_the_stored_studies_render():
    page = _studies_html()
    assert "Refinement, motor_step" in page and "Refinement, release" in page


def test_engine_comparison_shows_the_switch_sample_left_out():
    """docs/physics.md §4.2 item 4: the reaction force at a release is reported, not compared."""
    import numpy as np

    from cases.loader import load_case
    from report.build import _compare_html
    from rsmcheck.observables import allocate
    from rsmcheck.store import EngineRun, Event

    case = load_case("release")
    t = np.arange(401) * 5e-3
    runs = {}
    for engine, jump in (("reference", 0.9), ("exudyn", 0.0)):
        obs = allocate(t.size)
        obs["time"] = t
        obs["reaction_forces_I"][:, 0] = np.where(t >= 1.0, -10.0 - 0.9, -10.0)
        obs["reaction_forces_I"][200, 0] = -10.0 - jump  # the left limit in one engine
        runs[engine] = EngineRun(engine, obs, events=[Event(1.0, "release", "arm=2")])
    page = _compare_html(case, runs, short=True)
    assert "not compared at the constraint switch (t = 1 s: 0.9)" in page


def test_fault_matrix_section_marks_missed_faults_and_false_alarms(tmp_path):
    import json

    from report.build import _faults_html

    assert _faults_html(tmp_path) == ""
    doc = {"commit": "abc", "cases": ["release"], "faults": [
        {"name": "caught", "layer": "reference", "what": "x", "crosscheck": ["release: ee2_pos_B"], "pinocchio": [],
         "gate": ["release/reference: ee2_pos_B"], "caught_by": ["crosscheck", "gate"]},
        {"name": "missed", "layer": "exudyn", "what": "y", "crosscheck": [], "pinocchio": [], "gate": [], "caught_by": []},
        {"name": "noop", "layer": "none", "what": "z", "crosscheck": [], "pinocchio": [], "gate": [], "caught_by": []},
    ]}
    (tmp_path / "faults.json").write_text(json.dumps(doc))
    page = _faults_html(tmp_path)
    assert page.count("as expected") == 2 and page.count("MISSED") == 1
    assert "release/reference: ee2_pos_B" in page
