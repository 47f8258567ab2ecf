"""Joint torques bend the links (docs/physics.md §3.3): beam theory for end couples.

A joint torque is a couple on an end section.  For a link pinned at both ends (PP, chord
frame) with counter-clockwise couples C_0 at ξ = 0 and C_L at ξ = L, Euler–Bernoulli beam
theory gives

    w(L/2) = (C_0 − C_L) L² / (16 EI),
    w'(0)  = (2C_0 − C_L) L / (6 EI),     w'(L) = (2C_L − C_0) L / (6 EI).

The reference's static response is a = K_ff⁻¹ (C_0 φ'(0) + C_L φ'(L)) (the generalised
forces of the couples on the amplitudes, the paper's u_e).  With the sine modes alone it
converges like their series: w'(0) under C_0 alone is (6/π²) Σ_{j≤N} 1/j² of the exact
value (0.61, 0.76, 0.81, 0.85 for N = 1…4), w(L/2) like Σ 1/j³ (+3.2 % for N = 1, 2); with
the two static correction shapes (docs/physics.md §2.4) the response is exact for every N.

Energy consistency: the generalised force that `system.assemble` applies at rest (no
gravity) is −∂V/∂q of the elastic energy it reports (`energy` observable: links, joint
springs on ψ_J − θ_m, wrist bistop on ψ_w).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference_model.beam_modes import PF, PP, modal_basis
from reference_model.build import Configuration, ReferenceModel, terminal_basis
from reference_model.model_arrays import N_INPUTS
from reference_model.observe import energy_of_state
from rsmcheck.core.params import Params

LINK = Params().link
L, EI = LINK.length, LINK.ei


def beam_theory(c0: float, cl: float) -> tuple[float, float, float]:
    """(w(L/2), w'(0), w'(L)) of a pinned-pinned Euler–Bernoulli beam under end couples."""
    return (c0 - cl) * L**2 / (16 * EI), (2 * c0 - cl) * L / (6 * EI), (2 * cl - c0) * L / (6 * EI)


def modal_static(n_eigen: int, n_static: int, c0: float, cl: float) -> tuple[float, float, float]:
    b = modal_basis(PP, n_eigen, L, LINK.rho_a, LINK.ei, n_static)
    a = np.linalg.solve(b.k_ff, c0 * b.slope_0 + cl * b.slope_L)
    return float(b.phi_mid @ a), float(b.slope_0 @ a), float(b.slope_L @ a)


@pytest.mark.parametrize("n_eigen", [1, 2, 3, 4, 6])
def test_sine_modes_converge_like_their_series(n_eigen):
    """C_0 alone: end slope (6/π²)Σ1/j², mid-span Σ_odd ±1/j³ of the exact value."""
    mid, s0, sl = modal_static(n_eigen, 0, 5.0, 0.0)
    w_mid, w0, wl = beam_theory(5.0, 0.0)
    j = np.arange(1, n_eigen + 1)
    assert s0 / w0 == pytest.approx(6 / math.pi**2 * np.sum(1.0 / j**2), rel=1e-10)
    assert sl / wl == pytest.approx(-12 / math.pi**2 * np.sum((-1.0) ** j / j**2), rel=1e-10)
    assert mid / w_mid == pytest.approx(32 / math.pi**3 * np.sum(np.sin(j * math.pi / 2) / j**3), rel=1e-10)
    if n_eigen == 2:  # the paper's two modes: the slope 24 % low, mid-span 3.2 % high
        assert s0 / w0 == pytest.approx(0.760, abs=1e-3)
        assert mid / w_mid == pytest.approx(1.032, abs=1e-3)


@pytest.mark.parametrize("n_eigen", [0, 1, 2, 4])
@pytest.mark.parametrize("couples", [(5.0, 0.0), (0.0, -7.0), (5.0, 10.0), (-10.0, 5.0)])
def test_static_shapes_make_the_end_couple_response_exact(n_eigen, couples):
    got = modal_static(n_eigen, 2, *couples)
    want = beam_theory(*couples)
    scale = max(abs(v) for v in want)
    assert np.allclose(got, want, rtol=0.0, atol=1e-12 * scale), (got, want)


@pytest.mark.parametrize("kind", [PP, PF])
@pytest.mark.parametrize("n_eigen", [1, 2, 4])
def test_static_shapes_keep_the_basis_and_the_eigenmodes(kind, n_eigen):
    """The augmented basis is mass- and stiffness-orthogonal (diagonal M_ff, K_ff), keeps the
    eigenmodes' frequencies exactly, its static shapes lie above them, and it keeps the
    frame's definition (PP: w(0) = w(L) = 0; PF: w(0) = 0, ∫ρξw = 0)."""
    plain = modal_basis(kind, n_eigen, L, LINK.rho_a, LINK.ei)
    b = modal_basis(kind, n_eigen, L, LINK.rho_a, LINK.ei, 2)
    assert b.n == n_eigen + 2
    for mat in (b.m_ff, b.k_ff):
        off = mat - np.diag(np.diag(mat))
        assert np.abs(off).max() <= 1e-12 * np.abs(mat).max()
    assert np.allclose(b.m_ff[:n_eigen, :n_eigen], plain.m_ff, rtol=1e-12, atol=0)
    assert np.allclose(b.k_ff[:n_eigen, :n_eigen], plain.k_ff, rtol=1e-12, atol=0)
    assert np.all(b.omega[n_eigen:] > b.omega[n_eigen - 1])
    assert np.abs(b.shapes(np.array([0.0]))).max() <= 1e-14
    if kind == PP:
        assert np.abs(b.shapes(np.array([L]))).max() <= 1e-13
    else:
        assert np.abs(b.phi_x).max() <= 1e-12 * LINK.mass * L
    fine = np.linspace(0.0, L, 4001)  # the grid the shapes are scaled on: peak |φ| = 1
    assert np.abs(b.shapes(fine)).max(axis=0) == pytest.approx(np.ones(b.n), abs=1e-12)


