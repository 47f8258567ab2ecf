"""The Exudyn engine: construction, link frames, and comparisons with the reference.

Unit tests check the model against its own definitions (initial state = rsmcheck.driver.initial,
frames of docs/physics.md §2.1).  `crosscheck` tests run both engines through the shared
sampled-data loop and compare every observable with `rsmcheck.orchestration.compare` (scale = max of the
reference, with the physical floors of `SCALE_FLOORS`).  The tolerances are the measured
differences with a margin, each explained in docs/exudyn.md:

* rigid links: the two engines solve the same ODE; positions, angles, momentum, energy
  agree to ≤ 1e-6.  Reaction forces are dominated by the undamped 92 Hz rotor ripple
  (C_m = 0.002 N·m·s/rad, ζ = 1.4e-5); generalized-α (2nd order) shifts its phase by
  ≈ (ωh)²/12 per radian, the reference (Dormand–Prince, rtol 1e-9) does not: ≈ 1e-2 at
  h = 0.5 ms after 1 s, shrinking as h².
* flexible links: additionally the finite-element vs modal discretisation and the axial
  compliance of the FE beam (the t = 0 reaction: an unstretched FE beam carries no
  centripetal load yet).
"""

from __future__ import annotations

import dataclasses
import math

import exudyn as exu
import numpy as np
import pytest

from exudyn_model.engine import ExudynEngine
from exudyn_model.switching import first_moment, plastic_impact, switch_basis
from rsmcheck.core.cases import load_case
from rsmcheck.orchestration.compare import compare_runs
from rsmcheck.core.engine import Inputs
from rsmcheck.core.errors import SimulationDiverged
from rsmcheck.core.geometry import rigid_arm
from rsmcheck.driver.initial import build_initial
from rsmcheck.core.observables import NAMES
from rsmcheck.driver.runner import run

ALL = [n for n in NAMES if n != "time"]


@pytest.fixture(scope="module")
def free_drift():
    return load_case("free_drift")


@pytest.mark.parametrize("rigid", [True, False])
def test_initial_state_is_the_shared_one(free_drift, rigid):
    eng = ExudynEngine(free_drift, rigid=rigid)
    s = eng.sensors()
    init = build_initial(free_drift)
    assert np.allclose(s.base_pose_I, init.base_pose, atol=1e-14)
    assert np.allclose(s.joint_angles, init.joint_angles, atol=1e-13)
    assert np.allclose(s.joint_rates, init.joint_rates, atol=1e-13)
    assert np.allclose(s.motor_angles, init.joint_angles, atol=1e-13)
    assert np.allclose(s.target_pose_I, init.target_pose, atol=1e-13)
    for arm in (1, 2):
        p, v, *_ = rigid_arm(free_drift.params, init.base_pose, init.base_rate,
                             init.joint_angles[3 * arm - 3:3 * arm], init.joint_rates[3 * arm - 3:3 * arm], arm)
        assert np.allclose(s.ee_pos_I[arm - 1], p, atol=1e-13)
        assert np.allclose(s.ee_vel_I[arm - 1], v, atol=1e-13)


@pytest.mark.parametrize("rigid", [True, False])
def test_sensors_read_the_coordinates_they_name(free_drift, rigid):
    """The sensors are one compiled gather (`index.sensor_table`): at a state where every
    coordinate and rate differs, each must equal its definition by the index tables
    (`exudyn_model.indices`: ψ_J = proximal hub − parent's distal hub, θ_J = frame − parent frame,
    ψ_w = θ_T − terminal distal hub, the end effector = the tip node's x, y)."""
    eng = ExudynEngine(free_drift, rigid=rigid)
    sd = eng.mbs.systemData
    rng = np.random.default_rng(7)
    n = len(eng.model.index.q_ref)
    sd.SetODE2Coordinates(np.asarray(sd.GetODE2Coordinates()) + rng.normal(0.0, 1e-2, n))
    sd.SetODE2Coordinates_t(rng.normal(0.0, 1.0, n))
    q, v = eng.coordinates()
    s = eng.sensors()
    ix = eng.model.index
    parent_hub = np.array([ix.i_base[2], *ix.i_hub_dist[:2], ix.i_base[2], *ix.i_hub_dist[3:5]])
    parent_frame = np.array([ix.i_base[2], *ix.i_frame[:2], ix.i_base[2], *ix.i_frame[3:5]])
    expected = {"base_pose_I": q[ix.i_base], "base_rate_I": v[ix.i_base],
                "target_pose_I": q[ix.i_target], "target_rate_I": v[ix.i_target],
                "motor_angles": q[ix.i_rotor], "motor_rates": v[ix.i_rotor],
                "joint_angles": q[ix.i_hub_prox] - q[parent_hub], "joint_rates": v[ix.i_hub_prox] - v[parent_hub],
                "joint_frame_angles": q[ix.i_frame] - q[parent_frame],
                "joint_frame_rates": v[ix.i_frame] - v[parent_frame],
                "wrist_angles": q[ix.i_target[2]] - q[ix.i_hub_dist[[2, 5]]]}
    if not rigid:
        tips = [eng.model.links[i].coords[-4:-2] for i in (2, 5)]
        expected.update(ee_pos_I=np.array([q[t] for t in tips]), ee_vel_I=np.array([v[t] for t in tips]))
    for name, value in expected.items():
        assert np.array_equal(getattr(s, name), value), name


