"""The static correction shapes slaved to the springs (Guyan condensation), compiled
(docs/physics.md §2.4).

Each flexible link carries, after its eigenmodes, two static shapes: its bending under
unit end couples.  As states they add Ritz frequencies of 0.4–0.8 kHz on a fixed frame
(0.8–1.1 kHz coupled to the free-floating frames), above the beam modes they stand in for
and far above the loads.  Slaved, their amplitudes are at every instant the static
equilibrium of each arm under the joint springs of eq. (5) and the wrist stop's torque,
given all the other coordinates,

    ∂V/∂a_s = d_w τ_w,   V = ½ Σ_i aᵀ K_ff,i a + ½ K_m Σ_J (ψ_J − θ_m,J)²,
    ψ_J = ψ_J,r + D_J a_s,        ψ_w = ψ_w,r + d_wᵀ a_s,

with ψ_J,r, ψ_w,r the section angles without the static shapes, D_J their end slopes
(+φ_s'(0) of the child, −φ_s'(L) of the parent), d_w = −φ_s'(L) of the terminal link
and τ_w the stop's torque on the target (−τ_w on the terminal link's distal section).
Per arm (six static amplitudes) this is linear:

    K̃ a_s = −K_m Σ_J D_Jᵀ (ψ_J,r − θ_m,J) − K_se a_e + d_w τ_w,
    K̃ = blockdiag(K_ss,i) + K_m Σ_J D_Jᵀ D_J,

(K_se, the stiffness between static shapes and eigenmodes, is zero to round-off).  With
z = [Y, θ_m] (the rotors after Y) the right-hand side is B z + d_w τ_w, so

    a_s = T z + g τ_w,   T = K̃⁻¹ B,   g = K̃⁻¹ d_w,   ȧ_s = T ż,

T and g constant for a given terminal basis (`slaving_tables`, once per model), τ_w here
the part of the stop's torque the link carries elastically (−s e/h below).  The
equations of z follow from the kinetic and potential energy of the whole model with the
shapes slaved (their mass kept):

    M_z = Pᵀ blockdiag(M_g, B_m I) P,    f_z = Pᵀ [f; τ_m − u_J],

P the identity with the static rows replaced by T (`reduced_mass`, `project`).  Since the
springs and the stop balance on the shapes by construction, what Tᵀ f_s carries to z is
their damping (Kelvin–Voigt, the joints' C_m), their field and their inertial loads.  The
slaved shapes also couple each arm's rotors to it through their inertia (T has rotor
columns).

The wrist stop (a holding arm beyond ±ψ_lim) is the one load on the shapes whose damping
cannot be left out of their balance: its Hunt–Crossley damping λδ (2 400 N·m·s/rad at
δ = 0.02 rad) is ten times its spring k, and it acts right on the terminal link's tip
slope.  Massless, the terminal link is then a spring of compliance h = d_wᵀ K̃⁻¹ d_w
(2.6e-6 rad/(N·m), holding arm) in series with the stop, whose relaxation time λδh
(6 ms at δ = 0.02 rad) is that of the contact itself.  Its state is
the link's tip deflection under the stop, e ≥ 0 (one per arm, `Layout.stop_deflection`),

    ψ_w = ψ_free − s e,   δ_0 = s ψ_free − ψ_lim,   δ = δ_0 − e,   a_s = T z − g s e/h,

ψ_free = ψ_w,r + d_wᵀ T z the wrist angle the shapes would give without the stop and s
the side of the stop.  Along g the massless shapes balance the stop's push against their
spring e/h and their Kelvin–Voigt damping, c_e ė on the rate g (−s ė/h) and x_kv =
(η K_ss g)·T ż / h on the slaved rates, c_e = η gᵀ K_ss g / h²; the stop's law
(system._bistop) with δ̇ = s ψ̇_free − ė then gives

    push = e/h + c_e ė − s x_kv = δ (k + λ δ̇),   τ_w = −s push,
    ė = [δ (k + λ s ψ̇_free) − e/h + s x_kv] / (λ δ + c_e)      (`_stop_rate`).

Where it would pull the stop lets go (push = 0, the link relaxes), e stays ≥ 0, and off
the stop a deflection left over relaxes to 0 (e/h + c_e ė = 0), still in a_s (the link
does not jump back); without any damping e = δ_0 k h / (1 + k h), the spring-only
equilibrium.  The rate g ė is massless: ȧ_s = T ż leaves it out (it carries no momentum)
and its Kelvin–Voigt force is added to the shapes' (system._assemble).  At a release the
deflection is dropped with the grasp (its energy e²/2h, ~0.01 J at the peaks of the
randomized cases, is not reported).  A grasp's constraint rows
never involve the shapes: a holding arm's links are all in the PP basis, whose shapes
vanish at the distal pin, so the end effector does not move with them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from reference_model.model_arrays import S_BM, S_ETA, S_KM, S_WK, S_WLAM, S_WLIM

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
def _loads(k, m, basis, D):
    """B = ∂(right-hand side)/∂z of arm k (6 × n_z, z = [Y, θ_m]: the rotors after Y):
    −K_m D_Jᵀ ∂ψ_J,r/∂z over its joints (+K_m D_Jᵀ on θ_m,J) and −K_se on the eigen
    amplitudes."""
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
    return B


#: columns of z an arm's shapes can be slaved to: 3 joints, up to 3 × N_MAX eigen
#: amplitudes and 3 rotors
N_COLS = 3 + 3 * 6 + 3


@njit(cache=True)
def _columns(k, m, cols):
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
    return c


def slaving_tables(m):
    """T, g and h of both arms in either terminal basis, once per model (they depend on the
    bases only, not on the state): (T (2 arms, 2 terminal bases, 6, N_COLS), g (2, 2, 6),
    h (2, 2), η K_ss g (2, 2, 6), c_e (2, 2), d_w (2, 2, 6), cols (2, N_COLS), ncol (2)).
    The terminal basis index is that of `beam_modes` (PP = 0, PF = 1); the inner links are
    always PP.

    c_e is the damping the arm opposes to the rate of its stop deflection e (a_s = g τ_w,
    τ_w = −s e/h), the links' Kelvin–Voigt on it: c_e = η gᵀ K_ss g / h² (the joints' C_m,
    1e-7 of it, left out)."""
    T = np.zeros((2, 2, N_ARM, N_COLS))
    g = np.zeros((2, 2, N_ARM))
    h = np.zeros((2, 2))
    kg = np.zeros((2, 2, N_ARM))
    ce = np.zeros((2, 2))
    dws = np.zeros((2, 2, N_ARM))
    cols = np.zeros((2, N_COLS), dtype=np.int64)
    ncol = np.zeros(2, dtype=np.int64)
    for k in range(2):
        ncol[k] = _columns(k, m, cols[k])
        for term in range(2):
            basis = np.zeros(6, dtype=np.int64)
            basis[3 * k + 2] = term
            Kt, D, dw, _ = _stiffness(k, m, basis)
            dws[k, term] = dw
            B = _loads(k, m, basis, D)
            T[k, term, :, :ncol[k]] = np.linalg.solve(Kt, B[:, cols[k, :ncol[k]]])
            g[k, term] = np.linalg.solve(Kt, dw)
            h[k, term] = dw @ g[k, term]
            Kss = Kt - m.sc[S_KM] * (D.T @ D)  # blockdiag(K_ss,i) (identity rows where no shapes)
            for r in range(N_ARM):
                if _slot(m, 3 * k + r // 2, r % 2) < 0:
                    Kss[r, :] = 0.0
            kg[k, term] = m.sc[S_ETA] * Kss @ g[k, term]
            if h[k, term] > 0.0:  # zero where the terminal link has no static shapes
                ce[k, term] = g[k, term] @ kg[k, term] / h[k, term] ** 2
    return T, g, h, kg, ce, dws, cols, ncol


#: penetration below which the stop's rate is evaluated at this floor [rad]: e only nears
#: δ_0 (δ → 0) when an integration step overshoots, and ė then pulls it straight back
DELTA_FLOOR = 1e-12


@njit(cache=True, inline="always")
def _overlap(psi_free, lim):
    """The stop's side s (±1; 0 off the stop, |ψ_free| ≤ ψ_lim) and δ_0 = s ψ_free − ψ_lim."""
    if psi_free > lim:
        return 1.0, psi_free - lim
    if psi_free < -lim:
        return -1.0, -psi_free - lim
    return 0.0, 0.0


