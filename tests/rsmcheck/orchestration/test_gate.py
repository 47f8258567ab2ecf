"""The regression gate (docs/gate.md): goldens written and read back with their provenance,
gate tolerances measured from a perturbed run, moved results found with the observable and
the first time, changed inputs reported as such, bad goldens and a bless without a reason
stopped with exit 2."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from reference_model.engine import ReferenceEngine
from rsmcheck.core.cases import load_case
from rsmcheck.cli import main
from rsmcheck.orchestration.gate import (
    PERTURBATION,
    STEP_FACTOR,
    STEP_PERTURBATION,
    WORK_SLACK,
    WORK_TOL,
    WorkChange,
    compare_with_golden,
    golden_path,
    kept_samples,
    measured_tolerances,
    perturbed_case,
    read_golden,
    step_perturbed_case,
    summarize_change,
    write_golden,
)
from rsmcheck.driver.runner import run
from rsmcheck.core.store import Event

TINY = """\
name = "tiny"
description = "a tiny valid case for the gate"
duration = 0.05
[initial]
grasp = [1, 0]
joint_rates = [0.05, -0.05, 0.05, 0.0, 0.0, 0.0]
[solver]
control_period = 1e-3
output_period = 1e-3
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    d = tmp_path_factory.mktemp("gate")
    path = d / "tiny.toml"
    path.write_text(TINY)
    return load_case(path).variant(True), d


@pytest.fixture(scope="module")
def tiny_runs(tiny):
    case, _ = tiny
    nominal = run(ReferenceEngine(case), case, case.duration)
    pert = perturbed_case(case)
    perturbed = run(ReferenceEngine(pert), pert, pert.duration)
    return nominal, perturbed


def test_kept_samples_stride_and_keep_the_last():
    assert kept_samples(5, 100).tolist() == [0, 1, 2, 3, 4]
    idx = kept_samples(1001, 100)
    assert len(idx) <= 101 and idx[0] == 0 and idx[-1] == 1000
    assert np.all(np.diff(idx)[:-1] == 11)


def test_perturbation_scales_every_mass_and_nothing_else(tiny):
    case, _ = tiny
    p0, p1 = case.params, perturbed_case(case).params
    for section in ("base", "target", "link"):
        assert getattr(p1, section).mass == pytest.approx(getattr(p0, section).mass * (1 + PERTURBATION), rel=1e-15)
        assert getattr(p1, section).mass != getattr(p0, section).mass
    assert p1.motor == p0.motor and p1.geometry == p0.geometry


def test_gate_tolerances_are_measured_from_the_perturbed_run(tiny_runs):
    nominal, perturbed = tiny_runs
    m = measured_tolerances(nominal, perturbed)
    tol, delta = m.tolerance, m.mass
    assert all(v == 0.0 for v in m.path.values()) and m.per_path == {}  # no code-path runs: no bound from them
    assert m.step is None  # no step-perturbed run: no bound from it
    # the perturbation moves the dynamics, but only at its own relative size
    assert 0 < delta["base_pose_I"] < 1e-9
    assert tol["base_pose_I"] >= 10 * delta["base_pose_I"]
    assert delta["time"] == 0 and tol["time"] > 0  # the floor: never a zero tolerance


def test_the_step_perturbation_changes_only_rtol_and_bounds_the_tolerance(tiny, tiny_runs):
    """The reference's third bless run: rtol × (1 + STEP_PERTURBATION), nothing else of the
    reference (Exudyn's Newton tolerance is scaled as well, next test); it takes
    another step sequence (other step sizes: the run differs), and STEP_FACTOR × its
    change is a lower bound of every gate tolerance.  The tiny case moves its arm, so that
    the steps are the error control's, not the control period's."""
    case, _ = tiny
    stepped_case = step_perturbed_case(case)
    assert stepped_case.engine_settings["reference"].rtol == pytest.approx(case.engine_settings["reference"].rtol * (1 + STEP_PERTURBATION), rel=1e-15)
    assert stepped_case.params == case.params and stepped_case.initial == case.initial
    nominal, perturbed = tiny_runs
    engine = ReferenceEngine(stepped_case)
    stepped = run(engine, stepped_case, stepped_case.duration)
    assert engine.steps > 2 * len(stepped.observables["time"])  # error control sets the steps
    m = measured_tolerances(nominal, perturbed, stepped)
    tol, delta_step = m.tolerance, m.step
    assert delta_step["ee2_pos_B"] > 0.0
    for name, d in delta_step.items():
        assert tol[name] >= STEP_FACTOR * d, name


