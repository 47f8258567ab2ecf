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
