"""Compiled core of the Kane–Newton reference model: plain arrays in, plain arrays out.

Read next to the paper (Sect. 2, Appendix) and docs/physics.md.  Everything here is a
`numba.njit` function on arrays; `reference_model.build` builds the arrays and gives
them names.  The model's constant arrays travel as one named tuple `ModelArrays`, the
switching state (bases, grasps, held points) as `Switches`.  A compiled call that is not
inlined copies such a tuple and counts a reference to each of its arrays (17 atomic
increments and decrements): the helpers of the right-hand side that take it are therefore
`inline="always"` (half the cost of the rigid RHS).

Coordinates (docs/physics.md §1)
-------------------------------
q_m  = [x_B, y_B, θ_B, θ_J1..θ_J6, a_link1.., .., a_link6..]      (nq)   eq. (4) ordering
X_T  = [x_T, y_T, θ_T]                                             (3)
θ_m  = six motor angles, relative to the parent end section       (6)
Y    = [q_m, X_T] (ny = nq + 3),  Y* = [Y, θ_m] (ns = ny + 6)      eq. (7)
ODE state x = [Y*, Ẏ*, r_O (2), v_O (2), m_used]: r_O, v_O are the co-moving reference
point (docs/physics.md §5), m_used the propellant burnt.

Newtonian coordinates of a link (the X_m of eq. A.1): X_i = [R_i (2), θ_i, a_i (n_i)] —
origin of the link frame (its proximal pin), frame angle, modal amplitudes.  A material
point at abscissa ξ is at r = R + A(θ) u(ξ), u = (ξ, w(ξ)), w = Σ a_j φ_j (eq. 1); its
cross-section is turned by θ + w'(ξ).  (A(·) is the 2×2 rotation; the constraint Jacobian
of eq. 8 is called `G` here to keep the letters apart.)

Joints (docs/physics.md §3.3): a joint is a hinge between two end sections.  Its
section-relative angle is ψ_J = θ_J + w_child'(0) − w_parent'(L) (the parent of the first
joint is the rigid base), the spring-damper of eq. (5) acts on ψ_J − θ_m, and its
generalised force u_J ∂ψ_J/∂q puts u_J on θ_J and the paper's u_e (eq. 4) on the
amplitudes of both links.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from reference_model.field import tidal, tidal_potential

# --- indices into the scalar parameter vector `sc` -----------------------------------
S_MB0 = 0  # base mass at t = 0 [kg]
S_JB = 1  # base inertia about COM [kg m²]
S_MT = 2  # target mass
S_JT = 3  # target inertia about COM
S_ML = 4  # link mass
S_L = 5  # link length
S_RHO = 6  # ρA [kg/m]
S_I0 = 7  # ∫ρ ξ² dξ = m L²/3, link about its pin
S_JEX = 8  # rotary inertia beyond the slender beam, on the frame rotation
S_ETA = 9  # Kelvin–Voigt coefficient η [s]
S_BM = 10  # motor inertia B_m
S_KM = 11  # K_m
S_CM = 12  # C_m
S_ALPHA = 13  # Baumgarte α
S_BETA = 14  # Baumgarte β
S_WLIM = 15  # wrist bistop half-range
S_WK = 16  # wrist bistop stiffness
S_WC = 17  # wrist bistop damping
S_MU = 18  # Earth μ
S_ISPG0 = 19  # Isp·g0 [m/s]
S_ORBIT = 20  # 1.0: tidal gravity on, 0.0: off
S_MTOT0 = 21  # total mass at t = 0
N_SCALARS = 22

# --- inputs u (held constant over a control period) ----------------------------------
U_TAU_M = 0  # 6 motor torques (after saturation)
U_TAU_B = 6  # base torque
U_THRUST = 7  # thrust magnitude along +x_B
N_INPUTS = 8

N_LINKS = 6

#: The model's constant arrays.  Per link i and basis b (PP = 0, PF = 1), shape index a:
#:   phi_bar[i, b, a] = ∫ρφ_a dξ,  phi_x = ∫ρξφ_a dξ,  m_ff[i, b] = ∫ρφφᵀ,  k_ff = ∫EIφ''φ''ᵀ,
#:   phi_tip = φ_a(L),  slope_0 = φ_a'(0),  slope_L = φ_a'(L),  phi_g[i, b, g, a] = φ_a(x_g[g]);
#:   nm[i] shapes of link i, starting at q[mo[i]]; mount[k] the root of arm k (base frame);
#:   order, first: elimination order and envelope of the mass matrix (`elimination_order`).
ModelArrays = namedtuple("ModelArrays", [
    "nq", "sc", "nm", "mo", "phi_bar", "phi_x", "m_ff", "k_ff", "phi_tip", "slope_0", "slope_L",
    "phi_g", "x_g", "w_g", "mount", "order", "first"])
#: The switching part: basis[i] of each link, grasp_on[k], held points rho_G[k] (target frame).
Switches = namedtuple("Switches", ["basis", "grasp_on", "rho_G"])
#: What `kinematics` returns, eqs. (A.1)–(A.2): per link i (0..5) the frame angle th[i], its
#: rate om[i], the frame origin R[i] (proximal pin) and its velocity Rd[i], the Jacobians
#: JR[i] = ∂R_i/∂q, Jth[i] = ∂θ_i/∂q and cR[i] = J̇q̇ of R_i; per end effector k (0, 1) the
#: same as rE[k], rEd[k], JE[k], cE[k].
Kinematics = namedtuple("Kinematics", ["th", "om", "R", "Rd", "JR", "Jth", "cR", "rE", "rEd", "JE", "cE"])


@njit(cache=True)
def _bistop(psi, psid, lim, k, c):
    """Wrist bistop: one-sided spring-damper beyond ±lim on the relative rotation ψ."""
    if psi > lim:
        return -k * (psi - lim) - c * psid
    if psi < -lim:
        return -k * (psi + lim) - c * psid
    return 0.0


# =====================================================================================
# Kinematics, eqs. (A.1)–(A.2)
# =====================================================================================
@njit(cache=True)
def kinematics(q, qd, m, basis):
    """Frames of the six links and the two end effectors, with Jacobians (A.1) and J̇q̇ (A.2).

    Returns a `Kinematics` (named tuple of arrays):
            th[6], om[6]                 frame angles and rates
            R[6,2], Rd[6,2]              frame origins (proximal pins) and their velocities
            JR[6,2,nq], Jth[6,nq]        ∂R/∂q, ∂θ/∂q
            cR[6,2]                      J̇q̇ of R (the part of R̈ not proportional to q̈)
            rE[2,2], rEd[2,2], JE[2,2,nq], cE[2,2]   the same for the end effectors
    Recursion along an arm (i-th link, d_i = (L, w_i(L)) its distal pin in its frame):
        θ_i = θ_B + Σ_{s≤i} θ_Js,     R_{i+1} = R_i + A(θ_i) d_i,
        R̈_{i+1} = R̈_i + θ̈_i A S d_i + A e_y ẅ_i(L) − θ̇_i² A d_i + 2 θ̇_i A S e_y ẇ_i(L).
    """
    nq = q.shape[0]
    L = m.sc[S_L]
    th = np.zeros(N_LINKS)
    om = np.zeros(N_LINKS)
    R = np.zeros((N_LINKS, 2))
    Rd = np.zeros((N_LINKS, 2))
    JR = np.zeros((N_LINKS, 2, nq))
    Jth = np.zeros((N_LINKS, nq))
    cR = np.zeros((N_LINKS, 2))
    rE = np.zeros((2, 2))
    rEd = np.zeros((2, 2))
    JE = np.zeros((2, 2, nq))
    cE = np.zeros((2, 2))
    cb = math.cos(q[2])
    sb = math.sin(q[2])
    wb = qd[2]
    for k in range(2):
        # root of arm k: r_B + A(θ_B) r_M  (base frame mount point)
        mx = cb * m.mount[k, 0] - sb * m.mount[k, 1]
        my = sb * m.mount[k, 0] + cb * m.mount[k, 1]
        px = q[0] + mx
        py = q[1] + my
        vx = qd[0] - wb * my
        vy = qd[1] + wb * mx
        # the Jacobians are written in place: JR[i] and Jth[i] of the first link from the
        # mount, of the next ones from the previous link's, JE[k] from the last link's
        i0 = 3 * k
        JR[i0, 0, 0] = 1.0
        JR[i0, 1, 1] = 1.0
        JR[i0, 0, 2] = -my
        JR[i0, 1, 2] = mx
        Jth[i0, 2] = 1.0
        cx = -wb * wb * mx
        cy = -wb * wb * my
        theta = q[2]
        for s in range(3):
            i = i0 + s
            j = 3 + i
            b = basis[i]
            theta = theta + q[j]
            if s > 0:
                Jth[i] = Jth[i - 1]
            Jth[i, j] = 1.0
            Jt = Jth[i]
            omega = 0.0
            for c in range(nq):
                omega += Jt[c] * qd[c]
            th[i] = theta
            om[i] = omega
            R[i, 0] = px
            R[i, 1] = py
            Rd[i, 0] = vx
            Rd[i, 1] = vy
            cR[i, 0] = cx
            cR[i, 1] = cy
            # distal pin d = (L, w(L)) and its rate (0, ẇ(L))
            wt = 0.0
            wtd = 0.0
            for a in range(m.nm[i]):
                wt += m.phi_tip[i, b, a] * q[m.mo[i] + a]
                wtd += m.phi_tip[i, b, a] * qd[m.mo[i] + a]
            c = math.cos(theta)
            sn = math.sin(theta)
            dx = c * L - sn * wt  # A d
            dy = sn * L + c * wt
            eyx = -sn  # A e_y
            eyy = c
            Jn = JR[i + 1] if s < 2 else JE[k]  # the distal pin's Jacobian
            Jn[:, :] = JR[i]
            for col in range(nq):
                Jn[0, col] += -dy * Jt[col]  # A S d = (−(A d)_y, (A d)_x)
                Jn[1, col] += dx * Jt[col]
            for a in range(m.nm[i]):
                Jn[0, m.mo[i] + a] += eyx * m.phi_tip[i, b, a]
                Jn[1, m.mo[i] + a] += eyy * m.phi_tip[i, b, a]
            px = px + dx
            py = py + dy
            vx = vx - omega * dy + eyx * wtd
            vy = vy + omega * dx + eyy * wtd
            # −θ̇² A d + 2 θ̇ A S e_y ẇ(L),  A S e_y = −A e_x = (−c, −s)
            cx = cx - omega * omega * dx - 2.0 * omega * c * wtd
            cy = cy - omega * omega * dy - 2.0 * omega * sn * wtd
        rE[k, 0] = px
        rE[k, 1] = py
        rEd[k, 0] = vx
        rEd[k, 1] = vy
        cE[k, 0] = cx
        cE[k, 1] = cy
    return Kinematics(th, om, R, Rd, JR, Jth, cR, rE, rEd, JE, cE)


@njit(cache=True, inline="always")
def _slope(i, end_L, v, m, basis):
    """w_i'(0) (end_L False) or w_i'(L) (True) of link i for amplitudes (or rates) in v."""
    s = 0.0
    b = basis[i]
    for a in range(m.nm[i]):
        s += (m.slope_L[i, b, a] if end_L else m.slope_0[i, b, a]) * v[m.mo[i] + a]
    return s


@njit(cache=True, inline="always")
def joint_section_angles(q, qd, m, basis):
    """ψ_J and ψ̇_J of the six joints (docs/physics.md §3.3): the angle between the child's
    proximal end section and the parent's distal one (the base for the first joint),
        ψ_J = θ_J + w_child'(0) − w_parent'(L),
    what a link-side joint encoder reads; θ_J is the frame-relative coordinate of Y."""
    psi = np.zeros(6)
    psid = np.zeros(6)
    for j in range(6):
        psi[j] = q[3 + j] + _slope(j, False, q, m, basis)
        psid[j] = qd[3 + j] + _slope(j, False, qd, m, basis)
        if j % 3 != 0:
            psi[j] -= _slope(j - 1, True, q, m, basis)
            psid[j] -= _slope(j - 1, True, qd, m, basis)
    return psi, psid


@njit(cache=True, inline="always")
def wrist_angles(q, qd, XT, XTd, th, om, m, basis):
    """ψ_w and ψ̇_w of both wrists: target attitude relative to the distal end section of
    the terminal link, ψ_w = θ_T − (θ_3 + w_3'(L)) (docs/physics.md §4.3)."""
    psi = np.zeros(2)
    psid = np.zeros(2)
    for k in range(2):
        i3 = 3 * k + 2
        psi[k] = XT[2] - th[i3] - _slope(i3, True, q, m, basis)
        psid[k] = XTd[2] - om[i3] - _slope(i3, True, qd, m, basis)
    return psi, psid


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


# =====================================================================================
# One link in Newtonian coordinates, eq. (A.3)
# =====================================================================================
@njit(cache=True, inline="always")
def link_newton(i, q, qd, th, om, m, basis, M, V):
    """Floating-frame mass matrix M_X and force V + elastic of link i (eq. A.3 for one body),
    written into the leading (3 + n) × (3 + n) block of M and the first 3 + n entries of V
    (work arrays of `_link_rows`, at least that large).

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
def _field_link(i, q, th, R, rO, aunif, m, basis, M, Q, rel):
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
    mass at the Gauss points of `_field_link`, Σ_i Σ_g ρ w_g U(r_O, R_i + A u_g)/μ, the
    energy whose negative gradient `_field_link`'s forces are (observe's energy)."""
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
        _field_link(i, q, th, R, rO, aunif, m, basis, M, Q, rel)
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


@njit(cache=True, inline="always")
def _grasp_rows(f, q, qd, XT, XTd, kin, m, sw):
    """Wrist bistops and the grasp constraints of eqs. (8)–(12), for the active grasps.

    Bistop (docs/physics.md §4.3): τ_w = bistop(ψ_w, ψ̇_w), +τ_w on the target, −τ_w on the
    terminal link's distal section (generalised force −τ_w ∂(θ_3 + w_3'(L))/∂q).
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
        tw = _bistop(psi_w[k], psid_w[k], sc[S_WLIM], sc[S_WK], sc[S_WC])
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
    """
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
    G, phi, phid, Bs, tauw = _grasp_rows(f, q, qd, XT, XTd, kin, m, sw)

    aO = athr.copy()
    if sc[S_ORBIT] != 0.0:
        r2 = rO[0] * rO[0] + rO[1] * rO[1]
        r3 = r2 * math.sqrt(r2)
        aO[0] += -sc[S_MU] * rO[0] / r3
        aO[1] += -sc[S_MU] * rO[1] / r3
    return Mg, f, G, phi, phid, Bs, thmdd, uJ, tauw, aO


def elimination_order(nq, nm, mo):
    """Order of the rows of Mg for its Cholesky factor, and the envelope of each row.

    Mg couples the base with both arms and each arm with itself, but never the two arms
    with each other (a link's Newtonian coordinates depend on the base and its own arm
    only, eq. A.6), and the target only with itself (eq. 3).  Eliminated in the order
    arm 1 (joints, amplitudes), arm 2, base, target, the factor has no fill-in outside the
    envelope `first[r]` ≤ column ≤ r: a quarter of the dense work at 4 shapes per link.
    Returns (order, first): row r of the ordered matrix is row order[r] of Mg.
    """
    ny = nq + 3
    order = np.empty(ny, dtype=np.int64)
    first = np.empty(ny, dtype=np.int64)
    r = 0
    for k in range(2):
        start = r
        for s in range(3):
            order[r] = 3 + 3 * k + s
            r += 1
        for s in range(3):
            i = 3 * k + s
            for a in range(nm[i]):
                order[r] = mo[i] + a
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
    not touched).  False if A is not positive definite."""
    n = A.shape[0]
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
    """
    nc = G.shape[0]
    ny = Mg.shape[0]
    order = m.order
    Lc = np.empty((ny, ny))
    ydd = np.empty(ny)
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


@njit(cache=True)
def rhs(x, u, m, sw):
    """ẋ of the full ODE: eq. (7) with (11)–(12), the reference point and mass depletion."""
    ny = m.nq + 3
    ns = ny + 6
    Mg, f, G, phi, phid, Bs, thmdd, uJ, tauw, aO = assemble(x, u, m, sw)
    ydd, Rcl = solve_constrained(Mg, f, G, Bs, m)
    dx = np.empty_like(x)
    dx[0:ns] = x[ns:2 * ns]
    dx[ns:ns + ny] = ydd
    dx[ns + ny:2 * ns] = thmdd
    dx[2 * ns:2 * ns + 2] = x[2 * ns + 2:2 * ns + 4]
    dx[2 * ns + 2:2 * ns + 4] = aO
    dx[2 * ns + 4] = u[U_THRUST] / m.sc[S_ISPG0]
    return dx