def test_the_state_of_a_sample_is_read_again_after_every_change(free_drift):
    """`coordinates()` returns the state read at the end of `advance` until the state changes: a
    capture, a release, a restart or any other change goes through `Stepper.pause`, after which it
    is read from Exudyn again (else the sensors would see the state before the change)."""
    eng = ExudynEngine(free_drift)
    eng.advance(1e-3, Inputs())
    q1, v1 = eng.coordinates()
    assert eng.coordinates()[0] is q1  # the sample's arrays, not a new copy
    with pytest.raises(ValueError):  # and read-only: a reader cannot change them for the others
        q1[0] += 1.0
    sd = eng.mbs.systemData
    eng.stepper.pause()
    sd.SetODE2Coordinates_t(np.asarray(sd.GetODE2Coordinates_t()) + 1e-3)
    assert np.array_equal(eng.coordinates()[1], v1 + 1e-3)
    assert np.array_equal(eng.sensors().base_rate_I, v1[eng.model.index.i_base] + 1e-3)
    eng.advance(2e-3, Inputs())
    assert eng.sensors().time == 2e-3 and eng.coordinates()[0] is not q1
    before = eng.coordinates()[1].copy()
    info = eng.release(1) if eng.state.grasp_on[0] else eng.capture(1)  # a switch projects the velocities
    assert info["impact_loss_J"] >= 0.0
    assert np.array_equal(eng.coordinates()[1], np.asarray(sd.GetODE2Coordinates_t()))
    assert not np.array_equal(eng.coordinates()[1], before)


@pytest.mark.crosscheck
@pytest.mark.parametrize("rigid", [True, False])
def test_initial_observables_match_reference(free_drift, rigid):
    """Energy, momentum, COM of the same rigid-motion state: exact integrals in both."""
    from reference_model.engine import ReferenceEngine

    a = ExudynEngine(free_drift, rigid=rigid).observe(Inputs())
    b = ReferenceEngine(free_drift, n_modes=0 if rigid else 2).observe(Inputs())
    for name in ("com_pos_B", "energy", "momentum_I", "ee1_pos_B", "ee2_pos_B", "target_pose_B", "system_mass"):
        assert np.allclose(a[name], b[name], rtol=1e-12, atol=1e-12), (name, a[name], b[name])


def test_pf_frame_is_mass_orthogonal_and_pp_frame_is_the_chord(free_drift):
    """After 0.2 s of free drift (links vibrating): arm 2's terminal frame (PF) satisfies
    ∫ρ ξ w dξ = 0, every PP frame passes through both pins (docs/physics.md §2.1)."""
    eng = ExudynEngine(free_drift)
    for k in range(1, 201):
        eng.advance(k * 1e-3, Inputs())
    q, _ = eng.coordinates()
    p = eng.params.link
    for it in eng.model.links:
        qi = q[it.coords]
        th = q[eng.model.index.i_frame[it.index]]
        n = np.array([-math.sin(th), math.cos(th)])
        R = qi[:2]
        if eng.state.basis[it.index] == "PF":
            w_moment = n @ (eng.model.moment @ qi - 0.5 * p.mass * p.length * R)
            assert abs(w_moment) < 1e-14 * eng.model.I0, (it.index, w_moment)
        else:
            assert abs(n @ (qi[-4:-2] - R)) < 1e-12, it.index
    assert eng.state.basis == ["PP", "PP", "PP", "PP", "PP", "PF"]