@njit(cache=True, inline="always")
def _stop_rate(psi_free, psid_free, e, h, ce, x_kv, lim, k, lam):
    """The terminal link's deflection under the stop, e, as the state the stop's law leaves
    (module doc): (e_eff, ė, τ_w).  x_kv = (η K_ss g)·T ż / h, the links' Kelvin–Voigt
    force of the slaved rates along g.  Off the stop (|ψ_free| ≤ ψ_lim) no torque and a
    deflection left over relaxes (e/h + c_e ė = 0), still in a_s: the link does not jump
    back (without damping, c_e = 0, it does: e_eff = 0); without any damping e_eff is the spring-only equilibrium
    and ė = 0; a terminal link without static shapes (h = 0) does not deflect, the law acts
    at ψ_free.  Where the stop would pull it lets go: no torque, the link relaxes under its
    own damping (push = 0); e stays ≥ 0."""
    s, d0 = _overlap(psi_free, lim)
    if s == 0.0:  # off the stop: a deflection left over relaxes, e/h + c_e ė = 0, and stays in a_s
        if e > 0.0 and ce > 0.0:
            return e, -e / (h * ce), 0.0
        return 0.0, 0.0, 0.0
    if h == 0.0:
        return 0.0, 0.0, -s * max(d0 * (k + lam * s * psid_free), 0.0)
    if lam == 0.0 and ce == 0.0:  # e/h = k (δ_0 − e)
        e = d0 * k * h / (1.0 + k * h)
        return e, 0.0, -s * e / h
    e = min(max(e, 0.0), d0)
    d = max(d0 - e, DELTA_FLOOR)  # δ = δ_0 − e
    # push = e/h + c_e ė − s x_kv = δ (k + λ (s ψ̇_free − ė))
    edot = (d * (k + lam * s * psid_free) - e / h + s * x_kv) / (lam * d + ce)
    if e / h + ce * edot - s * x_kv < 0.0:  # the stop would pull: it lets go, push = 0
        edot = (s * x_kv - e / h) / ce if ce > 0.0 else 0.0
    if e <= 0.0 and edot < 0.0:
        edot = 0.0
    push = e / h + ce * edot - s * x_kv
    return e, edot, -s * max(push, 0.0)


