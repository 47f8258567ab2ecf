"""The IMEX integrator (reference_model/imex.py, ARK5(4)8L[2]SA, the stiff shapes implicit).

What must hold: the tableau is the published one (its order conditions hold to round-off:
explicit, implicit and coupled to 4th order, each tableau to 5th); it solves the same ODE
as Dormand–Prince (agreement at the tolerance level, the error shrinking with rtol); the
stiff set S is the static shapes (and the highest eigenmodes) in both bases; and it does
what it is for: with the static shapes' 0.8–0.9 kHz modes in the model it takes one step
per 1 ms control sample where the explicit pair needs two or more.  The measurement that
it does not pay at the suite's accuracy rests on these (docs/records.md).  Step
counts are deterministic and can be asserted; wall time is not (docs/benchmarks.md).  No case
integrates with it by default: the tests that integrate are `study` (its kernels compile for
minutes); the tableau's are not.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from reference_model import imex
from reference_model.beam_modes import PF, PP
from reference_model.engine import ReferenceEngine
from rsmcheck.driver import runner
from rsmcheck.core.cases import load_case
from rsmcheck.core.engine import Inputs

A_E, A_I, B, B_HAT, C = imex._AE, imex._AI, imex._B, imex._BHAT, imex._C



def _advance(engine: ReferenceEngine, t_end: float, dt: float, tau: float = 0.0) -> np.ndarray:
    """Advance with a held motor torque on arm 2's shoulder (a step at t = 0)."""
    tau_m = np.zeros(6)
    tau_m[3] = tau
    for k in range(int(round(t_end / dt))):
        engine.advance((k + 1) * dt, Inputs(tau_m=tau_m))
    return engine.x


# ---- the tableau -----------------------------------------------------------------
def test_tableaux_are_consistent_and_share_their_nodes():
    for a in (A_E, A_I):
        np.testing.assert_allclose(a.sum(axis=1), C, atol=1e-15)
    assert np.all(np.triu(A_E) == 0.0)  # explicit
    assert np.all(np.diag(A_I)[1:] == imex._GAMMA) and A_I[0, 0] == 0.0  # ESDIRK
    np.testing.assert_array_equal(A_I[-1], B)  # stiffly accurate


@pytest.mark.parametrize("pair", list(itertools.product((A_E, A_I), repeat=2)))
def test_fourth_order_conditions_hold_for_every_combination_of_the_tableaux(pair):
    """Additive RK order conditions up to order 4 (Kennedy & Carpenter 2003, Table 1):
    every product of A's may be either tableau."""
    a1, a2 = pair
    conditions = {
        "b·1 = 1": (B.sum(), 1.0),
        "b·c = 1/2": (B @ C, 1 / 2),
        "b·c² = 1/3": (B @ C**2, 1 / 3),
        "b·A c = 1/6": (B @ a1 @ C, 1 / 6),
        "b·c³ = 1/4": (B @ C**3, 1 / 4),
        "b·(c∘A c) = 1/8": (B @ (C * (a1 @ C)), 1 / 8),
        "b·A c² = 1/12": (B @ a1 @ C**2, 1 / 12),
        "b·A A c = 1/24": (B @ a1 @ a2 @ C, 1 / 24),
    }
    for name, (value, exact) in conditions.items():
        assert value == pytest.approx(exact, abs=1e-12), name


@pytest.mark.parametrize("a", (A_E, A_I))
def test_each_tableau_is_fifth_order(a):
    """The nine conditions of the order-5 trees for one Runge–Kutta tableau."""
    ac = a @ C
    conditions = {
        "b·c⁴ = 1/5": (B @ C**4, 1 / 5),
        "b·(c²∘Ac) = 1/10": (B @ (C**2 * ac), 1 / 10),
        "b·(c∘Ac²) = 1/15": (B @ (C * (a @ C**2)), 1 / 15),
        "b·(c∘AAc) = 1/30": (B @ (C * (a @ ac)), 1 / 30),
        "b·(Ac)² = 1/20": (B @ ac**2, 1 / 20),
        "b·Ac³ = 1/20": (B @ a @ C**3, 1 / 20),
        "b·A(c∘Ac) = 1/40": (B @ a @ (C * ac), 1 / 40),
        "b·AAc² = 1/60": (B @ a @ a @ C**2, 1 / 60),
        "b·AAAc = 1/120": (B @ a @ a @ ac, 1 / 120),
    }
    for name, (value, exact) in conditions.items():
        assert value == pytest.approx(exact, abs=1e-11), name


