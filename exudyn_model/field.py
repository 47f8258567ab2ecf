"""The acceleration field felt in the co-moving frame of the reference point O
(docs/physics.md §5), written for this engine from the formulas of physics.md (no code of
the reference model is used).

A mass element at ρ (relative to O, inertial axes) feels the exact tidal acceleration
    Δg(ρ) = g(r_O + ρ) − g(r_O),  g(r) = −μ r/|r|³,
evaluated without cancellation: q = (2 r_O·ρ + ρ·ρ)/|r_O|², F = −expm1(−1.5 log1p q),
Δg = μ (F (r_O + ρ) − ρ)/|r_O|³,
and the uniform inertial field −a_thr of the thrust acceleration of O.  The tidal
potential energy per unit mass, −∇_ρ U = Δg (r_O fixed), is
    U = −μ/|r_O+ρ| + μ/|r_O| − μ r_O·ρ/|r_O|³ = μ (h(q) + |ρ|²/(2|r_O|²))/|r_O|,
    h(q) = 1 − (1+q)^(−1/2) − q/2,
to second order −μ ρᵀ(3 r̂r̂ᵀ − I)ρ/(2|r_O|³) (negative along the radial: it stretches).
"""

from __future__ import annotations

import numpy as np


def tidal(mu: float, r_o: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Δg at points ρ (shape (..., 2)) [m/s²]."""
    rho = np.asarray(rho, float)
    r2 = float(r_o @ r_o)
    q = (2.0 * rho @ r_o + np.sum(rho * rho, axis=-1)) / r2
    f = -np.expm1(-1.5 * np.log1p(q))
    return mu * (f[..., None] * (r_o + rho) - rho) / (r2 * np.sqrt(r2))


def tidal_potential(mu: float, r_o: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """U at points ρ [J/kg] (series for h when |q| is small, to keep full precision)."""
    rho = np.asarray(rho, float)
    r2 = float(r_o @ r_o)
    rho2 = np.sum(rho * rho, axis=-1)
    q = (2.0 * rho @ r_o + rho2) / r2
    small = np.abs(q) < 1e-3
    h_series = q * q * (-3.0 / 8.0 + q * (5.0 / 16.0 + q * (-35.0 / 128.0 + q * 63.0 / 256.0)))
    h_exact = 1.0 - 1.0 / np.sqrt(1.0 + np.where(small, 0.0, q)) - 0.5 * q
    h = np.where(small, h_series, h_exact)
    return mu * (h + 0.5 * rho2 / r2) / np.sqrt(r2)