def test_the_pf_point_is_tied_to_the_beam_only_while_the_link_is_pf(free_drift):
    """P, the point that carries a terminal link's PF axis, is tied to the beam only in PF;
    in PP it is parked at its reference position and the tie is off (build.py), and each
    basis switch places it where the new constraints hold (switching._switch_basis)."""
    eng = ExudynEngine(free_drift)
    it = eng.model.links[5]
    ip = eng.mbs.GetNodeODE2Index(it.p_node) + np.arange(2)
    scale = eng.params.link.length / eng.model.I0
    active = lambda item: bool(eng.mbs.GetObjectParameter(item, "activeConnector"))  # noqa: E731

    def p_error():
        """|P − (R + (L/I_0)∫ρξ(r − R)dξ)| and the same for the velocities."""
        q, v = eng.coordinates()
        qi, vi = q[it.coords], v[it.coords]
        return (np.abs(q[ip] - qi[:2] - scale * first_moment(eng.model, qi)).max(),
                np.abs(v[ip] - vi[:2] - scale * first_moment(eng.model, vi)).max())

    def parked():
        q, v = eng.coordinates()
        return np.abs(q[ip] - eng.model.index.q_ref[ip]).max() < 1e-14 and np.abs(v[ip]).max() < 1e-12

    def switch(basis, t):
        """Switch (as a capture or release does) and fly 50 samples; the state right after
        the switch is checked before the solver could mend it."""
        eng.stepper.pause()
        switch_basis(eng.model, eng.state, 5, basis)
        plastic_impact(eng.model, eng.constraint_forces)
        eng.stepper.restart()
        right_after = p_error() if basis == "PF" else parked()
        for k in range(1, 51):
            eng.advance(t + k * 1e-3, Inputs())
        return t + 0.05, right_after

    t, (dq, dv) = switch("PF", 0.0)  # free_drift's arm 2 starts PF: no switch
    assert eng.state.basis[5] == "PF" and active(it.p_tie) and not any(active(c) for c in it.p_park)
    assert dq < 1e-12 and dv < 1e-10, (dq, dv)
    t, was_parked = switch("PP", t)
    assert not active(it.p_tie) and all(active(c) for c in it.p_park)
    assert was_parked and parked()
    assert p_error()[0] > 1e-6  # the beam has moved on: P no longer follows it
    _, (dq, dv) = switch("PF", t)
    assert active(it.p_tie) and not any(active(c) for c in it.p_park)
    assert dq < 1e-12 and dv < 1e-10, (dq, dv)  # placed on the beam by the switch
    dq, dv = p_error()
    assert dq < 1e-12 and dv < 1e-10, (dq, dv)  # and kept there by the tie


def _runs(case, duration, n_modes, **options):
    from reference_model.engine import ReferenceEngine

    return run(ReferenceEngine(case, n_modes=n_modes), case, duration), run(ExudynEngine(case, **options), case, duration)


def _check(case, ref, exu, tolerances, default):
    rows = compare_runs(case.name, ref, exu, {n: tolerances.get(n, default) for n in ALL})
    bad = [(r.observable, f"{r.error:.2e} > {r.tolerance:.0e} at t={r.worst_time}") for r in rows if not r.passed]
    assert not bad, bad
    return {r.observable: r.error for r in rows}


@pytest.mark.crosscheck
def test_rigid_equivalence_free_drift(free_drift):
    ref, exu = _runs(free_drift, 1.0, 0, rigid=True)
    _check(free_drift, ref, exu, {"reaction_forces_I": 3e-2}, 1e-5)


@pytest.mark.crosscheck
def test_rigid_rotor_ripple_converges_with_step():
    """closed_squeeze: the motor torque steps excite the 92 Hz rotor ripple; the difference
    in everything it drives shrinks at least like h (≈ h² asymptotically) — it is the
    integrator's phase error, not a modelling difference."""
    from reference_model.engine import ReferenceEngine

    case = load_case("closed_squeeze")
    ref = run(ReferenceEngine(case, n_modes=0), case, 0.3)
    errs = {}
    for sub in (2, 8):
        exu = run(ExudynEngine(case, rigid=True, substeps=sub), case, 0.3)
        errs[sub] = {r.observable: r.error for r in compare_runs(
            case.name, ref, exu, {n: 1.0 for n in ("motor_angles", "reaction_forces_I", "ee2_speed", "joint_angles")})}
    for name in ("motor_angles", "reaction_forces_I", "ee2_speed"):
        assert errs[8][name] < errs[2][name] / 4.0, (name, errs)
    assert errs[2]["joint_angles"] < 1e-5, errs


