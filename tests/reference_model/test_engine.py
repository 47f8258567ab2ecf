"""The reference engine's step settings (reference_model/engine.py).

What must hold: the largest DP5 step comes from the case's [reference] table (or an
explicit option), and it matters where a case needs it: a rotor ripple far below the error
scale rtol·|θ| is accepted at 1 ms steps (ωh = 0.58 for the 92 Hz rotor mode), where DP5
damps it numerically; with h ≤ 0.2 ms its energy is kept.  Undamped, uncontrolled, rigid
links: after a 1 ms torque pulse the total energy must stay constant.
"""

from __future__ import annotations

import numpy as np

from reference_model.engine import H_MAX, ReferenceEngine
from rsmcheck.core.engine import Inputs

RIPPLE = """
description = "rigid robot at rest, undamped rotors: a tiny torque pulse rings the 92 Hz rotor modes"
duration = 2.0
[initial]
grasp = [1, 0]
[solver]
control_period = 1e-3
output_period = 1e-2
rtol = 1e-9
[reference]
n_modes = 0
h_max = 2e-4
why = "the ripple is below the error scale (this test)"
[params.motor]
damping = 0.0
"""


def _ring(engine: ReferenceEngine, t_end: float) -> tuple[float, float]:
    """Total energy [J] just after a 1e-3 N·m pulse on motor 1 and at t_end."""
    engine.advance(1e-3, Inputs(tau_m=np.array([1e-3, 0.0, 0.0, 0.0, 0.0, 0.0])))
    e0 = float(np.sum(engine.observe(Inputs())["energy"]))
    n = int(round(t_end / 1e-3))
    for k in range(2, n + 1):
        engine.advance(k * 1e-3, Inputs())
    return e0, float(np.sum(engine.observe(Inputs())["energy"]))


def test_the_case_table_caps_the_step(make_case):
    case = make_case("ripple", RIPPLE)
    capped = ReferenceEngine(case)
    assert capped.h_max == 2e-4 and capped.solver_settings()["h_max"] == 2e-4
    assert ReferenceEngine(case, h_max=1e-3).h_max == 1e-3  # an explicit option wins
    assert ReferenceEngine(case, integrator="trbdf2").h_max == 2e-4


def test_a_ripple_below_the_error_scale_keeps_its_energy_only_with_short_steps(make_case):
    case = make_case("ripple", RIPPLE)
    capped, default = ReferenceEngine(case), ReferenceEngine(case, h_max=H_MAX)
    e0c, e1c = _ring(capped, 2.0)
    e0d, e1d = _ring(default, 2.0)
    assert capped.steps >= 2.0 / 2e-4 and default.steps < 1.5 * 2.0 / 1e-3  # 1 ms steps accepted
    drift_capped, drift_default = abs(e1c / e0c - 1), abs(e1d / e0d - 1)
    assert drift_capped < 1e-4, drift_capped
    assert drift_default > 10 * drift_capped, (drift_default, drift_capped)
