"""The Exudyn engine's tidal field (exudyn_model/field.py) and how it is held over a control
period (`Stepper.set_inputs`, docs/exudyn.md §5 item 5).

A held force is right when it delivers the period's impulse: its value must be the mean of
the exact field over the period.  Along the period's motion (every coordinate moving at
its rate, O on its Kepler orbit) the field held at the period's middle misses that mean by
O(Δt²); held at the period's start it misses by ½ Δt Ḟ, first order.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from exudyn_model.engine import ExudynEngine
from exudyn_model.state import base_mass, mass_flow, system_mass
from rsmcheck.core.cases import load_case
from rsmcheck.core.engine import Inputs

#: nodes of the 8-point Gauss–Legendre rule on [0, 1] (the period's mean field)
_XS, _WS = np.polynomial.legendre.leggauss(8)
_XS, _WS = 0.5 * (_XS + 1.0), 0.5 * _WS


@pytest.fixture(scope="module")
def drifting():
    """gravity_gradient (700 km orbit, no control), flexible links, after 50 ms of flight:
    O moves at 7.5 km/s and every body at its own small rate."""
    eng = ExudynEngine(load_case("gravity_gradient"), rigid=False)
    for k in range(1, 11):
        eng.advance(k * 5e-3, Inputs())
    return eng


def _mean_field(eng, span: float) -> np.ndarray:
    """The mean over [t, t + span] of the exact tidal forces along the straight-line motion
    of the coordinates and O's Kepler motion to second order (r_O + s v_O + ½ s² g)."""
    q, v = eng.coordinates()
    mu = eng.params.orbit.mu
    g_O = -mu * eng.state.r_O / np.linalg.norm(eng.state.r_O) ** 3
    r_O, v_O = eng.state.r_O, eng.state.v_O
    return sum(w * eng.field_forces.tidal_forces(q, v, s, r_O + s * v_O + 0.5 * s * s * g_O, base_mass(eng.params, eng.state))
               for s, w in zip(span * _XS, _WS))


def _held(eng, span: float) -> np.ndarray:
    """The tidal forces `Stepper.set_inputs` holds for a period of `span` (on a copy of the
    engine's thrust-inertia holder: the engine's own is left alone)."""
    holder = copy.copy(eng.field_forces.thrust_inertia)
    eng.stepper.set_inputs((np.zeros(6), 0.0, 0.0), holder, span)
    return holder.q_held


def test_the_held_tidal_field_is_the_period_mean_to_second_order(drifting):
    """Measured (forces up to 2.1e-3 N): misses the mean by 1.45e-14 N at 5 ms and 3.6e-15 N
    at 2.5 ms (ratio 4.0: second order), against 8.2e-9 N and 4.1e-9 N for the field held at
    the period's start (ratio 2: first order)."""
    eng = drifting
    err = {}
    for span in (5e-3, 2.5e-3):
        mean = _mean_field(eng, span)
        err[span] = np.abs(_held(eng, span) - mean).max()
        start = np.abs(_held(eng, 0.0) - mean).max()
        assert start > 100.0 * err[span], (span, start, err[span])
    assert 3.0 < err[5e-3] / err[2.5e-3] < 5.0, err



class _StillBase:
    """The two calls `_ThrustInertia` makes on an Exudyn system, for a base at θ = 0 at rest."""

    def GetNodeOutput(self, node, kind):  # noqa: N802 (Exudyn's name)
        return np.zeros(3)

    def SetObjectParameter(self, obj, name, value):  # noqa: N802
        pass


def test_thrust_acceleration_of_O_is_not_biased_by_the_solver_clock():
    """Exudyn's clock is its own sum t += h, which drifts from the runner's samples by
    ~1e-13 s per step at t ≈ 3000 s: the mean acceleration over an interval must divide the
    impulse by the time it was summed over, not by the runner's span (docs/exudyn.md §4;
    p4_hohmann's burn 2 took 1.1e-4 too much thrust acceleration, 0.69 m of altitude)."""
    from exudyn_model.field import _ThrustInertia

    inertia = _ThrustInertia(carrier=0, base_node=0, theta_ref=0.0)
    t0, span, steps, drift = 2845.539, 1e-3, 2, 1e-7  # a clock 1e-7 s ahead by the interval's end
    inertia.hold(np.zeros(0), np.zeros((0, 2)), accel=0.2, t_start=t0)
    for k in range(1, steps + 1):
        inertia(_StillBase(), t0 + k * span / steps + drift * k / steps)
    assert inertia.mean_acceleration(span) == pytest.approx([0.2, 0.0], rel=1e-12)


def test_a_period_held_thrust_acceleration_is_the_rocket_equation_s_mean():
    """Over a period Δt of thrust T the mass falls by ṁΔt (ṁ = T/(I_sp g0)) and O gains
    ΔV = I_sp g0 ln(m(t)/m(t + Δt)) (the rocket equation, no other force).  The held T/m is
    that of the period's middle: it misses ΔV/Δt by (ṁΔt/m)²/24, ~1e-16 here; held at the
    period's start it would be low by ṁΔt/(2m): 1.85e-7 at this 5 ms period, 3.7e-8 at the
    burns' 1 ms (docs/records.md).  The base's inertial mass is held at the middle as well."""
    case = load_case("thrust_burn")
    eng = ExudynEngine(case)
    a = case.params.actuators
    thrust, span = a.thrust, 5e-3
    m_sys = eng.observer.com(eng.coordinates()[0])[1]
    m_base = base_mass(eng.params, eng.state)
    holder = copy.copy(eng.field_forces.thrust_inertia)
    eng.stepper.set_inputs((np.zeros(6), 0.0, thrust), holder, span)
    dm = thrust / (a.isp * a.g0) * span
    rocket = -a.isp * a.g0 * np.log1p(-dm / m_sys) / span
    assert holder.accel == pytest.approx(rocket, rel=1e-13)
    assert eng.mbs.GetObjectParameter(eng.model.base, "mass") == pytest.approx(m_base - 0.5 * dm, rel=1e-15)


