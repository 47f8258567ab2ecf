"""Self-checks of the Pinocchio side, without the reference model.

Three kinds of evidence that `pinocchio_check.model` answers the right questions:
* a textbook planar model written here by hand (`hand_bodies`: positions and velocities
  of every body COM from sums of link vectors) — kinetic energy, COM, momentum, end
  effectors, grasp points;
* calculus: Jacobians and J̇q̇ against central differences of Pinocchio's own positions,
  bias forces against Lagrange's h = Ṁẏ − ½ ∂(ẏᵀMẏ)/∂y from differences of M;
* mechanics: Newton–Euler of the target and the RSM equation of eq. (3) with the
  reaction forces Pinocchio returns, constraint accelerations, momentum balance, the
  λ sign of ``pin.forwardDynamics``, and a second, independent constrained formulation
  (free target + 4 multipliers, the structure of eq. 11).
Both base-joint variants (PX-PY-RZ and JointModelPlanar) are exercised.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinocchio_check import states as S
from pinocchio_check.model import (
    LWA,
    N_Q,
    PinocchioRSM,
    build_model,
    frame_pose_velocity_y,
    mass_matrix_y,
    point_kinematics_y,
)
from rsmcheck.core.geometry import rot
from rsmcheck.core.params import Params

PARAMS = Params()
SEEDS = range(8)


@pytest.fixture(scope="module", params=["pxpyrz", "planar"])
def rsm(request) -> PinocchioRSM:
    return PinocchioRSM(PARAMS, base_joint=request.param)


@pytest.fixture(scope="module")
def rsm_px() -> PinocchioRSM:
    return PinocchioRSM(PARAMS)


def perp(v):
    """Rotate a planar vector by +90°: ω × v = ω perp(v) for ω about z."""
    return np.array([-v[1], v[0]])


def cross2(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


# ---------------------------------------------------------------------------------------
# The hand model: a planar chain written out with trigonometry, no Pinocchio.
# ---------------------------------------------------------------------------------------
def hand_bodies(p: Params, q, qd, X_T=None, XT_d=None):
    """[(name, m, I_z, r_c, v_c, ω)] of base, six links [, target]; plus EE positions."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    L, m_l, I_l = p.link.length, p.link.mass, p.link.inertia_z
    r_B, v_B, th_B, w_B = q[:2], qd[:2], q[2], qd[2]
    out = [("base", p.base.mass, p.base.inertia_z, r_B, v_B, w_B)]
    ee = {}
    for arm, cols in ((1, slice(3, 6)), (2, slice(6, 9))):
        m_B = rot(th_B) @ np.array(p.geometry.mount_B(arm))
        r_j, v_j = r_B + m_B, v_B + w_B * perp(m_B)
        phi, w = th_B, w_B
        for i, (th, thd) in enumerate(zip(q[cols], qd[cols]), start=1):
            phi, w = phi + th, w + thd
            e = np.array([np.cos(phi), np.sin(phi)])
            out.append((f"link{i}_{arm}", m_l, I_l, r_j + L / 2 * e, v_j + w * L / 2 * perp(e), w))
            r_j, v_j = r_j + L * e, v_j + w * L * perp(e)
        ee[arm] = r_j
    if X_T is not None:
        out.append(("target", p.target.mass, p.target.inertia_z, np.asarray(X_T[:2], float),
                    np.asarray(XT_d[:2], float), float(XT_d[2])))
    return out, ee


def rng_q(seed):
    rng = np.random.default_rng(1000 + seed)
    q = np.concatenate([rng.uniform(-1, 1, 3), S.NOMINAL_ARM1 + rng.uniform(-1.5, 1.5, 3),
                        S.NOMINAL_ARM2 + rng.uniform(-1.5, 1.5, 3)])
    return q, rng.uniform(-0.3, 0.3, N_Q), rng


# ---------------------------------------------------------------------------------------
# Model structure
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("target", [None, "arm1", "arm2", "free"])
@pytest.mark.parametrize("base_joint", ["pxpyrz", "planar"])
def test_model_structure(target, base_joint):
    pm = build_model(PARAMS, target, base_joint)
    assert pm.model.check(pm.data)
    assert pm.chart.n == pm.model.nv == {None: 9, "arm1": 10, "arm2": 10, "free": 12}[target]
    assert np.all(pm.model.gravity.linear == 0.0)
    total = sum(pm.model.inertias[j].mass for j in range(pm.model.njoints))
    expected = PARAMS.base.mass + 6 * PARAMS.link.mass + (0 if target is None else PARAMS.target.mass)
    assert total == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("seed", SEEDS)