FLEX_TOL = {
    # ξ, deflection: FE (8 elements) vs 2 modes, plus the integrator on 30–150 Hz modes
    "link_deflection": 0.1,  # of max(|w|, 0.1 µm): nanometre-level vibration in free drift
    # t = 0: the unstretched FE beam carries no centripetal load yet (decays in ~1 ms)
    "reaction_forces_I": 1.0,
    "motor_angles": 1e-5,
    "ee2_speed": 2e-5,
    "capture_gap_B": 2e-5,
    "energy": 1e-5,
    # 5e-7 rad apart, as the joint angles, but relative to the wrists' 0.01 rad in free drift
    "wrist_angles": 1e-4,
}


@pytest.mark.crosscheck
def test_flexible_free_drift(free_drift):
    ref, exu = _runs(free_drift, 1.0, 2)
    _check(free_drift, ref, exu, FLEX_TOL, 1e-5)
    # after the first samples the reaction forces agree to 2 % of their size
    t = ref.observables["time"]
    late = t >= 0.02
    d = np.abs(ref.observables["reaction_forces_I"][late] - exu.observables["reaction_forces_I"][late]).max()
    assert d < 2e-2 * np.abs(ref.observables["reaction_forces_I"]).max(), d


@pytest.mark.crosscheck
def test_release_basis_switch_matches_reference():
    """Closed → open at t = 1 s (case release): the frame of arm 2's terminal link turns by
    δ to the mass-orthogonal axis in both engines; the joint spring torque jumps by K_m δ."""
    case = load_case("release")
    # the case's 32 steps and Jacobian per step are for its angular momentum (cases/release.toml);
    # δ and the poses are the same at 8 steps, in a quarter of the time
    ref, exu = _runs(case, 1.2, 2, substeps=8, jacobian_per_step=False)
    ev_r = [e for e in ref.events if e.kind == "release"]
    ev_e = [e for e in exu.events if e.kind == "release"]
    assert len(ev_r) == len(ev_e) == 1 and ev_r[0].time == ev_e[0].time
    d_r = float(ev_r[0].detail.split("delta_rad=")[1].split()[0])
    d_e = float(ev_e[0].detail.split("delta_rad=")[1].split()[0])
    print(f"\nrelease: δ = {d_r:.4e} rad (reference), {d_e:.4e} rad (Exudyn)")
    # δ is the mass-weighted tilt of the deflection at that instant, δ ≈ ∫ρξw/I_0: with the
    # squeeze ramped in, the static bend of the squeeze (measured −6.512e-7 vs −6.520e-7 rad,
    # 1.2e-3 apart).  In torque: K_m |δ_e − δ_r| < 0.01 N·m.
    assert abs(d_e - d_r) < 1e-2 * abs(d_r), (d_r, d_e)
    assert case.params.motor.stiffness * abs(d_e - d_r) < 1e-2
    rows = {r.observable: r for r in compare_runs(case.name, ref, exu, {n: 1.0 for n in ALL})}
    for name in ("base_pose_I", "ee1_pos_B", "ee2_pos_B", "joint_angles", "target_pose_B", "com_pos_B"):
        assert rows[name].error < 2e-4, (name, rows[name].error)


def test_release_conserves_momentum():
    """At the release the frame of arm 2's terminal link is redefined (PP → PF) and its rate
    changes; J_extra on that frame is coupled to the system by the plastic projection
    (docs/physics.md §2.3, §4.4), so linear and angular momentum do not jump.  The squeeze
    as a step (no ramp) rings the links, so that the frame's rate does jump."""
    case = load_case("release")
    case = dataclasses.replace(case, controller=dataclasses.replace(case.controller, ramp_time=0.0))

    class Probe(ExudynEngine):
        def release(self, arm):
            q, v = self.coordinates()
            self.before = (self.observer.momentum(q, v), v[self.model.index.i_frame[3 * arm - 1]])
            info = super().release(arm)
            q, v = self.coordinates()
            self.after = (self.observer.momentum(q, v), v[self.model.index.i_frame[3 * arm - 1]])
            return info

    eng = Probe(case, substeps=2)
    run(eng, case, 1.0)
    (p0, om0), (p1, om1) = eng.before, eng.after
    step_without_coupling = case.params.link.inertia_extra * abs(om1 - om0)
    print(f"\nrelease: frame rate {om0:.6e} → {om1:.6e} rad/s (J_extra·Δω = {step_without_coupling:.2e}), "
          f"Δp = {np.abs(p1[:2] - p0[:2]).max():.1e} kg·m/s, ΔL = {abs(p1[2] - p0[2]):.1e} kg·m²/s")
    assert step_without_coupling > 1e-6  # the frame rate did jump
    assert np.abs(p1[:2] - p0[:2]).max() <= 1e-12 and abs(p1[2] - p0[2]) <= 1e-11


