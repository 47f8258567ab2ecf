"""One link in Newtonian coordinates, eq. (A.3), compiled: its floating-frame mass matrix
and forces (inertial, elastic, Kelvin–Voigt), and the acceleration field over its
distributed mass (uniform part and tidal part at Gauss points, with its potential).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from reference_model.field import tidal, tidal_potential
from reference_model.model_arrays import N_LINKS, S_ETA, S_I0, S_JEX, S_L, S_ML, S_MU, S_ORBIT, S_RHO


# =====================================================================================
# One link in Newtonian coordinates, eq. (A.3)
# =====================================================================================
@njit(cache=True, inline="always")
def link_newton(i, q, qd, th, om, m, basis, M, V):
    """Floating-frame mass matrix M_X and force V + elastic of link i (eq. A.3 for one body),
    written into the leading (3 + n) × (3 + n) block of M and the first 3 + n entries of V
    (work arrays of `system._link_rows`, at least that large).

    With S1 = ∫ρ u dξ = (m L/2, φ̄·a) and ṙ = Ṙ + θ̇ A S u + A e_y Φ ȧ:
        M_RR = m I,  M_Rθ = A S S1,  M_Ra = A e_y φ̄ᵀ,
        M_θθ = ∫ρ|u|² + J_extra = I_0 + aᵀ M_ff a + J_extra,  M_θa = ∫ρ ξ Φ,  M_aa = M_ff.
    The part of r̈ not linear in Ẍ is −θ̇² A u + 2 θ̇ A S e_y Φ ȧ, whence
        V_R = θ̇² A S1 − 2 θ̇ A S e_y (φ̄·ȧ),  V_θ = −2 θ̇ aᵀ M_ff ȧ,  V_a = θ̇² M_ff a,
    and the elastic and Kelvin–Voigt forces −K_ff a − η K_ff ȧ on the amplitudes.
    """
    sc = m.sc
    n = m.nm[i]
    b = basis[i]
    o = m.mo[i]
    mass = sc[S_ML]
    c = math.cos(th[i])
    s = math.sin(th[i])
    w = om[i]
    nx = 3 + n
    M[:nx, :nx] = 0.0
    V[:nx] = 0.0
    s1x = 0.5 * mass * sc[S_L]
    s1y = 0.0
    pbd = 0.0  # φ̄·ȧ
    for a in range(n):
        s1y += m.phi_bar[i, b, a] * q[o + a]
        pbd += m.phi_bar[i, b, a] * qd[o + a]
    # A S S1 = A (−S1y, S1x)
    ass_x = c * (-s1y) - s * s1x
    ass_y = s * (-s1y) + c * s1x
    M[0, 0] = mass
    M[1, 1] = mass
    M[0, 2] = ass_x
    M[1, 2] = ass_y
    M[2, 0] = ass_x
    M[2, 1] = ass_y
    mtt = sc[S_I0] + sc[S_JEX]
    for a in range(n):
        M[0, 3 + a] = -s * m.phi_bar[i, b, a]
        M[1, 3 + a] = c * m.phi_bar[i, b, a]
        M[3 + a, 0] = M[0, 3 + a]
        M[3 + a, 1] = M[1, 3 + a]
        M[2, 3 + a] = m.phi_x[i, b, a]
        M[3 + a, 2] = m.phi_x[i, b, a]
        for e in range(n):
            M[3 + a, 3 + e] = m.m_ff[i, b, a, e]
            mtt += q[o + a] * m.m_ff[i, b, a, e] * q[o + e]
    M[2, 2] = mtt
    # V_R = θ̇² A S1 − 2 θ̇ A S e_y (φ̄·ȧ);  A S1 = (c S1x − s S1y, s S1x + c S1y); A S e_y = (−c, −s)
    V[0] = w * w * (c * s1x - s * s1y) + 2.0 * w * c * pbd
    V[1] = w * w * (s * s1x + c * s1y) + 2.0 * w * s * pbd
    vth = 0.0
    for a in range(n):
        mfa = 0.0
        mfd = 0.0
        kf = 0.0
        for e in range(n):
            mfa += m.m_ff[i, b, a, e] * q[o + e]
            mfd += m.m_ff[i, b, a, e] * qd[o + e]
            kf += m.k_ff[i, b, a, e] * (q[o + e] + sc[S_ETA] * qd[o + e])
        vth += -2.0 * w * q[o + a] * mfd
        V[3 + a] = w * w * mfa - kf
    V[2] = vth


@njit(cache=True, inline="always")
def _gauss_point(i, b, g, q, c, s, R, m, rel):
    """Gauss point g of link i (basis b, frame angle with cosine c and sine s) relative to O,
    written into `rel`: R_i + A (x_g, w_g); returns its deflection w_g = φ(x_g)·a."""
    wg = 0.0
    for a in range(m.nm[i]):
        wg += m.phi_g[i, b, g, a] * q[m.mo[i] + a]
    ux = m.x_g[g]
    rel[0] = R[i, 0] + c * ux - s * wg
    rel[1] = R[i, 1] + s * ux + c * wg
    return wg


@njit(cache=True, inline="always")
def link_field_force(i, q, th, R, rO, aunif, m, basis, M, Q, rel):
    """Generalised force of the acceleration field on link i, over its distributed mass,
    into the first 3 + n entries of Q (`rel`: a 2-vector of scratch).

    The uniform part (thrust inertia of the reference point, −a_thr) is exact:
    Q = M_X[:, R] a_unif.  The tidal part is integrated with Gauss points along the beam:
    Q = Σ_g w_g ρ [I; (A S u_g)ᵀ; (A e_y φ_g)ᵀ] Δg(r_O, R + A u_g).
    """
    sc = m.sc
    n = m.nm[i]
    b = basis[i]
    for r in range(3 + n):
        Q[r] = M[r, 0] * aunif[0] + M[r, 1] * aunif[1]
    if sc[S_ORBIT] == 0.0:
        return
    c = math.cos(th[i])
    s = math.sin(th[i])
    rel[:] = 0.0
    rho = sc[S_RHO]
    for g in range(m.x_g.shape[0]):
        wg = _gauss_point(i, b, g, q, c, s, R, m, rel)
        ux = m.x_g[g]
        gx, gy = tidal(rO, rel)
        gx *= sc[S_MU] * rho * m.w_g[g]
        gy *= sc[S_MU] * rho * m.w_g[g]
        Q[0] += gx
        Q[1] += gy
        # A S u = (−(A u)_y, (A u)_x),  A u = (c ux − s wg, s ux + c wg)
        Q[2] += -(s * ux + c * wg) * gx + (c * ux - s * wg) * gy
        for a in range(n):
            Q[3 + a] += m.phi_g[i, b, g, a] * (-s * gx + c * gy)


@njit(cache=True)
def links_tidal_potential(q, th, R, rO, m, basis):
    """Tidal potential energy of the six links / μ [kg·m²/s² per m³/s²]: the distributed
    mass at the Gauss points of `link_field_force`, Σ_i Σ_g ρ w_g U(r_O, R_i + A u_g)/μ, the
    energy whose negative gradient `link_field_force`'s forces are (observe's energy)."""
    rho = m.sc[S_RHO]
    rel = np.empty(2)
    e = 0.0
    for i in range(N_LINKS):
        b = basis[i]
        c = math.cos(th[i])
        s = math.sin(th[i])
        for g in range(m.x_g.shape[0]):
            _gauss_point(i, b, g, q, c, s, R, m, rel)
            e += rho * m.w_g[g] * tidal_potential(rO, rel)
    return e