def test_mass_matrix_symmetric_positive_definite(rsm, seed):
    q, _, _ = rng_q(seed)
    M = rsm.mass_matrix(q)
    assert np.allclose(M, M.T, rtol=0, atol=1e-12 * np.abs(M).max())
    assert np.linalg.eigvalsh(M).min() > 0.0


@pytest.mark.parametrize("seed", SEEDS)
def test_kinetic_energy_equals_hand_sum(rsm, seed):
    q, qd, rng = rng_q(seed)
    X_T, XT_d = rng.uniform(-3, 3, 3), rng.uniform(-0.3, 0.3, 3)
    bodies, _ = hand_bodies(PARAMS, q, qd, X_T, XT_d)
    T_hand = sum(0.5 * m * v @ v + 0.5 * I * w * w for _, m, I, _, v, w in bodies)
    y, yd = np.concatenate([q, X_T]), np.concatenate([qd, XT_d])
    T_pin = 0.5 * yd @ mass_matrix_y(rsm.free, y) @ yd
    assert T_pin == pytest.approx(T_hand, rel=1e-13)
    # RSM alone: the same sum without the target.
    T_rsm = 0.5 * qd @ rsm.mass_matrix(q) @ qd
    T_hand_rsm = sum(0.5 * m * v @ v + 0.5 * I * w * w for n, m, I, _, v, w in bodies if n != "target")
    assert T_rsm == pytest.approx(T_hand_rsm, rel=1e-13)


@pytest.mark.parametrize("seed", SEEDS)
def test_body_com_frames_match_hand_model(rsm_px, seed):
    q, qd, _ = rng_q(seed)
    bodies, _ = hand_bodies(PARAMS, q, qd)
    for name, _, _, r_c, v_c, _ in bodies:
        r, J, _ = point_kinematics_y(rsm_px.rsm, q, qd, "com_" + name)
        assert np.allclose(r, r_c, rtol=0, atol=1e-13)
        assert np.allclose(J @ qd, v_c, rtol=0, atol=1e-13)


# ---------------------------------------------------------------------------------------
# End effectors, grasp points, Jacobians and J̇q̇
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_end_effectors_match_hand_model(rsm, seed):
    q, qd, _ = rng_q(seed)
    _, ee = hand_bodies(PARAMS, q, qd)
    for arm in (1, 2):
        r, _, _ = rsm.point_kinematics(q, qd, f"ee{arm}")
        assert np.allclose(r, ee[arm], rtol=0, atol=1e-13)


def test_nominal_configuration_closes_both_grasps(rsm_px):
    """θ_J = ±(60°, −120°, 60°), θ_B = θ_T = 0 and the target centre at (5.5, 0): both end
    effectors on their grasp points (the COM offset moves X_T, not the grasp points)."""
    q = np.concatenate([np.zeros(3), S.NOMINAL_ARM1, S.NOMINAL_ARM2])
    o = PARAMS.geometry.target_com_offset_T
    X_T = np.array([5.5 + o[0], o[1], 0.0])
    for arm in (1, 2):
        r_ee, _, _ = rsm_px.point_kinematics(q, np.zeros(9), f"ee{arm}")
        assert np.allclose(r_ee, rsm_px.grasp_point(X_T, arm), atol=1e-14)


@pytest.mark.parametrize("seed", SEEDS)
def test_grasp_points_match_hand_formula(rsm, seed):
    rng = np.random.default_rng(seed)
    X_T = rng.uniform(-4, 4, 3)
    for arm in (1, 2):
        expected = X_T[:2] + rot(X_T[2]) @ np.array(PARAMS.geometry.grasp_T(arm))
        assert np.allclose(rsm.grasp_point(X_T, arm), expected, rtol=0, atol=1e-14)