@pytest.mark.parametrize("a", (A_E, A_I))
def test_the_embedded_weights_are_fourth_order_and_differ_from_b(a):
    assert B_HAT.sum() == pytest.approx(1.0, abs=1e-12)
    assert B_HAT @ C == pytest.approx(1 / 2, abs=1e-12)
    assert B_HAT @ C**2 == pytest.approx(1 / 3, abs=1e-12)
    assert B_HAT @ a @ C == pytest.approx(1 / 6, abs=1e-12)
    assert B_HAT @ C**3 == pytest.approx(1 / 4, abs=1e-12)
    assert B_HAT @ a @ a @ C == pytest.approx(1 / 24, abs=1e-12)
    assert abs(B_HAT @ C**4 - 1 / 5) > 1e-4  # not 5th order: the difference estimates the error


def test_the_implicit_part_is_l_stable():
    """R(z) = 1 + z bᵀ(I − zA)⁻¹1 of the ESDIRK: |R| ≤ 1 on the imaginary axis and
    R(z) → 0 like 1/z for z → −∞ (evaluated where the sum's cancellation, |z|·ε, stays
    far below R)."""
    one = np.ones(len(B))

    def stability(z):
        return 1.0 + z * B @ np.linalg.solve(np.eye(len(B)) - z * A_I, one)

    r4, r6 = abs(stability(-1e4)), abs(stability(-1e6))
    assert r4 < 1e-3 and r6 < 1e-5 and r6 == pytest.approx(r4 / 100, rel=0.01)
    for w in np.logspace(-2, 4, 200):
        assert abs(stability(1j * w)) <= 1.0 + 1e-12


# ---- the stiff set -----------------------------------------------------------------
@pytest.mark.parametrize("n_modes, per_link", [(2, [2, 3]), (4, [3, 4, 5])])
def test_the_stiff_set_is_the_static_shapes_and_the_highest_modes_in_both_bases(ringing_chain, n_modes, per_link):
    case = ringing_chain
    engine = ReferenceEngine(case, integrator="imex", n_modes=n_modes, static_modes="explicit")
    lay = engine.model.layout
    expected = [lay.mode_offset[i] + j for i in range(6) for j in per_link]
    np.testing.assert_array_equal(engine.stepper.imex.stiff, np.r_[expected, np.add(expected, lay.ns)])
    # the same shapes stand above STIFF_HZ in the PP and the PF basis of every link
    arrays = engine.model.arrays
    for i, n in enumerate(lay.n_modes):
        for kind in (PP, PF):
            f = np.sqrt(np.diag(arrays.k_ff[i, kind])[:n] / np.diag(arrays.m_ff[i, kind])[:n]) / (2 * np.pi)
            assert list(np.flatnonzero(f > imex.STIFF_HZ)) == per_link, (i, kind, f)


# ---- the integration ---------------------------------------------------------------
@pytest.mark.study
def test_imex_agrees_with_dopri5_and_its_error_shrinks_with_rtol(ringing_chain):
    case = ringing_chain
    exact = _advance(ReferenceEngine(case, integrator="dopri5", rtol=1e-11, static_modes="explicit"), 0.2, 1e-3, tau=10.0)
    lay = ReferenceEngine(case, static_modes="explicit").model.layout
    errors = []
    for rtol in (1e-5, 1e-7):
        x = _advance(ReferenceEngine(case, integrator="imex", rtol=rtol, static_modes="explicit"), 0.2, 1e-3, tau=10.0)
        errors.append(max(np.max(np.abs(x[lay.q][:9] - exact[lay.q][:9])),  # rigid [m, rad]
                          np.max(np.abs(x[lay.q][9:] - exact[lay.q][9:]))))  # amplitudes [m]
    assert errors[1] < 1e-8, errors
    assert errors[1] < errors[0] / 10.0, errors


