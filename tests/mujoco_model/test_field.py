"""The MuJoCo engine's tidal field against the linear gravity gradient and its own potential."""

from __future__ import annotations

import numpy as np

from mujoco_model import field as fld

MU = 3.986004418e14


def test_tidal_field_is_the_gravity_gradient_for_small_offsets():
    r_o = np.array([7.078e6, 1.0e5])
    rho = np.array([[3.0, -2.0], [-1.5, 0.5]])
    r = np.linalg.norm(r_o)
    u = r_o / r
    linear = MU / r**3 * (3.0 * (rho @ u)[:, None] * u - rho)
    assert np.allclose(fld.tidal(MU, r_o, rho), linear, rtol=1e-5, atol=0.0)


def test_potential_gradient_is_minus_the_field():
    r_o = np.array([6.678e6, -2.0e6])
    rho = np.array([2.5, 1.0])
    h = 1e-3
    grad = np.array([(fld.tidal_potential(MU, r_o, rho + h * e) - fld.tidal_potential(MU, r_o, rho - h * e)) / (2 * h)
                     for e in np.eye(2)])
    assert np.allclose(grad, -fld.tidal(MU, r_o, rho), rtol=1e-6)
    assert fld.tidal_potential(MU, r_o, np.zeros(2)) == 0.0
