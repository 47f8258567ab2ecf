"""`rsmcheck fuzz` without the engines: the scenarios drawn, written and read back, and the
criterion on synthetic runs (the campaign itself: tests/crosscheck/test_fuzz_campaign.py)."""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.params import Params
from rsmcheck.core.store import EngineRun
from rsmcheck.driver.initial import build_initial
from rsmcheck.orchestration import fuzz
from rsmcheck.orchestration.compare import check_runs
from rsmcheck.orchestration.fuzz_scenarios import case_text, declared, draw

RANGES = declared()["ranges"]
DRAWS = [draw(7, i) for i in range(300)]


def test_a_scenario_depends_on_its_seed_and_index_only():
    assert draw(7, 12) == DRAWS[12] and draw(8, 12) != DRAWS[12] and draw(7, 13) != DRAWS[12]


def test_every_drawn_value_lies_in_its_declared_range():
    nominal, spread = RANGES["joint_angles_deg"]
    for s in DRAWS:
        assert RANGES["duration_s"][0] <= s.duration <= RANGES["duration_s"][1]
        assert all(abs(a - n) <= spread + 1e-9 for a, n in zip(s.joint_angles_deg, nominal))
        assert all(abs(r) <= h for r, h in zip(s.base_rate, RANGES["base_rate"]))
        assert max(map(abs, s.joint_rates)) <= RANGES["joint_rate"]
        # held torque + sine inside Table 4's limit, base torque inside Table 3's
        assert max(abs(t) + abs(a) for t, a in zip(s.motor_torques, s.sine_amplitude)) <= Params().motor.torque_max
        assert abs(s.base_torque) <= RANGES["base_torque"]
        assert RANGES["link_mass_factor"][0] <= s.link_mass_factor <= RANGES["link_mass_factor"][1]
        assert RANGES["link_stiffness_factor"][0] <= s.link_stiffness_factor <= RANGES["link_stiffness_factor"][1]
        assert (s.ramp_time == 0.0) == (s.torque_form == "step")
        assert (s.sine_frequency_hz > 0.0) == (s.torque_form == "sine")
    # every chain, torque form and both orbit states are drawn, in shares near their odds
    for attr, values in (("chain", RANGES["chains"]), ("torque_form", ["step", "ramp", "sine"])):
        counts = [sum(getattr(s, attr) == v for s in DRAWS) for v in values]
        assert min(counts) > 60, (attr, counts)  # 100 expected of 300
    assert 110 < sum(s.orbit for s in DRAWS) < 190


@pytest.mark.parametrize("index", range(6))
def test_the_case_file_reads_back_as_drawn(tmp_path, index):
    s = DRAWS[index]
    path = tmp_path / f"{s.name}.toml"
    path.write_text(case_text(s))
    case = load_case(path)
    assert case.name == s.name and case.duration == s.duration and case.orbit == s.orbit
    assert case.initial.grasp == s.grasp
    assert case.controller.motor_torques == s.motor_torques and case.controller.ramp_time == s.ramp_time
    assert case.controller.sine_amplitude == s.sine_amplitude
    # the link: mass and EI scaled by their factors, the extra rotary inertia keeps its sign
    p0, p = Params().link, case.params.link
    assert p.mass / p0.mass == pytest.approx(s.link_mass_factor, rel=1e-12)
    assert p.ei / p0.ei == pytest.approx(s.link_stiffness_factor, rel=1e-12)
    assert p.inertia_extra / p0.inertia_extra == pytest.approx(s.link_mass_factor, rel=1e-12)


def _run(engine: str, t: np.ndarray, **series) -> EngineRun:
    obs = {"time": t}
    obs.update(series)
    return EngineRun(engine, obs)


def _runs(scale_b: float, wobble_a: float, wobble_b: float):
    """Synthetic runs of joint_angles: A and B's default runs, A' and B' their refinements."""
    t = np.linspace(0.0, 1.0, 201)
    x = 0.5 * np.outer(t**2, np.ones(6))  # a motion of 0.5 rad
    bump = np.outer(np.sin(40 * t), np.ones(6))
    return {("reference", "default"): _run("reference", t, joint_angles=x + wobble_a * bump),
            ("reference", "finer"): _run("reference", t, joint_angles=x),
            ("exudyn", "default"): _run("exudyn", t, joint_angles=scale_b * x + wobble_b * bump),
            ("exudyn", "finer"): _run("exudyn", t, joint_angles=scale_b * x)}


@pytest.fixture
def only_joint_angles(monkeypatch):
    monkeypatch.setattr(fuzz, "observables", lambda s: ["joint_angles"])


