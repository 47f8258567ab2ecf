"""rsmcheck.orchestration.targets: the speed targets read off a bench document."""

from __future__ import annotations

import math

import pytest

from rsmcheck.orchestration.targets import TARGETS, read_targets, targets_table


def _mission(engine, wall, phases=(), variant="full", **extra):
    return {"case": "mission", "engine": engine, "variant": variant, "wall_s": wall, "sim_s": 5920.0,
            "peak_mb": 1.0, "phases": [{"phase": p, "sim_s": s, "wall_s": w} for p, s, w in phases], **extra}


def _doc(*runs, ref=5.0, aba=2.0):
    return {"runs": list(runs), "rhs_us": {"reference_rigid_compiled": ref, "pinocchio_aba": aba}}


def test_readings_and_margins():
    """Upper bounds: margin bound/measured; lower bounds: measured/bound; the slowest phase is
    the phase target's reading."""
    doc = _doc(_mission("reference", 600.0, [("p1", 1200.0, 100.0), ("p2", 380.0, 10.0)]),
               _mission("exudyn", 600.0), ref=5.0, aba=2.0)
    r = {x.target.key: x for x in read_targets(doc)}
    assert r["reference_mission"].measured == 600.0 and r["reference_mission"].margin == pytest.approx(0.5)
    assert not r["reference_mission"].met
    assert r["reference_phases"].measured == pytest.approx(12.0) and "slowest p1" in r["reference_phases"].detail
    assert r["reference_phases"].margin == pytest.approx(0.6) and not r["reference_phases"].met
    assert r["exudyn_mission"].margin == pytest.approx(2.0) and r["exudyn_mission"].met
    assert r["rigid_rhs"].measured == pytest.approx(2.5) and r["rigid_rhs"].met


def test_a_bound_met_exactly_is_met_and_a_faster_run_has_a_larger_margin():
    at = {x.target.key: x for x in read_targets(_doc(_mission("reference", 300.0), ref=6.0, aba=2.0))}
    assert at["reference_mission"].met and at["rigid_rhs"].met and at["rigid_rhs"].margin == pytest.approx(1.0)
    fast = {x.target.key: x for x in read_targets(_doc(_mission("reference", 150.0)))}
    assert fast["reference_mission"].margin == pytest.approx(2.0)


def test_the_short_cases_are_summed_without_the_mission_and_failed_runs():
    short = [{"case": c, "engine": "reference", "variant": "short", "wall_s": w, "sim_s": 1.0}
             for c, w in (("motor_step", 4.0), ("p2_capture_regrasp", 20.0), ("capture", 6.0))]
    doc = {"runs": short + [_mission("reference", 99.0, variant="short"),
                            {"case": "release", "engine": "reference", "variant": "short", "error": "boom"}]}
    r = {x.target.key: x for x in read_targets(doc)}
    assert r["reference_short"].measured == 30.0 and r["reference_short"].met
    assert "3 cases; slowest p2_capture_regrasp 20.0 s" == r["reference_short"].detail


def test_what_a_document_does_not_measure_is_not_read():
    """Short runs, failed runs and a missing Pinocchio time measure nothing: None, not a
    pass, and no row in the table."""
    doc = {"runs": [_mission("reference", 30.0, variant="short"),
                    _mission("exudyn", None, error="boom")],
           "rhs_us": {"reference_rigid_compiled": 5.0, "pinocchio_aba": math.nan}}
    readings = read_targets(doc)
    assert [x.measured for x in readings] == [None] * len(TARGETS)
    assert all(x.met is None and x.margin is None for x in readings)
    assert targets_table(readings) == ""


def test_the_floor_is_the_integrators_share_of_the_missions_wall():
    """A wall-time target's floor is the run's `wall_integrator_s` (rsmcheck.driver.runner's split),
    its margin bound / floor: 300 s against 750 s of integrator is 0.4, whatever the loop
    around it cost; a run that did not record its split has no floor, and the targets that
    are not wall times have none."""
    doc = _doc(_mission("reference", 1000.0, [("p1", 1200.0, 100.0)], split={"wall_integrator_s": 750.0}),
               _mission("exudyn", 1500.0, split={"wall_integrator_s": 1000.0}))
    r = {x.target.key: x for x in read_targets(doc)}
    assert r["reference_mission"].floor == 750.0 and r["reference_mission"].floor_margin == pytest.approx(0.4)
    assert r["reference_mission"].margin == pytest.approx(0.3)
    assert r["exudyn_mission"].floor_margin == pytest.approx(1.2) and not r["exudyn_mission"].met
    assert r["reference_phases"].floor is None and r["rigid_rhs"].floor_margin is None
    assert read_targets(_doc(_mission("reference", 400.0)))[0].floor is None
    lines = targets_table(read_targets(doc)).splitlines()
    assert "engine alone" in lines[0]
    assert lines[2].split()[-1] != "–" and "0.400" in lines[2] and "integrator 750 s" in lines[2]
    assert "1.200" in lines[4] and "integrator 1000 s" in lines[4]
    # the outside share: 1 − 1000/1500 of Exudyn's mission, a third, against 15 %
    assert r["exudyn_outside"].measured == pytest.approx(100.0 / 3) and not r["exudyn_outside"].met


def test_table_names_each_measured_target_with_its_verdict():
    doc = _doc(_mission("reference", 600.0, [("p1", 1200.0, 100.0)]))
    lines = targets_table(read_targets(doc)).splitlines()
    assert len(lines) == 2 + 3  # header, rule, reference mission, its phases, the RHS ratio
    assert "≤ 300 s" in lines[2] and " no " in lines[2]
    assert "≥ 20 × real time" in lines[3] and " yes " in lines[4]
