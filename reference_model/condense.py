"""The static correction shapes slaved to the springs (Guyan condensation), compiled
(docs/physics.md §2.4).

Each flexible link carries, after its eigenmodes, two static shapes: its bending under
unit end couples.  As states they add Ritz frequencies of 0.4–0.8 kHz on a fixed frame
(0.8–1.1 kHz coupled to the free-floating frames), above the beam modes they stand in for
and far above the loads.  Slaved, their amplitudes are at every instant the static
equilibrium of each arm under the joint springs of eq. (5) and the wrist stop, given all
the other coordinates,

    ∂V/∂a_s = 0,   V = ½ Σ_i aᵀ K_ff,i a + ½ K_m Σ_J (ψ_J − θ_m,J)² + ½ k_w δ_w²,
    ψ_J = ψ_J,r + D_J a_s,        ψ_w = ψ_w,r + d_wᵀ a_s,

with ψ_J,r, ψ_w,r the section angles without the static shapes, D_J their end slopes
(+φ_s'(0) of the child, −φ_s'(L) of the parent), d_w = −φ_s'(L) of the terminal link and
δ_w = ψ_w ∓ ψ_lim beyond a stop.  Per arm (six static amplitudes) this is linear:

    K̃ a_s = −K_m Σ_J D_Jᵀ (ψ_J,r − θ_m,J) − k_w d_w (ψ_w,r ∓ ψ_lim) − K_se a_e,
    K̃ = blockdiag(K_ss,i) + K_m Σ_J D_Jᵀ D_J + k_w d_w d_wᵀ,

the k_w terms only where the wrist of a holding arm is beyond its stop (K_se, the
stiffness between static shapes and eigenmodes, is zero to round-off).  With
z = [Y, θ_m] (the rotors after Y) the right-hand side is B z + k_w d_w (±ψ_lim), so

    a_s = T z + c,   T = K̃⁻¹ B,   ȧ_s = T ż,

T and c constant for a given terminal basis and stop state (`slaving_tables`, once per
model).  The equations of z follow from the kinetic and potential energy of the whole
model with the shapes slaved (their mass kept):

    M_z = Pᵀ blockdiag(M_g, B_m I) P,    f_z = Pᵀ [f; τ_m − u_J],

P the identity with the static rows replaced by T (`reduced_mass`, `project`).  Since the
springs balance on the shapes by construction, what Tᵀ f_s carries to z is their damping
(Kelvin–Voigt, the joints' C_m, the stop's), their field and their inertial loads; the
elastic forces on z are −∂V/∂z of the condensed energy, the damping dissipates what the
full model would at ȧ_s = T ż.  The slaved shapes also couple each arm's rotors to it
through their inertia (T has rotor columns).

A grasp's constraint rows never involve the shapes: a holding arm's links are all in the
PP basis, whose shapes vanish at the distal pin, so the end effector does not move with
them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from reference_model.kinematics import joint_section_angles
from reference_model.model_arrays import S_BM, S_KM, S_WK, S_WLIM

#: static amplitudes per arm: 2 per link, 3 links
N_ARM = 6


@njit(cache=True, inline="always")
def _slot(m, i, s):
    """Index in q of static shape s (0, 1) of link i, or −1 if the link has none."""
    if m.nm[i] - m.ne[i] <= s:
        return -1
    return m.mo[i] + m.ne[i] + s


@njit(cache=True)
def _stiffness(k, m, basis):
    """K̃ of arm k without the stop (6×6), D (3 joints × 6) and d_w (6) in the local order
    [link 1: s0, s1, link 2: …, link 3: …], and the q-index of each local amplitude (−1
    where a link has no static shapes: an identity block, the amplitude solves to zero)."""
    km = m.sc[S_KM]
    Kt = np.zeros((N_ARM, N_ARM))
    D = np.zeros((3, N_ARM))
    dw = np.zeros(N_ARM)
    idx = np.full(N_ARM, -1, dtype=np.int64)
    for li in range(3):
        i = 3 * k + li
        b = basis[i]
        ne = m.ne[i]
        for s in range(2):
            r = 2 * li + s
            idx[r] = _slot(m, i, s)
            if idx[r] < 0:
                Kt[r, r] = 1.0
                continue
            for t in range(2):
                if _slot(m, i, t) >= 0:
                    Kt[r, 2 * li + t] = m.k_ff[i, b, ne + s, ne + t]
            D[li, r] += m.slope_0[i, b, ne + s]  # ψ_J of the joint at the link's root
            if li < 2:
                D[li + 1, r] -= m.slope_L[i, b, ne + s]  # ψ_J of the next joint
            else:
                dw[r] = -m.slope_L[i, b, ne + s]  # ψ_w = θ_T − θ_3 − w_3'(L)
    for r in range(N_ARM):
        for c in range(N_ARM):
            v = 0.0
            for j in range(3):
                v += D[j, r] * D[j, c]
            Kt[r, c] += km * v
    return Kt, D, dw, idx


@njit(cache=True)
def _loads(k, m, basis, D, dw, with_stop):
    """B = ∂(right-hand side)/∂z of arm k (6 × n_z, z = [Y, θ_m]: the rotors after Y):
    −K_m D_Jᵀ ∂ψ_J,r/∂z over its joints (+K_m D_Jᵀ on θ_m,J), −K_se on the eigen
    amplitudes, and with the stop −k_w d_w ∂ψ_w,r/∂z."""
    nq = m.nq
    ny = nq + 3
    km = m.sc[S_KM]
    B = np.zeros((N_ARM, ny + 6))
    for jl in range(3):
        J = 3 * k + jl
        for r in range(N_ARM):
            c = -km * D[jl, r]
            B[r, 3 + J] += c  # ψ_J,r = θ_J + w_J'(0) − w_{J−1}'(L)
            B[r, ny + J] -= c
            bc = basis[J]
            for e in range(m.ne[J]):
                B[r, m.mo[J] + e] += c * m.slope_0[J, bc, e]
            if jl > 0:
                p = J - 1
                bp = basis[p]
                for e in range(m.ne[p]):
                    B[r, m.mo[p] + e] -= c * m.slope_L[p, bp, e]
    for li in range(3):  # −K_se a_e
        i = 3 * k + li
        b = basis[i]
        ne = m.ne[i]
        for s in range(2):
            if _slot(m, i, s) < 0:
                continue
            for e in range(ne):
                B[2 * li + s, m.mo[i] + e] -= m.k_ff[i, b, ne + s, e]
    if with_stop:
        kw = m.sc[S_WK]
        i3 = 3 * k + 2
        b3 = basis[i3]
        for r in range(N_ARM):
            c = -kw * dw[r]
            B[r, nq + 2] += c  # ψ_w,r = θ_T − (θ_B + θ_J1 + θ_J2 + θ_J3) − w_3,e'(L)
            B[r, 2] -= c
            for jl in range(3):
                B[r, 3 + 3 * k + jl] -= c
            for e in range(m.ne[i3]):
                B[r, m.mo[i3] + e] -= c * m.slope_L[i3, b3, e]
    return B


#: columns of z an arm's shapes can be slaved to: 3 joints, up to 3 × N_MAX eigen
#: amplitudes, 3 rotors, and with the stop θ_B and θ_T
N_COLS = 3 + 3 * 6 + 3 + 2


@njit(cache=True)
def _columns(k, m, with_stop, cols):
    """The columns of z = [Y, θ_m] arm k's shapes depend on, into cols; their number."""
    ny = m.nq + 3
    c = 0
    for jl in range(3):
        cols[c] = 3 + 3 * k + jl
        c += 1
    for li in range(3):
        i = 3 * k + li
        for e in range(m.ne[i]):
            cols[c] = m.mo[i] + e
            c += 1
    for jl in range(3):
        cols[c] = ny + 3 * k + jl
        c += 1
    if with_stop:
        cols[c] = 2
        cols[c + 1] = m.nq + 2
        c += 2
    return c


