"""The stiff-capable integrator (reference_model/trbdf2.py, TR-BDF2).

What must hold: it solves the same ODE as the explicit Dormand–Prince pair (agreement at
the level of the tolerances), its error control works (the error shrinks with rtol at
second order), and it is stiff-capable: in a quiet phase it takes steps far beyond the
explicit stability limit (~2.5 ms for the 160 Hz link modes) without going unstable.
Step counts are deterministic, so they can be asserted; wall time is not (docs/benchmarks.md).
No case integrates with it by default: its tests are `study` (its kernels compile for minutes).
"""

from __future__ import annotations

import numpy as np
import pytest

from reference_model.engine import ReferenceEngine
from rsmcheck.core.engine import Inputs

pytestmark = pytest.mark.study

QUIET_ORBIT = """
description = "closed chain at rest in orbit: only the tidal field moves it"
duration = 20.0
[initial]
grasp = [1, 1]
[orbit]
enabled = true
[solver]
control_period = 0.1
output_period = 0.1
rtol = 1e-6
"""



def _advance(engine: ReferenceEngine, t_end: float, dt: float) -> np.ndarray:
    n = int(round(t_end / dt))
    for k in range(n):
        engine.advance((k + 1) * dt, Inputs())
    return engine.x


def test_trbdf2_agrees_with_dopri5_and_converges_at_second_order(ringing_chain):
    case = ringing_chain
    exact = _advance(ReferenceEngine(case, integrator="dopri5", rtol=1e-11), 0.2, 1e-3)
    lay = ReferenceEngine(case).model.layout
    errors = []
    for rtol in (1e-6, 1e-8):
        x = _advance(ReferenceEngine(case, integrator="trbdf2", rtol=rtol), 0.2, 1e-3)
        errors.append(np.max(np.abs(x[lay.q] - exact[lay.q])[:9]))  # rigid coordinates [m, rad]
    # error control: a 100× tighter tolerance gives a smaller error, and both are small
    assert errors[0] < 1e-5, errors
    assert errors[1] < errors[0] / 5.0, errors


def test_trbdf2_takes_large_steps_in_a_quiet_phase(make_case):
    case = make_case("quiet", QUIET_ORBIT)
    implicit = ReferenceEngine(case, integrator="trbdf2")
    _advance(implicit, 20.0, 0.1)
    explicit = ReferenceEngine(case, integrator="dopri5")
    _advance(explicit, 20.0, 0.1)
    lay = implicit.model.layout
    # stiff-capable: at most a few steps per 0.1 s control period (the explicit pair needs
    # ~50, bound by stability near 2 ms), with the same rigid motion
    assert implicit.steps <= 3 * 200, implicit.steps
    assert explicit.steps > 10 * implicit.steps, (explicit.steps, implicit.steps)
    rigid = slice(0, 9)
    assert np.max(np.abs(implicit.x[lay.q][rigid] - explicit.x[lay.q][rigid])) < 1e-6
    assert np.all(np.isfinite(implicit.x))
