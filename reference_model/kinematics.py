"""Kinematics of the two arms, eqs. (A.1)–(A.2), compiled: the frames of the six links
and the two end effectors with their Jacobians and J̇q̇, and the section-relative angles
of the joints (docs/physics.md §3.3) and the wrists (§4.3).  Coordinates: model_arrays.py.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from reference_model.model_arrays import N_LINKS, S_L

#: What `kinematics` returns, eqs. (A.1)–(A.2): per link i (0..5) the frame angle th[i], its
#: rate om[i], the frame origin R[i] (proximal pin) and its velocity Rd[i], the Jacobians
#: JR[i] = ∂R_i/∂q, Jth[i] = ∂θ_i/∂q and cR[i] = J̇q̇ of R_i; per end effector k (0, 1) the
#: same as rE[k], rEd[k], JE[k], cE[k].
Kinematics = namedtuple("Kinematics", ["th", "om", "R", "Rd", "JR", "Jth", "cR", "rE", "rEd", "JE", "cE"])


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
