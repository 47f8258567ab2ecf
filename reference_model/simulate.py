"""One call from a case to a trajectory of the reference model (the Python API)."""

from __future__ import annotations

from reference_model.engine import ReferenceEngine
from rsmcheck.core.cases import Case
from rsmcheck.core.params import Params
from rsmcheck.driver.runner import Progress, run
from rsmcheck.core.store import EngineRun


def simulate(case: Case, params: Params | None = None, short: bool = False,
             progress: Progress | None = None, **engine_options) -> EngineRun:
    """Run `case` through the reference model; `params` defaults to the case's own.

    engine_options go to `ReferenceEngine` (n_modes, rtol).
    """
    engine = ReferenceEngine(case, params, **engine_options)
    return run(engine, case, case.run_duration(short), progress)