def test_compiled_field_equals_the_dense_quadrature(drifting):
    """`tidal_carrier_forces` (the sparse, compiled form used every control sample, at the
    positions q + s q̇) against the quadrature written out densely with `tidal`:
    Σ_g S(ξ_g)ᵀ ρA w_g Δg(S(ξ_g) q) per link, m Δg(ρ) for the base and the target, each in
    its place of the carrier's vector.  The two differ by round-off only (measured 2e-19 N
    of 1.4e-3 N)."""
    from exudyn_model.field import tidal

    eng = drifting
    q, v = eng.coordinates()
    rng = np.random.default_rng(3)
    q = q + rng.normal(0.0, 1e-3, q.shape)  # every coordinate off its rest value
    v = v + rng.normal(0.0, 1e-2, v.shape)
    s = 0.37e-3
    x = q + s * v
    m_base = base_mass(eng.params, eng.state)
    got = eng.field_forces.tidal_forces(q, v, s, eng.state.r_O, m_base)
    _, ws, D = eng.model.mesh.sample(4)
    mu = eng.params.orbit.mu
    assert len(eng.field_forces.flex_coords) == 6
    for coords, places in zip(eng.field_forces.flex_coords, eng.field_forces.carrier_flex):
        points = (D @ x[coords]).reshape(-1, 2)
        dense = ((eng.params.link.rho_a * ws)[:, None] * tidal(mu, eng.state.r_O, points)).reshape(-1) @ D
        assert np.abs(got[places] - dense).max() <= 1e-12 * np.abs(dense).max(), np.abs(got[places] - dense).max()
    ff = eng.field_forces
    for coords, places, m in zip(ff.points, ff.carrier_points, (m_base, eng.params.target.mass)):
        dense = m * tidal(mu, eng.state.r_O, x[coords])
        assert np.abs(got[places] - dense).max() <= 1e-12 * np.abs(dense).max(), (got[places], dense)
    # the places between them (the base's and the target's rotation) take no tidal force here
    assert got[2] == 0.0 and got[5] == 0.0


def test_the_stored_mass_matrix_follows_the_burning_base(monkeypatch):
    """The solver keeps one mass matrix (`reuseConstantMassMatrix`); the base's mass, which
    the thrust burns down at every control sample, reaches it through `Stepper.set_base_mass`.  A
    burn with output samples (whose reactions hold and restore the base mass) must equal, to
    the last bit, the burn of a solver that recomputes the mass matrix at every Newton
    residual.  Without the recomputation in `Stepper.set_base_mass` the stored matrix keeps the
    base's mass at build and the runs part (the base pose by 9.6e-10 after 50 ms)."""
    from exudyn_model import stepper
    from rsmcheck.driver.runner import run

    case = load_case("thrust_burn").variant(True)
    stored = run(ExudynEngine(case), case, 0.05)
    settings = stepper.simulation_settings

    def recomputed(options):
        s = settings(options)
        s.timeIntegration.reuseConstantMassMatrix = False
        return s

    monkeypatch.setattr(stepper, "simulation_settings", recomputed)
    fresh = run(ExudynEngine(case), case, 0.05)
    assert fresh.observables["system_mass"][-1] < fresh.observables["system_mass"][0]  # it burns
    for name, values in fresh.observables.items():
        np.testing.assert_array_equal(stored.observables[name], values, err_msg=name)


def test_the_thrust_inertia_runs_at_every_step_only_while_there_is_thrust():
    """The thrust inertia's pre-step function has nothing to do without thrust: it is
    registered with the solver from the first interval with thrust to the first without.
    While registered it runs at every step: the interval's mean thrust acceleration of O
    (the impulse it sums step by step) is T/m_sys along the base's x axis."""
    case = load_case("thrust_burn")
    eng = ExudynEngine(case)
    thrust = case.params.actuators.thrust
    for k, f in enumerate((0.0, 0.0, thrust, thrust, 0.0, 0.0)):
        eng.advance((k + 1) * 1e-3, Inputs(thrust=f))
        assert (eng.mbs.GetPreStepUserFunction() != 0) == (f != 0.0), k
        a_O = eng.field_forces.thrust_inertia.mean_acceleration(1e-3)
        if f == 0.0:
            assert np.all(a_O == 0.0)
        else:
            # T/m at the interval's middle, along θ_B at its end (the base turns by ~1e-9 rad
            # within the interval: hence the 1e-8 of the magnitude in the direction)
            i_thB = eng.model.index.i_base[2]
            theta_B = eng.field_forces.thrust_inertia.theta_ref + eng.coordinates()[0][i_thB] - eng.model.index.q_ref[i_thB]
            m_mid = system_mass(eng.params, eng.state) + 0.5 * 1e-3 * mass_flow(eng.params, f)
            expected = f / m_mid * np.array([math.cos(theta_B), math.sin(theta_B)])
            assert np.allclose(a_O, expected, rtol=1e-12, atol=1e-8 * f / m_mid), (a_O, expected)
