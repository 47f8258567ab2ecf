"""Linearisation of the reference model: the linear plant of a case at its initial state
(the closed-loop analysis, rsmcheck.orchestration.closed_loop) and the coupled frequencies
of the robot at rest (`rsmcheck modes`).  Mirrors `exudyn_model/modes.py`: the same
functions with the same signatures (rsmcheck/core/engine.py), so the orchestration asks both
engines the same way; `engine_options` go to `ReferenceEngine` (e.g. n_modes).

Both are central differences of the reference's own ODE (`ode.rhs`) and sensors about
the initial state x₀ of the case: the oscillatory eigenvalues of ∂ẋ/∂x are the coupled
frequencies (Baumgarte's real ones drop out).
"""

from __future__ import annotations

import numpy as np

from reference_model.engine import ReferenceEngine
from reference_model.model_arrays import N_INPUTS, U_TAU_B, U_TAU_M
from rsmcheck.core.cases import at_rest, undamped


def coupled_frequencies(case, n: int = 6, f_min: float = 1.0, **engine_options) -> np.ndarray:
    """The first `n` oscillatory frequencies [Hz] above `f_min` of the reference linearised
    at rest in the initial configuration of `case`, undamped (ζ = 0, C_m = 0)."""
    jac, _, _ = linear_plant(undamped(at_rest(case)), lambda s: np.zeros(0), **engine_options)
    lam = np.linalg.eigvals(jac)
    return np.sort(np.abs(lam.imag[lam.imag > 2 * np.pi * f_min]))[:n] / (2 * np.pi)


def linear_plant(case, outputs, n_inputs: int = 7, eps: float = 1e-7, **engine_options):
    """(A, B, C) of the reference linearised at the initial state of `case` (damping kept):
    ẋ = A x + B u on x = (Y*, Ẏ*), u = (τ_m1..6, τ_B), y = `outputs(sensors)`; central
    differences of its ODE and of its sensors.  The reference point O, the propellant and
    the stop deflections e (condense.py) are held: e is zero off the wrist stops, and a
    state that starts on a stop (e ≠ 0) is refused, its linearisation would leave out the
    stop's own relaxation."""
    ref = ReferenceEngine(case, **engine_options)
    model, x0, cfg = ref.model, ref.x.copy(), ref.cfg
    e0 = x0[model.layout.stop_deflection]
    if np.any(e0 != 0.0):
        raise ValueError(f"{case.name}: the initial state is on a wrist stop (stop deflections e = "
                         f"{e0[0]:.3g}, {e0[1]:.3g} rad); the linear plant holds e and would leave out "
                         "the stop's relaxation")
    m = 2 * model.layout.ns
    u0 = np.zeros(N_INPUTS)
    A, B, cols = np.zeros((m, m)), np.zeros((m, n_inputs)), []
    for i in range(m):
        e = eps * max(1.0, abs(x0[i]))
        dx = np.zeros_like(x0)
        dx[i] = e
        A[:, i] = (model.rhs(x0 + dx, u0, cfg)[:m] - model.rhs(x0 - dx, u0, cfg)[:m]) / (2 * e)
        ys = []
        for sign in (1.0, -1.0):
            ref.x = x0 + sign * dx
            ys.append(outputs(ref.sensors()))
        cols.append((ys[0] - ys[1]) / (2 * e))
    ref.x = x0
    for j in range(n_inputs):
        u = u0.copy()
        u[U_TAU_M + j if j < 6 else U_TAU_B] = 1.0
        B[:, j] = model.rhs(x0, u, cfg)[:m] - model.rhs(x0, u0, cfg)[:m]
    return A, B, np.array(cols).T
