"""rsmcheck.orchestration.bench: the table of where a control sample's time goes."""

from __future__ import annotations

import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.orchestration.bench import bench_cases, bench_run, main, per_sample_us, phase_table, split_table, table


def _run(case, engine, split):
    return {"case": case, "engine": engine, "variant": "short", "wall_s": 1.0, "sim_s": 1.0, "peak_mb": 1.0,
            "split": split}


def test_split_per_sample_and_table():
    split = {"samples": 1000, "wall_s": 0.5, "wall_integrator_s": 0.3, "wall_advance_s": 0.32,
             "wall_sensors_s": 0.05, "wall_controller_s": 0.06, "wall_observe_s": 0.01}
    us = per_sample_us(split)
    want = {"integrator": 300.0, "engine": 20.0, "sensors": 50.0, "controller": 60.0, "observe": 10.0,
            "runner": 60.0}
    assert us.keys() == want.keys() and all(abs(us[k] - v) < 1e-9 for k, v in want.items()), us
    text = split_table([_run("p4_hohmann", "reference", split),
                        {"case": "x", "engine": "exudyn", "variant": "short", "error": "boom"}])
    lines = text.splitlines()
    assert lines[0].startswith("µs per control sample") and len(lines) == 3  # the failed run has no row
    assert lines[2].split()[:3] == ["p4_hohmann", "ref", "1000"] and lines[2].split()[-1] == "500.0"


def test_no_split_no_table():
    """Runs stored before the split was recorded (or failed runs) give no table, not an error."""
    assert split_table([_run("free_drift", "reference", {})]) == ""


def test_bench_times_the_variant_that_check_runs():
    """`--variant short` times each case's [short] variant with its own segments and engine
    settings (motor_step's short run keeps modified Newton; its full run takes a Jacobian
    per step), not the full case cut at the short duration."""
    full = load_case("motor_step")
    timed, warm = bench_cases("motor_step", short=True)
    assert timed is warm and timed.duration == full.short_duration
    assert timed.segments == full.short.segments != full.segments
    assert full.engine_settings["exudyn"].jacobian_per_step and not timed.engine_settings["exudyn"].jacobian_per_step
    assert bench_cases("motor_step", short=False)[0].engine_settings["exudyn"] == full.engine_settings["exudyn"]
    mission, first = bench_cases("mission", short=True)
    assert first.name == mission.phases[0] and first.duration == load_case(first.name).short_duration


def test_bench_run_reports_what_it_ran():
    """A real (short, cheap) run in a fresh process: its numbers and the settings behind them."""
    r = bench_run("p1_rigid_gains", "reference", "short")
    assert "error" not in r, r
    assert abs(r["sim_s"] - 0.2) < 1e-9 and r["wall_s"] > 0 and r["peak_mb"] > 0
    assert r["solver"]["steps"] > 0 and r["split"]["samples"] == 200


def test_phase_table_lists_each_mission_phase_per_engine():
    """The mission's phases, each with its own × real time per engine (README's speed target
    per phase); an engine that did not fly a phase shows a dash, not a number."""
    ref = dict(_run("mission", "reference", {}), phases=[{"phase": "p1", "sim_s": 50.0, "wall_s": 10.0},
                                                         {"phase": "p2", "sim_s": 60.0, "wall_s": 30.0}])
    exu = dict(_run("mission", "exudyn", {}), phases=[{"phase": "p1", "sim_s": 50.0, "wall_s": 25.0}])
    lines = phase_table([ref, exu, _run("free_drift", "reference", {})], ["reference", "exudyn"]).splitlines()
    assert len(lines) == 4, lines  # head, rule, p1, p2: a case without phases has no row
    assert lines[2].split()[:4] == ["mission", "p1", "short", "50.00"]
    assert lines[2].split()[-5:] == ["10.00", "5.000", "|", "25.00", "2.000"]
    assert lines[3].split()[-2:] == ["|", "—"]
    assert phase_table([_run("free_drift", "reference", {})], ["reference"]) == ""


