"""Jacobians (A.1), J̇q̇ (A.2) and the mass matrix of eq. (6) against calculus.

* J (JR, Jth, JE) against central differences of the positions kinematics.kinematics returns;
* J̇q̇ (cR, cE) against central differences of J along q̇:
  (J(q + εq̇) − J(q − εq̇))/2ε · q̇ — relative error ≤ 1e-6;
* M_g of `assemble` symmetric positive definite at 100 seeded random states, with modes,
  PF/PP terminal links and grasps;
* ½ẎᵀM_gẎ equals the kinetic energy integrated directly over the material points of the
  links (an independent quadrature of ½∫ρ|ṙ|² from the frames and mode shapes).

States are random and flexible: large modal amplitudes (centimetres) so that the elastic
terms of the tip vector d = (L, w(L)) matter, PF terminal links where w(L) ≠ 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference_model.beam_modes import PF
from reference_model.build import Configuration, ReferenceModel, terminal_basis
from reference_model.model_arrays import N_INPUTS
from rsmcheck.core.params import Params

JDOT_REL_TOL = 1e-6
J_REL_TOL = 1e-6
N_RANDOM = 100

GRASPS = [(0, 0), (1, 0), (0, 1), (1, 1)]


@pytest.fixture(scope="module")
def model() -> ReferenceModel:
    return ReferenceModel(Params(), (2, 3, 2, 1, 2, 4), static_modes="explicit")


def random_state(model: ReferenceModel, rng: np.random.Generator, amp: float = 0.02):
    lay = model.layout
    q = np.zeros(lay.nq)
    qd = np.zeros(lay.nq)
    q[0:2] = rng.normal(size=2)
    q[2] = rng.uniform(-math.pi, math.pi)
    q[3:9] = rng.uniform(-2.5, 2.5, size=6)
    q[9:] = amp * rng.normal(size=lay.nq - 9)
    qd[0:9] = rng.normal(size=9) * 0.5
    qd[9:] = amp * 30.0 * rng.normal(size=lay.nq - 9)
    return q, qd


def random_cfg(model: ReferenceModel, rng: np.random.Generator) -> Configuration:
    g = np.array(GRASPS[rng.integers(len(GRASPS))], dtype=np.int64)
    rho = rng.normal(size=(2, 2))
    return Configuration(grasp_on=g, rho_G=rho, basis=terminal_basis(g))


def test_jdot_qdot_against_finite_differences_of_j(model):
    """cR and cE (= J̇q̇) against central differences of JR and JE along q̇."""
    rng = np.random.default_rng(20240601)
    worst = 0.0
    for trial in range(40):
        q, qd = random_state(model, rng)
        cfg = random_cfg(model, rng)
        kin = model.kinematics(q, qd, cfg)
        cR, cE = kin.cR, kin.cE
        eps = 1e-6 / max(1.0, np.linalg.norm(qd))
        plus = model.kinematics(q + eps * qd, qd, cfg)
        minus = model.kinematics(q - eps * qd, qd, cfg)
        fd_R = np.einsum("ijk,k->ij", (plus.JR - minus.JR) / (2 * eps), qd)
        fd_E = np.einsum("ijk,k->ij", (plus.JE - minus.JE) / (2 * eps), qd)
        fd_th = ((plus.Jth - minus.Jth) / (2 * eps)) @ qd
        # scale: |J̇q̇| is ~ |q̇|² × lengths; compare relative to the largest entry of the set
        scale_R = np.abs(cR).max()
        scale_E = np.abs(cE).max()
        assert scale_R > 1e-3 and scale_E > 1e-3
        err_R = np.abs(fd_R - cR).max() / scale_R
        err_E = np.abs(fd_E - cE).max() / scale_E
        assert err_R <= JDOT_REL_TOL, (trial, err_R)
        assert err_E <= JDOT_REL_TOL, (trial, err_E)
        assert np.abs(fd_th).max() == 0.0  # frame angles are linear in q: J̇_θ = 0
        worst = max(worst, err_R, err_E)
    print(f"max relative error of J̇q̇ vs finite differences: {worst:.2e}")


def test_jacobians_against_finite_differences_of_positions(model):
    rng = np.random.default_rng(7)
    nq = model.layout.nq
    worst = 0.0
    for trial in range(10):
        q, qd = random_state(model, rng)
        cfg = random_cfg(model, rng)
        kin = model.kinematics(q, qd, cfg)
        JR, Jth, JE, Rd, rEd, om = kin.JR, kin.Jth, kin.JE, kin.Rd, kin.rEd, kin.om
        fd_R = np.zeros_like(JR)
        fd_th = np.zeros_like(Jth)
        fd_E = np.zeros_like(JE)
        eps = 1e-6
        for c in range(nq):
            dq = np.zeros(nq)
            dq[c] = eps
            p = model.kinematics(q + dq, qd, cfg)
            m = model.kinematics(q - dq, qd, cfg)
            fd_th[:, c] = (p.th - m.th) / (2 * eps)
            fd_R[:, :, c] = (p.R - m.R) / (2 * eps)
            fd_E[:, :, c] = (p.rE - m.rE) / (2 * eps)
        for fd, J in ((fd_R, JR), (fd_E, JE), (fd_th, Jth)):
            err = np.abs(fd - J).max() / np.abs(J).max()
            assert err <= J_REL_TOL, (trial, err)
            worst = max(worst, err)
        # velocities are J q̇, the angle rates Jθ q̇
        assert np.allclose(np.einsum("ijk,k->ij", JR, qd), Rd, rtol=0, atol=1e-13 * np.abs(Rd).max())
        assert np.allclose(np.einsum("ijk,k->ij", JE, qd), rEd, rtol=0, atol=1e-13 * np.abs(rEd).max())
        assert np.allclose(Jth @ qd, om, rtol=0, atol=1e-14 * np.abs(om).max())
    print(f"max relative error of J vs finite differences: {worst:.2e}")


def test_end_effector_is_the_distal_pin_with_tip_deflection(model):
    """rE = R_3 + A(θ_3)(L, w_3(L)): PF tip deflection moves the end effector, PP does not."""
    rng = np.random.default_rng(3)
    lay = model.layout
    L = model.params.link.length
    for grasp in GRASPS:
        q, qd = random_state(model, rng)
        cfg = Configuration(grasp_on=np.array(grasp), basis=terminal_basis(grasp))
        th, _, R, *_rest = model.kinematics(q, qd, cfg)
        rE = _rest[4]
        for k in range(2):
            i = 3 * k + 2
            n = lay.n_modes[i]
            kind = int(cfg.basis[i])
            wL = (model.bases[i][kind].shapes(np.array([L]))[0] @ q[lay.modes(i)]) if kind == PF else 0.0
            c, s = math.cos(th[i]), math.sin(th[i])
            want = R[i] + np.array([c * L - s * wL, s * L + c * wL])
            assert np.allclose(rE[k], want, rtol=0, atol=1e-13)
            if kind == PF:
                assert abs(wL) > 1e-4


def test_mass_matrix_symmetric_positive_definite_at_random_states(model):
    rng = np.random.default_rng(12345)
    lay = model.layout
    u = np.zeros(N_INPUTS)
    worst_asym = 0.0
    min_ratio = np.inf
    for trial in range(N_RANDOM):
        q, qd = random_state(model, rng)
        cfg = random_cfg(model, rng)
        x = model.zero_state()
        x[lay.q] = q
        x[lay.qd] = qd
        x[lay.target] = [*rng.normal(size=2) * 3, rng.uniform(-3, 3)]
        x[lay.target_d] = rng.normal(size=3) * 0.1
        x[lay.motors] = q[3:9]
        Mg = model.assemble(x, u, cfg)[0]
        asym = np.abs(Mg - Mg.T).max() / np.abs(Mg).max()
        assert asym <= 1e-13, (trial, asym)
        lam = np.linalg.eigvalsh(0.5 * (Mg + Mg.T))
        assert lam[0] > 0.0, (trial, lam[0])
        worst_asym = max(worst_asym, asym)
        min_ratio = min(min_ratio, lam[0] / lam[-1])
    print(f"M_g: max asymmetry {worst_asym:.1e}, min λ_min/λ_max {min_ratio:.1e}")


def _link_kinetic_energy_by_quadrature(model, q, qd, cfg) -> float:
    """½∫ρ|ṙ|² + ½J_extra θ̇² over the six links, r = R + A(θ)(ξ, w), from the shapes."""
    lay = model.layout
    lk = model.params.link
    L = lk.length
    xg, wg = np.polynomial.legendre.leggauss(40)
    xi = 0.5 * L * (xg + 1)
    w_q = 0.5 * L * wg
    th, om, R, Rd, *_ = model.kinematics(q, qd, cfg)
    T = 0.0
    for i in range(6):
        n = lay.n_modes[i]
        phi = model.bases[i][int(cfg.basis[i])].shapes(xi)
        w = phi @ q[lay.modes(i)]
        wd = phi @ qd[lay.modes(i)]
        c, s = math.cos(th[i]), math.sin(th[i])
        # ṙ = Ṙ + θ̇ A S u + A e_y ẇ,  S u = (−w, ξ)
        vx = Rd[i, 0] + om[i] * (c * -w - s * xi) - s * wd
        vy = Rd[i, 1] + om[i] * (s * -w + c * xi) + c * wd
        T += 0.5 * lk.rho_a * np.sum(w_q * (vx**2 + vy**2)) + 0.5 * lk.inertia_extra * om[i] ** 2
    return T


def test_mass_matrix_is_the_kinetic_metric(model):
    """½ẎᵀM_gẎ = kinetic energy of base + target (rigid) + links (material quadrature)."""
    rng = np.random.default_rng(99)
    lay = model.layout
    p = model.params
    u = np.zeros(N_INPUTS)
    for trial in range(20):
        q, qd = random_state(model, rng)
        cfg = random_cfg(model, rng)
        x = model.zero_state()
        x[lay.q] = q
        x[lay.qd] = qd
        XTd = rng.normal(size=3) * 0.2
        x[lay.target_d] = XTd
        x[lay.motors] = q[3:9]
        Mg = model.assemble(x, u, cfg)[0]
        Yd = np.concatenate([qd, XTd])
        T_model = 0.5 * Yd @ Mg @ Yd
        T_base = 0.5 * p.base.mass * qd[0:2] @ qd[0:2] + 0.5 * p.base.inertia_z * qd[2] ** 2
        T_target = 0.5 * p.target.mass * XTd[0:2] @ XTd[0:2] + 0.5 * p.target.inertia_z * XTd[2] ** 2
        T_direct = T_base + T_target + _link_kinetic_energy_by_quadrature(model, q, qd, cfg)
        assert T_model == pytest.approx(T_direct, rel=1e-12, abs=0.0), trial


def test_velocity_forces_are_lagranges_from_the_mass_matrix():
    """The velocity-dependent part of f (eq. 6: −J̇-terms of A.6 and the V of each link,
    centrifugal and Coriolis incl. the modal ones) equals −h with Lagrange's
    h = Ṁ Ẏ − ½ ∂(ẎᵀMẎ)/∂Y, all derivatives of M_g by central differences.
    Damping off (η = 0, C_m = 0) so f(Y, Ẏ) − f(Y, 0) is purely inertial."""
    from rsmcheck.core.params import Params as P

    prm = P.from_overrides({"link": {"damping_ratio": 0.0}, "motor": {"damping": 0.0}}, "test")
    mdl = ReferenceModel(prm, (2, 3, 2, 1, 2, 4), static_modes="explicit")
    lay = mdl.layout
    u = np.zeros(N_INPUTS)
    rng = np.random.default_rng(31)
    worst = 0.0
    for trial in range(10):
        q, qd = random_state(mdl, rng, amp=0.05)
        g = GRASPS[trial % 4]
        cfg = Configuration(grasp_on=np.zeros(2, dtype=np.int64), rho_G=np.zeros((2, 2)), basis=terminal_basis(g))
        Yd = np.concatenate([qd, rng.normal(size=3) * 0.1])

        def state(qq, yd):
            x = mdl.zero_state()
            x[lay.q] = qq
            x[lay.motors] = qq[3:9]
            x[lay.qd] = yd[:lay.nq]
            x[lay.target_d] = yd[lay.nq:]
            x[lay.motors_d] = yd[3:9]
            return x

        def Mg(qq):
            return mdl.assemble(state(qq, np.zeros(lay.ny)), u, cfg)[0]

        f_v = mdl.assemble(state(q, Yd), u, cfg)[1] - mdl.assemble(state(q, np.zeros(lay.ny)), u, cfg)[1]
        eps = 1e-6
        Mdot = (Mg(q + eps * qd) - Mg(q - eps * qd)) / (2 * eps)
        grad = np.zeros(lay.ny)
        for c in range(lay.nq):
            e = np.zeros(lay.nq)
            e[c] = eps
            grad[c] = 0.5 * Yd @ ((Mg(q + e) - Mg(q - e)) / (2 * eps)) @ Yd
        h = Mdot @ Yd - grad
        err = np.abs(f_v + h).max() / np.abs(h).max()
        assert err <= 1e-6, (trial, err)
        worst = max(worst, err)
    print(f"velocity forces vs Lagrange: max relative error {worst:.1e}")
