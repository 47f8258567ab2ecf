"""A row's tolerance for any pair of engines (rsmcheck.core.tolerances): the stated pair gets
the case file's figure, every other pair its own parts, never another engine's error."""

from __future__ import annotations

import math

import pytest

from rsmcheck.core.cases import CompareSpec, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.tolerances import pair_tolerance

#: capture_gap_B of capture.toml as budgeted: 3.5 × (3.2e-8 + 7.0e-10 + 1.8e-9)
ROW = CompareSpec("capture_gap_B", 1.2e-7, "budget", allowance=3.2e-8,
                   errors={"reference": 7.0e-10, "exudyn": 1.8e-9})
K = 1.2e-7 / (3.2e-8 + 7.0e-10 + 1.8e-9)


def test_the_stated_pair_gets_the_case_files_tolerance_in_either_order():
    for pair in (("reference", "exudyn"), ("exudyn", "reference")):
        pt = pair_tolerance(ROW, pair)
        assert pt.stated and pt.tolerance == 1.2e-7


def test_a_new_engine_is_judged_by_the_allowance_its_own_error_and_its_partners():
    pt = pair_tolerance(ROW, ("reference", "mine"), measured={"mine": 5e-9})
    assert not pt.stated
    assert pt.tolerance == pytest.approx(K * (3.2e-8 + 7.0e-10 + 5e-9), rel=1e-12)
    # not Exudyn's error: the new pair's tolerance moves with its own engine's error only
    assert pair_tolerance(ROW, ("reference", "mine"), measured={"mine": 0.0}).tolerance == \
        pytest.approx(K * (3.2e-8 + 7.0e-10), rel=1e-12)
    why = pt.why(" m")
    assert why.startswith("reference against mine: budget")
    assert "allowance 3.2e-08" in why and "reference integration 7.0e-10 (recorded" in why
    assert "mine integration 5.0e-09 (measured" in why and "exudyn integration" not in why


def test_an_engine_without_refinement_counts_zero_and_says_so():
    pt = pair_tolerance(ROW, ("reference", "norefine"))
    assert pt.tolerance == pytest.approx(K * (3.2e-8 + 7.0e-10), rel=1e-12)
    assert "norefine integration not measured (no refined_options: taken as 0)" in pt.why()


def test_departures_widen_only_the_pairs_of_their_engine():
    dep = {"soft": (1e-7, "soft closed-chain constraint, gap 1e-7 m measured")}
    mine = pair_tolerance(ROW, ("reference", "soft"), measured={"soft": 0.0}, departures=dep)
    assert mine.tolerance == pytest.approx(K * (3.2e-8 + 7.0e-10 + 1e-7), rel=1e-12)
    assert "soft departure 1.0e-07 (soft closed-chain" in mine.why()
    # the stated pair passes no departure of another engine: check_runs hands each pair
    # only its own engines' departures, and without them it is the case file's figure
    assert pair_tolerance(ROW, ("reference", "exudyn"), departures={}).tolerance == 1.2e-7


def test_a_rule_row_is_the_same_for_every_pair():
    flag = CompareSpec("grasp_state", 0.5, "both captured", metric="final")
    for pair in (("reference", "exudyn"), ("reference", "mine")):
        pt = pair_tolerance(flag, pair, measured={"mine": 1.0})
        assert pt.stated and pt.tolerance == 0.5 and pt.budget is None


def test_the_shipped_rows_state_the_in_tree_pair(tmp_path):
    """Every budgeted row of capture.toml names the reference and Exudyn, and its margin
    factor k = tolerance / budget lies in (1, 10]: above 10 it would be blind."""
    case = load_case("capture")
    budgeted = [s for s in case.compare if s.allowance is not None]
    assert budgeted
    for s in budgeted:
        assert set(s.errors) == {"reference", "exudyn"}
        k = s.tolerance / (s.allowance + sum(s.errors.values()))
        assert 1.0 < k <= 10.0 and math.isfinite(k), (s.observable, k)


