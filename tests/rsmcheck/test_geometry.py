"""rsmcheck.core.geometry (rotation, rigid three-link arm) and rsmcheck.core.beams (analytic link
frequencies): the shared helpers against first principles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsmcheck.core.beams import analytic_frequencies, beta_l
from rsmcheck.core.geometry import arm_jacobian, arm_pins, rigid_arm, rot
from rsmcheck.core.params import TABLE2_HZ, Params

P = Params()


def test_rot_is_a_proper_rotation_by_the_angle():
    for a in (0.0, 0.3, -2.0, math.pi):
        A = rot(a)
        assert np.allclose(A.T @ A, np.eye(2), atol=1e-15) and np.linalg.det(A) == pytest.approx(1.0)
        assert np.allclose(A @ [1.0, 0.0], [math.cos(a), math.sin(a)])
    assert np.allclose(rot(0.4) @ rot(0.5), rot(0.9))


def test_arm_pins_are_a_length_apart_at_the_summed_angles():
    q = (0.4, -1.1, 0.7)
    pins = np.array(arm_pins(0.5, -0.25, 0.3, 1.5, q))
    assert pins.shape == (4, 2) and np.allclose(pins[0], [0.5, -0.25])
    for s in range(3):
        d = pins[s + 1] - pins[s]
        assert np.allclose(d, 1.5 * np.array([math.cos(0.3 + sum(q[:s + 1])), math.sin(0.3 + sum(q[:s + 1]))]))


def test_arm_jacobian_is_the_derivative_of_the_end_effector():
    q = np.array([0.4, -1.1, 0.7])
    jac = arm_jacobian(arm_pins(0.1, 0.2, 0.0, 1.5, q), attitude=True)
    h = 1e-6
    for s in range(3):
        dq = np.zeros(3)
        dq[s] = h
        e_plus, e_minus = arm_pins(0.1, 0.2, 0.0, 1.5, q + dq)[3], arm_pins(0.1, 0.2, 0.0, 1.5, q - dq)[3]
        assert np.allclose(jac[:2, s], (np.array(e_plus) - np.array(e_minus)) / (2 * h), atol=1e-8)
    assert np.array_equal(jac[2], [1.0, 1.0, 1.0])
    assert np.array_equal(arm_jacobian(arm_pins(0.1, 0.2, 0.0, 1.5, q)), jac[:2])


def test_rigid_arm_velocity_is_the_time_derivative_of_its_position():
    base_pose, base_rate = np.array([0.3, -0.2, 0.5]), np.array([0.01, -0.02, 0.03])
    q, qd = np.array([1.0, -2.0, 1.0]), np.array([0.05, -0.1, 0.2])
    for arm in (1, 2):
        p, v, th, om, jac = rigid_arm(P, base_pose, base_rate, q, qd, arm)
        h = 1e-6
        p_plus = rigid_arm(P, base_pose + h * base_rate, base_rate, q + h * qd, qd, arm)[0]
        p_minus = rigid_arm(P, base_pose - h * base_rate, base_rate, q - h * qd, qd, arm)[0]
        assert np.allclose(v, (p_plus - p_minus) / (2 * h), atol=1e-8)
        assert th == pytest.approx(base_pose[2] + q.sum()) and om == pytest.approx(base_rate[2] + qd.sum())
        assert jac.shape == (2, 3)


def test_beam_roots_and_frequencies():
    assert beta_l("PP", 3) == 3 * math.pi
    for j in (1, 2, 5):
        b = beta_l("PF", j)
        assert abs(math.tan(b) - math.tanh(b)) < 1e-12 and (j + 0.25) * math.pi - 1e-3 < b < (j + 0.25) * math.pi
    assert f"{beta_l('PF', 1):.5f}" == "3.92660" and f"{beta_l('PF', 2):.5f}" == "7.06858"
    # EI is derived from Table 2's first PP frequency (rsmcheck.core.params): f1 comes back
    assert analytic_frequencies(P.link, "PP", 1)[0] == pytest.approx(TABLE2_HZ["PP"][0], rel=1e-12)
    f = analytic_frequencies(P.link, "PF", 3)
    assert f.shape == (3,) and np.all(np.diff(f) > 0)


def test_the_reference_derives_the_same_roots_on_its_own():
    """reference_model/beam_modes.py keeps its own roots (the analytic column checks its
    modal basis); the two derivations agree."""
    from reference_model.beam_modes import PF, PP
    from reference_model.beam_modes import beta_l as reference_beta_l

    for j in (1, 2, 3, 6):
        assert reference_beta_l(PP, j) == pytest.approx(beta_l("PP", j), rel=1e-14)
        assert reference_beta_l(PF, j) == pytest.approx(beta_l("PF", j), rel=1e-14)
