"""rsmcheck.orchestration.budget and `rsmcheck budget`: a [compare] row's error budget is
the engines' model difference plus each engine's integration error (its run against its
plug-in's finer run), each by the row's own metric; the verdicts ok / tight / blind, the
suggested tolerance and why, the document (merged, atomic), the exit codes, and one real
run of the cheapest case with a [compare] table."""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib

import numpy as np
import pytest

import rsmcheck.orchestration.budget as bud
import rsmcheck.orchestration.runs as runs_mod
from rsmcheck.orchestration import case_edit, collect
from rsmcheck.cli import main
from rsmcheck.core.cases import CompareSpec, load_case
from rsmcheck.core.observables import allocate
from rsmcheck.core.plugins import plugin, settings_of
from rsmcheck.core.store import EngineRun
from rsmcheck.orchestration.runs import read_stored

A, B = "reference", "exudyn"  # the default engines: the model under test, the other


def _run(engine: str, t: np.ndarray, offset: float = 0.0, sigma: float = 68.0, rms_spike: float = 0.0) -> EngineRun:
    """A run whose ee1/ee2 positions are `offset` everywhere, motor torques e^{σt} (a growth
    rate σ exactly) and joint angles 0 but `rms_spike` at one sample."""
    obs = allocate(t.size)
    obs["time"] = t
    obs["ee1_pos_B"][...] = offset
    obs["ee2_pos_B"][...] = offset
    obs["motor_torques"][...] = np.exp(sigma * t)[:, None]
    obs["joint_angles"][t.size // 2, 3] = rms_spike
    return EngineRun(engine, obs, solver={"wall_s": 0.1})


def _case(*specs: CompareSpec):
    """p1_rigid_gains short (0.2 s, 1 ms samples) with the [compare] rows `specs`."""
    return dataclasses.replace(load_case("p1_rigid_gains").variant(True), compare=specs)


T = np.round(np.arange(201) * 1e-3, 12)


def test_the_budget_is_the_sum_of_the_measured_differences_by_each_rows_metric():
    """model difference d(A, B), integration errors d(A, A'), d(B, B'), each by the row's
    metric (max_abs, rms, growth in its window); budget = sum; the verdicts."""
    case = _case(CompareSpec("ee1_pos_B", 2e-7, "ok row"),
                 CompareSpec("ee2_pos_B", 5e-6, "blind row"),
                 CompareSpec("motor_torques", 0.3, "tight row", "growth", (0.1, 0.2)),
                 CompareSpec("joint_angles", 1e-3, "rms row", "rms"))
    runs = {A: _run(A, T, 0.0, 68.0, 0.0), B: _run(B, T, 1e-7, 68.2, 2e-4)}
    fine = {A: _run(A, T, 1e-8, 68.01, 1e-4), B: _run(B, T, 1.3e-7, 68.35, 2e-4)}
    ok, blind, tight, rms = bud.budget_rows(case, runs, fine, [A, B])

    assert (ok.engines, ok.tolerance, ok.why) == ((A, B), 2e-7, "ok row")
    assert ok.model_difference == pytest.approx(1e-7, rel=1e-9)
    assert ok.integration_error == {A: pytest.approx(1e-8, rel=1e-9), B: pytest.approx(3e-8, rel=1e-6)}
    assert ok.budget == pytest.approx(1.4e-7, rel=1e-6) and ok.margin == pytest.approx(2e-7 / 1.4e-7, rel=1e-6)
    assert ok.verdict == "ok" and ok.complete

    assert blind.budget == pytest.approx(1.4e-7, rel=1e-6) and blind.margin > 10 and blind.verdict == "blind"

    # growth: |σ_a − σ_b| [1/s] of the fitted envelopes, exact for a pure exponential
    assert tight.metric == "growth [0.1, 0.2] s"
    assert tight.model_difference == pytest.approx(0.2, abs=1e-9)
    assert tight.integration_error == {A: pytest.approx(0.01, abs=1e-9), B: pytest.approx(0.15, abs=1e-9)}
    assert tight.budget == pytest.approx(0.36, abs=1e-9) and tight.verdict == "tight"  # 0.3 < 0.36

    # rms over the 201 samples of one 2e-4 (1e-4) spike, not its max_abs
    n = T.size
    assert rms.model_difference == pytest.approx(2e-4 / math.sqrt(n), rel=1e-9)
    assert rms.integration_error == {A: pytest.approx(1e-4 / math.sqrt(n), rel=1e-9), B: 0.0}


def test_the_verdict_edges_and_a_budget_of_nothing():
    row = bud.Budget("c", "ee1_pos_B", "max_abs", (A, B), 1.0, 0.5, {A: 0.25, B: 0.25})
    assert (row.budget, row.margin, row.verdict) == (1.0, 1.0, "ok")  # budget = tolerance: covered
    assert dataclasses.replace(row, tolerance=0.999).verdict == "tight"
    assert dataclasses.replace(row, tolerance=10.0).verdict == "ok"  # margin 10: still ok
    assert dataclasses.replace(row, tolerance=10.01).verdict == "blind"
    zero = dataclasses.replace(row, model_difference=0.0, integration_error={A: 0.0, B: 0.0})
    assert zero.margin == math.inf and zero.verdict == "blind" and zero.suggested_tolerance() is None
    blown = dataclasses.replace(row, model_difference=math.inf)
    assert blown.verdict == "tight" and blown.suggested_tolerance() is None
    assert json.loads(json.dumps(blown.as_dict()))["budget"] == "inf"  # strict JSON


@pytest.mark.parametrize("x, expected", [(0.36 * 3, 1.1), (0.75, 0.75), (0.7501, 0.76), (1.23e-7, 1.3e-7),
                                         (3.0e-7, 3.0e-7), (0.995, 1.0), (42.0, 42.0)])
def test_suggested_tolerances_are_rounded_up_to_two_significant_figures(x, expected):
    assert bud.round_up(x) == expected


def test_the_suggestion_names_every_part_and_the_rule():
    row = bud.Budget("c", "ee1_pos_B", "max_abs", (A, B), 1e-7, 2.77e-8, {A: 3.6e-9, B: 2.74e-8}, unit=" m")
    assert row.suggested_tolerance() == 1.8e-7  # 3 × 5.87e-8 = 1.761e-7, rounded up
    assert row.suggested_why({A: "rtol/10", B: "half step"}) == (
        "Budget 5.9e-08 m on the full run (docs/data/budget.json): model difference 2.8e-08, reference "
        "integration 3.6e-09 (rtol/10), exudyn integration 2.7e-08 (half step); tolerance 3 × budget.")
    assert row.suggested_why({A: "rtol/10", B: "half step"}, run="short run").startswith(
        "Budget 5.9e-08 m on the short run (docs/data/budget.json): ")


def test_an_engine_without_a_finer_run_is_not_measured_and_the_budget_says_lower_bound():
    case = _case(CompareSpec("ee1_pos_B", 1e-6, "row"))
    row, = bud.budget_rows(case, {A: _run(A, T), B: _run(B, T, 1e-7)}, {A: _run(A, T, 1e-8), B: None}, [A, B])
    assert row.integration_error == {A: pytest.approx(1e-8), B: None} and not row.complete
    assert row.budget == pytest.approx(1.1e-7)
    assert "(a lower bound)" in row.suggested_why({A: "rtol/10"}) and "exudyn integration not measured" \
        in row.suggested_why({A: "rtol/10"})
    assert row.as_dict()["integration_error"] == {A: pytest.approx(1e-8), B: None}


# ---------------------------------------------------------------------------------------
# the command, on synthetic runs (the engines replaced: run_engine returns these)
# ---------------------------------------------------------------------------------------
#: (engine, refined) → (offset of the positions, growth rate of the motor torques)
SYNTHETIC = {(A, False): (0.0, 68.0), (A, True): (1e-9, 68.01), (B, False): (2e-8, 68.2), (B, True): (4e-8, 68.35)}


@pytest.fixture
def fake_engines(monkeypatch):
    """run_engine replaced by SYNTHETIC runs on the case's own samples; the calls listed."""
    calls = []

    def fake(engine, case, options=None):
        calls.append((engine, case.name, case.is_short, dict(options or {})))
        t = np.round(np.arange(round(case.duration / case.solver.output_period) + 1) * case.solver.output_period, 12)
        offset, sigma = SYNTHETIC[(engine, bool(options))]
        return _run(engine, t, offset, sigma)

    monkeypatch.setattr(bud, "run_engine", fake)
    return calls


def test_the_command_runs_each_engine_at_the_case_settings_and_refined(fake_engines, tmp_path, capsys):
    """p1_rigid_gains --short: four runs (each engine as the case sets it and refined by its
    plug-in), a table with the three rows, exit 0 (none tight), the document written with
    every run's settings and the machine; --suggest prints a tolerance and why per row."""
    out = tmp_path / "data" / "budget.json"
    assert main(["budget", "p1_rigid_gains", "--short", "--serial", "--suggest", "--out", str(out)]) == 0
    case = load_case("p1_rigid_gains").variant(True)
    assert sorted(map(str, fake_engines)) == sorted(map(str, [
        (A, case.name, True, {}), (A, case.name, True, {"rtol": settings_of(case, A).rtol / 10, "h_max": 0.5e-3}),
        (B, case.name, True, {}), (B, case.name, True, {"substeps": 2 * settings_of(case, B).substeps})]))
    stdout, stderr = capsys.readouterr()
    assert "4 runs in this process" in stderr and stderr.count("] p1_rigid_gains / ") == 4
    assert "p1_rigid_gains / exudyn refined (substeps=128: half step)" in stderr
    for spec in case.compare:
        assert spec.observable in stdout
    assert "3 rows: 2 ok, 0 tight, 1 blind" in stdout  # ee2_pos_B: 5e-7 over 4.1e-8
    assert stdout.count(f"on the short run ({out})") == 3  # the document it wrote
    assert stdout.count("tolerance 3 × budget.") == 3

    doc = json.loads(out.read_text())
    entry = doc["variants"]["short"]["p1_rigid_gains"]
    assert entry["engines"] == [A, B] and entry["machine"]["logical_cpus"] >= 1 and entry["failures"] == {}
    assert entry["runs"][A]["refined"]["options"] == {"rtol": settings_of(case, A).rtol / 10, "h_max": 0.5e-3}
    assert entry["runs"][B]["refined"]["options"] == {"substeps": 128}
    assert entry["runs"][B]["case"]["case_settings"] == {"substeps": 64}
    assert entry["refinements"] == {A: plugin(A).refinement, B: plugin(B).refinement}
    rows = {r["observable"]: r for r in entry["rows"]}
    assert rows["ee1_pos_B"]["model_difference"] == pytest.approx(2e-8)
    assert rows["ee1_pos_B"]["integration_error"] == {A: pytest.approx(1e-9), B: pytest.approx(2e-8)}
    assert rows["ee1_pos_B"]["budget"] == pytest.approx(4.1e-8) and rows["ee1_pos_B"]["verdict"] == "ok"
    assert rows["ee2_pos_B"]["verdict"] == "blind" and rows["motor_torques"]["verdict"] == "ok"
    assert rows["ee1_pos_B"]["suggested_tolerance"] == 1.3e-7
    assert not list(out.parent.glob("*.tmp"))  # written atomically: no temporary left


def test_with_a_run_folder_the_runs_at_the_settings_are_stored_then_reused(fake_engines, tmp_path, capsys,
                                                                           monkeypatch):
    """--runs DIR: the first budget stores its runs at the case's settings where check --out
    and the report find them (the refined ones are not kept); a second reads them and runs
    only the refined ones, to the same rows."""
    out, runs = tmp_path / "budget.json", tmp_path / "runs"
    argv = ["budget", "p1_rigid_gains", "--short", "--serial", "--out", str(out), "--runs", str(runs)]
    assert main(argv) == 0
    first = json.loads(out.read_text())["variants"]["short"]["p1_rigid_gains"]
    assert len(fake_engines) == 4 and (runs / "p1_rigid_gains.h5").is_file()
    case = load_case("p1_rigid_gains")
    assert sorted(read_stored(runs / "p1_rigid_gains.h5", case, True)[0]) == sorted([A, B])
    assert main(argv) == 0
    assert len(fake_engines) == 6 and all(c[3] for c in fake_engines[4:])  # the refined ones only
    assert "stored runs reused: p1_rigid_gains / " in capsys.readouterr().err
    second = json.loads(out.read_text())["variants"]["short"]["p1_rigid_gains"]
    assert second["rows"] == first["rows"]
    assert second["runs"][A]["case"]["reused"] is True and "reused" not in first["runs"][A]["case"]
    monkeypatch.setattr(runs_mod, "run_engine", lambda *a, **k: pytest.fail("check ran an engine"))
    assert main(["check", "p1_rigid_gains", "--short", "--serial", "--out", str(runs)]) == 0  # no engine ran
    assert "3 of 3 comparisons pass" in capsys.readouterr().out


def test_a_tight_row_exits_1_and_the_document_keeps_the_other_cases(fake_engines, tmp_path, capsys, monkeypatch):
    out = tmp_path / "budget.json"
    out.write_text(json.dumps({"format": bud.FORMAT, "variants": {"short": {"other_case": {"rows": []}},
                                                                   "full": {"x": {}}}}))
    monkeypatch.setitem(SYNTHETIC, (B, True), (1e-6, 68.35))  # exudyn's step error 1e-6 m > 1e-7 m
    assert main(["budget", "p1_rigid_gains", "--short", "--serial", "--out", str(out)]) == 1
    assert "tight" in capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert set(doc["variants"]["short"]) == {"other_case", "p1_rigid_gains"} and doc["variants"]["full"] == {"x": {}}


def test_a_failed_run_is_named_and_exits_1(fake_engines, tmp_path, capsys, monkeypatch):
    good = bud.run_engine

    def refined_fails(engine, case, options=None):
        if engine == B and options:
            raise RuntimeError("Newton did not converge")
        return good(engine, case, options)

    monkeypatch.setattr(bud, "run_engine", refined_fails)
    assert main(["budget", "p1_rigid_gains", "--short", "--serial", "--out", str(tmp_path / "b.json")]) == 1
    out = capsys.readouterr().out
    assert "exudyn refined: FAILED: RuntimeError: Newton did not converge" in out
    assert "lower bound" in out and "runs that failed: p1_rigid_gains / exudyn refined" in out


def test_an_engine_without_refined_options_is_reported_not_measured(fake_engines, tmp_path, capsys, monkeypatch):
    monkeypatch.delattr(type(plugin(B)), "refined_options")
    assert main(["budget", "p1_rigid_gains", "--short", "--serial", "--out", str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    assert len(fake_engines) == 3 and "n/m" in out
    assert "integration error of exudyn not measured (no refined_options in its plug-in)" in out


@pytest.mark.parametrize("argv, field", [
    (["budget", "no_such_case"], "case"),
    (["budget", "p1_rigid_gains", "--engines", "reference"], "--engines"),
    (["budget", "p1_rigid_gains", "--engines", "reference,warp"], "warp"),
    (["budget", "p1_rigid_gains", "--out", "."], "--out"),
    (["budget", "p1_rigid_gains", "--factor", "0.5"], "--factor"),  # tight by construction
    (["budget", "p1_rigid_gains", "--factor", "12"], "--factor"),  # blind by construction
    (["budget", "p1_rigid_gains", "--engines", "reference,pinocchio"], "pinocchio"),  # checks, does not simulate
])
def test_budget_bad_input_exits_2_in_one_line(argv, field, capsys):
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert len(err.splitlines()) == 1 and field in err and "Traceback" not in err and not out


def test_the_factor_of_the_suggestion_is_an_option(fake_engines, tmp_path, capsys):
    out = tmp_path / "b.json"
    assert main(["budget", "p1_rigid_gains", "--short", "--serial", "--suggest", "--factor", "2", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "Suggested tolerances (2 x budget, rounded up to 2 significant figures)" in stdout
    assert "ee1_pos_B: tolerance 1e-07 -> 8.2e-08" in stdout  # 2 × 4.1e-8
    entry = json.loads(out.read_text())["variants"]["short"]["p1_rigid_gains"]
    assert entry["suggested_tolerance"] == "2 x budget, rounded up to 2 significant figures"
    row = next(r for r in entry["rows"] if r["observable"] == "ee1_pos_B")
    assert row["suggested_tolerance"] == 8.2e-8 and row["suggested_why"].endswith("tolerance 2 × budget.")


def test_an_out_file_that_is_not_a_budget_document_is_refused_before_anything_runs(fake_engines, tmp_path, capsys):
    other = tmp_path / "check.json"
    other.write_text('{"checks": []}')
    assert main(["budget", "p1_rigid_gains", "--short", "--serial", "--out", str(other)]) == 2
    assert "is not a budget document" in capsys.readouterr().err
    assert other.read_text() == '{"checks": []}' and fake_engines == []


def test_a_case_without_compare_rows_is_not_budgeted(fake_engines, tmp_path, capsys):
    assert main(["budget", "free_drift", "--short", "--serial", "--out", str(tmp_path / "b.json")]) == 1
    out, err = capsys.readouterr()
    assert "free_drift: NOT BUDGETED: no [compare] table" in out and "nothing was budgeted" in err
    assert fake_engines == [] and not (tmp_path / "b.json").exists()


# ---------------------------------------------------------------------------------------
# one real run
# ---------------------------------------------------------------------------------------
@pytest.mark.crosscheck
def test_a_real_budget_of_the_cheapest_case(tmp_path, capsys):
    """p1_rigid_gains --short (0.2 s of flight; ~20 s on 2 cores, through Dask): four real
    runs, every row's parts measured and > 0, the exit code the verdicts call for."""
    out = tmp_path / "budget.json"
    code = main(["budget", "p1_rigid_gains", "--short", "--out", str(out)])
    entry = json.loads(out.read_text())["variants"]["short"]["p1_rigid_gains"]
    case = load_case("p1_rigid_gains").variant(True)
    assert [r["observable"] for r in entry["rows"]] == [s.observable for s in case.compare]
    for r in entry["rows"]:
        assert r["complete"] and r["model_difference"] > 0 and all(v > 0 for v in r["integration_error"].values())
        assert r["budget"] == pytest.approx(r["model_difference"] + sum(r["integration_error"].values()))
    assert code == (1 if any(r["verdict"] == "tight" for r in entry["rows"]) else 0)
    assert entry["runs"][A]["refined"]["solver"]["rtol"] == settings_of(case, A).rtol / 10
    assert entry["runs"][B]["refined"]["solver"]["substeps"] == 2 * entry["runs"][B]["case"]["solver"]["substeps"]
    assert capsys.readouterr().err.count("] p1_rigid_gains / ") == 4


# ---------------------------------------------------------------------------------------
# --apply: minimal edits of the case files
# ---------------------------------------------------------------------------------------
CASE_TEXT = '''# a comment that stays
name = "x"

[compare.ee1_pos_B]
tolerance = 1e-7   # the old one
why = "Measured 2.1e-8 m (\\"short\\"); 1e-7 is 4.7x."
[short.compare.ee1_pos_B]
metric = "max_abs"
tolerance = 1e-7
why = "short row"  # stays a comment
[short.compare.ee2_pos_B]
tolerance = 5e-7
why = """a multi-line
why"""
'''


def _row(tolerance, why, **parts):
    return {"tolerance": tolerance, "why": why, **parts}


def test_an_edit_changes_the_two_lines_of_the_row_and_nothing_else():
    new, changed, refused = case_edit.edit_text(CASE_TEXT, "short.compare", {
        "ee1_pos_B": _row(1.8e-7, 'budget 5.9e-08 m: "quoted" \\ slash'), "ee2_pos_B": _row(1.0, "x"),
        "com_pos_B": _row(1.0, "y")})
    assert changed == ["ee1_pos_B"]
    assert "not a one-line basic string" in refused["ee2_pos_B"] and "no [short.compare.com_pos_B] table" in refused["com_pos_B"]
    old_lines, new_lines = CASE_TEXT.splitlines(), new.splitlines()
    differ = [i for i, (a, b) in enumerate(zip(old_lines, new_lines)) if a != b]
    assert len(old_lines) == len(new_lines) and [old_lines[i] for i in differ] == [
        "tolerance = 1e-7", 'why = "short row"  # stays a comment']
    assert [new_lines[i] for i in differ] == [
        "tolerance = 1.8e-07", 'why = "budget 5.9e-08 m: \\"quoted\\" \\\\ slash"  # stays a comment']
    row = tomllib.loads(new)["short"]["compare"]["ee1_pos_B"]
    assert row == {"metric": "max_abs", "tolerance": 1.8e-7, "why": 'budget 5.9e-08 m: "quoted" \\ slash'}
    assert tomllib.loads(new)["compare"] == tomllib.loads(CASE_TEXT)["compare"]  # the full row untouched
    new, changed, _ = case_edit.edit_text(CASE_TEXT, "compare", {"ee1_pos_B": _row(3.0, "z")})
    assert changed == ["ee1_pos_B"] and "tolerance = 3.0   # the old one" in new.splitlines()


def test_an_edit_adds_the_budgets_parts_after_the_tolerance_then_replaces_them():
    parts = {"allowance": 2.04e-8, "errors": {"reference": 1.23e-10, "exudyn": 4.5e-9}}
    new, changed, _ = case_edit.edit_text(CASE_TEXT, "compare", {"ee1_pos_B": _row(1e-7, "w", **parts)})
    lines = new.splitlines()
    at = lines.index("tolerance = 1e-07   # the old one")
    assert changed == ["ee1_pos_B"] and lines[at + 1:at + 3] == [
        "allowance = 2e-08", "errors = { reference = 1.2e-10, exudyn = 4.5e-09 }"]
    assert tomllib.loads(new)["compare"]["ee1_pos_B"]["errors"] == {"reference": 1.2e-10, "exudyn": 4.5e-9}
    again, _, _ = case_edit.edit_text(new, "compare", {"ee1_pos_B": _row(1e-7, "w", allowance=3e-8,
                                                                         errors={"reference": 1e-9, "exudyn": 2e-9})})
    assert len(again.splitlines()) == len(lines)  # replaced in place, not added twice
    assert tomllib.loads(again)["compare"]["ee1_pos_B"]["allowance"] == 3e-8


def test_a_short_variant_that_takes_the_full_rows_is_not_edited():
    assert case_edit.compare_table(load_case("thrust_burn"), True) is None  # no [short.compare]
    assert case_edit.compare_table(load_case("thrust_burn"), False) == "compare"
    assert case_edit.compare_table(load_case("p1_rigid_gains"), True) == "short.compare"
    edit = case_edit.apply_rows(load_case("thrust_burn"), True, {"joint_angles": _row(2e-5, "x")})
    assert edit.changed == [] and "apply a full budget" in edit.refused["joint_angles"]


def test_apply_writes_the_suggestions_into_the_case_file(fake_engines, tmp_path, capsys, monkeypatch):
    """A copy of p1_rigid_gains (as p1_copy, in its own --cases-dir) with exudyn's step error
    above ee1_pos_B's tolerance: tight, then --apply sets every row to 3 × its budget (exit
    0: nothing tight is left); the file differs in those lines only and loads."""
    cases = tmp_path / "cases"
    cases.mkdir()
    source = load_case("p1_rigid_gains").path
    text = open(source, encoding="utf-8").read().replace('name = "p1_rigid_gains"', 'name = "p1_copy"')
    (cases / "p1_copy.toml").write_text(text, encoding="utf-8")
    monkeypatch.setitem(SYNTHETIC, (B, True), (2e-7, 68.35))
    out = tmp_path / "budget.json"
    assert main(["--cases-dir", str(cases), "budget", "p1_copy", "--short", "--serial", "--out", str(out)]) == 1
    assert main(["--cases-dir", str(cases), "budget", "p1_copy", "--short", "--serial", "--apply",
                 "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "p1_copy.toml: set motor_torques, ee1_pos_B, ee2_pos_B" in stdout
    new = (cases / "p1_copy.toml").read_text(encoding="utf-8")
    assert len(new.splitlines()) == len(text.splitlines())  # the rows had their parts: replaced
    differ = [(a, b) for a, b in zip(text.splitlines(), new.splitlines()) if a != b]
    assert differ and all(a.split("=")[0] == b.split("=")[0] for a, b in differ)
    assert {a.split("=")[0].strip() for a, _ in differ} <= {"tolerance", "allowance", "errors", "why"}
    rows = {r["observable"]: r for r in json.loads(out.read_text())["variants"]["short"]["p1_copy"]["rows"]}
    short = load_case(str(cases / "p1_copy.toml")).variant(True)
    for spec in short.compare:
        r = rows[spec.observable]
        assert spec.tolerance == r["suggested_tolerance"]
        assert spec.why == r["suggested_why"] and str(out) in spec.why
        assert spec.allowance == float(f"{r['model_difference']:.2g}")
        assert spec.errors == {e: float(f"{v:.2g}") for e, v in r["integration_error"].items()}
    assert load_case(str(cases / "p1_copy.toml")).compare == load_case("p1_rigid_gains").compare  # full rows kept


# ---------------------------------------------------------------------------------------
# a sequence: its phases' rows in the chained flight
# ---------------------------------------------------------------------------------------
@pytest.fixture
def fake_flights(monkeypatch):
    """run_sequence replaced by whole flights of the sequence's phases (each phase's samples
    from its own t = 0, concatenated as `chain.run_mission` does) with SYNTHETIC offsets, a
    refined flight's from its second sample on (it starts where the unrefined one does);
    the flights listed with each phase's options."""
    flights = []

    def fly(engine, case, short, workdir, options=None, phase_options=None):
        phases = [load_case(p).variant(short) for p in case.variant(short).phases]
        flights.append((engine, {ph.name: dict(phase_options(ph)) if phase_options else {} for ph in phases}))
        offset, _ = SYNTHETIC[(engine, phase_options is not None)]
        pieces, t0 = [], 0.0
        for ph in phases:
            pieces.append(t0 + np.round(np.arange(round(ph.duration / ph.solver.output_period) + 1)
                                        * ph.solver.output_period, 12))
            t0 += ph.duration
        run = _run(engine, np.concatenate(pieces), offset, 0.0)
        for key in ("ee1_pos_B", "ee2_pos_B"):
            run.observables[key][0] = SYNTHETIC[(engine, False)][0]
        return runs_mod.SequenceRun(run, {})

    monkeypatch.setattr(bud, "run_sequence", fly)
    return flights


def test_a_sequence_is_budgeted_by_its_phases_rows_in_the_chained_flight(fake_engines, fake_flights, tmp_path,
                                                                         capsys):
    """mission --short: each engine flown twice, the refined flight with every phase at its
    own plug-in refinement (p2's rtol is not p3's); every row the report checks the chained
    phases by (their own and the replaced ones), named "mission/PHASE", with the difference
    the engines carry in (d0) added to the tolerance as in the report, and as integration
    errors what each refined flight departs by in the phase beyond where it entered it;
    --apply writes nothing into the sequence file and says so."""
    out = tmp_path / "budget.json"
    mission = load_case("mission")
    before = open(mission.path, encoding="utf-8").read()
    assert main(["budget", "mission", "--short", "--serial", "--apply", "--out", str(out)]) in (0, 1)
    assert fake_engines == [] and sorted(e for e, _ in fake_flights) == sorted([A, A, B, B])
    phases = [load_case(p).variant(True) for p in mission.variant(True).phases]
    for engine in (A, B):
        refined = [opts for e, opts in fake_flights if e == engine and any(opts.values())]
        assert refined == [{ph.name: plugin(engine).refined_options(ph) for ph in phases}]
    assert refined[0]["p2_capture_regrasp"] == refined[0]["p3_com_alignment"]  # Exudyn: half step in both
    ref_refined = next(opts for e, opts in fake_flights if e == A and any(opts.values()))
    assert ref_refined["p2_capture_regrasp"]["rtol"] != ref_refined["p3_com_alignment"]["rtol"]

    entry = json.loads(out.read_text())["variants"]["short"]["mission"]
    expected = [(f"mission/{ph.name}", s.observable, s.tolerance)
                for ph in phases for s in collect.phase_specs(mission, True, ph)]
    assert [(r["case"], r["observable"]) for r in entry["rows"]] == [(c, o) for c, o, _ in expected]
    for r, (_, obs, tol) in zip(entry["rows"], expected):
        if obs in ("ee1_pos_B", "ee2_pos_B"):  # offset everywhere: d0 = the model difference
            assert r["model_difference"] == pytest.approx(2e-8) and r["inherited"] == pytest.approx(2e-8)
            assert r["tolerance"] == pytest.approx(tol + 2e-8)
            if r["case"] == "mission/p2_capture_regrasp":  # the refined flights depart in the first phase
                assert r["integration_error"] == {A: pytest.approx(1e-9), B: pytest.approx(2e-8)}
                assert r["integration_inherited"] == {A: 0, B: 0}
                # the row's own tolerance: 3 × what the phase and the steps add to d0 (2.1e-8)
                assert r["suggested_tolerance"] == 6.3e-8 and "3 × (budget − d0)" in r["suggested_why"]
            else:  # and carry that into the later ones, which add nothing
                assert r["integration_error"] == {A: 0, B: 0}
                assert r["integration_inherited"] == {A: pytest.approx(1e-9), B: pytest.approx(2e-8)}
                assert r["budget"] == pytest.approx(2e-8) and r["suggested_tolerance"] is None
        else:
            assert r["model_difference"] == 0 and r["tolerance"] == tol
    stdout = capsys.readouterr().out
    assert "p2_capture_regrasp: ee1_pos_B" in stdout and "mission/p2_capture_regrasp ee1_pos_B" not in stdout
    assert "mission.toml: nothing set: a sequence's phase rows" in stdout
    assert open(mission.path, encoding="utf-8").read() == before


def test_apply_with_another_pair_records_only_its_engines_own_errors(fake_engines, tmp_path, capsys, monkeypatch):
    """`--apply --engines mujoco,reference`: the rows keep their tolerance, allowance, stated
    errors and why (another pair's model difference never becomes every pair's allowance); each budgeted row gains `engine_errors = { mujoco = ε }`, ε measured
    against the engine's refined run, and a check then needs no refined run of it."""
    from rsmcheck.orchestration.compare import needs_error

    cases = tmp_path / "cases"
    cases.mkdir()
    text = open(load_case("p1_rigid_gains").path, encoding="utf-8").read().replace(
        'name = "p1_rigid_gains"', 'name = "p1_copy"')
    # without the other engines' errors the case file may record already
    text = "".join(ln for ln in text.splitlines(keepends=True) if not ln.startswith("engine_errors = "))
    (cases / "p1_copy.toml").write_text(text, encoding="utf-8")
    monkeypatch.setitem(SYNTHETIC, ("mujoco", False), (3e-8, 68.1))
    monkeypatch.setitem(SYNTHETIC, ("mujoco", True), (3.5e-8, 68.12))
    before = load_case(str(cases / "p1_copy.toml")).variant(True)
    assert needs_error(before, "mujoco")
    main(["--cases-dir", str(cases), "budget", "p1_copy", "--short", "--serial", "--apply",
          "--engines", "mujoco,reference", "--out", str(tmp_path / "budget.json")])
    assert "p1_copy.toml: set " in capsys.readouterr().out
    after = load_case(str(cases / "p1_copy.toml")).variant(True)
    assert not needs_error(after, "mujoco")
    for old, new in zip(before.compare, after.compare):
        assert (new.tolerance, new.allowance, dict(new.errors), new.why) == \
               (old.tolerance, old.allowance, dict(old.errors), old.why)
        if old.allowance is not None:
            assert set(new.engine_errors) == {"mujoco"} and new.engine_errors["mujoco"] > 0.0
    new_lines = (cases / "p1_copy.toml").read_text(encoding="utf-8").splitlines()
    assert [ln for ln in new_lines if ln not in text.splitlines()] == \
           [ln for ln in new_lines if ln.startswith("engine_errors = { mujoco = ")]