@pytest.mark.parametrize("row, key, reason", [
    ("allowance = 1e-8", "errors", "missing"),
    ("errors = { reference = 1e-9, exudyn = 1e-9 }", "allowance", "missing"),
    ("allowance = -1e-8\nerrors = { reference = 1e-9, exudyn = 1e-9 }", "allowance", "must be >="),
    ("allowance = 1e-8\nerrors = { reference = 1e-9 }", "errors", "two engines"),
    ("engine_errors = { exudyn = 1e-9 }", "engine_errors", "only with a budget"),
    ("allowance = 1e-8\nerrors = { reference = 1e-9, exudyn = 1e-9 }\nengine_errors = { exudyn = 1e-9 }",
     "engine_errors.exudyn", "is in errors already"),
    ("allowance = 1e-8\nerrors = { reference = 1e-9, exudyn = 1e-9 }\nengine_errors = { nosuch = 1e-9 }",
     "engine_errors.nosuch", "not a registered engine"),
    ("allowance = 1e-8\nerrors = { reference = 1e-9, exudyn = 1e-9 }\nengine_errors = { pinocchio = -1 }",
     "engine_errors.pinocchio", "must be >="),
])
def test_a_half_budget_is_one_error_naming_the_key(tmp_path, row, key, reason):
    text = open(load_case("capture").path, encoding="utf-8").read()
    text = text.replace('name = "capture"', 'name = "capture_bad"')
    text = text.replace("[compare.grasp_state]\ntolerance = 0.5\n", f"[compare.grasp_state]\ntolerance = 0.5\n{row}\n")
    path = tmp_path / "capture_bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as exc:
        load_case(str(path))
    assert f"compare.grasp_state.{key}" in str(exc.value) and reason in str(exc.value)


def test_a_recorded_error_of_an_engine_outside_the_pair_is_used_instead_of_a_refined_run():
    """`engine_errors` (from `rsmcheck budget`): the engine's pairs take it as recorded, a
    measured value does not replace it, and a check needs no refined run of that engine."""
    from dataclasses import replace

    from rsmcheck.orchestration.compare import needs_error

    row = replace(ROW, engine_errors={"mine": 4e-9})
    pt = pair_tolerance(row, ("reference", "mine"), measured={"mine": 1.0})
    assert pt.tolerance == pytest.approx(K * (3.2e-8 + 7.0e-10 + 4e-9), rel=1e-12)
    assert "mine integration 4.0e-09 (recorded" in pt.why()
    assert pair_tolerance(row, ("reference", "exudyn")).tolerance == 1.2e-7  # the stated pair as stated
    variant = replace(load_case("capture"), compare=(row,))
    assert not needs_error(variant, "mine") and needs_error(variant, "other")


def test_a_chained_phase_gives_every_pair_the_stated_tolerance_and_says_why():
    pt = pair_tolerance(ROW, ("reference", "mine"), measured={"mine": 5e-9}, chained=True)
    assert pt.stated and pt.tolerance == 1.2e-7
    assert "chained flight" in pt.why() and "chained flight" in pt.formula()


def test_the_stated_pair_keeps_its_tolerance_whatever_its_engines_declare():
    """The allowance was measured on the stated pair: its engines' departures are in it."""
    pt = pair_tolerance(ROW, ("reference", "exudyn"), departures={"exudyn": (1e-7, "axial compliance")})
    assert pt.stated and pt.tolerance == 1.2e-7 and pt.departures == ()


def test_a_row_says_why_an_error_was_not_measured():
    pt = pair_tolerance(ROW, ("reference", "mine"), missing={"mine": "its refined run failed: diverged at 0.3 s"})
    assert "mine integration not measured (its refined run failed: diverged at 0.3 s: taken as 0)" in pt.why()
    assert pt.as_dict()["errors"]["mine"]["how"].startswith("its refined run failed")


def test_a_misspelt_engine_in_errors_is_one_error(tmp_path):
    text = open(load_case("capture").path, encoding="utf-8").read().replace('name = "capture"', 'name = "capture_bad"')
    text = text.replace("errors = { reference = 7e-10, exudyn = 1.8e-09 }", "errors = { reference = 7e-10, exudyn2 = 1.8e-09 }")
    path = tmp_path / "capture_bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match="compare.capture_gap_B.errors.exudyn2: not a registered engine"):
        load_case(str(path))