@pytest.mark.study
def test_one_step_per_control_sample_where_the_explicit_pair_needs_two():
    """The point of the method: the static shapes' ~0.9 kHz modes bound DP5 near 0.46 ms;
    with them implicit, a quiet phase (the first 0.3 s of p1's transport, its own
    controller) takes one step per 1 ms sample (its explicit part sees ~0.2 kHz)."""
    case = load_case("p1_transport")
    runs = {}
    for integrator in ("imex", "dopri5"):
        engine = ReferenceEngine(case, integrator=integrator, static_modes="explicit")
        runs[integrator] = (engine, runner.run(engine, case, duration=0.3))
    (imex_engine, imex_run), (dp5, dp5_run) = runs["imex"], runs["dopri5"]
    assert imex_engine.steps <= 302 and imex_engine.rejected == 0, (imex_engine.steps, imex_engine.rejected)
    assert dp5.steps >= 2 * 300, dp5.steps
    for name in ("ee1_pos_B", "ee2_pos_B", "joint_angles"):
        assert np.max(np.abs(imex_run.observables[name] - dp5_run.observables[name])) < 1e-9, name
    # L = ∂f/∂x_S was evaluated once per REFRESH_S of simulated time (and at the start)
    assert imex_engine.stepper.imex.work[imex.W_JACOBIANS] == np.ceil(0.3 / imex.REFRESH_S)


@pytest.mark.study
def test_a_change_of_the_system_forces_a_new_L(ringing_chain):
    case = ringing_chain
    engine = ReferenceEngine(case, integrator="imex", static_modes="explicit")
    _advance(engine, 0.01, 1e-3)
    assert engine.stepper.imex.work[imex.W_JACOBIANS] == 1
    engine.release(1)
    engine.advance(0.011, Inputs())
    assert engine.stepper.imex.work[imex.W_JACOBIANS] == 2


@pytest.mark.study
def test_the_quiet_segments_go_to_the_quiet_integrator():
    """`quiet_integrator` (an option of the [reference] table): the intervals longer than the
    case's control period (a coast's 5 ms) go to the IMEX pair, the others to DP5, bit for
    bit as without it.  With the static shapes as Ritz states (the stiff set), a 0.5 s burn
    of p4, then a 7 s coast: once the shutdown has rung out
    (~6 s: 15, 8.2, 6.8, 5.4, 4.5, 3.7 steps per sample in its first six seconds) the IMEX
    takes three steps per 5 ms sample where DP5 takes nine (measured on this
    coast), and the two runs agree far below the engines' differences."""
    base = load_case("p4_hohmann").variant(True)
    burn, coast = base.segments[0], base.segments[1]
    case = replace(base, segments=(replace(burn, duration=0.5), replace(coast, duration=7.0)), duration=7.5)
    runs, late_steps, x_at_shutdown = {}, {}, {}
    for quiet in ("imex", "dopri5"):
        engine = ReferenceEngine(case, quiet_integrator=quiet, static_modes="explicit")
        advance, steps = engine.advance, []

        def logged(t_next, inputs, engine=engine, advance=advance, steps=steps):
            if abs(engine.t - 0.5) < 1e-9:
                x_at_shutdown[quiet] = engine.x.copy()
            n = engine.steps
            advance(t_next, inputs)
            steps.append((t_next, engine.steps - n))

        engine.advance = logged
        runs[quiet] = (engine, runner.run(engine, case))
        late_steps[quiet] = np.mean([n for t, n in steps if t > 6.5 + 1e-9])
    np.testing.assert_array_equal(x_at_shutdown["imex"], x_at_shutdown["dopri5"])  # the burn: DP5 in both
    (imex_engine, imex_run), (dp5_engine, dp5_run) = runs["imex"], runs["dopri5"]
    assert imex_engine.quiet_steps > 0 and dp5_engine.quiet_steps == 0
    assert late_steps["imex"] <= 3.1 and late_steps["dopri5"] >= 8.0, late_steps
    assert imex_engine.solver_settings()["quiet_integrator"].startswith("ARK5(4)8L[2]SA")
    # measured: 2.15e-7 rad, 1.70e-4 N·m, 5.8e-10 m, of the order of either integrator's own
    # error against rtol 1e-10 (docs/records.md); the bounds are 3.5–6× those, far
    # below the engines' differences
    for name, bound in (("joint_angles", 1e-6), ("motor_torques", 1e-3), ("link_deflection", 2e-9)):
        assert np.max(np.abs(imex_run.observables[name] - dp5_run.observables[name])) < bound, name
