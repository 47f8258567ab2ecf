"""The coupled system, eqs. (3)–(12), compiled: base, links (eq. A.6), joints and rotors,
target and grasps assembled into M_g, f and the active constraint rows, step by step.
Solving it for the constraint forces and accelerations: solve.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from reference_model.condense import condense, project, reduced_mass
from reference_model.field import tidal
from reference_model.kinematics import joint_section_angles, kinematics, wrist_angles
from reference_model.link import link_field_force, link_newton
from reference_model.model_arrays import (
    N_LINKS, S_ALPHA, S_BETA, S_BM, S_CM, S_JB, S_JT, S_KM, S_MB0, S_MT, S_MTOT0, S_MU, S_ORBIT, S_WK,
    S_WLAM, S_WLIM, U_TAU_B, U_TAU_M, U_THRUST)


# =====================================================================================
# The coupled system, eqs. (3)–(12), step by step
# =====================================================================================
@njit(cache=True, inline="always")
def _base_rows(Mg, f, q, rO, mB, aunif, u, sc):
    """Base rows of eq. (3): M = diag(m_B, m_B, J_B); thrust T A(θ_B) e_x through the COM,
    control torque u_B (eq. 4), the field felt in O's frame (docs/physics.md §5)."""
    cb = math.cos(q[2])
    sb = math.sin(q[2])
    thrust = u[U_THRUST]
    Mg[0, 0] = mB
    Mg[1, 1] = mB
    Mg[2, 2] = sc[S_JB]
    f[0] += mB * aunif[0] + thrust * cb
    f[1] += mB * aunif[1] + thrust * sb
    f[2] += u[U_TAU_B]
    if sc[S_ORBIT] != 0.0:
        gx, gy = tidal(rO, q[0:2])
        f[0] += sc[S_MU] * mB * gx
        f[1] += sc[S_MU] * mB * gy


@njit(cache=True, inline="always")
def _link_rows(Mg, f, q, qd, kin, rO, aunif, m, basis):
    """The links projected on q_m, eq. (A.6):  Jᵀ M J q̈ = Jᵀ (V + F_ext − M J̇ q̇).

    J = ∂X_i/∂q_m is zero outside the base, the joints up to link i and the amplitudes of
    the links up to it (its arm), and its amplitude rows are [0 | I] on the link's own
    amplitudes (the last columns): the products are written out on that structure,
        (M J)[r, c]   = Σ_{s<3} M[r, s] J[s, c] + M[r, 3 + c − c0]       (c ≥ c0),
        (Jᵀ M J)[r, c] = Σ_{s<3} J[s, r] (M J)[s, c] + (M J)[3 + r − c0, c]  (r ≥ c0),
    with c0 the first column of the own amplitudes.
    """
    th, om, R, JR, Jth, cR = kin.th, kin.om, kin.R, kin.JR, kin.Jth, kin.cR
    # work arrays, one set for the six links (a link's block is its leading part): the
    # same arithmetic as fresh arrays per link, without the 48 allocations
    nx_max = 3 + m.nq
    M = np.empty((nx_max, nx_max))
    V = np.empty(nx_max)
    Q = np.empty(nx_max)
    F = np.empty(nx_max)
    rel = np.empty(2)
    cols = np.empty(m.nq, dtype=np.int64)
    J3 = np.empty((3, m.nq))  # the frame rows of J: R (2) and θ
    MJ = np.empty((nx_max, m.nq))
    for i in range(N_LINKS):
        n = m.nm[i]
        nx = 3 + n
        link_newton(i, q, qd, th, om, m, basis, M, V)
        link_field_force(i, q, th, R, rO, aunif, m, basis, M, Q, rel)
        nc = _arm_columns(i, m, cols)
        c0 = nc - n  # the link's own amplitudes are the last columns
        for c in range(nc):
            J3[0, c] = JR[i, 0, cols[c]]
            J3[1, c] = JR[i, 1, cols[c]]
            J3[2, c] = Jth[i, cols[c]]
        for r in range(nx):
            F[r] = V[r] + Q[r]
            F[r] -= M[r, 0] * cR[i, 0] + M[r, 1] * cR[i, 1]  # − M J̇q̇ (only R has J̇q̇ ≠ 0)
        for r in range(nx):
            for c in range(nc):
                v = M[r, 0] * J3[0, c] + M[r, 1] * J3[1, c] + M[r, 2] * J3[2, c]
                if c >= c0:
                    v += M[r, 3 + c - c0]
                MJ[r, c] = v
        for r in range(nc):
            gr = cols[r]
            jf = J3[0, r] * F[0] + J3[1, r] * F[1] + J3[2, r] * F[2]
            if r >= c0:
                jf += F[3 + r - c0]
            f[gr] += jf
            for c in range(r, nc):
                v = J3[0, r] * MJ[0, c] + J3[1, r] * MJ[1, c] + J3[2, r] * MJ[2, c]
                if r >= c0:
                    v += MJ[3 + r - c0, c]
                Mg[gr, cols[c]] += v
                if c != r:
                    Mg[cols[c], gr] += v