@pytest.mark.parametrize("seed", SEEDS)
def test_jacobians_and_jdot_by_finite_differences(rsm, seed):
    q, qd, _ = rng_q(seed)
    h = 1e-6
    for point in ("ee1", "ee2"):
        _, J, jdot_qd = rsm.point_kinematics(q, qd, point)
        J_fd = np.column_stack([
            (rsm.point_kinematics(q + h * e, qd, point)[0] - rsm.point_kinematics(q - h * e, qd, point)[0]) / (2 * h)
            for e in np.eye(N_Q)
        ])
        assert np.allclose(J, J_fd, rtol=0, atol=1e-8)
        Jp = rsm.point_kinematics(q + h * qd, qd, point)[1]
        Jm = rsm.point_kinematics(q - h * qd, qd, point)[1]
        assert np.allclose(jdot_qd, (Jp - Jm) / (2 * h) @ qd, rtol=0, atol=1e-8)


@pytest.mark.parametrize("seed", SEEDS)
def test_jdot_qd_equals_pinocchio_jacobian_time_variation(rsm_px, seed):
    """With T = I the classical-acceleration route equals getFrameJacobianTimeVariation."""
    q, qd, _ = rng_q(seed)
    pm = rsm_px.rsm
    pin.computeJointJacobiansTimeVariation(pm.model, pm.data, q, qd)
    pin.updateFramePlacements(pm.model, pm.data)
    for point in ("ee1", "ee2"):
        dJ = pin.getFrameJacobianTimeVariation(pm.model, pm.data, pm.frames[point], LWA)
        _, _, jdot_qd = rsm_px.point_kinematics(q, qd, point)
        assert np.allclose(jdot_qd, (dJ @ qd)[:2], rtol=0, atol=1e-13)


# ---------------------------------------------------------------------------------------
# Bias forces and base-joint variants
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_bias_forces_equal_lagrange_form(rsm, seed):
    """h = Ṁ q̇ − ½ ∂(q̇ᵀ M q̇)/∂q, derivatives of M by central differences."""
    q, qd, _ = rng_q(seed)
    h = 1e-6
    Mdot = (rsm.mass_matrix(q + h * qd) - rsm.mass_matrix(q - h * qd)) / (2 * h)
    grad = np.array([
        (qd @ rsm.mass_matrix(q + h * e) @ qd - qd @ rsm.mass_matrix(q - h * e) @ qd) / (2 * h)
        for e in np.eye(N_Q)
    ])
    expected = Mdot @ qd - 0.5 * grad
    assert np.allclose(rsm.bias_forces(q, qd), expected, rtol=0, atol=1e-6 * np.abs(expected).max())


@pytest.mark.parametrize("seed", SEEDS)
def test_planar_base_joint_gives_the_same_reference_quantities(seed):
    """The T-mapping of the planar joint against the identity chart (PX-PY-RZ)."""
    a, b = PinocchioRSM(PARAMS, "pxpyrz"), PinocchioRSM(PARAMS, "planar")
    s = S.open_state(a, seed)
    c = S.closed_state(a, seed + 2)
    tol = dict(rtol=1e-12, atol=1e-11)
    assert np.allclose(a.mass_matrix(s.q), b.mass_matrix(s.q), **tol)
    assert np.allclose(a.bias_forces(s.q, s.qd), b.bias_forces(s.q, s.qd), **tol)
    for point in ("ee1", "ee2"):
        for x, y in zip(a.point_kinematics(s.q, s.qd, point), b.point_kinematics(s.q, s.qd, point)):
            assert np.allclose(x, y, **tol)
    for x, y in zip(a.com(s.q, s.X_T), b.com(s.q, s.X_T)):
        assert np.allclose(x, y, **tol)
    assert np.allclose(a.momentum(s.q, s.qd, s.X_T, s.XT_d), b.momentum(s.q, s.qd, s.X_T, s.XT_d), **tol)
    for st in [s] + ([c] if c is not None else []):
        ra = a.constrained_accelerations(st.q, st.qd, st.X_T, st.XT_d, st.grasp, st.u_J, st.tau_B)
        rb = b.constrained_accelerations(st.q, st.qd, st.X_T, st.XT_d, st.grasp, st.u_J, st.tau_B)
        for x, y in zip(ra, rb):
            assert np.allclose(x, y, rtol=1e-11, atol=1e-10)