@pytest.mark.parametrize("static_modes", ["off", "explicit", "condensed"])
def test_generalised_forces_derive_from_the_elastic_energy(static_modes):
    """At rest, no orbit, no inputs: f of `assemble` = −∂V/∂Y, V the `energy` observable's
    elastic part, with the links bent, every rotor off its section angle (u_J ≠ 0: the
    u_e terms on both links of each joint) and arm 1's wrist pressed 0.05 rad into its stop
    (the bistop on the distal section).  Condensed static shapes: V is the elastic energy
    at their equilibrium (condense.py), a function of the other coordinates, and the
    rotors feel −∂V/∂θ_m = B_m θ̈_m too; the shapes' own slots are not coordinates."""
    model = ReferenceModel(Params(), 2, static_modes=static_modes)
    lay = model.layout
    rng = np.random.default_rng(11)
    u = np.zeros(N_INPUTS)
    grasp = (1, 0)
    cfg = Configuration(grasp_on=np.array(grasp), rho_G=np.zeros((2, 2)), basis=terminal_basis(grasp))
    x = model.zero_state()
    x[3:9] = np.radians([60, -120, 60, -60, 120, -60])
    x[9:lay.nq] = 2e-5 * rng.normal(size=lay.nq - 9)
    psi, _ = model.joint_section_angles(x[lay.q], x[lay.qd], cfg)
    x[lay.motors] = psi + 3e-4 * rng.choice([-1.0, 1.0], size=6)
    th3 = model.kinematics(x[lay.q], x[lay.qd], cfg)[0][2]
    slope_L = model.bases[2][PP].slope_L @ x[lay.q][lay.modes(2)]
    x[lay.target] = [5.0, 0.5, th3 + slope_L + model.params.wrist.limit + 0.05]
    x = model.complete(x, cfg, settle=True)  # condensed: the stop deflection e at rest

    def elastic(xx):
        Mg = model.assemble(xx, u, cfg)[0]
        return energy_of_state(model, xx, u, cfg, Mg)[1]

    f = model.assemble(x, u, cfg)[1]
    grad = np.zeros(lay.ny)
    for c in range(lay.ny):
        h = 1e-7 if c >= 9 else 1e-6
        xp, xm = x.copy(), x.copy()
        xp[c] += h
        xm[c] -= h
        grad[c] = (elastic(xp) - elastic(xm)) / (2 * h)
    assert np.abs(model.assemble(x, u, cfg)[7]).min() > 1.0  # every joint spring loaded (u_J of N·m)
    assert abs(f[lay.nq + 2]) > 100.0  # the bistop pushes the target
    r = model.coordinates
    assert np.abs(f[r] + grad[r]).max() <= 1e-6 * np.abs(f).max(), np.abs(f[r] + grad[r]).max()
    if model.condensed:
        assert np.abs(grad[np.setdiff1d(np.arange(lay.ny), r)]).max() == 0.0
        rotor = model.params.motor.inertia * model.assemble(x, u, cfg)[6]
        grad_m = np.zeros(6)
        for j in range(6):
            xp, xm = x.copy(), x.copy()
            xp[lay.motors.start + j] += 1e-7
            xm[lay.motors.start + j] -= 1e-7
            grad_m[j] = (elastic(xp) - elastic(xm)) / 2e-7
        assert np.abs(rotor + grad_m).max() <= 1e-6 * np.abs(rotor).max(), (rotor, grad_m)