@njit(cache=True, inline="always")
def _arm_columns(i, m, cols):
    """Columns of q_m the Newtonian coordinates of link i depend on, into the first entries
    of cols: the base (3), the joints of its arm up to it, the amplitudes of its arm's links
    up to it (its own last).  Returns their number."""
    k = i // 3
    first = 3 * k
    cols[0], cols[1], cols[2] = 0, 1, 2
    c = 3
    for j in range(first, i + 1):
        cols[c] = 3 + j
        c += 1
    for j in range(first, i + 1):
        for a in range(m.nm[j]):
            cols[c] = m.mo[j] + a
            c += 1
    return c


@njit(cache=True, inline="always")
def _joint_rows(f, q, qd, thm, thmd, u, m, basis):
    """Joint springs and rotors, eqs. (5), (2) and the u_e of eq. (4).

    Eq. (5) on the section-relative angle (docs/physics.md §3.3):
        u_J = −K_m(ψ_J − θ_m) − C_m(ψ̇_J − θ̇_m),   ψ_J = θ_J + w_c'(0) − w_p'(L).
    Its generalised force u_J ∂ψ_J/∂q: u_J on θ_J; on the amplitudes the paper's
        u_e = u_J φ_c'(0) on the child link,  −u_J φ_p'(L) on the parent link,
    i.e. +u_J on the child's proximal section and −u_J on the parent's distal section.
    Eq. (2), the last row of eq. (7):  B_m θ̈_m = τ_m − K_m(θ_m − ψ_J) − C_m(θ̇_m − ψ̇_J)
                                               = τ_m − u_J.
    """
    sc = m.sc
    psi, psid = joint_section_angles(q, qd, m, basis)
    uJ = np.zeros(6)
    thmdd = np.zeros(6)
    for j in range(6):
        uJ[j] = -sc[S_KM] * (psi[j] - thm[j]) - sc[S_CM] * (psid[j] - thmd[j])
        f[3 + j] += uJ[j]
        c = j
        bc = basis[c]
        for a in range(m.nm[c]):
            f[m.mo[c] + a] += uJ[j] * m.slope_0[c, bc, a]
        if j % 3 != 0:
            p = j - 1
            bp = basis[p]
            for a in range(m.nm[p]):
                f[m.mo[p] + a] -= uJ[j] * m.slope_L[p, bp, a]
        thmdd[j] = (u[U_TAU_M + j] - uJ[j]) / sc[S_BM]
    return uJ, thmdd


@njit(cache=True, inline="always")
def _target_rows(Mg, f, XT, rO, aunif, nq, sc):
    """Target rows of eq. (3) (Newtonian, X_T): M = diag(m_T, m_T, J_T), the field."""
    Mg[nq, nq] = sc[S_MT]
    Mg[nq + 1, nq + 1] = sc[S_MT]
    Mg[nq + 2, nq + 2] = sc[S_JT]
    f[nq] += sc[S_MT] * aunif[0]
    f[nq + 1] += sc[S_MT] * aunif[1]
    if sc[S_ORBIT] != 0.0:
        gx, gy = tidal(rO, XT[0:2])
        f[nq] += sc[S_MU] * sc[S_MT] * gx
        f[nq + 1] += sc[S_MU] * sc[S_MT] * gy