@njit(cache=True)
def _cholesky6(A):
    """L Lᵀ = A (symmetric positive definite, small): L, lower triangular."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for r in range(n):
        for j in range(r + 1):
            s = A[r, j]
            for c in range(j):
                s -= L[r, c] * L[j, c]
            if j < r:
                L[r, j] = s / L[j, j]
            else:
                L[r, r] = np.sqrt(s)
    return L


@njit(cache=True)
def _solve_columns(L, B):
    """L⁻ᵀ L⁻¹ B, column by column, in place on B (n × nb)."""
    n = L.shape[0]
    for col in range(B.shape[1]):
        for r in range(n):
            s = B[r, col]
            for c in range(r):
                s -= L[r, c] * B[c, col]
            B[r, col] = s / L[r, r]
        for r in range(n - 1, -1, -1):
            s = B[r, col]
            for c in range(r + 1, n):
                s -= L[c, r] * B[c, col]
            B[r, col] = s / L[r, r]


def slaving_tables(m):
    """T and the stop's offset of both arms for every configuration they can be in, once
    per model (they depend on the bases and the stop state only, not on the state):
    (T (2 arms, 2 terminal bases, 2 stop states, 6, N_COLS), c (2, 2, 6): K̃⁻¹ k_w d_w,
    d_w (2, 2, 6), cols (2, 2 stop states, N_COLS), ncol (2, 2)).  The terminal basis
    index is that of `beam_modes` (PP = 0, PF = 1); the inner links are always PP."""
    T = np.zeros((2, 2, 2, N_ARM, N_COLS))
    c = np.zeros((2, 2, N_ARM))
    dws = np.zeros((2, 2, N_ARM))
    cols = np.zeros((2, 2, N_COLS), dtype=np.int64)
    ncol = np.zeros((2, 2), dtype=np.int64)
    kw = m.sc[S_WK]
    for k in range(2):
        for term in range(2):
            basis = np.zeros(6, dtype=np.int64)
            basis[3 * k + 2] = term
            Kt, D, dw, _ = _stiffness(k, m, basis)
            dws[k, term] = dw
            for stop in range(2):
                K = Kt + (kw * np.outer(dw, dw) if stop else 0.0)
                nc = _columns(k, m, stop == 1, cols[k, stop])
                ncol[k, stop] = nc
                B = _loads(k, m, basis, D, dw, stop == 1)
                T[k, term, stop, :, :nc] = np.linalg.solve(K, B[:, cols[k, stop, :nc]])
                if stop:
                    c[k, term] = np.linalg.solve(K, kw * dw)
    return T, c, dws, cols, ncol


@njit(cache=True, inline="always")
def condense(x, m, sw):
    """The static shapes of every arm slaved to the rest of the state (module doc).

    Returns (xc, T, cols, ncol, idx): xc, the state x with the static amplitudes and rates
    set to a_s = T z + c and ȧ_s = T ż (z = [Y, θ_m], the static slots zero; x itself is
    not changed and its static slots are not read); per arm k, T[k] (6 × N_COLS) on the
    columns cols[k, :ncol[k]] of z (the others are zero: `slaving_tables`, by the arm's
    terminal basis and stop state); idx (2 × 6), the q-index of each shape (−1: none).
    Explicit or no static shapes: x itself (the caller must not write it), T and cols
    without columns, ncol = 0 and idx = −1."""
    ncol = np.zeros(2, dtype=np.int64)
    if m.cond == 0:  # nothing slaved: x itself (not written), arrays without columns
        return x, np.zeros((2, N_ARM, 0)), np.zeros((2, 0), dtype=np.int64), ncol, \
            np.full((2, N_ARM), -1, dtype=np.int64)
    xc = x.copy()
    nq = m.nq
    ny = nq + 3
    ns = ny + 6
    T = np.zeros((2, N_ARM, N_COLS))
    cols = np.zeros((2, N_COLS), dtype=np.int64)
    idx = np.full((2, N_ARM), -1, dtype=np.int64)
    for i in range(6):
        for s in range(2):
            j = _slot(m, i, s)
            if j >= 0:
                xc[j] = 0.0
                xc[ns + j] = 0.0
    z = xc[:ns]  # z = [Y, θ_m]
    lim = m.sc[S_WLIM]
    a = np.zeros(N_ARM)
    for k in range(2):
        for li in range(3):
            for s in range(2):
                idx[k, 2 * li + s] = _slot(m, 3 * k + li, s)
        term = sw.basis[3 * k + 2]
        stop = 0
        offset = 0.0
        for attempt in range(2):
            nc = m.sl_ncol[k, stop]
            for r in range(N_ARM):
                v = 0.0
                for c in range(nc):
                    v += m.sl_T[k, term, stop, r, c] * z[m.sl_cols[k, stop, c]]
                a[r] = v + offset * m.sl_c[k, term, r]
            if stop == 1 or sw.grasp_on[k] == 0:
                break
            # ψ_w = ψ_w,r + d_w·a_s;  beyond a stop its spring joins the equilibrium
            i3 = 3 * k + 2
            psi_w = z[nq + 2] - z[2] - z[3 + 3 * k] - z[4 + 3 * k] - z[5 + 3 * k]
            for e in range(m.ne[i3]):
                psi_w -= m.slope_L[i3, term, e] * z[m.mo[i3] + e]
            for r in range(N_ARM):
                psi_w += m.sl_dw[k, term, r] * a[r]
            if -lim <= psi_w <= lim:
                break
            stop = 1
            offset = lim if psi_w > lim else -lim
        nc = m.sl_ncol[k, stop]
        ncol[k] = nc
        for c in range(nc):
            cols[k, c] = m.sl_cols[k, stop, c]
        for r in range(N_ARM):
            for c in range(nc):
                T[k, r, c] = m.sl_T[k, term, stop, r, c]
            j = idx[k, r]
            if j >= 0:
                v = 0.0
                for c in range(nc):
                    col = cols[k, c]
                    v += T[k, r, c] * xc[ns + col]  # ż = [Ẏ, θ̇_m] = x[ns:2ns]
                xc[j] = a[r]
                xc[ns + j] = v
    return xc, T, cols, ncol, idx


@njit(cache=True, inline="always")
def project(f, thmdd, T, cols, ncol, idx, m):
    """Pass the generalised force on the static shapes, f_s = f[idx], on to the coordinates
    they are slaved to: f_z += Tᵀ f_s (module doc), in place on f (Y) and on the rotors'
    θ̈_m = (τ_m − u_J + (Tᵀ f_s)_θm)/B_m."""
    ny = m.nq + 3
    bm = m.sc[S_BM]
    for k in range(2):
        for s in range(N_ARM):
            if idx[k, s] < 0:
                continue
            fs = f[idx[k, s]]
            for c in range(ncol[k]):
                col = cols[k, c]
                if col < ny:
                    f[col] += T[k, s, c] * fs
                else:
                    thmdd[col - ny] += T[k, s, c] * fs / bm


@njit(cache=True)
def reduced_mass(Mg, T, cols, ncol, idx, m):
    """The mass matrix of z = [Y, θ_m] with the shapes slaved, M_z = Pᵀ M_ext P,
    M_ext = blockdiag(M_g, B_m I) and P the identity with the static rows replaced by T:
        M_z = M_ext + C + Cᵀ + Tᵀ M_ss T,   C = M_ext[:, s] T,
    arm by arm (the arms' shapes share no mass).  The static rows and columns of M_z are
    zero (they are not coordinates)."""
    ny = m.nq + 3
    n = ny + 6
    Mz = np.zeros((n, n))
    Mz[:ny, :ny] = Mg
    for j in range(6):
        Mz[ny + j, ny + j] = m.sc[S_BM]
    for k in range(2):
        nc = ncol[k]
        if nc == 0:
            continue
        C = np.zeros((ny, nc))  # M_g[:, s] T  (the rotors have no mass coupling with s)
        for s in range(N_ARM):
            js = idx[k, s]
            if js < 0:
                continue
            for r in range(ny):
                mrs = Mg[r, js]
                if mrs != 0.0:
                    for c in range(nc):
                        C[r, c] += mrs * T[k, s, c]
        MT = np.zeros((N_ARM, nc))  # M_ss T
        for s in range(N_ARM):
            if idx[k, s] < 0:
                continue
            for t in range(N_ARM):
                if idx[k, t] < 0:
                    continue
                mst = Mg[idx[k, s], idx[k, t]]
                for c in range(nc):
                    MT[s, c] += mst * T[k, t, c]
        for c in range(nc):
            cc = cols[k, c]
            for r in range(ny):
                Mz[r, cc] += C[r, c]
                Mz[cc, r] += C[r, c]
            for d in range(nc):
                v = 0.0
                for s in range(N_ARM):
                    v += T[k, s, c] * MT[s, d]
                Mz[cc, cols[k, d]] += v
    for k in range(2):
        for s in range(N_ARM):
            js = idx[k, s]
            if js >= 0:
                Mz[js, :] = 0.0
                Mz[:, js] = 0.0
    return Mz
