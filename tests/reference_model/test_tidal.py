"""Tidal acceleration field.tidal and its potential field.tidal_potential (docs/physics.md §5).

`tidal(r_O, ρ)` returns (g(r_O + ρ) − g(r_O))/μ with g(r) = −μ r/|r|³, written without
cancellation.  Checked against
* a 50-digit `decimal` evaluation of the naive difference (orbit scale, where float64 naive
  differencing loses most digits — the test shows that too, so it can tell them apart);
* the float64 naive difference at a moderate radius where cancellation is harmless;
* the linearised gravity gradient (μ/r³)(3 r̂r̂ᵀ − I)ρ = 3μ/r³ (r̂r̂ᵀ − I/3)ρ, which must agree
  to first order in ρ/r (relative error ≤ 5 ρ/r and halving with ρ);
* −∇_ρ of `tidal_potential` by central differences (the force derives from the potential
  the energy observable uses, so energy can be conserved in orbit).
"""

from __future__ import annotations

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest

from reference_model.field import tidal, tidal_potential

R_LEO = 6378137.0 + 700e3


def tidal_decimal(rO, rel, digits: int = 50) -> np.ndarray:
    """(g(r_O + ρ) − g(r_O))/μ in `digits`-digit decimal arithmetic, rounded to float."""
    getcontext().prec = digits
    ox, oy = Decimal(float(rO[0])), Decimal(float(rO[1]))
    px, py = ox + Decimal(float(rel[0])), oy + Decimal(float(rel[1]))

    def g(x, y):
        r = (x * x + y * y).sqrt()
        r3 = r * r * r
        return -x / r3, -y / r3

    gx1, gy1 = g(px, py)
    gx0, gy0 = g(ox, oy)
    return np.array([float(gx1 - gx0), float(gy1 - gy0)])


def naive(rO, rel) -> np.ndarray:
    r = np.asarray(rO, float) + np.asarray(rel, float)
    return -r / np.linalg.norm(r) ** 3 + np.asarray(rO, float) / np.linalg.norm(rO) ** 3


def linear_gradient(rO, rel) -> np.ndarray:
    r = np.linalg.norm(rO)
    rh = np.asarray(rO) / r
    return (3.0 * np.outer(rh, rh) - np.eye(2)) @ np.asarray(rel) / r**3


def _points(rng, n, r, rho_range):
    out = []
    for _ in range(n):
        a = rng.uniform(0, 2 * math.pi)
        b = rng.uniform(0, 2 * math.pi)
        rho = 10 ** rng.uniform(*rho_range)
        out.append((r * np.array([math.cos(a), math.sin(a)]), rho * np.array([math.cos(b), math.sin(b)])))
    return out


def test_tidal_against_50_digit_decimal_at_orbit_scale():
    rng = np.random.default_rng(1)
    worst = 0.0
    worst_naive = 0.0
    for rO, rel in _points(rng, 200, R_LEO, (-2, 4)):  # ρ from 1 cm to 10 km
        ref = tidal_decimal(rO, rel)
        got = np.array(tidal(rO, rel))
        err = np.linalg.norm(got - ref) / np.linalg.norm(ref)
        assert err <= 1e-12, (rO, rel, err)
        worst = max(worst, err)
        worst_naive = max(worst_naive, np.linalg.norm(naive(rO, rel) - ref) / np.linalg.norm(ref))
    # the reference can tell a cancellation-free formula from naive differencing
    assert worst_naive > 1e3 * max(worst, 1e-16)
    print(f"tidal vs 50 digits: {worst:.1e} (naive float64: {worst_naive:.1e})")


def test_tidal_against_naive_difference_at_moderate_radius():
    """At |r_O| = 10, |ρ| ~ 0.1–5 the naive float64 difference is accurate to ~1e-14."""
    rng = np.random.default_rng(2)
    for rO, rel in _points(rng, 200, 10.0, (-1, 0.7)):
        ref = naive(rO, rel)
        got = np.array(tidal(rO, rel))
        assert np.linalg.norm(got - ref) <= 1e-12 * np.linalg.norm(ref), (rO, rel)


def test_tidal_is_the_gravity_gradient_to_first_order():
    rng = np.random.default_rng(3)
    for rO, rel in _points(rng, 50, R_LEO, (0, 4)):
        rho = np.linalg.norm(rel)
        got = np.array(tidal(rO, rel))
        lin = linear_gradient(rO, rel)
        rel_err = np.linalg.norm(got - lin) / np.linalg.norm(lin)
        assert rel_err <= 5.0 * rho / R_LEO, (rho, rel_err)
        # and the difference is genuinely second order: it halves with ρ
        half = np.array(tidal(rO, 0.5 * rel))
        rel_err_half = np.linalg.norm(half - 0.5 * lin) / np.linalg.norm(0.5 * lin)
        assert rel_err_half == pytest.approx(0.5 * rel_err, rel=0.05, abs=0.0)