# ---------------------------------------------------------------------------------------
# COM and momentum
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_com_and_momentum_match_hand_sums(rsm, seed):
    q, qd, rng = rng_q(seed)
    X_T, XT_d = rng.uniform(-3, 3, 3), rng.uniform(-0.3, 0.3, 3)
    bodies, _ = hand_bodies(PARAMS, q, qd, X_T, XT_d)
    m_tot = sum(m for _, m, *_ in bodies)
    c_hand = sum(m * r for _, m, _, r, _, _ in bodies) / m_tot
    v_hand = sum(m * v for _, m, _, _, v, _ in bodies) / m_tot
    L_hand = sum(cross2(r, m * v) + I * w for _, m, I, r, v, w in bodies)
    c, Jc = rsm.com(q, X_T)
    assert np.allclose(c, c_hand, rtol=0, atol=1e-13)
    assert np.allclose(Jc @ np.concatenate([qd, XT_d]), v_hand, rtol=0, atol=1e-13)
    p = rsm.momentum(q, qd, X_T, XT_d)
    assert np.allclose(p[:2], m_tot * v_hand, rtol=0, atol=1e-11)
    assert p[2] == pytest.approx(L_hand, rel=1e-12, abs=1e-11)


@pytest.mark.parametrize("seed", SEEDS)
def test_com_jacobian_by_finite_differences(rsm, seed):
    q, _, rng = rng_q(seed)
    X_T = rng.uniform(-3, 3, 3)
    y, h = np.concatenate([q, X_T]), 1e-6
    _, Jc = rsm.com(q, X_T)
    J_fd = np.column_stack([
        (rsm.com((y + h * e)[:9], (y + h * e)[9:])[0] - rsm.com((y - h * e)[:9], (y - h * e)[9:])[0]) / (2 * h)
        for e in np.eye(12)
    ])
    assert np.allclose(Jc, J_fd, rtol=0, atol=1e-8)


@pytest.mark.parametrize("seed", SEEDS)
def test_wrist_tree_and_free_target_agree_on_consistent_states(rsm_px, seed):
    """COM and momentum of the held tree (minimal coordinates) = free-target model."""
    s = S.open_state(rsm_px, seed)
    pm = rsm_px.held[1]
    y, yd = rsm_px.tree_coordinates(1, s.q, s.qd, s.X_T, s.XT_d)
    qp, vp = pm.state(y, yd)
    c = pin.centerOfMass(pm.model, pm.data, qp)[:2]
    hg = pin.computeCentroidalMomentum(pm.model, pm.data, qp, vp)
    assert np.allclose(c, rsm_px.com(s.q, s.X_T)[0], rtol=0, atol=1e-13)
    p = rsm_px.momentum(s.q, s.qd, s.X_T, s.XT_d)
    assert np.allclose(hg.linear[:2], p[:2], rtol=0, atol=1e-11)
    assert hg.angular[2] + cross2(c, hg.linear[:2]) == pytest.approx(p[2], abs=1e-10)


# ---------------------------------------------------------------------------------------
# States
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_random_states_satisfy_their_grasps(rsm_px, seed):
    s = S.open_state(rsm_px, seed)
    phi, phid = rsm_px.grasp_residual(1, s.q, s.qd, s.X_T, s.XT_d)
    assert np.abs(phi).max() < 1e-13 and np.abs(phid).max() < 1e-13
    y, yd = rsm_px.tree_coordinates(1, s.q, s.qd, s.X_T, s.XT_d)
    pose, _ = frame_pose_velocity_y(rsm_px.held[1], y, yd, "target")
    assert np.angle(np.exp(1j * (pose[2] - s.X_T[2]))) == pytest.approx(0.0, abs=1e-14)
    (c,) = S.closed_states(rsm_px, 1, first_seed=seed * 7)
    for arm in (1, 2):
        phi, phid = rsm_px.grasp_residual(arm, c.q, c.qd, c.X_T, c.XT_d)
        assert np.abs(phi).max() < 1e-12 and np.abs(phid).max() < 1e-13


def test_inconsistent_state_is_refused(rsm_px):
    s = S.open_state(rsm_px, 0)
    X_T = s.X_T + np.array([1e-3, 0.0, 0.0])
    with pytest.raises(ValueError, match="grasp 1"):
        rsm_px.constrained_accelerations(s.q, s.qd, X_T, s.XT_d, (True, False))


