"""Stiff-capable integrator of the reference: TR-BDF2 with error control (numba).

TR-BDF2 (Bank et al. 1985; Hosea & Shampine 1996, the method of MATLAB's ode23tb) written
as a stiffly accurate ESDIRK with an explicit first stage:

    c = [0, γ, 1],   γ = 2 − √2,   d = γ/2,   w = (1 − d)/2 = √2/4
    Y2 = x + h (d k1 + d k2)                      trapezoidal rule to t + γh
    Y3 = x + h (w k1 + w k2 + d k3) = x_{n+1}     BDF2 to t + h
    error: x̂ − x_{n+1} with the 3rd-order weights b̂ = [(1 − w)/3, (3w + 1)/3, d/3],
           filtered by (I − d h J)⁻¹ (Shampine) so stiff components do not shrink h.

L-stable, second order; both implicit stages use the same iteration matrix I − d h J,
so one Jacobian (finite differences of `ode.rhs`) and one inverse serve many steps: the
Jacobian is recomputed only when Newton fails to converge, the inverse when h changes.
It lets a quiet system take steps far beyond the explicit stability limit (~0.46 ms with
the static correction shapes' ~1 kHz modes, ~2.5 ms for the 160 Hz link modes without
them), which is what long, quiet runs at loose tolerance need; DP5(4) (`dopri5.py`)
remains the accurate choice for the short, dynamic cases.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from reference_model.ode import rhs
from reference_model.integration import jacobian_columns

_GAMMA = 2.0 - math.sqrt(2.0)
_D = 0.5 * _GAMMA
_W = 0.25 * math.sqrt(2.0)
_E1 = _W - (1.0 - _W) / 3.0  # b − b̂
_E2 = _W - (3.0 * _W + 1.0) / 3.0
_E3 = _D - _D / 3.0
_NEWTON_MAX = 7
_NEWTON_TOL = 0.03  # on the scaled Newton increment, relative to the error tolerance

#: slots of `work`, the bookkeeping of the iteration matrix carried between calls (floats)
W_HAVE_J = 0  # 1.0 while J belongs to the present system; the owner sets 0.0 when it changes
W_H_OF_MINV = 1  # the step size Minv = (I − d h J)⁻¹ was formed for (−1.0: none)
W_JACOBIANS = 2  # Jacobians computed so far
W_NEWTON_FAILURES = 3  # stage iterations that did not converge
N_WORK = 4


@njit(cache=True)
def _norm(v, x, rtol, atol):
    m = 0.0
    for c in range(v.shape[0]):
        m = max(m, abs(v[c]) / (atol[c] + rtol * abs(x[c])))
    return m


@njit(cache=True)
def _stage(base, guess, hd, Minv, rtol, atol, u, m, sw):
    """Solve Y = base + h d f(Y) by simplified Newton; returns (Y, f(Y), converged)."""
    Y = guess.copy()
    for _ in range(_NEWTON_MAX):
        fY = rhs(Y, u, m, sw)
        G = Y - base - hd * fY
        dY = -(Minv @ G)
        Y = Y + dY
        if not np.all(np.isfinite(Y)):
            return Y, fY, False
        if _norm(dY, Y, rtol, atol) < _NEWTON_TOL:
            fY = rhs(Y, u, m, sw)
            return Y, fY, True
    return Y, fY, False


@njit(cache=True)
def integrate_trbdf2(x0, t0, t1, h, rtol, atol, hmax, J, Minv, work, u, m, sw):
    """Integrate from t0 to t1 with inputs u held.

    J, Minv (n×n) and work (N_WORK: slots W_HAVE_J, W_H_OF_MINV, W_JACOBIANS,
    W_NEWTON_FAILURES) carry the iteration matrix between calls (mutated in place).  Returns (x(t1), next h, accepted,
    rejected, status) with status 0 ok, 1 non-finite, 2 step size underflow.
    """
    x = x0.copy()
    n = x.shape[0]
    t = t0
    nacc = 0
    nrej = 0
    k1 = rhs(x, u, m, sw)
    fresh = False
    if work[W_HAVE_J] == 0.0:
        J[:, :] = jacobian_columns(x, k1, u, m, sw, np.arange(n), atol, rtol)
        work[W_HAVE_J] = 1.0
        work[W_H_OF_MINV] = -1.0
        work[W_JACOBIANS] += 1.0
        fresh = True
    h = min(h, hmax)
    while t < t1:
        last = False
        h_nominal = h
        if t + h >= t1 - 1e-12 * max(1.0, abs(t1)):
            h = t1 - t
            last = True
        hd = h * _D
        if abs(work[W_H_OF_MINV] - h) > 1e-9 * h:  # reuse the inverse for the same step size
            Minv[:, :] = np.linalg.inv(np.eye(n) - hd * J)
            work[W_H_OF_MINV] = h
        base2 = x + hd * k1
        Y2, k2, ok = _stage(base2, x + _GAMMA * h * k1, hd, Minv, rtol, atol, u, m, sw)
        if ok:
            base3 = x + h * _W * (k1 + k2)
            guess = x + h * (0.5 * k1 + 0.5 * k2)
            Y3, k3, ok = _stage(base3, guess, hd, Minv, rtol, atol, u, m, sw)
        if not ok:
            work[W_NEWTON_FAILURES] += 1.0
            nrej += 1
            if not fresh:  # first remedy: a new Jacobian at the current state
                J[:, :] = jacobian_columns(x, k1, u, m, sw, np.arange(n), atol, rtol)
                work[W_H_OF_MINV] = -1.0
                work[W_JACOBIANS] += 1.0
                fresh = True
                h = h_nominal if last else h
            else:
                h *= 0.25
            if h < 1e-12:
                return x, h, nacc, nrej, 2
            continue
        est = h * (_E1 * k1 + _E2 * k2 + _E3 * k3)
        est = Minv @ est
        err = _norm(est, Y3, rtol, atol)
        if not np.isfinite(err):
            return x, h, nacc, nrej, 1
        if err <= 1.0:
            t = t1 if last else t + h
            x = Y3
            k1 = k3
            nacc += 1
            fresh = False
            fac = 4.0 if err == 0.0 else min(4.0, max(0.2, 0.9 * err ** (-1.0 / 3.0)))
            h = min((h_nominal if last else h * fac), hmax)
        else:
            nrej += 1
            h *= max(0.2, 0.9 * err ** (-1.0 / 3.0))
            if h < 1e-12:
                return x, h, nacc, nrej, 2
    return x, h, nacc, nrej, 0
