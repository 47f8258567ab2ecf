"""rsmcheck.orchestration.collect: what the report's runs are cut into and checked by."""

from __future__ import annotations

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.orchestration.collect import mission_checks, phase_runs, phase_specs
from rsmcheck.orchestration.compare import check_runs
from rsmcheck.core.observables import allocate
from rsmcheck.core.store import EngineRun, Event, Phase


def _flight(engine: str, mission, offsets: dict[str, float] | None = None) -> EngineRun:
    """A synthetic short mission: each phase sampled at its output period from its own
    t = 0 and concatenated as rsmcheck.orchestration.chain does (the boundary time appears twice)."""
    parts, events, phases = [], [], []
    start = 0.0
    for name in mission.variant(True).phases:
        ph = load_case(name).variant(True)
        t = np.linspace(0.0, ph.duration, int(round(ph.duration / ph.solver.output_period)) + 1)
        obs = allocate(t.size)
        obs["time"] = t + start
        for spec in ph.compare:
            obs[spec.observable][...] = (offsets or {}).get(name, 0.0)
        parts.append(obs)
        events.append(Event(start + 1.0, "capture", f"arm=1 phase={name}"))
        phases.append(Phase(name, start, start + ph.duration))
        start += ph.duration
    joined = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return EngineRun(engine, joined, events, phases)


def test_the_flight_is_cut_into_its_phases_on_their_own_time():
    mission = load_case("mission")
    cut = phase_runs(mission, True, _flight("reference", mission))
    names = mission.variant(True).phases
    assert [ph.name for ph, _, _ in cut] == list(names)
    start = 0.0
    for ph, t0, run in cut:
        t = run.observables["time"]
        assert t0 == pytest.approx(start)
        assert t[0] == pytest.approx(0.0, abs=1e-9) and t[-1] == pytest.approx(ph.duration)
        assert np.all(np.diff(t) > 0)  # the boundary sample belongs to one phase only
        assert [e.detail for e in run.events] == [f"arm=1 phase={ph.name}"]
        assert run.events[0].time == pytest.approx(1.0)
        assert [p.name for p in run.phases] == [ph.name]
        start += ph.duration


def test_a_chained_phase_is_checked_against_its_tolerance_plus_what_it_inherits():
    """d0 = the difference at the phase's first sample is added to max_abs rows: a constant
    offset of d0 passes, d0 + 1.5 × tolerance does not."""
    case = load_case("p5_release").variant(True)
    spec = next(s for s in case.compare if s.metric == "max_abs")
    t = np.linspace(0.0, case.duration, 31)
    runs = {}
    for engine, shift in (("reference", 0.0), ("exudyn", 1e-3)):
        obs = allocate(t.size)
        obs["time"] = t
        obs[spec.observable][...] = shift
        runs[engine] = EngineRun(engine, obs)
    row = next(r for r in check_runs(case, runs["reference"], runs["exudyn"], chained=True)
               if r.observable == spec.observable)
    assert row.inherited == pytest.approx(1e-3) and row.passed
    assert row.tolerance == pytest.approx(spec.tolerance + 1e-3)
    runs["exudyn"].observables[spec.observable][-1] += 1.5 * spec.tolerance
    row = next(r for r in check_runs(case, runs["reference"], runs["exudyn"], chained=True)
               if r.observable == spec.observable)
    assert not row.passed
    plain = next(r for r in check_runs(case, runs["reference"], runs["exudyn"]) if r.observable == spec.observable)
    assert plain.inherited == 0.0 and plain.tolerance == spec.tolerance


def test_every_phase_has_its_rows_and_the_sequence_replaces_only_its_own():
    mission = load_case("mission")
    rows = mission_checks(mission, True, {"reference": _flight("reference", mission),
                                          "exudyn": _flight("exudyn", mission)})
    for name in mission.variant(True).phases:
        own = [s.observable for s in load_case(name).variant(True).compare]
        assert [r["observable"] for r in rows if r["case"] == f"mission/{name}"] == own
    p3 = load_case("p3_com_alignment").variant(True)
    specs = {s.observable: s for s in phase_specs(mission, True, p3)}
    assert specs["motor_torques"].tolerance == 0.04  # cases/mission.toml [short_compare]
    assert specs["com_pos_B"] == next(s for s in p3.compare if s.observable == "com_pos_B")
    # the full flight has its own replaced rows ([compare.PHASE.OBSERVABLE], docs/cases.md §6)
    p4 = load_case("p4_hohmann").variant(False)
    full = {s.observable: s for s in phase_specs(mission, False, p4)}
    assert full["altitude"].tolerance == 1.5 and "quarter orbit" in full["altitude"].why
    assert full["joint_angles"] == next(s for s in p4.compare if s.observable == "joint_angles")  # not replaced
    assert [s.observable for s in phase_specs(mission, False, p4)] == [s.observable for s in p4.compare]


