"""What is measured of a state, compiled: the values the shared driver's sensors read
and the momentum of base, links and target (observe.py names and packs them).

`sense` and `completed` are whole calls from Python, one array back each: a compiled call
costs a few µs to unpack `ModelArrays` and to box what it returns, more than the
kernels' own work here, and the sampled-data loop makes them at every sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from reference_model.condense import condense
from reference_model.kinematics import joint_section_angles, kinematics, wrist_angles
from reference_model.model_arrays import N_LINKS, S_I0, S_JB, S_JEX, S_JT, S_L, S_MB0, S_ML, S_MT

@njit(cache=True)
def _mechanical_state(x, m):
    """(q, X_T, q̇, Ẋ_T, m_B) of the state x: the generalized coordinates, the target's pose,
    their rates and the base mass (the propellant used is the state's last entry)."""
    nq = m.nq
    ny = nq + 3
    ns = ny + 6
    return x[0:nq], x[nq:ny], x[ns:ns + nq], x[ns + nq:ns + ny], m.sc[S_MB0] - x[2 * ns + 4]


@njit(cache=True)
def sensor_values(x, m, sw):
    """What the sensors of the shared driver read, in one call (rsmcheck.core.engine.Sensors):
    end effectors rE, ṙE (2×2), ψ_J, ψ̇_J (6), wrist angles ψ_w (2), system COM relative to
    O (2) and the system mass.  COM: (m_B r_B + m_T r_T + Σ_i (m R_i + A(θ_i) S1_i)) / m_sys
    with S1_i = (m L/2, φ̄·a_i)."""
    sc = m.sc
    q, XT, qd, XTd, mB = _mechanical_state(x, m)
    kin = kinematics(q, qd, m, sw.basis)
    th, om, R = kin.th, kin.om, kin.R
    psi, psid = joint_section_angles(q, qd, m, sw.basis)
    psi_w, _ = wrist_angles(q, qd, XT, XTd, th, om, m, sw.basis)
    mL = sc[S_ML]
    msys = mB + sc[S_MT] + N_LINKS * mL
    com = np.zeros(2)
    com[0] = mB * q[0] + sc[S_MT] * XT[0]
    com[1] = mB * q[1] + sc[S_MT] * XT[1]
    s1x = 0.5 * mL * sc[S_L]
    for i in range(N_LINKS):
        b = sw.basis[i]
        s1y = 0.0
        for a in range(m.nm[i]):
            s1y += m.phi_bar[i, b, a] * q[m.mo[i] + a]
        c = math.cos(th[i])
        s = math.sin(th[i])
        com[0] += mL * R[i, 0] + c * s1x - s * s1y
        com[1] += mL * R[i, 1] + s * s1x + c * s1y
    return kin.rE, kin.rEd, psi, psid, psi_w, com / msys, msys


#: `sense`'s vector after the completed state (its first nx entries): offsets of ψ_J, ψ̇_J
#: (6 each), ψ_w (2), r_E, ṙ_E (2 × 2 each, a row per arm), the system COM in base axes
#: about the base COM (2) and the system mass (1)
SENSE_PSI, SENSE_PSID, SENSE_PSIW, SENSE_RE, SENSE_RED, SENSE_COMB, SENSE_MASS = 0, 6, 12, 14, 18, 22, 24
N_SENSED = 25


@njit(cache=True)
def completed(x, m, sw, settle):
    """x with the condensed static shapes filled in and the stop deflections in range: the
    first result of `condense.condense` (x itself when nothing is condensed)."""
    return condense(x, m, sw, settle)[0]


@njit(cache=True)
def sense(x, m, sw):
    """Everything the shared driver's sensors read of the state x, in one vector: x completed
    (`completed`), then the `sensor_values` of it at the offsets SENSE_* and the system
    COM in base axes about the base COM,
        COM_B = A(θ_B)ᵀ (COM − r_B)."""
    xc = condense(x, m, sw, False)[0]
    rE, rEd, psi, psid, psi_w, com, msys = sensor_values(xc, m, sw)
    nx = xc.shape[0]
    out = np.empty(nx + N_SENSED)
    out[:nx] = xc
    o = out[nx:]
    o[SENSE_PSI:SENSE_PSI + 6] = psi
    o[SENSE_PSID:SENSE_PSID + 6] = psid
    o[SENSE_PSIW:SENSE_PSIW + 2] = psi_w
    for k in range(2):
        for j in range(2):
            o[SENSE_RE + 2 * k + j] = rE[k, j]
            o[SENSE_RED + 2 * k + j] = rEd[k, j]
    c, s = math.cos(xc[2]), math.sin(xc[2])
    d0, d1 = com[0] - xc[0], com[1] - xc[1]
    o[SENSE_COMB] = c * d0 + s * d1
    o[SENSE_COMB + 1] = -s * d0 + c * d1
    o[SENSE_MASS] = msys
    return out


@njit(cache=True)
def momentum(x, m, sw):
    """(p_x, p_y, L_z): linear momentum and angular momentum about O of base, links and
    target (observe's `momentum_I`).  Per link, exactly from the modal integrals
    (r = R + A u, ṙ = Ṙ + θ̇ A S u + A e_y Φ ȧ, S1 = (m L/2, φ̄·a)):
        p = m Ṙ + θ̇ A S S1 + A e_y (φ̄·ȧ)
        L = R × p + (A S1) × Ṙ + θ̇ (I_0 + aᵀ M_ff a + J_extra) + (∫ρ ξ Φ)·ȧ."""
    sc = m.sc
    q, XT, qd, XTd, mB = _mechanical_state(x, m)
    kin = kinematics(q, qd, m, sw.basis)
    th, om, R, Rd = kin.th, kin.om, kin.R, kin.Rd
    mL = sc[S_ML]
    px = mB * qd[0] + sc[S_MT] * XTd[0]
    py = mB * qd[1] + sc[S_MT] * XTd[1]
    L = mB * (q[0] * qd[1] - q[1] * qd[0]) + sc[S_JB] * qd[2]
    L += sc[S_MT] * (XT[0] * XTd[1] - XT[1] * XTd[0]) + sc[S_JT] * XTd[2]
    s1x = 0.5 * mL * sc[S_L]
    for i in range(N_LINKS):
        b = sw.basis[i]
        o = m.mo[i]
        n = m.nm[i]
        s1y = 0.0
        pbd = 0.0  # φ̄·ȧ
        pxd = 0.0  # (∫ρ ξ Φ)·ȧ
        inertia = sc[S_I0] + sc[S_JEX]
        for a in range(n):
            s1y += m.phi_bar[i, b, a] * q[o + a]
            pbd += m.phi_bar[i, b, a] * qd[o + a]
            pxd += m.phi_x[i, b, a] * qd[o + a]
            for e in range(n):
                inertia += q[o + a] * m.m_ff[i, b, a, e] * q[o + e]
        c = math.cos(th[i])
        s = math.sin(th[i])
        asx = c * s1x - s * s1y  # A S1
        asy = s * s1x + c * s1y
        plx = mL * Rd[i, 0] - om[i] * asy - s * pbd  # A e_y = (−s, c)
        ply = mL * Rd[i, 1] + om[i] * asx + c * pbd
        px += plx
        py += ply
        L += R[i, 0] * ply - R[i, 1] * plx + asx * Rd[i, 1] - asy * Rd[i, 0] + om[i] * inertia + pxd
    out = np.empty(3)
    out[0] = px
    out[1] = py
    out[2] = L
    return out
