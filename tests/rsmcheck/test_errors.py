"""rsmcheck.core.errors: the exceptions keep their fields across processes (pickling)."""

import pickle

from rsmcheck.core.errors import InputError, SimulationDiverged


def test_input_error_pickles_with_its_fields():
    e = pickle.loads(pickle.dumps(InputError("cases/x.toml", "duration", "must be > 0")))
    assert (e.where, e.field, e.reason) == ("cases/x.toml", "duration", "must be > 0")
    assert str(e) == "cases/x.toml: duration: must be > 0"


def test_simulation_diverged_pickles_with_its_fields():
    e = pickle.loads(pickle.dumps(SimulationDiverged("exudyn", 1.25, "p2", "ODE2[3]", float("inf"))))
    assert (e.engine, e.time, e.phase, e.quantity, e.value) == ("exudyn", 1.25, "p2", "ODE2[3]", float("inf"))
    assert "t = 1.25 s in phase 'p2'" in str(e)