def test_a_difference_that_refinement_explains_passes(only_joint_angles):
    s = replace(DRAWS[0], duration=1.0)
    # the engines differ by their discretisation errors, 1e-4 and 2e-4: refinement shows both
    (row,) = fuzz.judge(s, _runs(1.0, 1e-4, -2e-4), ["reference", "exudyn"])
    c = declared()["criterion"]
    assert row.refinement["reference"] == pytest.approx(1e-4 * np.max(np.abs(np.sin(40 * np.linspace(0, 1, 201)))))
    assert row.motion == pytest.approx(0.5, abs=1e-4)  # the motion and A's wobble
    assert row.allowance == pytest.approx(c["factor"] * sum(row.refinement.values()) + c["relative"] * row.motion
                                          + c["absolute"]["joint_angles"])
    assert row.passed and row.ratio < 1


def test_a_difference_that_does_not_shrink_with_refinement_fails_and_check_reproduces_it(tmp_path, only_joint_angles):
    s = replace(DRAWS[0], duration=1.0)
    # a 1 % disagreement of the motion (a modelling difference): refinement leaves it
    runs = _runs(1.01, 1e-6, 1e-6)
    (row,) = fuzz.judge(s, runs, ["reference", "exudyn"])
    assert not row.passed and row.difference == pytest.approx(0.005, rel=1e-3)
    failed = fuzz.failing_case(s, [row], ["reference", "exudyn"])
    path = tmp_path / f"{s.name}.toml"
    path.write_text(case_text(failed))
    case = load_case(path)
    (check,) = check_runs(case, runs[("reference", "default")], runs[("exudyn", "default")])
    assert check.observable == "joint_angles" and not check.passed
    assert check.tolerance == pytest.approx(row.allowance, rel=5e-3)  # three significant figures


def test_a_closed_chain_closes_with_arm_2_in_the_joint_ranges():
    nominal, spread = RANGES["joint_angles_deg"]
    closed = [s for s in DRAWS[:40] if s.chain == "closed"]
    assert len(closed) >= 6
    with tempfile.TemporaryDirectory() as folder:
        for s in closed:
            path = Path(folder) / f"{s.name}.toml"
            path.write_text(case_text(s))
            q = np.degrees(build_initial(load_case(path)).joint_angles)
            assert np.all(np.abs(q - np.array(nominal)) <= spread + 1e-3), (s.name, q)
            assert np.allclose(q[3:], s.joint_angles_deg[3:], atol=1e-3)  # the file holds the closed angles


def test_the_observables_follow_the_scenario():
    free = next(s for s in DRAWS if s.chain == "free" and not s.orbit)
    closed = next(s for s in DRAWS if s.chain == "closed" and s.orbit)
    assert "target_pose_B" not in fuzz.observables(free) and "reaction_forces_I" not in fuzz.observables(free)
    assert {"target_pose_B", "reaction_forces_I"} <= set(fuzz.observables(closed))
    assert "altitude" not in fuzz.observables(closed)  # the orbit's own radius (fuzz_ranges.toml)


@pytest.mark.parametrize("args, field", [(["--n", "0"], "--n"), (["--seed", "-1"], "--seed"),
                                         (["--n", "two"], "--n"), (["--engines", "reference"], "--engines")])
def test_bad_arguments_are_one_line_and_exit_2(tmp_path, args, field):
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "fuzz", "--out", str(tmp_path / "f"), *args],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert field in lines[-1] and "Traceback" not in proc.stderr
    assert not (tmp_path / "f" / "fuzz.json").exists()


def test_the_floor_is_declared_for_every_compared_observable():
    absolute = declared()["criterion"]["absolute"]
    closed = next(s for s in DRAWS if s.chain == "closed" and s.orbit)
    assert all(math.isfinite(absolute[n]) and absolute[n] > 0 for n in fuzz.observables(closed))
    assert absolute["why"] and declared()["criterion"]["factor_why"] and declared()["criterion"]["relative_why"]


def _part(first: int, n: int, passed: int) -> dict:
    return {"format": fuzz.FORMAT, "seed": 4, "first": first, "n": n, "engines": ["reference", "exudyn"],
            "criterion": {"factor": 3.0}, "finer": {}, "passed": passed, "failed": n - passed, "wall_s": 10.0,
            "workers": 2, "commit": "x", "scenarios": [{"index": i} for i in range(first, first + n)]}


def test_parts_of_a_campaign_combine_in_order_and_only_in_order():
    doc = fuzz.combine([_part(0, 3, 3), _part(3, 2, 1)])
    assert [s["index"] for s in doc["scenarios"]] == [0, 1, 2, 3, 4]
    assert (doc["n"], doc["passed"], doc["failed"], doc["wall_s"]) == (5, 4, 1, 20.0) and len(doc["parts"]) == 2
    with pytest.raises(InputError, match="part 2.first"):
        fuzz.combine([_part(0, 3, 3), _part(4, 2, 2)])  # scenario 3 missing
    with pytest.raises(InputError, match="part 2.seed"):
        fuzz.combine([_part(0, 3, 3), {**_part(3, 2, 2), "seed": 5}])