def test_the_step_perturbation_moves_exudyn_s_newton_stops_and_bounds_the_tolerance():
    """Exudyn's third bless run: its absolute Newton tolerance × (1 + STEP_PERTURBATION),
    whichever it is (the case's, or the engine's default), and nothing else of the model.
    Where a step's residual lands between the two tolerances the iteration stops at another
    point (closed_squeeze, 0.5 s: one Newton iteration fewer), and STEP_FACTOR × the change
    this causes is a lower bound of every gate tolerance.  Without this run a golden of
    release measured only the mass perturbation, which flipped no stop there, and another CPU
    moved its link deflection 279 × past the tolerance (docs/gate.md)."""
    from exudyn_model.engine import ExudynEngine

    case = load_case("closed_squeeze").variant(True)
    stepped_case = step_perturbed_case(case)
    assert stepped_case.params == case.params and stepped_case.initial == case.initial
    assert case.engine_settings["exudyn"].newton_atol_scale is None  # a case file cannot set it
    assert dataclasses.replace(stepped_case.engine_settings["exudyn"], newton_atol_scale=None) == case.engine_settings["exudyn"]
    nominal_engine, stepped_engine = ExudynEngine(case), ExudynEngine(stepped_case)
    assert stepped_engine.newton_atol == pytest.approx(nominal_engine.newton_atol * (1 + STEP_PERTURBATION),
                                                       rel=1e-15)
    explicit = ExudynEngine(stepped_case, newton_atol=2e-3)
    assert explicit.newton_atol == pytest.approx(2e-3 * (1 + STEP_PERTURBATION), rel=1e-15)
    nominal = run(nominal_engine, case, 0.5)
    perturbed = run(ExudynEngine(perturbed_case(case)), perturbed_case(case), 0.5)
    stepped = run(stepped_engine, stepped_case, 0.5)
    assert stepped.solver["newton_iterations"] != nominal.solver["newton_iterations"]
    m = measured_tolerances(nominal, perturbed, stepped)
    tol, delta_step = m.tolerance, m.step
    assert delta_step["joint_angles"] > 0.0
    for name, d in delta_step.items():
        assert tol[name] >= STEP_FACTOR * d, name


def test_a_code_path_s_change_bounds_the_tolerance_and_is_stored(tiny, tiny_runs, tmp_path):
    """PATH_FACTOR × the largest change among the code-path runs is a lower bound of every
    gate tolerance; the golden keeps each path's change, and the tolerance table says which
    bound sets each tolerance."""
    from rsmcheck.orchestration.gate import PATH_FACTOR, tolerance_table

    case, _ = tiny
    nominal, perturbed = tiny_runs
    obs = {k: v.copy() for k, v in nominal.observables.items()}
    obs["ee1_pos_B"][40:, 0] += 1e-7  # another CPU's run, here one that moved an end effector
    other = dataclasses.replace(nominal, observables=obs)
    m = measured_tolerances(nominal, perturbed, None, {"x86-64-v3": other, "blas-1-thread": nominal})
    assert m.per_path["x86-64-v3"]["ee1_pos_B"] == pytest.approx(1e-7, rel=1e-6)
    assert m.per_path["blas-1-thread"]["ee1_pos_B"] == 0.0 and m.path["ee1_pos_B"] == m.per_path["x86-64-v3"]["ee1_pos_B"]
    assert m.tolerance["ee1_pos_B"] == PATH_FACTOR * m.path["ee1_pos_B"]
    write_golden(golden_path(case.name, "reference", tmp_path), case, nominal, m, "test")
    rows = {r["observable"]: r for r in tolerance_table([case], ["reference"], tmp_path)}
    assert rows["ee1_pos_B"]["set_by"] == "code paths" and rows["time"]["set_by"] == "floor"
    assert rows["ee1_pos_B"]["paths"] == {"x86-64-v3": m.per_path["x86-64-v3"]["ee1_pos_B"], "blas-1-thread": 0.0}
    assert np.isnan(rows["ee1_pos_B"]["step_change"])  # blessed without a step-perturbed run