@pytest.mark.parametrize("rho", [1e-3, 1.0, 30.0, 3000.0, 4000.0, 5e4])
def test_tidal_force_is_minus_gradient_of_tidal_potential(rho):
    """Δg = −∇_ρ U at several |ρ| including both sides of the series/closed-form switch
    of `tidal_potential` (|q| = 1e-3 at ρ ≈ 3.5 km in LEO)."""
    rng = np.random.default_rng(int(rho * 1000) % 2**32)
    for _ in range(20):
        a, b = rng.uniform(0, 2 * math.pi, size=2)
        rO = R_LEO * np.array([math.cos(a), math.sin(a)])
        rel = rho * np.array([math.cos(b), math.sin(b)])
        h = 1e-4 * rho
        grad = np.zeros(2)
        for d in range(2):
            e = np.zeros(2)
            e[d] = h
            grad[d] = (tidal_potential(rO, rel + e) - tidal_potential(rO, rel - e)) / (2 * h)
        force = np.array(tidal(rO, rel))
        # near the branch switch the closed form of U loses digits (1 − 1/√(1+q) − q/2
        # at q ~ 1e-3): allow 1e-5 there, 1e-6 elsewhere
        tol = 1e-5 if 1e3 <= rho <= 1e4 else 1e-6
        assert np.linalg.norm(-grad - force) <= tol * np.linalg.norm(force), (rho, grad, force)


def test_tidal_potential_vanishes_to_second_order():
    """U(0) = 0 and U = −½ ρᵀ(3r̂r̂ᵀ − I)ρ/r³ + O(ρ³): the potential of the gradient above."""
    rO = np.array([R_LEO, 0.0])
    assert tidal_potential(rO, np.zeros(2)) == 0.0
    for rel in (np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.array([3.0, -4.0])):
        want = -0.5 * rel @ linear_gradient(rO, rel)
        assert tidal_potential(rO, rel) == pytest.approx(want, rel=1e-5, abs=0.0)


def test_generalised_tidal_forces_derive_from_the_energy_observable():
    """f of `assemble` (orbit on, at rest, springs relaxed) = −∂(E_elastic + E_grav)/∂Y with
    the energies of the `energy` observable: the dynamics and the reported potential agree
    (same sign, same 8-point quadrature on the deformed links, base and target at COM)."""
    from reference_model.build import Configuration, ReferenceModel, terminal_basis
    from reference_model.model_arrays import N_INPUTS
    from reference_model.observe import energy_of_state
    from rsmcheck.core.params import Params

    for static_modes in ("explicit", "condensed"):
        _tidal_forces_derive_from_the_energy(ReferenceModel(Params(), 2, orbit=True, static_modes=static_modes))


def _tidal_forces_derive_from_the_energy(model):
    """The check above for one model.  Slaved static shapes (condense.py): their slots are
    not coordinates, and a joint moved with its rotor feels the force on both, f[θ_J] +
    B_m θ̈_m (the field on the shapes reaches the rotors through them)."""
    from reference_model.build import Configuration, terminal_basis
    from reference_model.model_arrays import N_INPUTS
    from reference_model.observe import energy_of_state

    lay = model.layout
    rng = np.random.default_rng(5)
    u = np.zeros(N_INPUTS)
    for grasp in ((0, 0), (1, 0)):
        cfg = Configuration(grasp_on=np.array(grasp), rho_G=np.zeros((2, 2)), basis=terminal_basis(grasp))
        cfg.grasp_on[:] = 0  # no constraint rows: f is the applied generalised force
        x = model.zero_state()
        x[0:3] = [0.3, -0.2, 0.4]
        x[3:9] = np.radians([60, -120, 60, -60, 120, -60]) + 0.1 * rng.normal(size=6)
        x[9:lay.nq] = 1e-6 * rng.normal(size=lay.nq - 9)
        x[lay.target] = [5.0, 0.5, 0.2]
        x[lay.motors] = model.joint_section_angles(x[lay.q], x[lay.qd], cfg)[0]  # springs relaxed
        x[lay.r_O] = [R_LEO * math.cos(0.7), R_LEO * math.sin(0.7)]

        def potential(xx):
            Mg = model.assemble(xx, u, cfg)[0]
            e = energy_of_state(model, xx, u, cfg, Mg)
            return e[1] + e[2]

        out = model.assemble(x, u, cfg)
        f = out[1].copy()
        f[3:9] += model.params.motor.inertia * out[6]  # the rotors moved with their joints
        r = model.coordinates
        grad = np.zeros(lay.ny)
        for c in range(lay.ny):
            h = 1e-6
            xp, xm = x.copy(), x.copy()
            xp[c] += h
            xm[c] -= h
            if 3 <= c < 9:  # moving a joint angle (and ψ_J with it): keep the rotor spring relaxed
                xp[lay.ny + c - 3] += h
                xm[lay.ny + c - 3] -= h
            grad[c] = (potential(xp) - potential(xm)) / (2 * h)
        scale = np.abs(f[:9]).max()
        assert scale > 1e-5  # tidal forces on a 900 kg robot a few metres from O
        assert np.abs(f[r] + grad[r]).max() <= 1e-6 * np.abs(f[r]).max(), (f, -grad)
        assert np.abs(f[:9] + grad[:9]).max() <= 1e-5 * scale
        # sign check independent of the elastic part: the target's force is its own tidal pull
        assert np.abs(f[lay.nq:lay.nq + 2] + grad[lay.nq:lay.nq + 2]).max() <= 1e-5 * np.abs(f[lay.nq:lay.nq + 2]).max()
