"""What the reference's integrators share (numba): the PI step-size controller of the
embedded 5(4) pairs (`dopri5.py`, `imex.py`: the step toward the interval's end, the
verdict on a step from its error) and finite-difference Jacobian columns of `ode.rhs`
(`trbdf2.py`, `imex.py`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from reference_model.ode import rhs


#: verdicts of `judge_step`
ACCEPTED = 0
REJECTED = 1  # retry from the same state with the returned step
NON_FINITE = 2  # give up: a non-finite error at a step below 1e-12 s (the integrators' status 1)
UNDERFLOW = 3  # give up: the step fell below 1e-13 s (status 2)


@njit(cache=True, inline="always")
def step_toward(t, t1, h):
    """The step from t toward the interval's end t1: h, or exactly what is left when h
    reaches t1 (to within round-off).  Returns (step, True if it lands on t1)."""
    if t + h >= t1 - 1e-12 * max(1.0, abs(t1)):
        return t1 - t, True
    return h, False


@njit(cache=True, inline="always")
def judge_step(err, h, h_nominal, err_old, rejected, last, hmax):
    """The verdict on a step of size h with scaled error norm err (≤ 1 accepts): (verdict,
    the next step size, err_old for the next step).  A non-finite error retries at h/5."""
    if not np.isfinite(err):
        if h < 1e-12:
            return NON_FINITE, h, err_old
        return REJECTED, 0.2 * h, err_old
    if err <= 1.0:
        h_next, err_next = accepted_step(h, h_nominal, err, err_old, rejected, last, hmax)
        return ACCEPTED, h_next, err_next
    h_next = rejected_step(h, err)
    if h_next < 1e-13:
        return UNDERFLOW, h_next, err_old
    return REJECTED, h_next, err_old


@njit(cache=True, inline="always")
def accepted_step(h, h_nominal, err, err_old, rejected, last, hmax):
    """Hairer & Wanner's PI step-size control (their DOPRI5: β = 0.04, safety 0.9, ratio
    in [0.2, 10]) after an accepted step of size h with scaled error err ≤ 1, for an error
    estimate O(h⁵):  h_new = h · 0.9 err^(−0.17) err_old^(0.04),  0.17 = 1/5 − 0.75 β.
    No growth right after a rejection; after the step clipped to the interval's end, the
    unclipped h_nominal (the clipped step says nothing about the next).  Returns
    (next step size, err_old for the next step)."""
    f11 = err ** 0.17 if err > 0.0 else 0.0
    fac = f11 / err_old ** 0.04 / 0.9
    fac = min(5.0, max(0.1, fac))  # h grows at most ×10, shrinks at most ×5
    h_next = h / fac
    if rejected:
        h_next = min(h_next, h)
    if last:
        return min(h_nominal, hmax), max(err, 1e-4)
    return min(h_next, hmax), max(err, 1e-4)


@njit(cache=True, inline="always")
def rejected_step(h, err):
    """The step size to retry with after a step rejected with scaled error err > 1."""
    return h / min(5.0, err ** 0.17 / 0.9)


@njit(cache=True)
def jacobian_columns(x, f0, u, m, sw, cols, atol, rtol):
    """∂f/∂x_c for the state components c in `cols` by forward differences from f0 = f(x);
    the perturbation is √ε relative to the component's size or its tolerance scale."""
    n = x.shape[0]
    J = np.empty((n, cols.shape[0]))
    xp = x.copy()
    for k in range(cols.shape[0]):
        c = cols[k]
        e = 1.5e-8 * max(abs(x[c]), atol[c] / rtol)
        xp[c] = x[c] + e
        fp = rhs(xp, u, m, sw)
        J[:, k] = (fp - f0) / e
        xp[c] = x[c]
    return J
