"""Solving the coupled system, compiled: the constraint forces of eq. (11) and the
accelerations of eq. (6), by an envelope Cholesky factor of M_g in an elimination order
that has no fill-in (`elimination_order`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def elimination_order(nq, nm, mo, n_dynamic=None, rotors=False):
    """Order of the rows of Mg for its Cholesky factor, and the envelope of each row.

    Mg couples the base with both arms and each arm with itself, but never the two arms
    with each other (a link's Newtonian coordinates depend on the base and its own arm
    only, eq. A.6), and the target only with itself (eq. 3).  Eliminated in the order
    arm 1 (joints, amplitudes), arm 2, base, target, the factor has no fill-in outside the
    envelope `first[r]` ≤ column ≤ r: a quarter of the dense work at 4 shapes per link.
    Returns (order, first): row r of the ordered matrix is row order[r] of Mg.

    With the static shapes slaved (condense.py) the matrix is M_z over z = [Y, θ_m]:
    n_dynamic[i] ≤ nm[i] are the leading shapes of link i that are coordinates (the
    others are left out of the order), `rotors` puts each arm's three rotors (rows ny +
    3k + s) at the end of its block (the slaved shapes couple them with their arm).
    """
    ny = nq + 3
    if n_dynamic is None:
        n_dynamic = nm
    size = ny - int(np.sum(nm)) + int(np.sum(n_dynamic)) + (6 if rotors else 0)
    order = np.empty(size, dtype=np.int64)
    first = np.empty(size, dtype=np.int64)
    r = 0
    for k in range(2):
        start = r
        for s in range(3):
            order[r] = 3 + 3 * k + s
            r += 1
        for s in range(3):
            i = 3 * k + s
            for a in range(n_dynamic[i]):
                order[r] = mo[i] + a
                r += 1
        if rotors:
            for s in range(3):
                order[r] = ny + 3 * k + s
                r += 1
        first[start:r] = start
    for d in range(3):  # the base couples with everything before it
        order[r] = d
        first[r] = 0
        r += 1
    for d in range(3):  # the target is diagonal
        order[r] = nq + d
        first[r] = r
        r += 1
    return order, first


@njit(cache=True)
def _cholesky(A, order, first, Lc):
    """Lc ← the Cholesky factor of the symmetric positive definite A in the elimination
    order of `elimination_order`: Lc Lcᵀ = P A Pᵀ (row r of P A is row order[r] of A), row
    by row, with entries only inside the envelope first[r] ≤ column ≤ r (the rest of Lc is
    not touched); A's rows and columns outside `order` are not read.  False if the
    ordered A is not positive definite."""
    n = order.shape[0]
    for r in range(n):
        o_r = order[r]
        f_r = first[r]
        for j in range(f_r, r + 1):
            s = A[o_r, order[j]]
            for k in range(max(f_r, first[j]), j):
                s -= Lc[r, k] * Lc[j, k]
            if j < r:
                Lc[r, j] = s / Lc[j, j]
            elif s <= 0.0:
                return False
            else:
                Lc[r, r] = math.sqrt(s)
    return True


@njit(cache=True)
def _forward(Lc, first, Y):
    """Y ← Lc⁻¹ Y (forward substitution inside the envelope), all columns of Y in one pass
    over Lc; the rows of Y are already in the elimination order."""
    nb = Y.shape[1]
    for r in range(Lc.shape[0]):
        for c in range(first[r], r):
            l_rc = Lc[r, c]
            for col in range(nb):
                Y[r, col] -= l_rc * Y[c, col]
        for col in range(nb):
            Y[r, col] /= Lc[r, r]


@njit(cache=True)
def _backward(Lc, first, y, order, x):
    """x ← Pᵀ Lc⁻ᵀ y (back substitution, column by column of Lc; y is overwritten)."""
    for r in range(Lc.shape[0] - 1, -1, -1):
        z = y[r] / Lc[r, r]
        for c in range(first[r], r):
            y[c] -= Lc[r, c] * z
        x[order[r]] = z


@njit(cache=True)
def solve_constrained(Mg, f, G, Bs, m):
    """Eq. (11) and the accelerations of eq. (6).

    With W = −Gᵀ (R_cl is the force on the target; the end effector feels −R_cl):
        R_cl = [G Mg⁻¹ W]⁻¹ [B* − G Mg⁻¹ f],     Ÿ = Mg⁻¹ (f + W R_cl).
    With the envelope Cholesky P Mg Pᵀ = L Lᵀ (`_cholesky`), y = L⁻¹ P f and Z = L⁻¹ P Gᵀ:
        G Mg⁻¹ Gᵀ = Zᵀ Z,   G Mg⁻¹ f = Zᵀ y,   Ÿ = Pᵀ L⁻ᵀ (y − Z R_cl),
    one forward substitution for [y, Z] and a single back substitution; the small system
    Zᵀ Z R_cl = Zᵀ y − B* is solved by its own (dense) Cholesky factor.

    Only the coordinates in the elimination order take part (`elimination_order`): with
    the static shapes slaved (condense.py) Mg, f, G are those of z = [Y, θ_m]
    (`system.assemble_reduced`) and the shapes' entries of the result are 0.
    """
    nc = G.shape[0]
    ny = m.order.shape[0]
    order = m.order
    Lc = np.empty((ny, ny))
    ydd = np.zeros(Mg.shape[0])
    Rcl = np.empty(nc)
    if not _cholesky(Mg, order, m.first, Lc):
        ydd[:] = np.nan  # not positive definite: the caller sees a non-finite state
        Rcl[:] = np.nan
        return ydd, Rcl
    Y = np.empty((ny, 1 + nc))  # [y, Z] = L⁻¹ P [f, Gᵀ]
    for r in range(ny):
        Y[r, 0] = f[order[r]]
        for i in range(nc):
            Y[r, 1 + i] = G[i, order[r]]
    _forward(Lc, m.first, Y)
    if nc > 0:
        S = np.empty((nc, nc))  # Zᵀ Z = G Mg⁻¹ Gᵀ
        w = np.empty((nc, 1))  # Zᵀ y − B* = G Mg⁻¹ f − B*
        for i in range(nc):
            for j in range(i + 1):
                s = 0.0
                for r in range(ny):
                    s += Y[r, 1 + i] * Y[r, 1 + j]
                S[i, j] = s
                S[j, i] = s
            s = -Bs[i]
            for r in range(ny):
                s += Y[r, 1 + i] * Y[r, 0]
            w[i, 0] = s
        natural = np.arange(nc)  # S is dense: natural order, the whole lower triangle
        full = np.zeros(nc, dtype=np.int64)
        Ls = np.empty((nc, nc))
        if not _cholesky(S, natural, full, Ls):
            ydd[:] = np.nan  # the active constraints are dependent
            Rcl[:] = np.nan
            return ydd, Rcl
        _forward(Ls, full, w)
        _backward(Ls, full, w[:, 0], natural, Rcl)
        for r in range(ny):
            for i in range(nc):
                Y[r, 0] -= Y[r, 1 + i] * Rcl[i]
    _backward(Lc, m.first, Y[:, 0], order, ydd)
    return ydd, Rcl
