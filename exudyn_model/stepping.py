"""The cost of stepping the Exudyn model, for the orchestration (rsmcheck.core.engine lists
the functions every engine package offers): `rhs_timing`, the cost of one right-hand side.
The mirror of `reference_model.stepping.rhs_timing`.  The stepping itself is
`exudyn_model.stepper` (one control interval) and `exudyn_model.worker` (the continuous
run across intervals).
"""

from __future__ import annotations

import math
import timeit

from exudyn_model.engine import ExudynEngine
from exudyn_model.reactions import ConstraintForces


def rhs_timing(case, n: int = 2000, **engine_options) -> dict[str, float]:
    """µs per evaluation of Exudyn's right-hand side at the initial state of `case` (best of
    3): `call_us` one `ComputeODE2RHS` from Python (through `reactions.ConstraintForces`),
    `compiled_us` NaN (the solver's own calls from C++ cannot be timed alone), `states` the
    size of the first-order state (2 × ODE2 coordinates).  `engine_options` go to
    `ExudynEngine`."""
    engine = ExudynEngine(case, **engine_options)
    cf = ConstraintForces(engine.mbs)
    cf.rhs()
    call = min(timeit.repeat(cf.rhs, number=n, repeat=3)) / n * 1e6
    return {"call_us": call, "compiled_us": math.nan, "states": 2 * cf.n2}