def test_golden_round_trip_and_verdicts(tiny, tiny_runs, tmp_path):
    case, _ = tiny
    nominal, perturbed = tiny_runs
    path = write_golden(golden_path(case.name, "reference", tmp_path), case, nominal, measured_tolerances(nominal, perturbed), "test")
    g = read_golden(path, "reference")
    for key in ("case_hash", "param_hash", "git_commit", "reason", "blessed_utc", "platform", "version.numpy"):
        assert g.attrs[key], key
    assert g.run.versions["numba"]  # the engine's package versions travel with the run
    assert compare_with_golden(case, nominal, g).unchanged
    assert compare_with_golden(case, perturbed, g).unchanged  # reproducibility level passes

    # a moved observable: which one, by how much, from when
    obs = {k: v.copy() for k, v in nominal.observables.items()}
    obs["ee2_pos_B"][30:, 1] += 1e-6
    res = compare_with_golden(case, dataclasses.replace(nominal, observables=obs), g)
    assert [m.observable for m in res.moved] == ["ee2_pos_B"]
    m = res.moved[0]
    assert m.change == pytest.approx(1e-6, rel=1e-6) and m.component == 1
    t_kept = nominal.observables["time"][g.index]
    assert m.first_time == t_kept[t_kept >= nominal.observables["time"][30]][0]
    # what the report reads: the ratio travels with the dict
    assert res.as_dict()["moved"][0]["ratio"] == pytest.approx(m.change / m.tolerance)

    # changed inputs are reported as such, not as numbers; reworded prose or a new
    # [compare] row is not a change
    path = Path(case.path)
    text = path.read_text()
    try:
        path.write_text(text.replace("a tiny valid case for the gate", "reworded") + "# a comment\n"
                        + '[compare.ee1_pos_B]\nmetric = "max_abs"\ntolerance = 1e-6\nwhy = "a new row"\n')
        assert compare_with_golden(case, nominal, g).unchanged  # a [compare] row is not a run input
        path.write_text(text.replace("output_period = 1e-3", "output_period = 2e-3"))
        res = compare_with_golden(case, nominal, g)
        assert res.inputs_changed and not res.moved and not res.unchanged
    finally:
        path.write_text(text)

    # a different time grid or event list is structural
    short = dataclasses.replace(nominal, observables={k: v[:-1] for k, v in nominal.observables.items()})
    assert compare_with_golden(case, short, g).structure
    capture = Event(0.5, "capture", "arm=2 impact_loss_J=5.83965e-05 gap_m=0.00139951")
    with_capture = dataclasses.replace(g.run, events=[capture])
    g_capture = dataclasses.replace(g, run=with_capture)
    # the last printed digit of a measured value is round-off, not structure ...
    roundoff = dataclasses.replace(capture, detail="arm=2 impact_loss_J=5.83966e-05 gap_m=0.00139952")
    assert compare_with_golden(case, dataclasses.replace(nominal, events=[roundoff]), g_capture).unchanged
    # ... the other arm, a later sample or another kind of event is
    for other in (dataclasses.replace(capture, detail="arm=1 impact_loss_J=5.83965e-05 gap_m=0.00139951"),
                  dataclasses.replace(capture, time=0.501), dataclasses.replace(capture, kind="release")):
        assert compare_with_golden(case, dataclasses.replace(nominal, events=[other]), g_capture).structure
    arm1 = dataclasses.replace(capture, detail="arm=1 impact_loss_J=5.83965e-05 gap_m=0.00139951")
    assert compare_with_golden(case, dataclasses.replace(nominal, events=[arm1]), g_capture).structure == [
        "event 'capture' at 0.5 s: 'arm=2 impact_loss_J gap_m' → 'arm=1 impact_loss_J gap_m'"]


def test_work_limit_counts_and_small_counts():
    assert WorkChange("steps", 1000, 1000).limit == 1000 + int(1000 * WORK_TOL) + WORK_SLACK
    assert not WorkChange("steps", 100_000, 105_000).grew and WorkChange("steps", 100_000, 105_004).grew
    # a few Jacobians may move by the slack, not by a percentage of a handful
    assert not WorkChange("Jacobians", 6, 6 + WORK_SLACK).grew and WorkChange("Jacobians", 6, 7 + WORK_SLACK).grew
    assert WorkChange("Jacobians", 0, 0).relative == 0.0 and WorkChange("Jacobians", 0, 4).grew
    w = WorkChange("Newton iterations", 177_497, 200_000)
    assert w.describe() == "Newton iterations 177 497 → 200 000 (+12.68%)"
    assert w.ratio == pytest.approx((200_000 - 177_497) / (w.limit - 177_497))
    assert WorkChange("steps", 1000, 10).ratio == 0.0  # less work is not a growth


