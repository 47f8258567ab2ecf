"""Orbit mechanics of the transfer phase (Sect. 4.1, 5.3; docs/controllers.md, "Burns"):
Hohmann numbers, the finite-burn schedule, and an orbit-only propagation (reference point +
mass depletion, no robot) that the p4_hohmann case and its tests are checked against.

The robot's thrust acts along +x_B through the base COM; the base attitude tracks the
retrograde direction (−v̂ of the orbit, eq. 13), so the orbit-only model thrusts along −v̂
with the full system mass: r̈ = −μ r/|r|³ − (T/m) v̂, ṁ = −T/(I_sp g0).

Finite burns: each burn lasts ~550 s and sweeps ~30° of orbit, so the impulsive Hohmann
numbers are only the first guess.  `finite_hohmann` shoots for the schedule that reaches
the circular final orbit with finite burns: burn 1 starts at t = 0 and lasts d1 (first
guess: the transfer orbit's perigee at the final radius), burn 2 starts at s2 (first
guess: centred on the transfer perigee) and lasts d2; then Gauss–Newton on (d1, s2, d2)
makes the final orbit's perigee and apogee both the final radius (to 1 cm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from rsmcheck.core.params import Params


@dataclass(frozen=True)
class Hohmann:
    """Impulsive Hohmann transfer between circular orbits of radii r1 → r2."""

    r1: float
    r2: float
    dv1: float  # [m/s] magnitude of the first impulse
    dv2: float
    transfer_time: float  # half period of the transfer ellipse [s]


def hohmann(mu: float, r1: float, r2: float) -> Hohmann:
    a = 0.5 * (r1 + r2)
    v1 = math.sqrt(mu / r1)
    v2 = math.sqrt(mu / r2)
    va = math.sqrt(mu * (2.0 / r1 - 1.0 / a))  # transfer speed at r1
    vp = math.sqrt(mu * (2.0 / r2 - 1.0 / a))  # at r2
    return Hohmann(r1, r2, abs(v1 - va), abs(vp - v2), math.pi * math.sqrt(a**3 / mu))


def rocket_mass(m0: float, dv: float, isp_g0: float) -> float:
    """Propellant burnt for Δv from mass m0 (Tsiolkovsky)."""
    return m0 * (1.0 - math.exp(-dv / isp_g0))


def burn_time(m0: float, dv: float, thrust: float, isp_g0: float) -> float:
    """Duration of a constant-thrust burn giving Δv (ideal, no gravity losses)."""
    return rocket_mass(m0, dv, isp_g0) * isp_g0 / thrust


def elements(r, v, mu: float) -> dict[str, float]:
    """Semi-major axis, eccentricity, perigee and apogee radii, specific energy."""
    r = np.asarray(r, float)
    v = np.asarray(v, float)
    rn = float(np.hypot(*r))
    energy = 0.5 * float(v @ v) - mu / rn
    a = -mu / (2.0 * energy)
    h = float(r[0] * v[1] - r[1] * v[0])
    e_vec = np.array([v[1] * h, -v[0] * h]) / mu - r / rn
    e = float(np.hypot(*e_vec))
    return {"a": a, "e": e, "r_p": a * (1.0 - e), "r_a": a * (1.0 + e), "energy": energy, "h": h}


@dataclass(frozen=True)
class Schedule:
    """Finite-burn schedule: burn 1 on [0, d1], burn 2 on [s2, s2 + d2] [s]."""

    d1: float
    s2: float
    d2: float

    @property
    def coast(self) -> float:
        return self.s2 - self.d1

    @property
    def end(self) -> float:
        return self.s2 + self.d2


def _rhs(t, y, mu, thrust_on, thrust, isp_g0):
    r = y[0:2]
    v = y[2:4]
    m = y[4]
    rn = math.hypot(r[0], r[1])
    a = -mu * r / rn**3
    dm = 0.0
    if thrust_on:
        vn = math.hypot(v[0], v[1])
        a = a - (thrust / m) * v / vn
        dm = -thrust / isp_g0
    return np.array([v[0], v[1], a[0], a[1], dm])


def propagate(r0, v0, m0: float, schedule: Schedule, params: Params, t_end: float | None = None,
              rtol: float = 1e-11) -> dict:
    """Orbit-only propagation through the schedule (thrust along −v̂) up to t_end
    (default: end of burn 2).  Returns final r, v, m and the orbital elements."""
    mu = params.orbit.mu
    T = params.actuators.thrust
    isp_g0 = params.actuators.isp * params.actuators.g0
    t_end = schedule.end if t_end is None else t_end
    arcs = [(0.0, schedule.d1, True), (schedule.d1, schedule.s2, False), (schedule.s2, schedule.end, True),
            (schedule.end, max(t_end, schedule.end), False)]
    y = np.array([*np.asarray(r0, float), *np.asarray(v0, float), m0])
    for a, b, on in arcs:
        a, b = min(a, t_end), min(b, t_end)
        if b <= a:
            continue
        sol = solve_ivp(_rhs, (a, b), y, method="DOP853", rtol=rtol, atol=1e-9,
                        args=(mu, on, T, isp_g0))
        y = sol.y[:, -1]
    out = elements(y[0:2], y[2:4], mu)
    out.update(r=y[0:2], v=y[2:4], m=y[4])
    return out


def circular_state(params: Params, altitude: float) -> tuple[np.ndarray, np.ndarray]:
    r = params.orbit.earth_radius + altitude
    return np.array([r, 0.0]), np.array([0.0, math.sqrt(params.orbit.mu / r)])


def system_mass(params: Params) -> float:
    return params.base.mass + params.target.mass + 6 * params.link.mass


def finite_hohmann(params: Params, altitude_from: float | None = None, altitude_to: float | None = None,
                   m0: float | None = None) -> Schedule:
    """The finite-burn schedule reaching the circular final orbit (module doc)."""
    o = params.orbit
    h1 = o.altitude_initial if altitude_from is None else altitude_from
    h2 = o.altitude_final if altitude_to is None else altitude_to
    m0 = system_mass(params) if m0 is None else m0
    r1, r2 = o.earth_radius + h1, o.earth_radius + h2
    isp_g0 = params.actuators.isp * params.actuators.g0
    T = params.actuators.thrust
    imp = hohmann(o.mu, r1, r2)
    rv0 = circular_state(params, h1)

    def perigee_after(d1: float) -> float:
        return propagate(*rv0, m0, Schedule(d1, d1, 0.0), params)["r_p"] - r2

    t1 = burn_time(m0, imp.dv1, T, isp_g0)
    d1 = brentq(perigee_after, 0.9 * t1, 1.1 * t1, xtol=1e-9)
    m1 = m0 - T / isp_g0 * d1
    t2 = burn_time(m1, imp.dv2, T, isp_g0)
    # burn 2 centred on the transfer perigee (burn 1 is centred on the transfer apogee)
    s2, d2 = 0.5 * d1 + imp.transfer_time - 0.5 * t2, t2

    def miss(x: np.ndarray) -> np.ndarray:
        el = propagate(*rv0, m0, Schedule(*x), params)
        return np.array([el["r_p"] - r2, el["r_a"] - r2])

    # Gauss–Newton (minimum-norm steps) on all three times: the perigee of the transfer
    # orbit found above is only where the final circular orbit is nearly reachable
    x = np.array([d1, s2, d2])
    for _ in range(30):
        f = miss(x)
        if np.max(np.abs(f)) < 1e-2:
            break
        jac = np.empty((2, 3))
        for j, h in enumerate((0.01, 0.1, 0.01)):
            dx = np.zeros(3)
            dx[j] = h
            jac[:, j] = (miss(x + dx) - f) / h
        x = x - np.linalg.lstsq(jac, f, rcond=None)[0]
    return Schedule(float(x[0]), float(x[1]), float(x[2]))
