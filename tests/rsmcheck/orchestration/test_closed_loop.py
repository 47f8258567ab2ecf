"""rsmcheck.orchestration.closed_loop: the zero-order-hold closure of the shared controller's laws,
checked on plants whose sampled loops are known in closed form."""

from __future__ import annotations

import math

import numpy as np

from rsmcheck.core.cases import load_case
from rsmcheck.orchestration.closed_loop import (I_BASE, N_INPUTS, closed_loop_exponents, controller_gains,
                                                rotor_modes)


def _scalar_plant(a: float):
    """ẋ = a x + τ_B, outputs θ_B = x (everything else zero)."""
    A = np.array([[a]])
    B = np.zeros((1, N_INPUTS))
    B[0, 6] = 1.0
    C = np.zeros((20, 1))
    C[I_BASE, 0] = 1.0
    return A, B, C


def test_sampled_proportional_loop_on_an_integrator():
    """ẋ = u, u_k = −k x_k held for Δt: x_{k+1} = (1 − kΔt) x_k; the filter states decay
    by (1 − α) per sample."""
    k, dt, alpha = 100.0, 1e-3, 0.2
    ky = np.zeros((N_INPUTS, 20))
    ky[6, I_BASE] = k
    s = closed_loop_exponents(*_scalar_plant(0.0), ky, np.zeros((N_INPUTS, 6)), alpha, dt)
    assert np.min(np.abs(s - math.log(1 - k * dt) / dt)) < 1e-9
    assert np.sum(np.abs(s - math.log(1 - alpha) / dt) < 1e-9) == 6


def test_sampled_loop_on_a_first_order_plant():
    """ẋ = a x + u, u_k = −k x_k: μ = e^{aΔt} − k (e^{aΔt} − 1)/a (exact ZOH)."""
    a, k, dt = -3.0, 40.0, 1e-2
    ky = np.zeros((N_INPUTS, 20))
    ky[6, I_BASE] = k
    s = closed_loop_exponents(*_scalar_plant(a), ky, np.zeros((N_INPUTS, 6)), 0.5, dt)
    mu = math.exp(a * dt) - k * (math.exp(a * dt) - 1) / a
    assert np.min(np.abs(s - np.log(complex(mu)) / dt)) < 1e-9


def test_controller_gains_follow_the_case():
    case = load_case("p1_rigid_gains")
    ky, kr, alpha = controller_gains(case, np.radians(case.initial.joint_angles_deg))
    assert alpha == 1.0  # eq. (14) as written: no filter on the joint rates
    assert np.allclose(np.diag(kr), [200, 200, 100, 200, 200, 100])
    assert (ky[6, I_BASE], ky[6, I_BASE + 1]) == (100.0, 1000.0)


def test_rotor_modes_selects_the_band():
    s = np.array([-0.1 + 2j * np.pi * 92, -1e4 + 2j * np.pi * 95, 0.5 + 2j * np.pi * 91, -2 + 2j * np.pi * 30])
    assert np.allclose(rotor_modes(s), [0.5 + 2j * np.pi * 91, -0.1 + 2j * np.pi * 92])