@pytest.mark.parametrize("stepping", ["continuous", "period"])
def test_intervals_other_than_the_control_period(free_drift, stepping):
    """The runner may advance by a segment's own control period or by an interval clipped at
    a segment boundary: the step stays h = control_period/substeps (an interval that is not
    a whole number of steps gets equal steps ≤ h), and with no inputs the trajectory does
    not depend on how the time axis is cut."""
    def final(spans):
        eng = ExudynEngine(free_drift, rigid=True, stepping=stepping)
        t = 0.0
        for span in spans:
            t += span
            eng.advance(t, Inputs())
        assert abs(eng.mbs.systemData.GetTime() - t) < 1e-12
        return eng.coordinates()[0]

    base = final([1e-3] * 30)
    assert np.abs(final([1e-3] * 5 + [1e-2] * 2 + [1e-3] * 5) - base).max() < 1e-12
    # 0.7 ms and 1.3 ms: 2 and 3 steps of 0.35 and 0.43 ms instead of 0.5 ms (O(h²) apart)
    assert np.abs(final([1e-3] * 5 + [7e-4, 1.3e-3] + [1e-3] * 23) - base).max() < 1e-9


def test_case_exudyn_table_sets_the_step_and_options_override_it():
    case = load_case("motor_step")
    assert case.engine_settings["exudyn"].substeps == 128
    assert ExudynEngine(case, rigid=True).substeps == 128
    assert ExudynEngine(case, rigid=True, substeps=4).substeps == 4
    assert ExudynEngine(load_case("free_drift"), rigid=True).substeps == 2  # no table: the default
    assert ExudynEngine(case).n_elements == 16
    # motor_step's stiffer, shorter elements (EA = 1e6·EI, 16 per link) run at 3e-3 N, not
    # 1000·ε·EA = 1e-2 N
    assert case.engine_settings["exudyn"].newton_atol == 3e-3
    assert ExudynEngine(case).newton_atol == 3e-3
    assert ExudynEngine(case, newton_atol=5e-3).newton_atol == 5e-3
    assert ExudynEngine(case, rigid=True).newton_atol == 1e-10  # rigid links: no axial round-off floor
    # release: a Newton Jacobian at every step (its angular momentum, docs/exudyn.md §8), 32
    # steps per ms at full length, 8 in the short variant
    release = load_case("release")
    full, short = ExudynEngine(release), ExudynEngine(release.variant(True))
    assert (full.substeps, full.jacobian_per_step, short.substeps, short.jacobian_per_step) == (32, True, 8, True)
    assert full.stepper.settings.timeIntegration.newton.modifiedNewtonJacUpdatePerStep
    assert not ExudynEngine(release, jacobian_per_step=False).stepper.settings.timeIntegration.newton.modifiedNewtonJacUpdatePerStep
    assert full.solver_settings()["jacobian_per_step"] is True


def test_stalled_newton_step_is_retried_with_a_looser_tolerance():
    """flex_arm_step with the absolute Newton tolerance at 30·ε·EA (3e-5 N, below the axial
    round-off floor) stalls (measured: in each of the first 10 control periods); the engine
    retries that step from its start with a 10× looser tolerance and goes on (docs/exudyn.md
    §4).  At 1e-5 N even the retry fails at t = 0."""
    case = load_case("flex_arm_step").variant(True)
    eng = ExudynEngine(case, newton_atol=3e-5, substeps=32)
    r = run(eng, case, 0.01)
    assert eng.stats["newton_retries"] >= 1
    assert eng.stepper.solver.newton.absoluteTolerance == 3e-5  # restored, in the solver's own copy
    assert eng.stepper.settings.timeIntegration.newton.absoluteTolerance == 3e-5
    assert np.all(np.isfinite(np.asarray(r.observables["link_deflection"])))
    assert r.observables["time"][-1] == pytest.approx(0.01)