# ---------------------------------------------------------------------------------------
# Constrained dynamics: mechanics checks on Pinocchio's answers
# ---------------------------------------------------------------------------------------
def target_newton_euler_residual(p: Params, rsm: PinocchioRSM, st, XT_dd, R_cl):
    """m_T a_T − ΣR_k and I_T θ̈_T − Σ (ρ_k × R_k), ρ_k = grasp k − target COM."""
    force, moment = np.zeros(2), 0.0
    for arm in (1, 2):
        R = R_cl[2 * arm - 2 : 2 * arm]
        rho = rsm.grasp_point(st.X_T, arm) - st.X_T[:2]
        force += R
        moment += cross2(rho, R)
    return p.target.mass * XT_dd[:2] - force, p.target.inertia_z * XT_dd[2] - moment


def rsm_equation_residual(rsm: PinocchioRSM, st, qdd, R_cl):
    """Eq. (3), RSM rows: M q̈ + h − Q + Σ J_EE,kᵀ R_k (the end effector feels −R)."""
    Q = np.zeros(9)
    Q[2], Q[3:9] = st.tau_B, st.u_J
    res = rsm.mass_matrix(st.q) @ qdd + rsm.bias_forces(st.q, st.qd) - Q
    for arm in (1, 2):
        _, J, _ = rsm.point_kinematics(st.q, st.qd, f"ee{arm}")
        res += J.T @ R_cl[2 * arm - 2 : 2 * arm]
    return res


def grasp_acceleration_residual(p: Params, rsm: PinocchioRSM, st, arm, qdd, XT_dd):
    """φ̈_k = a_EE,k − a_grasp,k, a_grasp = a_T + θ̈_T perp(ρ) − θ̇_T² ρ."""
    _, J, jdq = rsm.point_kinematics(st.q, st.qd, f"ee{arm}")
    rho = rsm.grasp_point(st.X_T, arm) - st.X_T[:2]
    a_g = XT_dd[:2] + XT_dd[2] * perp(rho) - st.XT_d[2] ** 2 * rho
    return J @ qdd + jdq - a_g


def states_for(rsm, chain):
    if chain == "open1":
        return [S.open_state(rsm, s, 1) for s in SEEDS]
    if chain == "open2":
        return [S.open_state(rsm, s, 2) for s in SEEDS]
    return S.closed_states(rsm, len(SEEDS))


@pytest.mark.parametrize("chain", ["open1", "open2", "closed"])
def test_constrained_dynamics_satisfy_newton_euler_and_eq3(rsm, chain):
    for st in states_for(rsm, chain):
        qdd, XT_dd, R_cl = rsm.constrained_accelerations(st.q, st.qd, st.X_T, st.XT_d, st.grasp, st.u_J, st.tau_B)
        f, n = target_newton_euler_residual(PARAMS, rsm, st, XT_dd, R_cl)
        scale = PARAMS.target.mass * np.abs(XT_dd[:2]).max() + np.abs(R_cl).max()
        assert np.abs(f).max() < 1e-12 * scale and abs(n) < 1e-12 * 10 * scale
        res = rsm_equation_residual(rsm, st, qdd, R_cl)
        assert np.abs(res).max() < 1e-11 * (np.abs(R_cl).max() + 100)
        for arm, on in zip((1, 2), st.grasp):
            if on:
                assert np.abs(grasp_acceleration_residual(PARAMS, rsm, st, arm, qdd, XT_dd)).max() < 1e-12
            else:
                assert np.all(R_cl[2 * arm - 2 : 2 * arm] == 0.0)


@pytest.mark.parametrize("seed", SEEDS)
def test_wrist_transmits_no_torque(rsm_px, seed):
    st = S.open_state(rsm_px, seed)
    pm = rsm_px.held[1]
    y, yd = rsm_px.tree_coordinates(1, st.q, st.qd, st.X_T, st.XT_d)
    qp, vp = pm.state(y, yd)
    tau = np.zeros(pm.model.nv)
    a = pin.aba(pm.model, pm.data, qp, vp, tau)
    _, n_wrist = rsm_px._wrist_force_I(pm, qp, vp, a)
    assert abs(n_wrist) < 1e-10


