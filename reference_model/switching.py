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

from reference_model.model_arrays import N_INPUTS
from reference_model.beam_modes import PF, PP, quadrature
from reference_model.build import Configuration, ReferenceModel
from rsmcheck.core.geometry import rot


@dataclass(frozen=True)
class SwitchReport:
    """What a basis switch did: frame rotation δ [rad], largest position and velocity
    discontinuity of a material point over the link [m, m/s] (the projection residual),
    and the generalised momentum the new coordinates dropped (`dropped_momentum`, over Ẏ)."""

    delta_rad: float
    residual_m: float
    residual_mps: float
    dropped_momentum: np.ndarray | None = None


def switch_basis(model: ReferenceModel, x: np.ndarray, cfg: Configuration, link: int, new: int) -> SwitchReport:
    """Re-express terminal link `link` in basis `new` (PP or PF), in place on x and cfg.

    Old frame θ, field w = Φ_old A; new frame θ' = θ + δ:
        capture (PP):  tan δ = w(L)/L                   (the chord through both pins)
        release (PF):  tan δ = ∫ρ ξ w dξ / I_0           (mass-orthogonal rigid mode)
    Transverse field in the new frame, w'(ξ) = n'·(r(ξ) − R) = −ξ sin δ + w cos δ, rate
    ẇ'(ξ) = θ̇ w sin δ + (θ̇ ξ + ẇ) cos δ − θ̇' ξ, with θ̇' fixed by the same condition on the
    rates; both projected on Φ_new by mass-weighted least squares constrained to keep the
    proximal section's slope w'(0), ẇ'(0) (so the joint's section angle ψ_J, and with it the
    spring torque of eq. 5, is continuous) and, for PF, the free tip w'(L), ẇ'(L) (the distal
    pin stays continuous; for PP the chord frame already puts it at w'(L) = 0).  θ_J of the
    link takes δ (and θ̇' − θ̇); the rotor angle and the proximal pin do not move.

    What the new rates do not carry is returned as a generalised momentum over Ẏ: the
    velocity field's residual r(ξ) = ṙ_old(ξ) − ṙ_new(ξ) at each material point, and J_extra's
    spin, which rides on the frame (physics.md §2.3) and still turns at the old rate θ̇:
        p_i = ∫ρ r·∂ṙ_new/∂q̇_i dξ + ∂θ/∂q_i J_extra (θ̇ − θ̇').
    `project_velocities` gives it back to the system.
    """
    lay = model.layout
    old = int(cfg.basis[link])
    if old == new:
        return SwitchReport(0.0, 0.0, 0.0)
    if model.condensed:
        x[:] = model.complete(x, cfg)  # the slaved static shapes at their values (condense.py)
    n = lay.n_modes[link]
    lk = model.params.link
    L, rho = lk.length, lk.rho_a
    I0 = lk.mass * L**2 / 3.0
    xi, wq = quadrature(L)
    q, qd = x[lay.q], x[lay.qd]
    sl = lay.modes(link)
    shapes_old = model.bases[link][old].shapes
    shapes_new = model.bases[link][new].shapes
    ends = np.array([0.0, L])
    phi_old = shapes_old(xi)
    phi_new = shapes_new(xi)
    w = phi_old @ q[sl] if n else np.zeros_like(xi)
    wd = phi_old @ qd[sl] if n else np.zeros_like(xi)
    w_L = shapes_old(ends[1:])[0] @ q[sl] if n else 0.0
    wd_L = shapes_old(ends[1:])[0] @ qd[sl] if n else 0.0
    if old == PP:
        w_L = wd_L = 0.0  # the chord frame passes through both pins
    slope_old = shapes_old(ends[:1], 1)[0]
    s0, sd0 = (slope_old @ q[sl], slope_old @ qd[sl]) if n else (0.0, 0.0)
    kin = model.kinematics(q, qd, cfg)
    th_old, om = kin.th[link], kin.om[link]
    # slaved static shapes (condense.py) of the arm's other links follow the switch too
    arm_links = [i for i in range(3 * (link // 3), 3 * (link // 3) + 3) if i != link] if model.condensed else []
    fields_before = {i: link_velocity_field(model, x, cfg, i, xi) for i in arm_links}

    if new == PP:
        delta = math.atan2(w_L, L)
        om_new = (math.sin(delta) * om * w_L + math.cos(delta) * (om * L + wd_L)) / L
    else:
        delta = math.atan2(rho * np.sum(wq * xi * w), I0)
        vn = math.sin(delta) * om * w + math.cos(delta) * (om * xi + wd)
        om_new = rho * np.sum(wq * xi * vn) / I0
    w_new = -xi * math.sin(delta) + w * math.cos(delta)
    wd_new = math.sin(delta) * om * w + math.cos(delta) * (om * xi + wd) - om_new * xi

    if n:
        mass = rho * (phi_new.T * wq) @ phi_new
        b_p = rho * (phi_new.T * wq) @ w_new
        b_v = rho * (phi_new.T * wq) @ wd_new
        # constraints: w'(0) and ẇ'(0) of the new field (the section keeps its angle and rate:
        # w'(0) = −sin δ + w_old'(0) cos δ, ẇ'(0) = θ̇ w_old'(0) sin δ + (θ̇ + ẇ_old'(0)) cos δ − θ̇');
        # for PF also the free tip w'(L) = n'·(r(L) − R) and its rate
        rows = [shapes_new(ends[:1], 1)[0]]
        c_p = [-math.sin(delta) + s0 * math.cos(delta)]
        c_v = [math.sin(delta) * om * s0 + math.cos(delta) * (om + sd0) - om_new]
        if new == PF:
            rows.append(shapes_new(ends[1:])[0])
            c_p.append(-L * math.sin(delta) + w_L * math.cos(delta))
            c_v.append(math.sin(delta) * om * w_L + math.cos(delta) * (om * L + wd_L) - om_new * L)
        if len(rows) >= n:  # too few shapes to honour every condition: the tip first
            rows, c_p, c_v = rows[1:], c_p[1:], c_v[1:]
        C = np.array(rows).reshape(len(rows), n)
        nc = C.shape[0]
        kkt = np.zeros((n + nc, n + nc))
        kkt[:n, :n] = mass
        kkt[:n, n:] = C.T
        kkt[n:, :n] = C
        a_new = np.linalg.solve(kkt, np.concatenate([b_p, c_p]))[:n]
        ad_new = np.linalg.solve(kkt, np.concatenate([b_v, c_v]))[:n]
        res_p = float(np.max(np.abs(w_new - phi_new @ a_new)))
        x[lay.q][sl] = a_new
        x[lay.qd][sl] = ad_new
    else:
        res_p = float(np.max(np.abs(w_new)))
    joint = 3 + link
    x[joint] += delta
    x[lay.ns + joint] += om_new - om
    cfg.basis[link] = new
    if model.condensed:
        # slaved static shapes (condense.py) take their values in the new basis: the field
        # kept, and with it the residual and the dropped momentum below, is that one
        x[:] = model.complete(x, cfg)

    # the velocity field before and after, at the same material points ξ (inertial axes):
    # ṙ(ξ) = Ṙ + A(θ)(−θ̇ w, θ̇ ξ + ẇ); the pin velocity Ṙ is the same in both
    w_kept = phi_new @ x[lay.q][sl] if n else np.zeros_like(xi)
    wd_kept = phi_new @ x[lay.qd][sl] if n else np.zeros_like(xi)
    th_new = th_old + delta
    r = (rot(th_old) @ np.array([-om * w, om * xi + wd])
         - rot(th_new) @ np.array([-om_new * w_kept, om_new * xi + wd_kept]))
    n_new = np.array([-math.sin(th_new), math.cos(th_new)])
    dropped = residual_momentum(model, x, cfg, link, xi, wq, r)
    dropped[:lay.nq] += model.kinematics(x[lay.q], x[lay.qd], cfg).Jth[link] * lk.inertia_extra * (om - om_new)
    for i in arm_links:
        dropped += link_dropped_momentum(model, x, cfg, i, xi, wq, fields_before[i])
    # the transverse part n'·r is the rate residual ẇ' − Φ_new ȧ' of the least squares
    return SwitchReport(delta, res_p, float(np.max(np.abs(n_new @ r))), dropped)


def link_velocity_field(model: ReferenceModel, x: np.ndarray, cfg: Configuration, i: int,
                        xi: np.ndarray) -> np.ndarray:
    """ṙ(ξ) (2 × len(ξ), inertial) of link i's material points: Ṙ + A(θ)(−θ̇ w, θ̇ ξ + ẇ)."""
    lay = model.layout
    kin = model.kinematics(x[lay.q], x[lay.qd], cfg)
    phi = model.bases[i][int(cfg.basis[i])].shapes(xi)
    sl = lay.modes(i)
    w = phi @ x[lay.q][sl] if lay.n_modes[i] else np.zeros_like(xi)
    wd = phi @ x[lay.qd][sl] if lay.n_modes[i] else np.zeros_like(xi)
    om = kin.om[i]
    return kin.Rd[i][:, None] + rot(kin.th[i]) @ np.array([-om * w, om * xi + wd])


def link_dropped_momentum(model: ReferenceModel, x: np.ndarray, cfg: Configuration, i: int,
                          xi: np.ndarray, wq: np.ndarray, before: np.ndarray) -> np.ndarray:
    """`residual_momentum` of link i's r = ṙ_before − ṙ(x), for a link whose slaved static
    shapes the switch moved (condense.py)."""
    return residual_momentum(model, x, cfg, i, xi, wq, before - link_velocity_field(model, x, cfg, i, xi))


def residual_momentum(model: ReferenceModel, x: np.ndarray, cfg: Configuration, i: int,
                      xi: np.ndarray, wq: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The generalised momentum over Ẏ of a velocity residual r(ξ) (2 × len(ξ)) over link
    i's mass in state x: p = ∫ρ r·∂ṙ/∂Ẏ dξ, with
    ∂ṙ/∂q̇_k = ∂R/∂q_k + ∂θ/∂q_k A(θ)(−w, ξ) + [k = a_j] A(θ) e_y φ_j."""
    lay = model.layout
    rho = model.params.link.rho_a
    kin = model.kinematics(x[lay.q], x[lay.qd], cfg)
    phi = model.bases[i][int(cfg.basis[i])].shapes(xi)
    sl = lay.modes(i)
    w = phi @ x[lay.q][sl] if lay.n_modes[i] else np.zeros_like(xi)
    turn = rot(kin.th[i]) @ np.array([-w, xi])
    n_i = np.array([-math.sin(kin.th[i]), math.cos(kin.th[i])])
    p = np.zeros(lay.ny)
    p[:lay.nq] = kin.JR[i].T @ (rho * (r @ wq)) + kin.Jth[i] * (rho * np.sum(wq * np.sum(r * turn, axis=0)))
    if lay.n_modes[i]:
        p[sl] += rho * (phi.T * wq) @ (n_i @ r)
    return p


def capture(model: ReferenceModel, x: np.ndarray, cfg: Configuration, arm: int) -> dict[str, float]:
    """Switch grasp `arm` on (docs/physics.md §4.2), in place.  Returns event figures."""
    lay = model.layout
    k = arm - 1
    e_before = kinetic_energy(model, x, cfg)
    report = switch_basis(model, x, cfg, 3 * k + 2, PP)
    q, qd = x[lay.q], x[lay.qd]
    rE = model.kinematics(q, qd, cfg).rE[k]
    XT = x[lay.target]
    c, s = math.cos(XT[2]), math.sin(XT[2])
    d = rE - XT[0:2]
    cfg.rho_G[k] = [c * d[0] + s * d[1], -s * d[0] + c * d[1]]  # A(θ_T)ᵀ (r_EE − r_T)
    cfg.grasp_on[k] = 1
    project_velocities(model, x, cfg, report.dropped_momentum)
    return {"delta_rad": report.delta_rad, "residual_m": report.residual_m,
            "residual_mps": report.residual_mps, "impact_loss_J": e_before - kinetic_energy(model, x, cfg)}


def release(model: ReferenceModel, x: np.ndarray, cfg: Configuration, arm: int) -> dict[str, float]:
    """Switch grasp `arm` off and its terminal link to the PF basis, in place."""
    k = arm - 1
    e_before = kinetic_energy(model, x, cfg)
    cfg.grasp_on[k] = 0
    report = switch_basis(model, x, cfg, 3 * k + 2, PF)
    project_velocities(model, x, cfg, report.dropped_momentum)
    return {"delta_rad": report.delta_rad, "residual_m": report.residual_m,
            "residual_mps": report.residual_mps, "impact_loss_J": e_before - kinetic_energy(model, x, cfg)}


def project_velocities(model: ReferenceModel, x: np.ndarray, cfg: Configuration,
                       dropped: np.ndarray | None) -> None:
    """Velocities after a switch (docs/physics.md §4.2, §4.4), in place: the generalised
    momentum the switch dropped is given back, then every active grasp is satisfied,

        M Ẏ⁺ = M Ẏ + p_dropped + Aᵀλ,   A Ẏ⁺ = 0,
        Ẏ⁺ = P (Ẏ + M⁻¹ p_dropped),   P = 1 − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹A,

    i.e. the old velocity field projected on the new admissible velocities in the
    kinetic-energy metric of the whole system.  All impulses are internal (the field's own,
    J_extra's on its frame, the grasps' Aᵀλ): linear and angular momentum are conserved.
    With nothing dropped and a grasp just added it is the plastic impact of §4.2.
    With the static shapes slaved (condense.py) the same over z = [Y, θ_m] in the metric
    M_z (`ReferenceModel.reduced`): the dropped momentum on the shapes goes to z as Tᵀ p_s,
    the rotors take part (the shapes couple them with their arm), and the shapes' rates
    follow (`ReferenceModel.complete`).
    """
    lay = model.layout
    if model.condensed:
        Mz, _, Az, *_ = model.reduced(x, np.zeros(N_INPUTS), cfg)
        r = np.sort(model.arrays.order)
        Z = np.concatenate([x[lay.qd], x[lay.target_d], x[lay.motors_d]])
        if dropped is not None:
            _, T, idx = model.slaving(x, cfg)
            p = np.concatenate([dropped, np.zeros(6)])
            p += T[idx >= 0].T @ dropped[idx[idx >= 0]]
            dropped_z = p[r]
        M, A, Yd = Mz[np.ix_(r, r)], Az[:, r], Z[r]
    else:
        M, _, A, *_ = model.assemble(x, np.zeros(N_INPUTS), cfg)
        Yd = np.concatenate([x[lay.qd], x[lay.target_d]])
        dropped_z = dropped
    if dropped is not None:
        Yd = Yd + np.linalg.solve(M, dropped_z)
    if A.shape[0]:
        # Ẏ⁺ = Ẏ − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹AẎ
        MinvAt = np.linalg.solve(M, A.T)
        Yd = Yd - MinvAt @ np.linalg.solve(A @ MinvAt, A @ Yd)
    if model.condensed:
        Z[r] = Yd
        x[lay.qd] = Z[:lay.nq]
        x[lay.target_d] = Z[lay.nq:lay.ny]
        x[lay.motors_d] = Z[lay.ny:]
        x[:] = model.complete(x, cfg)
    else:
        x[lay.qd] = Yd[:lay.nq]
        x[lay.target_d] = Yd[lay.nq:]


def kinetic_energy(model: ReferenceModel, x: np.ndarray, cfg: Configuration) -> float:
    """½ Ẏᵀ M Ẏ [J]: base, links (J_extra included) and target; the rotors are not touched
    by a switch (with the static shapes slaved they are: ½ żᵀ M_z ż, rotors included)."""
    lay = model.layout
    if model.condensed:
        Mz = model.reduced(x, np.zeros(N_INPUTS), cfg)[0]
        Z = np.concatenate([x[lay.qd], x[lay.target_d], x[lay.motors_d]])
        return float(0.5 * Z @ Mz @ Z)
    Mg = model.assemble(x, np.zeros(N_INPUTS), cfg)[0]
    Yd = np.concatenate([x[lay.qd], x[lay.target_d]])
    return float(0.5 * Yd @ Mg @ Yd)
