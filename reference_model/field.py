"""The acceleration field felt in the co-moving frame of the reference point O
(docs/physics.md §5): the exact tidal acceleration and its potential, compiled kernels of
one point each (numba), called by `reference_model.system` (the field's generalised forces
on the base and the target), `reference_model.link` (on the links' Gauss points, and their
potential) and `reference_model.observe` (the gravitational energy).  The Exudyn model has
its own `exudyn_model/field.py`, written from the same formulas.

A mass element at ρ (relative to O, inertial axes) feels
    Δg(ρ) = g(r_O + ρ) − g(r_O),  g(r) = −μ r/|r|³,
returned divided by μ (the caller applies μ and the mass).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def tidal(rO, rel):
    """Exact tidal acceleration g(r_O + ρ) − g(r_O), g(r) = −μ r/|r|³ (μ applied by caller).

    Written without cancellation (Encke/Battin form): with q = (2 r_O·ρ + ρ·ρ)/|r_O|²,
    F = 1 − (1 + q)^(−3/2) = −expm1(−1.5 log1p(q)),  Δg/μ = (F (r_O + ρ) − ρ)/|r_O|³.
    """
    r2 = rO[0] * rO[0] + rO[1] * rO[1]
    qv = (2.0 * (rO[0] * rel[0] + rO[1] * rel[1]) + rel[0] * rel[0] + rel[1] * rel[1]) / r2
    f = -math.expm1(-1.5 * math.log1p(qv))
    r3 = r2 * math.sqrt(r2)
    return (f * (rO[0] + rel[0]) - rel[0]) / r3, (f * (rO[1] + rel[1]) - rel[1]) / r3


@njit(cache=True)
def tidal_potential(rO, rel):
    """Tidal potential energy per unit mass / μ: −∇_ρ U = `tidal` (fixed r_O).

    U/μ = −1/|r_O+ρ| + 1/|r_O| − r_O·ρ/|r_O|³ = (h(q) + |ρ|²/(2|r_O|²))/|r_O| with
    h(q) = 1 − (1+q)^(−1/2) − q/2, evaluated by its series for small q.  To second order
    U/μ = −ρᵀ(3 r̂r̂ᵀ − I)ρ/(2|r_O|³): negative along the radial (the tidal force stretches).
    """
    r2 = rO[0] * rO[0] + rO[1] * rO[1]
    rho2 = rel[0] * rel[0] + rel[1] * rel[1]
    qv = (2.0 * (rO[0] * rel[0] + rO[1] * rel[1]) + rho2) / r2
    if abs(qv) < 1e-3:
        h = qv * qv * (-3.0 / 8.0 + qv * (5.0 / 16.0 + qv * (-35.0 / 128.0 + qv * 63.0 / 256.0)))
    else:
        h = 1.0 - 1.0 / math.sqrt(1.0 + qv) - 0.5 * qv
    return (h + 0.5 * rho2 / r2) / math.sqrt(r2)