@pytest.mark.parametrize("seed", SEEDS)
def test_forward_dynamics_lambda_sign(rsm_px, seed):
    """pin.forwardDynamics: M a + nle = τ + J_cᵀ λ (the convention `_closed_chain` uses)."""
    (st,) = S.closed_states(rsm_px, 1, first_seed=100 + 13 * seed)
    pm = rsm_px.held[1]
    y, yd = rsm_px.tree_coordinates(1, st.q, st.qd, st.X_T, st.XT_d)
    qp, vp = pm.state(y, yd)
    tau = np.random.default_rng(seed).uniform(-50, 50, pm.model.nv)
    _, Jc, gamma = rsm_px.closure_constraint(pm, y, yd)
    a = pin.forwardDynamics(pm.model, pm.data, qp, vp, tau, Jc, gamma, 0.0).copy()
    lam = pm.data.lambda_c.copy()
    M = pin.crba(pm.model, pm.data, qp)
    nle = pin.nonLinearEffects(pm.model, pm.data, qp, vp)
    assert np.allclose(M @ a + nle - tau, Jc.T @ lam, rtol=0, atol=1e-10)
    assert np.allclose(Jc @ a + gamma, 0.0, atol=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_closed_chain_equals_free_target_kkt(rsm_px, seed):
    """Eq. (11)'s structure inside Pinocchio: free target, 4-row constraint
    φ = (r_EE1 − r_g1, r_EE2 − r_g2) on the free-target model, λ = −R_cl."""
    (st,) = S.closed_states(rsm_px, 1, first_seed=200 + 11 * seed)
    pm = rsm_px.free
    y, yd = np.concatenate([st.q, st.X_T]), np.concatenate([st.qd, st.XT_d])
    qp, vp = pm.state(y, yd)
    rows_J, rows_g = [], []
    for arm in (1, 2):
        _, Je, ge = point_kinematics_y(pm, y, yd, f"ee{arm}")
        _, Jg, gg = point_kinematics_y(pm, y, yd, f"grasp{arm}")
        rows_J.append(Je - Jg)
        rows_g.append(ge - gg)
    Jc, gamma = np.vstack(rows_J), np.concatenate(rows_g)  # T = I for PX-PY-RZ
    tau = np.zeros(12)
    tau[2], tau[3:9] = st.tau_B, st.u_J
    a = pin.forwardDynamics(pm.model, pm.data, qp, vp, tau, Jc, gamma, 0.0).copy()
    lam = pm.data.lambda_c.copy()
    qdd, XT_dd, R_cl = rsm_px.constrained_accelerations(st.q, st.qd, st.X_T, st.XT_d, st.grasp, st.u_J, st.tau_B)
    assert np.allclose(a[:9], qdd, rtol=0, atol=1e-10)
    assert np.allclose(a[9:], XT_dd, rtol=0, atol=1e-10)
    assert np.allclose(-lam, R_cl, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize("chain", ["open1", "closed"])
def test_momentum_balance(rsm_px, chain):
    """d p/dt = 0 and d L_O/dt = τ_B (joint torques are internal, no gravity), from
    ``computeCentroidalMomentumTimeVariation`` on the wrist tree: L̇_O = L̇_G + (c × ṗ)_z."""
    for st in states_for(rsm_px, chain):
        qdd, XT_dd, _ = rsm_px.constrained_accelerations(st.q, st.qd, st.X_T, st.XT_d, st.grasp, st.u_J, st.tau_B)
        pm = rsm_px.held[1]
        y, yd = rsm_px.tree_coordinates(1, st.q, st.qd, st.X_T, st.XT_d)
        ydd = np.append(qdd, XT_dd[2] - qdd[2] - qdd[3:6].sum())  # ψ̈_1 = θ̈_T − θ̈_l3,1
        qp, vp = pm.state(y, yd)
        ap = pm.chart.T(y) @ ydd + pm.chart.Tdot_yd(y, yd)
        dh = pin.computeCentroidalMomentumTimeVariation(pm.model, pm.data, qp, vp, ap)
        c = pm.data.com[0][:2]
        assert np.abs(dh.linear[:2]).max() < 1e-10
        assert dh.angular[2] + cross2(c, dh.linear[:2]) == pytest.approx(st.tau_B, abs=1e-9)
