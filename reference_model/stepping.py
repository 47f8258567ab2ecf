"""The cost of the reference's stepping (`rsmcheck bench`): `rhs_timing`, the time of one
evaluation of the right-hand side every integrator stage pays.  The stepping itself is the
engine's `Stepper` (stepper.py); the mirror of `rhs_timing` in the Exudyn model is in
`exudyn_model/stepping.py`.
"""

from __future__ import annotations

import math
import time
import timeit

import numpy as np
from numba import njit

from reference_model.engine import ReferenceEngine
from reference_model.model_arrays import N_INPUTS
from reference_model.ode import rhs


@njit(cache=True)
def _rhs_loop(x, u, m, sw, n):  # pragma: no cover - compiled
    s = 0.0
    for _ in range(n):
        s += rhs(x, u, m, sw)[0]
    return s


def rhs_timing(case, n: int = 2000, **engine_options) -> dict[str, float]:
    """µs per evaluation of the right-hand side `ode.rhs` at the initial state of `case`
    (best of 3): `call_us` called from Python (numba's dispatch of the model's arrays
    included), `compiled_us` inside a compiled loop (what the integrators pay per stage),
    and `states`, the size of the ODE state.  `engine_options` go to `ReferenceEngine`."""
    engine = ReferenceEngine(case, **engine_options)
    m, sw = engine.model.core_args(engine.cfg)
    u = np.zeros(N_INPUTS)
    rhs(engine.x, u, m, sw)
    call = min(timeit.repeat(lambda: rhs(engine.x, u, m, sw), number=n, repeat=3)) / n * 1e6
    _rhs_loop(engine.x, u, m, sw, 10)
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _rhs_loop(engine.x, u, m, sw, 10 * n)
        best = min(best, (time.perf_counter() - t0) / (10 * n) * 1e6)
    return {"call_us": call, "compiled_us": best, "states": int(engine.model.layout.nx)}