def test_the_gate_sees_more_work_and_records_less(tiny, tiny_runs, tmp_path):
    case, _ = tiny
    nominal, perturbed = tiny_runs
    g = read_golden(write_golden(tmp_path / "g.h5", case, nominal, measured_tolerances(nominal, perturbed), "test"), "reference")
    res = compare_with_golden(case, nominal, g)
    assert [w.counter for w in res.work] == ["attempted steps", "Jacobians"]
    assert all(w.relative == 0.0 for w in res.work) and res.unchanged
    attempted = nominal.solver["steps"] + nominal.solver["rejected_steps"]

    def with_steps(n):
        return dataclasses.replace(nominal, solver={**nominal.solver, "steps": n - nominal.solver["rejected_steps"]})

    # the same trajectories with more steps than the limit: moved, on the work alone
    limit = WorkChange("attempted steps", attempted, attempted).limit
    assert compare_with_golden(case, with_steps(limit), g).unchanged
    res = compare_with_golden(case, with_steps(limit + 1), g)
    assert not res.unchanged and not res.moved and [w.counter for w in res.more_work] == ["attempted steps"]
    assert res.work_ratio > 1.0 and res.as_dict()["work"][0]["grew"]
    # half the work passes, and a bless records it in the changelog
    half = with_steps(attempted // 2)
    assert compare_with_golden(case, half, g).unchanged
    assert summarize_change(g, half, case) == [
        "work: " + WorkChange("attempted steps", attempted, attempted // 2).describe()]
    # a golden without the counter is not compared on it
    old = dataclasses.replace(g, run=dataclasses.replace(g.run, solver={}))
    assert compare_with_golden(case, with_steps(10 * attempted), old).work == []


def test_bad_goldens_are_input_errors(tiny, tiny_runs, tmp_path):
    from rsmcheck.core.errors import InputError

    case, _ = tiny
    with pytest.raises(InputError, match="bless it first"):
        read_golden(tmp_path / "nothing.h5", "reference")
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    with pytest.raises(InputError, match="not an HDF5 file"):
        read_golden(tmp_path / "junk.h5", "reference")
    nominal, perturbed = tiny_runs
    path = write_golden(tmp_path / "g.h5", case, nominal, measured_tolerances(nominal, perturbed), "test")
    with h5py.File(path, "a") as f:
        f.attrs["golden_schema"] = 99
    with pytest.raises(InputError, match="golden_schema"):
        read_golden(path, "reference")


def test_cli_bless_gate_unchanged_moved_and_bad_input(tiny, tmp_path, capsys):
    case, _ = tiny
    goldens = tmp_path / "goldens"
    args = [str(case.path), "--engines", "reference", "--goldens", str(goldens)]
    one_path = ["--code-paths", "blas-1-thread"]  # the others compile every kernel anew (test_code_paths.py)
    assert main(["bless", *args]) == 2  # no reason, no bless
    assert "--reason" in capsys.readouterr().err
    assert not goldens.exists()
    assert main(["gate", *args]) == 2  # no golden yet
    assert "bless it first" in capsys.readouterr().err
    assert main(["bless", *args, "--code-paths", "x86-64-v9", "--reason", "r"]) == 2  # no such path
    assert "x86-64-v9" in capsys.readouterr().err and not goldens.exists()
    assert main(["bless", *args, *one_path, "--reason", "first goldens of the tiny case"]) == 0
    log = (goldens / "CHANGELOG.md").read_text()
    assert "first goldens of the tiny case" in log and "tiny / reference**: new golden" in log
    assert main(["gate", *args]) == 0
    assert "unchanged" in capsys.readouterr().out
    g = read_golden(golden_path("tiny", "reference", goldens), "reference")
    assert g.attrs["code_paths"] == "blas-1-thread" and g.attrs["path_factor"] == 3.0
    assert main(["gate", *args, "--tolerances", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["tolerances"]
    assert all(set(r["paths"]) == {"blas-1-thread"} and r["path_change"] == r["paths"]["blas-1-thread"] for r in rows)
    assert all(r["set_by"] in ("masses", "decisions", "code paths", "floor") for r in rows)
    assert {r["set_by"] for r in rows} >= {"masses", "floor"}

    # one stored value off by 1 µm: the gate says what moved and exits 1
    path = golden_path("tiny", "reference", goldens)
    with h5py.File(path, "a") as f:
        f["reference/ee1_pos_B"][20, 0] += 1e-6
    assert main(["gate", *args]) == 1
    out = capsys.readouterr().out
    assert "MOVED" in out and "ee1_pos_B" in out

    # a golden that took a tenth fewer steps: the run does more work than it, exit 1
    with h5py.File(path, "a") as f:
        f["reference/ee1_pos_B"][20, 0] -= 1e-6
        f["reference"].attrs["solver.steps"] = int(0.9 * f["reference"].attrs["solver.steps"])
    assert main(["gate", *args]) == 1
    out = capsys.readouterr().out
    assert "MOVED" in out and "more work: attempted steps" in out and "ee1_pos_B" not in out
    with h5py.File(path, "a") as f:
        f["reference/ee1_pos_B"][20, 0] += 1e-6

    # re-blessing records what moved in the changelog, newest entry first
    assert main(["bless", *args, *one_path, "--reason", "restore the tiny golden"]) == 0
    log = (goldens / "CHANGELOG.md").read_text()
    assert log.index("restore the tiny golden") < log.index("first goldens of the tiny case")
    assert "ee1_pos_B: changed by 1.000e-06" in log