@njit(cache=True)
def _bistop(psi, psid, lim, k, lam):
    """Wrist bistop τ_w on the target (docs/physics.md §4.3): a Hunt–Crossley contact beyond
    ±ψ_lim on the relative rotation ψ, clamped so that it only pushes:

        δ = |ψ| − ψ_lim  (penetration),   δ̇ = sgn(ψ) ψ̇,
        τ_w = −sgn(ψ) max(0, k δ + λ δ δ̇)   for δ > 0,   τ_w = 0 otherwise.

    Zero at δ = 0 (continuous at contact), never pulling (τ_w ψ ≤ 0 beyond the limit).
    """
    if psi > lim:
        s = 1.0
    elif psi < -lim:
        s = -1.0
    else:
        return 0.0
    d = s * psi - lim
    push = d * (k + lam * s * psid)
    if push <= 0.0:
        return 0.0
    return -s * push


@njit(cache=True, inline="always")
def _grasp_rows(f, q, qd, XT, XTd, kin, m, sw, tauw_slaved):
    """Wrist bistops and the grasp constraints of eqs. (8)–(12), for the active grasps.

    Bistop (docs/physics.md §4.3): τ_w = bistop(ψ_w, ψ̇_w), +τ_w on the target, −τ_w on the
    terminal link's distal section (generalised force −τ_w ∂(θ_3 + w_3'(L))/∂q); with the
    static shapes condensed, `tauw_slaved` (the stop's law through the terminal link's
    deflection e, condense.py).
    Constraint:  φ_k = r_EE,k − (r_T + A(θ_T) ρ_G,k) = 0,  G = ∂φ/∂Y (eq. 8),
        B = −Ġ Ẏ = −c_EE − θ̇_T² A(θ_T) ρ_G (eq. 10),   B* = B − 2α φ̇ − β² φ (eq. 12).
    """
    sc = m.sc
    nq = m.nq
    ny = nq + 3
    th, om, Jth = kin.th, kin.om, kin.Jth
    rE, rEd, JE, cE = kin.rE, kin.rEd, kin.JE, kin.cE
    nc = 2 * (sw.grasp_on[0] + sw.grasp_on[1])
    G = np.zeros((nc, ny))
    phi = np.zeros(nc)
    phid = np.zeros(nc)
    Bs = np.zeros(nc)
    tauw = np.zeros(2)
    psi_w, psid_w = wrist_angles(q, qd, XT, XTd, th, om, m, sw.basis)
    cT = math.cos(XT[2])
    sT = math.sin(XT[2])
    row = 0
    for k in range(2):
        if sw.grasp_on[k] == 0:
            continue
        i3 = 3 * k + 2
        b3 = sw.basis[i3]
        if m.cond:
            tw = tauw_slaved[k]
        else:
            tw = _bistop(psi_w[k], psid_w[k], sc[S_WLIM], sc[S_WK], sc[S_WLAM])
        tauw[k] = tw
        f[nq + 2] += tw
        for col in range(nq):
            f[col] -= tw * Jth[i3, col]
        for a in range(m.nm[i3]):
            f[m.mo[i3] + a] -= tw * m.slope_L[i3, b3, a]
        gx = cT * sw.rho_G[k, 0] - sT * sw.rho_G[k, 1]  # A(θ_T) ρ_G
        gy = sT * sw.rho_G[k, 0] + cT * sw.rho_G[k, 1]
        for d in range(2):
            for col in range(nq):
                G[row + d, col] = JE[k, d, col]
            G[row + d, nq + d] = -1.0
        G[row, nq + 2] = gy  # −A S ρ_G = −(−gy, gx)
        G[row + 1, nq + 2] = -gx
        phi[row] = rE[k, 0] - XT[0] - gx
        phi[row + 1] = rE[k, 1] - XT[1] - gy
        phid[row] = rEd[k, 0] - XTd[0] + XTd[2] * gy
        phid[row + 1] = rEd[k, 1] - XTd[1] - XTd[2] * gx
        for d in range(2):
            g_d = gx if d == 0 else gy
            Bs[row + d] = (-cE[k, d] - XTd[2] * XTd[2] * g_d
                           - 2.0 * sc[S_ALPHA] * phid[row + d] - sc[S_BETA] ** 2 * phi[row + d])
        row += 2
    return G, phi, phid, Bs, tauw