def test_a_new_newton_tolerance_reaches_the_solver():
    """Exudyn's solver copies its Newton settings in `InitializeSolver`: a tolerance changed
    afterwards (the retry of a stalled step) must be set on that copy: set on the settings
    alone it has no effect."""
    eng = ExudynEngine(load_case("flex_arm_step").variant(True))
    eng.stepper.solver.InitializeSolverInitialConditions(eng.mbs, eng.stepper.settings)
    eng.stepper.set_newton_atol(7e-3)
    eng.stepper.solver.InitializeSolverInitialConditions(eng.mbs, eng.stepper.settings)
    assert eng.stepper.solver.newton.absoluteTolerance == 7e-3
    assert eng.stepper.settings.timeIntegration.newton.absoluteTolerance == 7e-3


def test_a_retry_finds_its_step_on_a_drifting_clock():
    """Exudyn's clock (t += h) drifts from the runner's samples (−2.6e-11 s at 60 s of the
    full p1, up to ~1e-7 s in p4's burn 2, docs/exudyn.md §5).  A stalled step that starts
    that far behind the runner's sample is still retried; a match to 1e-12 s refused it and
    ended the full p1 at 60.092 s."""
    case = load_case("flex_arm_step").variant(True)
    eng = ExudynEngine(case)
    for k in range(1, 4):
        eng.advance(k * 1e-3, Inputs(tau_m=np.full(6, 0.5)))
    sd = eng.mbs.systemData
    sd.SetTime(eng.state.t - 3e-11, exu.ConfigurationType.StartOfStep)
    assert eng.stepper.retry_looser(eng.state.t + 1e-3)
    assert sd.GetTime() == pytest.approx(eng.state.t + 1e-3, abs=1e-12)
    # a step that does not start in the interval is reported, not retried
    sd.SetTime(eng.state.t - 0.4e-3, exu.ConfigurationType.StartOfStep)
    with pytest.raises(SimulationDiverged, match="not in the interval"):
        eng.stepper.retry_looser(eng.state.t + 1e-3)


def test_the_worker_ends_an_interval_within_a_quarter_step():
    """The step that ends a control interval is recognised within h/4 of the sample, so a
    clock running 3e-9 s behind (more than the former 1e-6 h = 5e-10 s) does not run one
    step past the sample; a step h/2 short of it is a step inside the interval."""
    eng = ExudynEngine(load_case("free_drift"), rigid=True)
    eng.advance(1e-3, Inputs())
    worker = eng.stepper.worker
    h = worker.h
    worker.target = 2e-3
    assert worker.ends_interval(2e-3 - 3e-9) and worker.ends_interval(2e-3 + 3e-9)
    assert not worker.ends_interval(2e-3 - 0.5 * h)


def test_one_suspended_run_per_thread(free_drift):
    """Two engines advanced in turn on one thread: starting a run ends the other engine's
    suspended one at its sample (an earlier `SolveSteps` returning before a later one
    breaks pybind11's per-thread call stack and aborts the process: worker.py's
    `Worker`).  Each engine lands on its samples, and the two, started alike and restarted
    alike, stay equal to the bit."""
    a = ExudynEngine(free_drift, rigid=True)
    b = ExudynEngine(free_drift, rigid=True)
    for k in range(1, 6):
        a.advance(k * 1e-3, Inputs())
        assert a.stepper.worker.run is not None and b.stepper.worker.run is None
        b.advance(k * 1e-3, Inputs())
        assert b.stepper.worker.run is not None and a.stepper.worker.run is None
        for eng in (a, b):
            assert eng.mbs.systemData.GetTime() == pytest.approx(k * 1e-3, abs=1e-12)
    assert np.array_equal(np.concatenate(a.coordinates()), np.concatenate(b.coordinates()))


