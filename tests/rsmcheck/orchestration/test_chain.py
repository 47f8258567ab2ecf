"""rsmcheck.orchestration.chain: what a chained run (the mission) stores of its phases."""

from __future__ import annotations

import numpy as np

from rsmcheck.core.observables import NAMES
from rsmcheck.orchestration.chain import _concatenate
from rsmcheck.core.store import EngineRun


def _phase(duration: float, solver: dict) -> EngineRun:
    obs = {key: np.zeros(3) for key in NAMES}
    obs["time"] = np.array([0.0, 0.5 * duration, duration])
    return EngineRun(engine="exudyn", observables=obs, solver=solver)


def test_a_chained_run_counts_the_work_of_all_its_phases():
    """Each phase's engine counts its steps, Newton iterations, Jacobians and retries from
    zero: the chained run's counts and wall times are the sums, its settings the first
    phase's (the mission's Newton iterations once were p1's alone)."""
    first = {"steps": 10, "samples": 5, "newton_iterations": 12, "jacobians": 2, "newton_retries": 0,
             "restarts": 1, "wall_s": 1.5, "substeps": 2, "links": "ANCFCable2D x 8"}
    second = {"steps": 20, "samples": 10, "newton_iterations": 31, "jacobians": 3, "newton_retries": 1,
              "restarts": 4, "wall_s": 2.0, "substeps": 2, "links": "ANCFCable2D x 8"}
    run = _concatenate("exudyn", [(0.0, _phase(1.0, first)), (1.0, _phase(2.0, second))])
    assert run.solver == {"steps": 30, "samples": 15, "newton_iterations": 43, "jacobians": 5, "newton_retries": 1,
                          "restarts": 5, "wall_s": 3.5, "substeps": 2, "links": "ANCFCable2D x 8"}
    np.testing.assert_array_equal(run.observables["time"], [0.0, 0.5, 1.0, 1.0, 2.0, 3.0])


def test_the_quiet_integrators_steps_are_summed_from_the_first_phase_that_has_one():
    """The reference reports `quiet_steps` only where a case names a quiet integrator (p4,
    p5): the chained run sums them over the phases that have them."""
    phases = [(0.0, _phase(1.0, {"steps": 10})), (1.0, _phase(1.0, {"steps": 20, "quiet_steps": 7})),
              (2.0, _phase(1.0, {"steps": 30, "quiet_steps": 5}))]
    run = _concatenate("reference", phases)
    assert run.solver == {"steps": 60, "quiet_steps": 12}


def test_each_phase_of_a_flight_takes_the_common_options_and_its_own(monkeypatch):
    """`fly(..., options, phase_options)`: every phase's engine is made with the common
    options and what phase_options gives for that phase's variant (a budget's refined
    flight: each phase at a tenth of its own rtol), in the sequence's order."""
    from rsmcheck.core.cases import load_case
    from rsmcheck.core.plugins import settings_of
    from rsmcheck.orchestration import chain

    made = []

    def make(engine_name, case, start, **opts):
        made.append((case.name, opts))
        return object()

    monkeypatch.setattr(chain, "make_engine", make)
    monkeypatch.setattr(chain, "run", lambda engine, case, duration, progress=None: _phase(duration, {}))
    monkeypatch.setattr(chain, "end_state", lambda engine, params: {})
    monkeypatch.setattr(chain, "start_of", lambda state: None)
    mission = load_case("mission").variant(True)
    chain.fly(mission, "reference", True, None, {"n_modes": 2}, lambda ph: {"rtol": settings_of(ph, "reference").rtol / 10})
    assert [name for name, _ in made] == list(mission.phases)
    rtols = {p: settings_of(load_case(p).variant(True), "reference").rtol / 10 for p in mission.phases}
    assert made == [(p, {"n_modes": 2, "rtol": rtols[p]}) for p in mission.phases]
    assert rtols["p2_capture_regrasp"] != rtols["p3_com_alignment"]  # the phases differ: the test can tell