@njit(cache=True)
def assemble(x, u, m, sw):
    """The coupled system (3)/(6)–(12) at state x with inputs u.

    Returns Mg (ny×ny), f (ny) = −CẎ + NL + u  (right-hand side of eq. 6 without W R),
    the active constraint rows G (nc×ny), φ (nc), φ̇ (nc), B* (nc) of eqs. (8)–(12),
    the motor accelerations of eq. (2), the joint torques u_J of eq. (5) and the wrist
    torques, and the acceleration of the reference point.

    With the static shapes condensed (condense.py) their amplitudes and rates in x are not
    read: they are solved for first, and the force on them is passed on at the end (on
    f and the rotors' θ̈_m); Mg is the mass matrix of all of Y (`assemble_reduced`: of the
    coordinates left).
    """
    return _assemble(x, u, m, sw)[:10]


@njit(cache=True)
def assemble_reduced(x, u, m, sw):
    """The coupled system over z = [Y, θ_m] with the static shapes slaved (condense.py):
    (M_z, f_z, G_z, φ, φ̇, B*, u_J, τ_w, a_O, ė), ė the rates of the stop deflections; M_z = Pᵀ blockdiag(M_g, B_m I) P, f_z = [f,
    B_m θ̈_m] of `assemble` (which holds Tᵀ f_s already), G_z = [G, 0]; rows and columns of
    the static shapes zero.  What `solve.solve_constrained` takes with the elimination order
    of a condensed model (its z̈: Ÿ, then θ̈_m)."""
    Mg, f, G, phi, phid, Bs, thmdd, uJ, tauw, aO, T, cols, ncol, idx, edot = _assemble(x, u, m, sw)
    ny = m.nq + 3
    Mz = reduced_mass(Mg, T, cols, ncol, idx, m)
    fz = np.empty(ny + 6)
    fz[:ny] = f
    for j in range(6):
        fz[ny + j] = m.sc[S_BM] * thmdd[j]
    Gz = np.zeros((G.shape[0], ny + 6))
    Gz[:, :ny] = G
    return Mz, fz, Gz, phi, phid, Bs, uJ, tauw, aO, edot


@njit(cache=True, inline="always")
def _assemble(x, u, m, sw):
    """`assemble`, and the slaving of the static shapes (T, cols, ncol, idx of
    `condense.condense`)."""
    x, T, cols, ncol, idx, tauw_slaved, edot, fkv = condense(x, m, sw, False)
    nq = m.nq
    sc = m.sc
    ny = nq + 3
    ns = ny + 6
    q = x[0:nq]
    XT = x[nq:ny]
    thm = x[ny:ns]
    qd = x[ns:ns + nq]
    XTd = x[ns + nq:ns + ny]
    thmd = x[ns + ny:2 * ns]
    rO = x[2 * ns:2 * ns + 2]
    mused = x[2 * ns + 4]
    mB = sc[S_MB0] - mused
    msys = sc[S_MTOT0] - mused

    kin = kinematics(q, qd, m, sw.basis)

    # reference point: a_O = g(r_O) + T/m_sys A(θ_B) e_x; every element feels −a_thr
    cb = math.cos(q[2])
    sb = math.sin(q[2])
    thrust = u[U_THRUST]
    athr = np.array([thrust / msys * cb, thrust / msys * sb])
    aunif = -athr

    Mg = np.zeros((ny, ny))
    f = np.zeros(ny)
    _base_rows(Mg, f, q, rO, mB, aunif, u, sc)
    _link_rows(Mg, f, q, qd, kin, rO, aunif, m, sw.basis)
    uJ, thmdd = _joint_rows(f, q, qd, thm, thmd, u, m, sw.basis)
    _target_rows(Mg, f, XT, rO, aunif, nq, sc)
    G, phi, phid, Bs, tauw = _grasp_rows(f, q, qd, XT, XTd, kin, m, sw, tauw_slaved)
    for k in range(2):  # the Kelvin–Voigt force of the stop deflection's rate (condense.py)
        for s in range(idx.shape[1]):
            if idx[k, s] >= 0:
                f[idx[k, s]] += fkv[k, s]
    project(f, thmdd, T, cols, ncol, idx, m)

    aO = athr.copy()
    if sc[S_ORBIT] != 0.0:
        r2 = rO[0] * rO[0] + rO[1] * rO[1]
        r3 = r2 * math.sqrt(r2)
        aO[0] += -sc[S_MU] * rO[0] / r3
        aO[1] += -sc[S_MU] * rO[1] / r3
    return Mg, f, G, phi, phid, Bs, thmdd, uJ, tauw, aO, T, cols, ncol, idx, edot