@pytest.mark.parametrize("stepping", ["continuous", "period"])
def test_quiet_intervals_take_quiet_substeps_steps(free_drift, stepping):
    """With `quiet_substeps` an interval longer than the control period (a quiet segment's)
    is cut into that many steps, and the 1 ms intervals around it keep h = 0.5 ms.  Exudyn
    clips the step to the maxStepSize it took from the settings, so the worker sets it: left
    alone, a 2.5 ms step would run as 0.5 ms steps and stop 0.5 ms short of a 5 ms sample
    (within the worker's quarter step), which the clock check below refuses."""
    eng = ExudynEngine(free_drift, rigid=True, stepping=stepping, quiet_substeps=2)
    assert eng.solver_settings()["quiet_substeps"] == 2
    t = 0.0
    for span, h in [(1e-3, 5e-4), (5e-3, 2.5e-3), (5e-3, 2.5e-3), (1e-3, 5e-4)]:
        t += span
        eng.advance(t, Inputs())
        assert eng.stepper.solver.it.currentStepSize == pytest.approx(h, rel=1e-12)
        assert eng.mbs.systemData.GetTime() == pytest.approx(t, abs=1e-12)
    assert eng.stats["steps"] == 2 + 2 + 2 + 2
    assert eng.stats["restarts"] == 2  # one at each change of h
    with pytest.raises(ValueError, match="quiet_substeps"):
        ExudynEngine(free_drift, rigid=True, quiet_substeps=0)


def test_a_sample_missed_by_the_solver_clock_is_an_error(free_drift, monkeypatch):
    """The worker pauses at the step that ends within h/4 of the sample; a clock that
    ends further from the sample than h/100 (a wrong step count) stops the run with the
    clock's time, instead of carrying a state that is a fraction of a step behind."""
    eng = ExudynEngine(free_drift, rigid=True)
    eng.advance(1e-3, Inputs())
    step = eng.stepper.worker.step

    def short(t, t_next, h):
        ok = step(t, t_next, h)
        eng.mbs.systemData.SetTime(t_next - 0.2 * h)
        return ok

    monkeypatch.setattr(eng.stepper.worker, "step", short)
    with pytest.raises(SimulationDiverged, match="clock"):
        eng.advance(2e-3, Inputs())


def test_the_newton_jacobian_is_renewed_every_jacobian_period():
    """Modified Newton keeps a Jacobian until an iteration contracts by less than ½; one aged
    by the links' motion still contracts by far more but needs a second iteration per step
    (docs/exudyn.md §4, "The Jacobian's age").  With `jacobian_period` the worker asks for a
    new one every that many seconds of flight: the first 2 s of p3's short alignment move
    take 10 more Jacobians at 0.2 s than without, and fewer Newton iterations.  The request
    lasts one step and does not outlive the run (a retry's or a restart's `SolveSteps`
    would otherwise take a Jacobian at every step)."""
    case = load_case("p3_com_alignment").variant(True)
    runs = {}
    for period in (None, 0.2):
        eng = ExudynEngine(case, jacobian_period=period)
        r = run(eng, case, 2.0)
        runs[period] = (eng, r)
    (never, r_never), (every, r_every) = runs[None], runs[0.2]
    assert "jacobian_period" not in never.solver_settings()
    assert every.solver_settings()["jacobian_period"] == 0.2
    assert every.stats["steps"] == never.stats["steps"] == 4000
    assert every.stats["jacobians"] - never.stats["jacobians"] == pytest.approx(10, abs=1)
    assert every.stats["newton_iterations"] < never.stats["newton_iterations"]
    # the same converged solution, to Newton's tolerance
    assert np.abs(np.asarray(r_every.observables["joint_angles"])
                  - np.asarray(r_never.observables["joint_angles"])).max() < 1e-8
    # a request pending at a sample is withdrawn when the run ends there
    worker = every.stepper.worker
    every.advance(every.state.t + 1e-3, Inputs())  # (re)starts the suspended run
    worker.next_jacobian = every.state.t + 0.75e-3  # the second 0.5 ms step, the interval's last, asks for one
    every.advance(every.state.t + 1e-3, Inputs())
    assert worker.jacobian_requested and every.stepper.solver.newton.modifiedNewtonJacUpdatePerStep
    every.stepper.pause()
    assert not worker.jacobian_requested and not every.stepper.solver.newton.modifiedNewtonJacUpdatePerStep


def test_jacobian_period_is_checked_and_yields_to_a_jacobian_per_step(free_drift):
    assert ExudynEngine(free_drift, rigid=True, jacobian_period=math.inf).jacobian_period is None
    for bad in (0.0, -0.1, math.nan, "0.2"):
        with pytest.raises(ValueError, match="jacobian_period"):
            ExudynEngine(free_drift, rigid=True, jacobian_period=bad)
    # release takes a Jacobian at every step (its [exudyn] table): the period has nothing to add
    assert ExudynEngine(load_case("release").variant(True)).jacobian_period is None