def test_jobs_must_be_a_positive_whole_number(capsys):
    """A bad --jobs stops before any run, with the usage error (exit 2)."""
    for bad in ("0", "-1", "two"):
        with pytest.raises(SystemExit) as stop:
            main(["--jobs", bad, "--cases", "free_drift"])
        assert stop.value.code == 2
        assert "positive whole number" in capsys.readouterr().err


def test_table_ends_with_the_speed_targets_the_runs_measure():
    """A full mission per engine and the RHS timings put the four speed targets under the
    tables, each with its margin; a short bench shows the short cases' total and the RHS
    target."""
    runs = [dict(_run("mission", e, {}), variant="full", wall_s=w, sim_s=5920.0,
                 phases=[{"phase": "p1_transport", "sim_s": 1200.0, "wall_s": 300.0}])
            for e, w in (("reference", 900.0), ("exudyn", 2000.0))]
    rhs = {"reference_compiled": 10.0, "reference_call": 13.0, "reference_rigid_compiled": 5.0,
           "reference_rigid_call": 9.0, "pinocchio_aba": 2.5}
    text = table({"engines": ["reference", "exudyn"], "runs": runs, "rhs_us": rhs})
    block = text[text.index("speed target"):].splitlines()
    assert len(block) == 2 + 4
    assert "≤ 300 s" in block[2] and " 0.333 " in block[2] and " no " in block[2]
    assert "slowest p1_transport" in block[3] and " 0.200 " in block[3]
    assert "≤ 1200 s" in block[4] and " 0.600 " in block[4]
    assert "ABA" in block[5] and " 1.500 " in block[5] and " yes " in block[5]
    short = table({"engines": ["reference"], "runs": [_run("free_drift", "reference", {})], "rhs_us": rhs})
    lines = short[short.index("speed target"):].splitlines()
    assert len(lines) == 4 and lines[2].startswith("reference: all short cases ≤ 30 s")


def test_table_starts_with_the_machine_the_runs_ran_on():
    """The figures of a bench are the machine's: its first line names it, or says that an
    older document did not record it."""
    machine = {"cpu": "AMD EPYC (family 25, model 17)", "logical_cpus": 2, "memory_gib": 23.5,
               "system": "Linux", "python": "3.11.7", "packages": {"exudyn": "1.13.6"}}
    runs = [_run("free_drift", "reference", {})]
    first = table({"engines": ["reference"], "runs": runs, "machine": machine}).splitlines()[0]
    assert first == "machine: AMD EPYC (family 25, model 17), 2 logical CPUs, 23.5 GiB, Linux, Python 3.11.7 " \
                    "(exudyn 1.13.6)"
    assert "not recorded" in table({"engines": ["reference"], "runs": runs}).splitlines()[0]


def test_variant_targets_runs_the_full_mission_then_every_case_short(monkeypatch, capsys):
    """`--variant targets`: what the speed targets read, the mission at full length (one run
    per engine, first, so that two workers fly them side by side), then each case short."""
    from rsmcheck.orchestration import bench

    seen = []

    def fake_run_all(work, jobs, progress):
        seen.extend(work)
        return [dict(_run(c, e, {}), variant=v) for c, e, v in work]

    monkeypatch.setattr(bench, "run_all", fake_run_all)
    monkeypatch.setattr(bench, "rhs_timings", lambda: {})
    assert main(["--variant", "targets", "--engines", "reference,exudyn", "--cases", "free_drift", "capture",
                 "--json"]) == 0
    assert seen == [("mission", "reference", "full"), ("mission", "exudyn", "full"),
                    ("free_drift", "reference", "short"), ("free_drift", "exudyn", "short"),
                    ("capture", "reference", "short"), ("capture", "exudyn", "short")]
    capsys.readouterr()
