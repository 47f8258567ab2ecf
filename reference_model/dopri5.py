"""Explicit integrator of the reference: the embedded Dormand–Prince 5(4) pair with error
control (numba), the default for every case (docs/physics.md §7).

Seven stages, the 7th evaluated at the 5th-order solution (first same as last: six new
right-hand sides `ode.rhs` per step); the embedded 4th-order solution gives the error
estimate per component.  The highest frequencies of the flexible model bound its step by
stability: near 2.3 ms with the static correction shapes slaved (the default: the 140–230 Hz
coupled link modes are the highest left), near 0.46 ms with them as Ritz states
(`static_modes = "explicit"`: their 0.8–1.1 kHz modes); for quiet, stiff phases a case may
choose TR-BDF2 (`trbdf2.py`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from reference_model.ode import rhs
from reference_model.integration import ACCEPTED, NON_FINITE, UNDERFLOW, judge_step, step_toward

# --- the Dormand–Prince 5(4) tableau: nodes c, stages a, 5th-order weights b, error weights e = b − b̂
_C = np.array([0.0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1.0, 1.0])
_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1.0 / 5, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40, 9.0 / 40, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45, -56.0 / 15, 32.0 / 9, 0.0, 0.0, 0.0],
    [19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0.0, 0.0],
    [9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656, 0.0],
    [35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84],
])
_B5 = np.array([35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0.0])
_E = np.array([71.0 / 57600, 0.0, -71.0 / 16695, 71.0 / 1920, -17253.0 / 339200, 22.0 / 525,
               -1.0 / 40])


@njit(cache=True)
def integrate_dopri5(x0, t0, t1, h, rtol, atol, hmax, u, m, sw):
    """Integrate from t0 to t1 with inputs u held: embedded Dormand–Prince 5(4), error per
    component scaled by atol_i + rtol·|x_i| (max norm), step size by the PI controller of
    Hairer & Wanner's DOPRI5 (β = 0.04, safety 0.9, ratio in [0.2, 10]), which rejects far
    fewer steps near the stability limit than the plain err^(−1/5) rule.

    Returns (x(t1), next step size, accepted steps, rejected steps, status); status 0 ok,
    1 non-finite state, 2 step size underflow.
    """
    x = x0.copy()
    t = t0
    nx = x.shape[0]
    K = np.zeros((7, nx))
    K[0] = rhs(x, u, m, sw)
    nacc = 0
    nrej = 0
    h = min(h, hmax)
    h_nominal = h
    err_old = 1e-4
    rejected = False
    while t < t1:
        h_nominal = h
        h, last = step_toward(t, t1, h)
        for st in range(1, 7):
            xs = x.copy()
            for j in range(st):
                if _A[st, j] != 0.0:
                    xs += h * _A[st, j] * K[j]
            K[st] = rhs(xs, u, m, sw)
        xn = xs  # stage 7 is evaluated at the 5th-order solution (FSAL)
        err = 0.0
        for c in range(nx):
            e = 0.0
            for st in range(7):
                e += _E[st] * K[st, c]
            sc_c = atol[c] + rtol * max(abs(x[c]), abs(xn[c]))
            err = max(err, abs(h * e) / sc_c)
        verdict, h_next, err_old = judge_step(err, h, h_nominal, err_old, rejected, last, hmax)
        if verdict == ACCEPTED:
            t = t1 if last else t + h
            x = xn
            K[0] = K[6]
            nacc += 1
        elif verdict == NON_FINITE:
            return x, h, nacc, nrej, 1
        else:
            nrej += 1
        rejected = verdict != ACCEPTED
        h = h_next
        if verdict == UNDERFLOW:
            return x, h, nacc, nrej, 2
    return x, h, nacc, nrej, 0