def test_a_sequence_may_only_replace_rows_of_its_phases(tmp_path):
    from rsmcheck.core.errors import InputError

    src = load_case("mission").path
    text = open(src, encoding="utf-8").read()
    for table, field in (("[short_compare.p1_transport.ee2_speed]", "short_compare.p1_transport"),
                         ("[short_compare.p3_com_alignment.energy]", "short_compare.p3_com_alignment.energy")):
        bad = tmp_path / "mission.toml"
        bad.write_text(text + f'\n{table}\ntolerance = 1.0\nwhy = "x"\n', encoding="utf-8")
        for name in load_case("mission").phases:  # the phases next to the file
            (tmp_path / f"{name}.toml").write_text(open(load_case(name).path, encoding="utf-8").read())
        with pytest.raises(InputError) as err:
            load_case(bad)
        assert field in str(err.value)


@pytest.mark.engine_runs(("mission", "reference", True, ()), ("p2_capture_regrasp", "reference", True, ()))
def test_the_flights_first_phase_is_the_stand_alone_run(run_pool):
    """rsmcheck.orchestration.collect takes the first phase's run from the flight instead of running it
    again: it must be the same run, sample for sample."""
    mission = load_case("mission")
    first, _, cut = phase_runs(mission, True, run_pool.get("mission", "reference").run)[0]
    alone = run_pool.get("p2_capture_regrasp", "reference")
    assert first.name == "p2_capture_regrasp"
    for name, values in alone.observables.items():
        assert np.array_equal(values, cut.observables[name]), name
    assert [(e.kind, e.detail) for e in alone.events] == [(e.kind, e.detail) for e in cut.events]


def test_the_robot_wide_tables_come_with_the_whole_report_only(tmp_path, monkeypatch):
    """`collect` queues the rigid checks and the eigenfrequencies (a minute and a half of
    linearisations) for the whole report, not for one restricted to some cases; a plug-in
    whose error a row does not record gets its refined run queued beside the runs."""
    from rsmcheck.orchestration import collect as col
    from rsmcheck.orchestration.runs import RunSet

    queued = {}

    def fake_get_runs(cases, engines, short, run_dir, **kw):
        queued[tuple(c.name for c in cases)] = [j.label for j in kw.get("extra", ())]
        return RunSet()

    monkeypatch.setattr(col, "get_runs", fake_get_runs)
    monkeypatch.setattr(col, "verdict", lambda res, digest: {})
    col.collect(tmp_path / "some", True, ["reference", "exudyn"], ["free_drift"])
    assert queued[("free_drift",)] == []
    col.collect(tmp_path / "whole", True, ["reference", "exudyn"])
    labels = next(v for k, v in queued.items() if len(k) > 1)
    assert "modes" in labels and "pinocchio" in labels


def test_stored_integration_errors_count_only_for_unchanged_cases(tmp_path):
    """integration.json is read for this code, this variant and cases whose run inputs
    are unchanged: an edited case's errors are measured again."""
    import json

    from rsmcheck.orchestration import collect as col
    from rsmcheck.orchestration.runs import run_inputs_hash

    case = load_case("flex_arm_step")
    entry = {"inputs": run_inputs_hash(case), "engines": {"mine": {"link_deflection": 1e-12}}, "failed": {}}
    (tmp_path / col.INTEGRATION).write_text(json.dumps(
        {"source_digest": "d", "short": True, "cases": {"flex_arm_step": entry,
                                                         "motor_step": {**entry, "inputs": "an older file"}}}))
    got = col._measured(tmp_path, "d", True, [case, load_case("motor_step")])
    assert got == {"flex_arm_step": entry}
    assert col._measured(tmp_path, "other code", True, [case]) == {}
    assert col._measured(tmp_path, "d", False, [case]) == {}
