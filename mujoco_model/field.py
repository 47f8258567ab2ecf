"""The orbit of the co-moving point O and the forces of docs/physics.md §5, written for this
engine from the physics (no other engine's code).

* O: r̈_O = g(r_O) + a_T(t), g(r) = −μ r/|r|³, a_T the thrust acceleration of the whole
  system, integrated over each control period by classic RK4 in `ORBIT_SUBSTEPS` steps,
  with the base attitude of the period predicted linearly from its start (`OrbitPeriod`);
  the period's r_O(t) is the cubic Hermite of its two ends.
* tidal acceleration about O, Δg(ρ) = g(r_O + ρ) − g(r_O), free of cancellation:
  with q = (2 r_O·ρ + ρ²)/|r_O|² and F = 1 − (1 + q)^(−3/2) = −expm1(−1.5 log1p q),
  Δg = μ [F (r_O + ρ) − ρ] / |r_O|³;
* its potential U(ρ) = −μ/|r_O + ρ| + μ/|r_O| + g(r_O)·ρ (U(0) = 0, ∇U = −Δg), by a series
  in q where |q| is small.
"""

from __future__ import annotations

import math

import numpy as np

ORBIT_SUBSTEPS = 8
#: Gauss points per link piece for the tidal field (a piece is straight and short: the
#: field is linear on it to (ℓ/|r_O|)², and two points integrate force and torque of a
#: linear field exactly)
GAUSS = np.array([-1.0, 1.0]) / math.sqrt(3.0)


def tidal(mu: float, r_o: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Δg at the points `rho` (…, 2) about O at `r_o` [m/s²]."""
    r2 = float(r_o @ r_o)
    q = (2.0 * (rho @ r_o) + np.sum(rho * rho, axis=-1)) / r2
    F = -np.expm1(-1.5 * np.log1p(q))
    return mu * (F[..., None] * (r_o + rho) - rho) / (r2 * math.sqrt(r2))


def tidal_potential(mu: float, r_o: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """U at the points `rho` [J/kg]: μ/|r_O| · (1 − (1+q)^(−½) − q/2 + ρ²/(2|r_O|²))."""
    r2 = float(r_o @ r_o)
    rho2 = np.sum(rho * rho, axis=-1)
    q = (2.0 * (rho @ r_o) + rho2) / r2
    series = q * q * (-0.375 + q * (0.3125 + q * (-35.0 / 128.0 + q * (63.0 / 256.0))))
    exact = -np.expm1(-0.5 * np.log1p(q)) - 0.5 * q
    h = np.where(np.abs(q) < 1e-3, series, exact)
    return mu * (h + 0.5 * rho2 / r2) / math.sqrt(r2)


def gravity(mu: float, r: np.ndarray) -> np.ndarray:
    return -mu * r / float(r @ r) ** 1.5


class OrbitPeriod:
    """O over one control period [t0, t1]: thrust acceleration a_T(t) = (T/m_sys)(cos θ,
    sin θ) with θ = θ_B0 + ω_B0 (t − t0), and r_O(t), v_O(t) by cubic Hermite between the
    RK4-integrated ends.  The robot feels −a_T(t) on every mass element (the same a_T as
    O, so the system's absolute COM motion has the thrust exactly)."""

    def __init__(self, mu: float, t0: float, t1: float, r0, v0, thrust: float, m_sys: float,
                 theta0: float, omega0: float):
        self.mu, self.t0, self.t1 = mu, t0, t1
        self.thrust_acc = thrust / m_sys
        self.theta0, self.omega0 = theta0, omega0
        self.r0, self.v0 = np.array(r0, float), np.array(v0, float)
        r, v = self.r0.copy(), self.v0.copy()
        h = (t1 - t0) / ORBIT_SUBSTEPS
        t = t0
        acc = lambda t, r: gravity(mu, r) + self.a_thrust(t)  # noqa: E731
        for _ in range(ORBIT_SUBSTEPS):
            k1v, k1r = acc(t, r), v
            k2v, k2r = acc(t + h / 2, r + h / 2 * k1r), v + h / 2 * k1v
            k3v, k3r = acc(t + h / 2, r + h / 2 * k2r), v + h / 2 * k2v
            k4v, k4r = acc(t + h, r + h * k3r), v + h * k3v
            r = r + h / 6 * (k1r + 2 * k2r + 2 * k3r + k4r)
            v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            t += h
        self.r1, self.v1 = r, v

    def a_thrust(self, t: float) -> np.ndarray:
        if self.thrust_acc == 0.0:
            return np.zeros(2)
        th = self.theta0 + self.omega0 * (t - self.t0)
        return self.thrust_acc * np.array([math.cos(th), math.sin(th)])

    def r_O(self, t: float) -> np.ndarray:
        """Cubic Hermite of r_O between the period's ends."""
        h = self.t1 - self.t0
        if h <= 0.0:
            return self.r0.copy()
        s = min(max((t - self.t0) / h, 0.0), 1.0)
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * self.r0 + h10 * h * self.v0 + h01 * self.r1 + h11 * h * self.v1