@njit(cache=True, inline="always")
def _settled(psi_free, psid_free, h, x_kv, lim, k, lam):
    """e where the stop's law holds with ė = 0 (a start in contact; `_stop_rate` then gives
    ė = 0): push = e/h − s x_kv = (δ_0 − e)(k + λ s ψ̇_free), so

        e = h (δ_0 stiff + s x_kv) / (1 + h stiff),   stiff = max(k + λ s ψ̇_free, 0),

    clamped to push only (push = 0: e = s x_kv h) and to 0 ≤ e ≤ δ_0; and τ_w = −s push."""
    s, d0 = _overlap(psi_free, lim)
    if s == 0.0:
        return 0.0, 0.0
    stiff = max(k + lam * s * psid_free, 0.0)
    if h == 0.0:
        return 0.0, -s * stiff * d0
    e = h * (d0 * stiff + s * x_kv) / (1.0 + h * stiff)
    if e / h - s * x_kv < 0.0:  # the stop would pull: it lets go
        e = s * x_kv * h
    e = min(max(e, 0.0), d0)
    return e, -s * max(e / h - s * x_kv, 0.0)


@njit(cache=True, inline="always")
def condense(x, m, sw, settle):
    """The static shapes of every arm slaved to the rest of the state (module doc).

    Returns (xc, T, cols, ncol, idx, tauw, edot, f_kv): xc, the state x with the static
    amplitudes and rates set to a_s = T z + g τ_w and ȧ_s = T ż (z = [Y, θ_m], the static
    slots zero; x itself is not changed and its static slots are not read) and each arm's
    stop deflection e in its admissible range (`_stop_rate`; `settle`: at the value the
    stop's law holds with ė = 0, for a start); per arm k, T[k] (6 × N_COLS) on the columns
    cols[k, :ncol[k]] of z (by the arm's terminal basis); idx (2 × 6), the q-index of each
    shape (−1: none); τ_w (2), the stop's torque on the target; ė (2); f_kv (2 × 6), the
    Kelvin–Voigt force of the rate ė on the shapes (ȧ_s leaves that rate out: massless, it
    carries no momentum).  Explicit or no static shapes: x itself (the caller must not
    write it), T and cols without columns, ncol = 0, idx = −1, τ_w, ė and f_kv zero (the
    stop then acts through system._bistop)."""
    ncol = np.zeros(2, dtype=np.int64)
    tauw = np.zeros(2)
    edot = np.zeros(2)
    fkv = np.zeros((2, N_ARM))
    if m.cond == 0:  # nothing slaved: x itself (not written), arrays without columns
        return x, np.zeros((2, N_ARM, 0)), np.zeros((2, 0), dtype=np.int64), ncol, \
            np.full((2, N_ARM), -1, dtype=np.int64), tauw, edot, fkv
    xc = x.copy()
    nq = m.nq
    ny = nq + 3
    ns = ny + 6
    ie = 2 * ns + 5  # the stop deflections (build.Layout.stop_deflection)
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
    zd = xc[ns:2 * ns]
    sc = m.sc
    a = np.zeros(N_ARM)
    ad = np.zeros(N_ARM)
    for k in range(2):
        term = sw.basis[3 * k + 2]
        nc = m.sl_ncol[k]
        ncol[k] = nc
        for c in range(nc):
            cols[k, c] = m.sl_cols[k, c]
        for r in range(N_ARM):
            idx[k, r] = _slot(m, 3 * k + r // 2, r % 2)
            v = 0.0
            vd = 0.0
            for c in range(nc):
                T[k, r, c] = m.sl_T[k, term, r, c]
                v += T[k, r, c] * z[cols[k, c]]
                vd += T[k, r, c] * zd[cols[k, c]]
            a[r] = v
            ad[r] = vd
        e = 0.0
        if sw.grasp_on[k]:
            # ψ_free = θ_T − θ_B − Σ θ_J − w_3,e'(L) + d_wᵀ T z, and its rate
            i3 = 3 * k + 2
            psi = z[nq + 2] - z[2] - z[3 + 3 * k] - z[4 + 3 * k] - z[5 + 3 * k]
            psid = zd[nq + 2] - zd[2] - zd[3 + 3 * k] - zd[4 + 3 * k] - zd[5 + 3 * k]
            for el in range(m.ne[i3]):
                psi -= m.slope_L[i3, term, el] * z[m.mo[i3] + el]
                psid -= m.slope_L[i3, term, el] * zd[m.mo[i3] + el]
            for r in range(N_ARM):
                psi += m.sl_dw[k, term, r] * a[r]
                psid += m.sl_dw[k, term, r] * ad[r]
            h = m.sl_h[k, term]
            ce = m.sl_ce[k, term]
            x_kv = 0.0  # (η K_ss g)·T ż / h
            if h > 0.0:
                for r in range(N_ARM):
                    x_kv += m.sl_kg[k, term, r] * ad[r]
                x_kv /= h
            if settle:
                e, tauw[k] = _settled(psi, psid, h, x_kv, sc[S_WLIM], sc[S_WK], sc[S_WLAM])
            else:
                e, edot[k], tauw[k] = _stop_rate(psi, psid, x[ie + k], h, ce, x_kv, sc[S_WLIM], sc[S_WK],
                                                 sc[S_WLAM])
            # a_s += g (−s e/h); the Kelvin–Voigt force of the rate g (−s ė/h), +s ė/h η K_ss g,
            # on the shapes
            if h > 0.0:
                s_side = 1.0 if psi > 0.0 else -1.0
                for r in range(N_ARM):
                    a[r] -= m.sl_g[k, term, r] * s_side * e / h
                    fkv[k, r] = m.sl_kg[k, term, r] * s_side * edot[k] / h
        xc[ie + k] = e
        for r in range(N_ARM):
            j = idx[k, r]
            if j >= 0:
                xc[j] = a[r]
                xc[ns + j] = ad[r]
    return xc, T, cols, ncol, idx, tauw, edot, fkv


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
