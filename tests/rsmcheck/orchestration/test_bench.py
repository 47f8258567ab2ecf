"""rsmcheck.orchestration.bench: the table of where a control sample's time goes."""

from __future__ import annotations

from rsmcheck.orchestration.bench import per_sample_us, split_table


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
