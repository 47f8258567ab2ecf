"""rsmcheck.orchestration.compare: the metrics of the [compare] tables, margins, the relative
differences with their floors, and the `check` command's exit codes and JSON (docs/commands.md)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from rsmcheck.core.cases import CompareSpec, list_cases, load_case
from rsmcheck.cli import main
from rsmcheck.orchestration.compare import (METRICS, SCALE_FLOORS, Check, check_runs, compare_runs, difference,
                              growth_rate, relative_errors)
from rsmcheck.core.observables import NAMES, allocate
from rsmcheck.core.store import EngineRun, Event


def make_run(engine: str, n: int = 5, **values) -> EngineRun:
    obs = allocate(n)
    obs["time"] = np.arange(n) * 0.01
    for k, v in values.items():
        obs[k] = np.asarray(v, float).reshape(obs[k].shape)
    return EngineRun(engine=engine, observables=obs)


def test_every_metric_a_case_may_ask_for_is_computed():
    """rsmcheck.core.cases.METRICS (what the loader accepts) is what `difference` computes."""
    t = np.arange(0.0, 2.0, 0.01)
    obs = np.exp(0.1 * t)[:, None] * np.ones((1, 6))
    ref, other = make_run("reference", n=t.size, joint_angles=obs), make_run("exudyn", n=t.size, joint_angles=2 * obs)
    ref.observables["time"] = other.observables["time"] = t
    for metric in METRICS:
        err, _, _ = difference(ref, other, "joint_angles", metric, window=(0.5, 1.5))
        assert math.isfinite(err), metric
    with pytest.raises(ValueError, match="unknown metric"):
        difference(ref, other, "joint_angles", "median")


def test_max_abs_rms_final():
    a = np.zeros((5, 6))
    b = np.zeros((5, 6))
    b[1, 2] = 3e-3  # the worst sample, component 2
    b[4, 5] = 1e-3  # the last sample, component 5
    ref, other = make_run("reference", joint_angles=a), make_run("exudyn", joint_angles=b)
    err, t, c = difference(ref, other, "joint_angles", "max_abs")
    assert (err, t, c) == (pytest.approx(3e-3), pytest.approx(0.01), 2)
    err, t, c = difference(ref, other, "joint_angles", "final")
    assert (err, t, c) == (pytest.approx(1e-3), pytest.approx(0.04), 5)
    err, t, c = difference(ref, other, "joint_angles", "rms")
    assert err == pytest.approx(3e-3 / math.sqrt(5)) and c == 2 and math.isnan(t)


def test_a_window_limits_max_abs_and_rms_to_its_samples():
    """Samples outside [t0, t1] do not count; the worst sample inside is found and named;
    a window without a sample is an error, not a silent zero."""
    a = np.zeros((5, 6))
    b = np.zeros((5, 6))
    b[1, 2] = 3e-3  # t = 0.01 s: inside [0, 0.02]
    b[3, 4] = 5e-2  # t = 0.03 s: a stop contact after the window
    ref, other = make_run("reference", joint_angles=a), make_run("exudyn", joint_angles=b)
    assert difference(ref, other, "joint_angles", "max_abs")[0] == pytest.approx(5e-2)
    err, t, c = difference(ref, other, "joint_angles", "max_abs", window=(0.0, 0.02))
    assert (err, t, c) == (pytest.approx(3e-3), pytest.approx(0.01), 2)
    err, _, _ = difference(ref, other, "joint_angles", "rms", window=(0.0, 0.02))
    assert err == pytest.approx(3e-3 / math.sqrt(3))
    with pytest.raises(ValueError, match="no sample in the window"):
        difference(ref, other, "joint_angles", "max_abs", window=(0.011, 0.019))


def test_windowed_row_carries_its_window():
    case = dataclasses.replace(load_case("release"),
                               compare=(CompareSpec("joint_angles", 1e-2, "before the stop", window=(0.0, 0.02)),))
    b = np.zeros((5, 6))
    b[4, 0] = 1.0  # after the window
    (row,) = check_runs(case, make_run("reference", joint_angles=np.zeros((5, 6))),
                        make_run("exudyn", joint_angles=b))
    assert row.passed and row.error == 0.0 and row.as_dict()["window"] == [0.0, 0.02]
    assert row.metric_label == "max_abs [0, 0.02] s"


def test_growth_rate_of_a_sampled_oscillation():
    """σ of e^{σt}·|sin(2π·92 t)| sampled at 10 Hz (the rotor mode in p1_rigid_gains' output):
    the block maxima recover σ; two runs with different σ differ by exactly that."""
    t = np.arange(0.0, 20.0 + 1e-9, 0.1)
    osc = np.abs(np.sin(2 * np.pi * 92.0 * t + 0.3)) + 0.0  # phase at each sample: random-like
    runs = {}
    for name, sigma in (("reference", 0.55), ("exudyn", 0.45)):
        obs = allocate(t.size)
        obs["time"] = t
        obs["motor_torques"][:, 4] = 1e-3 * np.exp(sigma * t) * osc
        runs[name] = EngineRun(engine=name, observables=obs)
    assert growth_rate(t, runs["reference"].observables["motor_torques"], (8.0, 18.0)) == pytest.approx(0.55, abs=0.01)
    err, tw, c = difference(runs["reference"], runs["exudyn"], "motor_torques", "growth", window=(8.0, 18.0))
    assert err == pytest.approx(0.10, abs=0.01) and math.isnan(tw)
    with pytest.raises(ValueError, match="window"):
        difference(runs["reference"], runs["exudyn"], "motor_torques", "growth")
    with pytest.raises(ValueError, match="no sample"):
        growth_rate(t, runs["reference"].observables["motor_torques"], (30.0, 40.0))


def test_growth_check_reports_both_rates():
    t = np.arange(0.0, 10.0 + 1e-9, 0.01)
    ref = make_run("reference", n=t.size, ee2_speed=np.exp(0.5 * t))
    other = make_run("exudyn", n=t.size, ee2_speed=np.exp(0.2 * t))
    ref.observables["time"] = other.observables["time"] = t
    spec = CompareSpec("ee2_speed", 0.02, "w", "growth", (2.0, 8.0))
    case = dataclasses.replace(load_case(list_cases()[0]), compare=(spec,))
    (row,) = check_runs(case, ref, other)
    assert row.error == pytest.approx(0.3, rel=1e-6) and not row.passed
    d = row.as_dict()
    assert d["growth_rates"]["reference"] == pytest.approx(0.5) and d["growth_rates"]["exudyn"] == pytest.approx(0.2)
    json.dumps(d, allow_nan=False)


def test_scalar_observable_and_non_finite():
    ref = make_run("reference", ee2_speed=[0, 1, 2, 3, 4])
    other = make_run("exudyn", ee2_speed=[0, 1, 2, np.nan, 4])
    err, t, _ = difference(ref, other, "ee2_speed")
    assert err == math.inf and t == pytest.approx(0.03)


def test_unknown_metric_and_observable():
    ref, other = make_run("reference"), make_run("exudyn")
    with pytest.raises(ValueError, match="metric"):
        difference(ref, other, "energy", "mean")
    with pytest.raises(ValueError, match="observable"):
        difference(ref, other, "torque_ripple")


def test_different_sampling_is_refused():
    with pytest.raises(ValueError, match="same times"):
        difference(make_run("reference", n=5), make_run("exudyn", n=6), "energy")


def test_check_row_margin_pass_and_json():
    row = Check("c", "energy", error=2e-3, tolerance=1e-2, metric="max_abs", why="w")
    assert row.passed and row.margin == pytest.approx(5.0)
    d = row.as_dict()
    for key in ("case", "observable", "error", "tolerance", "margin", "pass"):
        assert key in d
    assert json.loads(json.dumps(d))["pass"] is True
    bad = Check("c", "energy", error=math.inf, tolerance=1e-2)
    assert not bad.passed and bad.margin == 0.0
    assert json.dumps(bad.as_dict(), allow_nan=False)  # inf/NaN are spelled out for JSON
    exact = Check("c", "energy", error=0.0, tolerance=1e-2)
    assert exact.passed and json.dumps(exact.as_dict(), allow_nan=False)


def test_check_runs_uses_the_case_table():
    case = load_case("release")
    spec = (CompareSpec("grasp_state", 0.5, "flags", "final"), CompareSpec("momentum_I", 1e-6, "conserved"))
    case = dataclasses.replace(case, compare=spec)
    g_ref = np.array([[1, 1], [1, 1], [1, 0], [1, 0], [1, 0]])
    g_exu = np.array([[1, 1], [1, 0], [1, 0], [1, 0], [1, 0]])  # released one sample early
    ref = make_run("reference", grasp_state=g_ref, momentum_I=np.full((5, 3), 2.0))
    exu = make_run("exudyn", grasp_state=g_exu, momentum_I=np.full((5, 3), 2.0 + 2e-6))
    rows = {r.observable: r for r in check_runs(case, ref, exu)}
    assert rows["grasp_state"].passed and rows["grasp_state"].error == 0.0  # final: both released
    assert not rows["momentum_I"].passed and rows["momentum_I"].error == pytest.approx(2e-6)
    assert rows["momentum_I"].reference_range == pytest.approx(2.0)
    assert rows["momentum_I"].why == "conserved"


def _released_at_sample_2(jump: float, later: float = 0.0):
    """Reaction forces of two runs whose grasp 2 lets go at sample 2 (t = 0.02 s): the
    reference's remaining grasp-1 force jumps there by `jump`, the other's only a sample
    later, where they differ by `later`."""
    f_ref = np.tile([-10.0, 3.0, 10.0, -3.0], (5, 1))
    f_ref[2:, 0] -= jump
    f_ref[2:, 2:] = 0.0
    f_exu = f_ref.copy()
    f_exu[2, 0] += jump  # the left limit at the switch sample
    f_exu[3, 0] += later
    case = dataclasses.replace(load_case("release"), compare=(
        CompareSpec("reaction_forces_I", 0.05, "squeeze"), CompareSpec("joint_angles", 1e-6, "angles")))
    angles = np.zeros((5, 6))
    ref = make_run("reference", reaction_forces_I=f_ref, joint_angles=angles)
    exu = make_run("exudyn", reaction_forces_I=f_exu, joint_angles=angles + np.where(np.arange(5) == 2, 1e-5, 0)[:, None])
    for r in (ref, exu):
        r.events.append(Event(0.02, "release", "arm=2"))
    return case, ref, exu


def test_multiplier_at_a_constraint_switch_is_reported_not_compared():
    """docs/physics.md §4.2 item 4: at a release the rigid-link reference's multiplier jumps,
    the penalty-EA one reaches the same value a sample later."""
    case, ref, exu = _released_at_sample_2(jump=0.9)
    rows = {r.observable: r for r in check_runs(case, ref, exu)}
    forces = rows["reaction_forces_I"]
    assert forces.passed and forces.error == 0.0
    assert forces.at_switches == ((pytest.approx(0.02), pytest.approx(0.9)),)
    assert "t = 0.02 s: 0.9" in forces.switch_note()
    assert json.loads(json.dumps(forces.as_dict()))["at_switches"] == [{"time": 0.02, "error": pytest.approx(0.9)}]
    # only multipliers: a joint angle off at the switch sample is a failure
    assert not rows["joint_angles"].passed and rows["joint_angles"].worst_time == pytest.approx(0.02)
    assert rows["joint_angles"].at_switches == ()


def test_multiplier_after_a_constraint_switch_is_compared():
    case, ref, exu = _released_at_sample_2(jump=0.9, later=0.2)
    forces = next(r for r in check_runs(case, ref, exu) if r.observable == "reaction_forces_I")
    assert not forces.passed and forces.error == pytest.approx(0.2) and forces.worst_time == pytest.approx(0.03)


def test_multiplier_blowing_up_at_a_switch_is_not_left_out():
    case, ref, exu = _released_at_sample_2(jump=0.9)
    exu.observables["reaction_forces_I"][2, 1] = np.nan
    forces = next(r for r in check_runs(case, ref, exu) if r.observable == "reaction_forces_I")
    assert forces.error == math.inf and not forces.passed and forces.at_switches == ()


def _regrasp(ref_start: float, exu_start: float, exu_events: tuple[str, ...] = ("regrasp",)):
    """capture_gap_B of two runs sampled every 0.1 s that enter a segment 'regrasp' (a new
    designated point: the gap jumps from the 2 mm grasp offset to 0.25 m) at `ref_start`
    and `exu_start`; `exu_events`: the segments the other engine reports."""
    case = dataclasses.replace(load_case("p2_capture_regrasp"), compare=(
        CompareSpec("capture_gap_B", 1e-5, "gap"), CompareSpec("ee1_pos_B", 1e-6, "hand")))
    ref, exu = _regrasp_runs(ref_start, exu_start, exu_events)
    return {r.observable: r for r in check_runs(case, ref, exu)}


def _regrasp_runs(ref_start: float, exu_start: float, exu_events: tuple[str, ...] = ("regrasp",)):
    t = np.arange(6) * 0.1

    def gap(t0):
        return np.where(t[:, None] >= t0, [[-0.25, 0.0]], [[-0.002, 0.0]])

    ref = make_run("reference", n=6, capture_gap_B=gap(ref_start))
    exu = make_run("exudyn", n=6, capture_gap_B=gap(exu_start))
    ref.events.append(Event(ref_start, "segment", "regrasp"))
    exu.events.extend(Event(exu_start, "segment", name) for name in exu_events)
    for r in (ref, exu):
        r.observables["time"] = t
    return ref, exu


def test_samples_between_the_engines_instants_of_one_event_are_reported_not_compared():
    """The chained full mission: the regrasp segment starts 17 ms apart in the two engines,
    and the one sample between compares a grasp offset with an approach gap (docs/cases.md §6)."""
    rows = _regrasp(0.294, 0.311)
    gap = rows["capture_gap_B"]
    assert gap.passed and gap.error == 0.0
    assert gap.between_events == ((pytest.approx(0.3), pytest.approx(0.248)),)
    assert gap.event_skew == pytest.approx(0.017)
    assert "at most 17 ms apart (t = 0.3 s: 0.248)" in gap.switch_note()
    doc = json.loads(json.dumps(gap.as_dict()))
    assert doc["between_events"] == [{"time": pytest.approx(0.3), "error": pytest.approx(0.248)}]
    assert rows["ee1_pos_B"].between_events == ()  # only observables defined by the segment


@pytest.mark.parametrize("exu_start, exu_events", [
    (0.411, ("regrasp",)),  # 117 ms after the reference: later than EVENT_SKEW_MAX
    (0.311, ("regrasp", "hold")),  # a segment the reference never entered
    (0.311, ("retreat",)),  # another segment
])
def test_a_late_or_different_event_is_compared(exu_start, exu_events):
    gap = _regrasp(0.294, exu_start, exu_events)["capture_gap_B"]
    assert not gap.passed and gap.error == pytest.approx(0.248) and gap.between_events == ()


def test_samples_outside_a_window_are_neither_left_out_nor_listed():
    rows = _regrasp(0.294, 0.311)
    case = dataclasses.replace(load_case("p2_capture_regrasp"), compare=(
        CompareSpec("capture_gap_B", 1e-5, "gap", window=(0.0, 0.2)),))
    ref, exu = _regrasp_runs(0.294, 0.311)
    gap = check_runs(case, ref, exu)[0]
    assert gap.passed and gap.between_events == () and gap.event_skew == 0.0
    assert rows["capture_gap_B"].between_events  # the same runs without the window


def test_the_same_instant_leaves_nothing_out():
    gap = _regrasp(0.3, 0.3)["capture_gap_B"]
    assert gap.passed and gap.between_events == () and gap.event_skew == 0.0


def test_relative_differences_use_the_floors():
    ref = make_run("reference", reaction_forces_I=np.zeros((5, 4)), energy=np.full((5, 3), 10.0))
    exu = make_run("exudyn", reaction_forces_I=np.full((5, 4), 1e-4), energy=np.full((5, 3), 10.001))
    rel = relative_errors("x", ref, exu, ["reaction_forces_I", "energy"])
    assert rel["reaction_forces_I"] == pytest.approx(1e-4 / SCALE_FLOORS["reaction_forces_I"])
    assert rel["energy"] == pytest.approx(1e-4)
    rows = compare_runs("x", ref, exu, {"energy": 1e-5}, t_from=0.02)
    assert rows[0].worst_time >= 0.02 and not rows[0].passed
    assert set(SCALE_FLOORS) == set(NAMES) - {"time"}


def test_every_compare_entry_names_a_metric_we_know():
    for path in list_cases():
        case = load_case(path)
        for variant in (case, case.variant(True)):
            for spec in variant.compare:
                assert spec.metric in METRICS and spec.tolerance > 0 and spec.why.strip()


# ---- the command line ----------------------------------------------------------------
def test_check_without_compare_table_is_not_a_silent_pass(capsys):
    """free_drift has no [compare] table: said explicitly, nothing compared → exit 1."""
    code = main(["check", "free_drift", "--short"])
    out, err = capsys.readouterr()
    assert code == 1
    assert "free_drift: NOT CHECKED" in out and "no [compare] table" in out
    assert "nothing was compared" in err


def test_check_json_without_compare_table(capsys):
    code = main(["check", "free_drift", "--short", "--json"])
    out, _ = capsys.readouterr()
    doc = json.loads(out)
    assert code == 1 and doc["checks"] == [] and doc["skipped"][0]["case"] == "free_drift"


@pytest.mark.parametrize("argv, field", [
    (["check", "no_such_case"], "case"),
    (["check", "flex_arm_step", "--option", "exudyn:substeps"], "substeps"),
    (["check", "flex_arm_step", "--option", "exudyn:warp=9"], "warp"),
    (["check", "flex_arm_step", "--option", "reference:n_elements=4"], "n_elements"),
])
def test_check_bad_input_exits_2(argv, field, capsys):
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert len(err.splitlines()) == 1 and field in err and "Traceback" not in err


@pytest.mark.crosscheck
def test_check_runs_both_engines():
    """A real (serial) check of the shortest case, flex_arm_step cut to its first 0.1 s:
    one row per [compare] entry with the keys docs/commands.md lists (pass/fail: tests/crosscheck)."""
    import rsmcheck.orchestration.compare as cmp

    case = load_case("flex_arm_step").variant(True)
    res, = cmp.check_cases([dataclasses.replace(case, duration=0.1, short=None)], short=False, workers=0)
    assert [r.observable for r in res.rows] == [s.observable for s in case.compare]
    for r in res.rows:
        assert math.isfinite(r.error) and r.reference_range > 0
        assert set(r.as_dict()) >= {"case", "observable", "error", "tolerance", "margin", "pass"}
    assert res.runs["reference"].observables["time"][-1] == pytest.approx(0.1)


def test_each_pair_gets_its_own_tolerance_and_departures_only_their_engines(monkeypatch):
    """check_runs judges (reference, X) by the row's parts (rsmcheck.core.tolerances):
    Exudyn's recorded error never enters another pair, X's measured error does, and a
    departure X's plug-in declares widens X's pairs only."""
    from rsmcheck.orchestration import compare

    spec = CompareSpec("momentum_I", 2e-6, "budget", allowance=5e-7, errors={"reference": 1e-7, "exudyn": 4e-7})
    case = dataclasses.replace(load_case("release"), compare=(spec,))
    k = 2e-6 / (5e-7 + 1e-7 + 4e-7)
    runs = {e: make_run(e, momentum_I=np.full((5, 3), 2.0 + d)) for e, d in
            (("reference", 0.0), ("exudyn", 1e-6), ("soft", 1.5e-6))}
    monkeypatch.setattr(compare, "departure_allowances",
                        lambda name, c: {"momentum_I": (1e-6, "a soft constraint")} if name == "soft" else {})
    (stated,) = check_runs(case, runs["reference"], runs["exudyn"])
    assert stated.tolerance == 2e-6 and stated.why == "budget" and stated.engines == ("reference", "exudyn")
    (soft,) = check_runs(case, runs["reference"], runs["soft"], measured={"soft": {"momentum_I": 3e-7}})
    assert soft.tolerance == pytest.approx(k * (5e-7 + 1e-7 + 3e-7 + 1e-6), rel=1e-12)
    assert soft.engines == ("reference", "soft") and soft.tolerance_parts.departures == (("soft", 1e-6, "a soft constraint"),)
    assert soft.why.startswith("reference against soft:") and "soft departure 1.0e-06 (a soft constraint)" in soft.why
    assert soft.as_dict()["tolerance_parts"]["errors"]["soft"] == {"value": 3e-7, "source": "measured"}
    # the in-tree pair is untouched by the plug-in's departure
    (again,) = check_runs(case, runs["reference"], runs["exudyn"], measured={"soft": {"momentum_I": 3e-7}})
    assert again.tolerance == 2e-6
