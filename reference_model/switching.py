"""Capture and release: grasp switching, PF↔PP basis switch, plastic impact (docs/physics.md §4).

The paper switches open/closed chain "operating on the terms R_cl and φ_T" (Sect. 2): a
grasp's two constraint rows are added (capture) or removed (release).  Here also the
terminal link's modal basis changes, and at capture the velocities jump onto the
constraint manifold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reference_model import core
from reference_model.beam_modes import PF, PP, mode_shapes, quadrature
from reference_model.model import Configuration, ReferenceModel


@dataclass(frozen=True)
class SwitchReport:
    """What a basis switch did: frame rotation δ [rad], largest position and velocity
    discontinuity of a material point over the link [m, m/s] (the projection residual)."""

    delta_rad: float
    residual_m: float
    residual_mps: float


def switch_basis(model: ReferenceModel, x: np.ndarray, cfg: Configuration, link: int, new: int) -> SwitchReport:
    """Re-express terminal link `link` in basis `new` (PP or PF), in place on x and cfg.

    Old frame θ, field w = Φ_old A; new frame θ' = θ + δ:
        capture (PP):  tan δ = w(L)/L                   (the chord through both pins)
        release (PF):  tan δ = ∫ρ ξ w dξ / I_0           (mass-orthogonal rigid mode)
    Transverse field in the new frame, w'(ξ) = n'·(r(ξ) − R) = −ξ sin δ + w cos δ, rate
    ẇ'(ξ) = θ̇ w sin δ + (θ̇ ξ + ẇ) cos δ − θ̇' ξ, with θ̇' fixed by the same condition on the
    rates; both projected on Φ_new by mass-weighted least squares (for PF constrained to
    keep the free tip w'(L), ẇ'(L): the distal pin stays continuous; for PP the chord frame
    already puts it at w'(L) = 0).  θ_J of the link takes
    δ (and θ̇' − θ̇); the rotor angle and the proximal pin do not move.
    """
    lay = model.layout
    old = int(cfg.basis[link])
    if old == new:
        return SwitchReport(0.0, 0.0, 0.0)
    n = lay.n_modes[link]
    lk = model.params.link
    L, rho = lk.length, lk.rho_a
    I0 = lk.mass * L**2 / 3.0
    xi, wq = quadrature(L)
    q, qd = x[lay.q], x[lay.qd]
    sl = lay.modes(link)
    phi_old = mode_shapes(old, n, L, xi)
    phi_new = mode_shapes(new, n, L, xi)
    w = phi_old @ q[sl] if n else np.zeros_like(xi)
    wd = phi_old @ qd[sl] if n else np.zeros_like(xi)
    w_L = mode_shapes(old, n, L, np.array([L]))[0] @ q[sl] if n else 0.0
    wd_L = mode_shapes(old, n, L, np.array([L]))[0] @ qd[sl] if n else 0.0
    if old == PP:
        w_L = wd_L = 0.0  # sin(jπ) = 0
    om = model.kinematics(q, qd, cfg)[1][link]

    if new == PP:
        delta = math.atan2(w_L, L)
        om_new = (math.sin(delta) * om * w_L + math.cos(delta) * (om * L + wd_L)) / L
    else:
        delta = math.atan2(rho * np.sum(wq * xi * w), I0)
        vn = math.sin(delta) * om * w + math.cos(delta) * (om * xi + wd)
        om_new = rho * np.sum(wq * xi * vn) / I0
    w_new = -xi * math.sin(delta) + w * math.cos(delta)
    wd_new = math.sin(delta) * om * w + math.cos(delta) * (om * xi + wd) - om_new * xi

    res_p = res_v = 0.0
    if n:
        mass = rho * (phi_new.T * wq) @ phi_new
        b_p = rho * (phi_new.T * wq) @ w_new
        b_v = rho * (phi_new.T * wq) @ wd_new
        if new == PF:
            # The distal pin must stay where it is (docs/physics.md §4.4: every pin is
            # continuous): least squares constrained to w'(L) = n'·(r(L) − R) and
            # ẇ'(L) likewise (the PP tip of the old field has w(L) = ẇ(L) = 0).
            tip = mode_shapes(PF, n, L, np.array([L]))[0]
            w_tip = -L * math.sin(delta) + w_L * math.cos(delta)
            wd_tip = math.sin(delta) * om * w_L + math.cos(delta) * (om * L + wd_L) - om_new * L
            kkt = np.zeros((n + 1, n + 1))
            kkt[:n, :n] = mass
            kkt[:n, n] = tip
            kkt[n, :n] = tip
            a_new = np.linalg.solve(kkt, np.append(b_p, w_tip))[:n]
            ad_new = np.linalg.solve(kkt, np.append(b_v, wd_tip))[:n]
        else:
            a_new = np.linalg.solve(mass, b_p)
            ad_new = np.linalg.solve(mass, b_v)
        res_p = float(np.max(np.abs(w_new - phi_new @ a_new)))
        res_v = float(np.max(np.abs(wd_new - phi_new @ ad_new)))
        x[lay.q][sl] = a_new
        x[lay.qd][sl] = ad_new
    else:
        res_p = float(np.max(np.abs(w_new)))
        res_v = float(np.max(np.abs(wd_new)))
    joint = 3 + link
    x[joint] += delta
    x[lay.ns + joint] += om_new - om
    cfg.basis[link] = new
    return SwitchReport(delta, res_p, res_v)


def capture(model: ReferenceModel, x: np.ndarray, cfg: Configuration, arm: int) -> dict[str, float]:
    """Switch grasp `arm` on (docs/physics.md §4.2), in place.  Returns event figures."""
    lay = model.layout
    k = arm - 1
    link = 3 * k + 2
    report = switch_basis(model, x, cfg, link, PP)
    q, qd = x[lay.q], x[lay.qd]
    rE = model.kinematics(q, qd, cfg)[7][k]
    XT = x[lay.target]
    c, s = math.cos(XT[2]), math.sin(XT[2])
    d = rE - XT[0:2]
    cfg.rho_G[k] = [c * d[0] + s * d[1], -s * d[0] + c * d[1]]  # A(θ_T)ᵀ (r_EE − r_T)
    cfg.grasp_on[k] = 1
    # plastic impact: Ẏ⁺ = Ẏ − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹AẎ
    Mg, _, A, *_ = model.assemble(x, np.zeros(core.N_INPUTS), cfg)
    Yd = np.concatenate([x[lay.qd], x[lay.target_d]])
    MinvAt = np.linalg.solve(Mg, A.T)
    jump = -MinvAt @ np.linalg.solve(A @ MinvAt, A @ Yd)
    e_before = 0.5 * Yd @ Mg @ Yd
    Yd = Yd + jump
    e_after = 0.5 * Yd @ Mg @ Yd
    x[lay.qd] = Yd[:lay.nq]
    x[lay.target_d] = Yd[lay.nq:]
    return {"delta_rad": report.delta_rad, "residual_m": report.residual_m,
            "residual_mps": report.residual_mps, "impact_loss_J": e_before - e_after}


def release(model: ReferenceModel, x: np.ndarray, cfg: Configuration, arm: int) -> dict[str, float]:
    """Switch grasp `arm` off and its terminal link to the PF basis, in place."""
    k = arm - 1
    cfg.grasp_on[k] = 0
    report = switch_basis(model, x, cfg, 3 * k + 2, PF)
    return {"delta_rad": report.delta_rad, "residual_m": report.residual_m,
            "residual_mps": report.residual_mps}
