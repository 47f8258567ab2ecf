"""Stepping of the Exudyn model: one control interval at a time with the inputs held
(zero-order hold, docs/physics.md §6), exactly to the next sample.

Integration: Exudyn's generalized-α (index 3) with a fixed step, `substeps` per control
period.  One `SolveSteps` runs across control periods in a greenlet, suspended at every
control sample by a post-step function (`worker.Worker`), so the algorithmic state and the
modified-Newton Jacobian carry over; `stepping="period"` calls `SolveSteps` once per period
instead.  No Python user function runs inside a Newton iteration.

`Stepper` owns the implicit solver, its settings and the worker; it sets the held inputs
into the mbs (`set_inputs`), restarts the integrator after a change of the model or its
state or a jump of the inputs (`restart`, `is_step`), and retries a step whose Newton
iteration stalled (`retry_looser`).  The reference's mirror is `reference_model/stepping.py`.
"""

from __future__ import annotations

import contextlib
import io
import math
import operator
import sys
import time

import numpy as np
from numba import njit

sys.exudynFast = True  # the engine's build: import order must not matter
# exudyn announces the fast build on stdout: keep it out of `--json` output
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu  # noqa: E402

from exudyn_model.field import FieldForces, _ThrustInertia  # noqa: E402
from exudyn_model.options import EngineOptions  # noqa: E402
from exudyn_model.state import EngineState, base_mass, coordinates, mass_flow, system_mass  # noqa: E402
from exudyn_model.worker import Worker, allow_step  # noqa: E402
from rsmcheck.core.engine import Inputs  # noqa: E402
from rsmcheck.core.errors import SimulationDiverged  # noqa: E402


def simulation_settings(options: EngineOptions) -> exu.SimulationSettings:
    """Exudyn's settings of the time integration for `options`."""
    s = exu.SimulationSettings()
    ti = s.timeIntegration
    ti.endTime = options.dt
    ti.numberOfSteps = options.substeps
    ti.generalizedAlpha.spectralRadius = options.spectral_radius
    ti.generalizedAlpha.computeInitialAccelerations = True
    if options.constraints == "index2":
        # Newmark (trapezoidal: β = 1/4, γ = 1/2, no numerical damping) with velocity-level
        # constraints: the multipliers scale as 1/h instead of 1/h² (docs/exudyn.md §6)
        ti.generalizedAlpha.useNewmark = True
        ti.generalizedAlpha.useIndex2Constraints = True
    ti.newton.relativeTolerance = options.newton_rtol
    ti.newton.absoluteTolerance = options.newton_atol
    ti.newton.useModifiedNewton = True
    ti.newton.modifiedNewtonJacUpdatePerStep = options.jacobian_per_step
    ti.adaptiveStep = True
    ti.verboseMode = 0
    # the mass matrix is computed once, not at every Newton residual (~6 % of the solver's
    # time); the one mass that changes, the base's under thrust, is set by
    # `Stepper.set_base_mass`, which recomputes it (docs/exudyn.md §4)
    ti.reuseConstantMassMatrix = True
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    s.solution.file.write = False
    s.solution.sensors.active = False
    s.solution.file.writeInitialValues = False
    return s


class Stepper:
    """Advances `model`'s mbs and `state` from control sample to control sample."""

    def __init__(self, model, options: EngineOptions, state: EngineState, field_forces: FieldForces | None,
                 is_quiet, name: str = "exudyn"):
        """`model`: the built `ExudynModel`; `field_forces`: the field part (None without
        the field machinery); `is_quiet(span)`: an interval of length span [s] belongs to a
        quiet segment (the case's solver settings); `name`: the engine's, for errors."""
        self.model, self.options, self.state, self.field_forces = model, options, state, field_forces
        self.is_quiet = is_quiet
        self.name = name
        self.base_mass = model.params.base.mass  # what the base and the solver's mass matrix carry
        self.pre_step_on = False  # the thrust inertia is the solver's pre-step function
        self.restart_pending = False  # restart at the next advance (after a retry)
        self.h_now: float | None = None  # the generalized-α step of the last interval [s]
        # the jumps of τ_m, τ_B, T beyond which the integrator restarts (`is_step`)
        p, f = model.params, options.restart_threshold
        self.step_limits = (f * p.motor.torque_max, f * p.actuators.torque_max, f * p.actuators.thrust)
        self.settings = simulation_settings(options)
        self.solver = exu.MainSolverImplicitSecondOrder()
        self.solver.InitializeSolver(model.mbs, self.settings)
        # a run left suspended when the engine is dropped is ended by the next run started on
        # this thread (`Worker`: never from a finalizer, which may run inside a pybind11 call)
        self.worker = (Worker(model.mbs, self.solver, self.settings, options.dt / options.substeps,
                              options.jacobian_period) if options.stepping == "continuous" else None)

    def restart(self) -> None:
        """Restart the integrator from the current (modified) state: consistent
        accelerations are recomputed (after a capture, release or basis switch)."""
        tic = time.perf_counter()
        self.pause()
        self._current_to_initial()
        self.settings.timeIntegration.startTime = self.state.t
        self.settings.timeIntegration.endTime = self.state.t + self.options.dt
        self.solver.InitializeSolverInitialConditions(self.model.mbs, self.settings)
        self.state.stats["restarts"] += 1
        self.state.stats["wall_integrator_s"] += time.perf_counter() - tic

    def _current_to_initial(self) -> None:
        sd = self.model.mbs.systemData
        ini = exu.ConfigurationType.Initial
        sd.SetODE2Coordinates(sd.GetODE2Coordinates(), configuration=ini)
        sd.SetODE2Coordinates_t(sd.GetODE2Coordinates_t(), configuration=ini)
        sd.SetDataCoordinates(sd.GetDataCoordinates(), configuration=ini)

    def pause(self) -> None:
        """Bring the continuous integration to a clean stop at the current control sample
        (before the state or the items are modified)."""
        self.state.sample = None  # the state is about to change (state.coordinates)
        if self.worker is not None:
            self.worker.stop()

    def advance(self, t_next: float, inputs: Inputs) -> None:
        """Integrate from the state's t to t_next with `inputs` held (the Engine protocol's
        advance)."""
        mbs, state, options, ff = self.model.mbs, self.state, self.options, self.field_forces
        if self.restart_pending:
            self.restart_pending = False
            self.restart()
        # plain floats: compared with the last held inputs and set into the mbs element by element
        held = (tuple(np.asarray(inputs.tau_m, float).tolist()), float(inputs.tau_B), float(inputs.thrust))
        thrust = held[2]
        if thrust != 0.0 and ff is None:
            raise SimulationDiverged(self.name, state.t, "?", "thrust without field (build with field=True)", thrust)
        span = t_next - state.t
        self.set_inputs(held, ff.thrust_inertia if ff is not None else None, span, previous=state.held)
        state.sample = None  # the solver is about to move the state
        if ff is not None and (thrust != 0.0) != self.pre_step_on:
            # the thrust inertia's pre-step function, registered only while there is thrust:
            # it has nothing to do without (a Python call per step, ~3 µs, 2.4 % of a coast)
            self.pre_step_on = thrust != 0.0
            mbs.SetPreStepUserFunction(ff.thrust_inertia if self.pre_step_on else 0)
        if state.held is None and ff is not None:
            # the solver's initial accelerations were computed at build, without the field
            # forces just set: restart so that they include them (else the first steps take
            # the O(h) error of an input jump; docs/exudyn.md §5 item 5, "the first interval")
            self.restart()
        if held != state.held:
            if options.restart_on_input_change and self.is_step(held):
                # a step in the held inputs is a jump in the accelerations: restart the
                # integrator with accelerations consistent with the new inputs (else the
                # algorithmic acceleration of generalized-α carries the old ones and the
                # solution takes an O(h) error at the jump).  Small sample-to-sample changes
                # of a feedback controller are left to the integrator (O(h²) per change).
                self.restart()
        state.held = held  # also when equal: the mbs now carries these bits (-0.0 == 0.0)
        solver = self.solver
        # the runner may advance by other intervals than the case's control period (a
        # segment's own control_period, an interval clipped at a segment boundary): the step
        # stays h = control_period/substeps; an interval that is not a whole number of steps
        # is done on its own with equal steps ≤ h.  An interval longer than the control
        # period belongs to a quiet segment: with `quiet_substeps` it is cut into that many
        # steps (docs/exudyn.md §4, "Quiet segments"), and at every change of h the
        # integrator restarts with consistent accelerations
        h = self.step_length(span)
        if self.h_now is not None and abs(h - self.h_now) <= 1e-9 * h:
            h = self.h_now  # the same step: spans differ by the clock's round-off
        elif self.h_now is not None:
            self.restart()
        self.h_now = h
        n = span / h
        whole = round(n) >= 1 and abs(n - round(n)) < 1e-6
        n_steps = int(round(n)) if whole else max(1, math.ceil(n - 1e-6))
        tic = time.perf_counter()
        if self.worker is not None and whole:
            ok = self.worker.step(state.t, t_next, h)
            clock = float(mbs.systemData.GetTime())
            if ok and abs(clock - t_next) > 1e-2 * h:
                # a step count other than span/h lands a fraction h/n_steps off the sample;
                # the clock's own round-off drift stays below ~1e-7 s (docs/exudyn.md §5)
                raise SimulationDiverged(self.name, state.t, "?", f"Exudyn's clock at the sample {t_next!r} s "
                                         f"(steps of {h!r} s)", clock)
        else:
            self.pause()
            solver.it.startTime = state.t
            solver.it.endTime = t_next
            solver.it.currentStepSize = span / n_steps
            allow_step(solver.it, h)
            solver.it.adaptiveStep = True  # (the worker turns it off) lets the last step land on t_next
            ok = solver.SolveSteps(mbs, self.settings)
        if not ok:
            ok = self.retry_looser(t_next)
        stats, it = state.stats, solver.it
        stats["wall_integrator_s"] += time.perf_counter() - tic
        stats["steps"] += n_steps
        stats["newton_iterations"] = int(it.newtonStepsCount)
        stats["jacobians"] = int(it.newtonJacobiCount)
        q, v = coordinates(self.model, state)
        if not ok or not all_finite(q, v):
            bad = int(np.argmax(~np.isfinite(q))) if not np.all(np.isfinite(q)) else -1
            raise SimulationDiverged(self.name, state.t, "?",
                                     "Newton failed (step reduction exhausted)" if ok is False else f"ODE2[{bad}]",
                                     float(q[bad]) if bad >= 0 else float("nan"))
        if ff is not None:  # (span = t_next − state.t: state.t has not moved)
            ff.advance_orbit(state, span, ff.thrust_inertia.mean_acceleration_xy(span))
            state.m_used += mass_flow(self.model.params, thrust) * span
        state.t = t_next
        q.setflags(write=False)  # shared by every reader until it changes
        v.setflags(write=False)
        state.sample = (q, v)  # the state at the sample, until it changes (state.coordinates)

    def step_length(self, span: float) -> float:
        """The generalized-α step h for a control interval of length `span` [s]:
        control_period/substeps, or span/quiet_substeps for the interval of a quiet segment
        (longer than the control period) when the engine is built with `quiet_substeps`."""
        if self.options.quiet_substeps is not None and self.is_quiet(span):
            return span / self.options.quiet_substeps
        return self.options.dt / self.options.substeps

    def retry_looser(self, t_next: float) -> bool:
        """Retry a step whose Newton iteration stalled, from the start of that step to
        t_next, with a 10× looser absolute tolerance set into the solver's own Newton
        settings (`set_newton_atol`); then restore it (the integrator is restarted at the
        next advance).  The stall is the round-off floor of the axial forces: seen in
        p4_hohmann chained from p3 (t = 52.43 s), the residual stuck at 1.03e-3 N against
        1.0e-3 with contractivity 0.996.  A looser tolerance everywhere costs accuracy
        (3e-3 N doubles release's momentum difference; docs/exudyn.md §4).

        The failed step starts at t0 by Exudyn's clock, a running sum t += h that drifts
        from the runner's samples (docs/exudyn.md §5, item 5: −2.6e-11 s at 60 s of p1,
        up to ~1e-7 s in p4's burn 2), so t0 is matched to the interval within a quarter
        step, not to round-off: a 1e-12 s match would refuse the retry of a stall at
        60.092 s of the full p1, 2.6e-11 s behind, and end the mission there."""
        if self.model.rigid:
            return False
        mbs, state = self.model.mbs, self.state
        sd = mbs.systemData
        sos = exu.ConfigurationType.StartOfStep
        q0 = np.asarray(sd.GetODE2Coordinates(configuration=sos))
        v0 = np.asarray(sd.GetODE2Coordinates_t(configuration=sos))
        t0 = float(sd.GetTime(sos))
        h = self.h_now
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(v0))):
            return False
        if not state.t - 0.25 * h <= t0 < t_next - 0.25 * h:
            raise SimulationDiverged(self.name, state.t, "?",
                                     f"Newton failed in a step that starts at {t0!r} s, not in the interval "
                                     f"[{state.t!r}, {t_next!r}) s (no retry)", t0)
        self.pause()
        sd.SetODE2Coordinates(q0)
        sd.SetODE2Coordinates_t(v0)
        sd.SetDataCoordinates(sd.GetDataCoordinates(configuration=sos))
        atol = self.options.newton_atol
        self.set_newton_atol(10.0 * atol)
        try:
            self._current_to_initial()
            self.settings.timeIntegration.startTime = t0
            self.settings.timeIntegration.endTime = t_next
            self.solver.InitializeSolverInitialConditions(mbs, self.settings)
            it = self.solver.it
            n = max(1, math.ceil((t_next - t0) / h - 1e-3))  # the clock's drift is not a step
            it.startTime, it.endTime = t0, t_next
            it.currentStepSize = (t_next - t0) / n
            allow_step(it, h)
            it.adaptiveStep = True
            ok = bool(self.solver.SolveSteps(mbs, self.settings))
        finally:
            self.set_newton_atol(atol)
        state.stats["newton_retries"] += 1
        self.restart_pending = True
        return ok

    def set_newton_atol(self, atol: float) -> None:
        """The absolute Newton tolerance the solver uses from now on.  The solver keeps its
        own copy of the Newton settings, taken by `InitializeSolver` (a change of
        `settings.timeIntegration.newton` alone is not seen, not even after
        `InitializeSolverInitialConditions`), so both are set."""
        self.settings.timeIntegration.newton.absoluteTolerance = atol
        self.solver.newton.absoluteTolerance = atol

    def set_inputs(self, held: tuple, thrust_inertia: "_ThrustInertia | None", span: float = 0.0,
                   previous: tuple | None = None) -> None:
        """Put the held inputs (τ_m, τ_B, thrust) of the coming control period of length
        `span` [s] into the mbs; with the field machinery also the base mass (that of the
        period's middle), the tidal forces and the thrust inertia, through `thrust_inertia`
        (evaluated every step).

        The tidal forces are held over the period at its middle: evaluated at the
        positions and the orbit point O extrapolated by span/2 (q + ½ span q̇,
        r_O + ½ span v_O).  Held at the period's start they would lag the field by half a
        period, a bias −½ Ġ span (Ġ = G ρ̇ for the gradient G ~ n²) that the relative
        orbital motion grows over long drifts (docs/exudyn.md §5, item 5); at the middle
        the hold's error is O(span²).  span = 0 (an observable at a sample): the field of
        the current positions.

        `previous`: the held inputs the mbs carries now (`state.held`, as `advance` set
        them: whoever changes a load in between puts it back, `reactions.held_inputs`),
        None: unknown.  A load is set only when it differs from that, to the sign of zero
        (the thrust is constant over whole phases, a torque whenever an arm is off, open
        loop or saturated, or the base off)."""
        model = self.model
        mbs = model.mbs
        tau_m, tau_B, thrust = held
        # only the loads that change (to the bit): a torque held from the last period, an
        # arm off or saturated, costs no call into the mbs (~1 µs each, 3 µs the vector)
        old_m, old_B, old_T = previous if previous is not None else ((None,) * 6, None, None)
        for j in range(6):
            if old_m[j] is None or not _same_float(tau_m[j], old_m[j]):
                mbs.SetLoadParameter(model.motor_loads[j], "load", float(tau_m[j]))
        if old_B is None or not _same_float(tau_B, old_B):
            mbs.SetLoadParameter(model.base_torque_load, "loadVector", [0.0, 0.0, float(tau_B)])
        if old_T is None or not _same_float(thrust, old_T):
            mbs.SetLoadParameter(model.thrust_load, "loadVector", [float(thrust), 0.0, 0.0])
        if thrust_inertia is not None:
            p, state, ff = model.params, self.state, self.field_forces
            q, v = coordinates(model, state)
            # the masses of the period's middle: m(t + span/2) = m(t) − ṁ span/2, ṁ = T/(I_sp g0)
            # (physics.md §5).  Held at the start, the mean thrust acceleration T/m would be
            # low by ṁ span/(2m), a first-order bias that the coasts turn into altitude
            # (docs/exudyn.md §5, item 5); at the middle 1/m misses its mean by O(span²).
            dm_half = 0.5 * span * mass_flow(p, thrust)
            m_base = base_mass(p, state) - dm_half
            self.set_base_mass(m_base)
            tidal = ff.tidal_forces(q, v, 0.5 * span, state.r_O + 0.5 * span * state.v_O, m_base)
            thrust_inertia.hold(tidal, ff.uniform_field_matrix(m_base), thrust / (system_mass(p, state) - dm_half),
                                state.t)
            mbs.SetObjectParameter(model.carrier, "forceVector", thrust_inertia.forces(q[model.index.i_base[2]]))

    def set_base_mass(self, mass: float) -> None:
        """Give the base the mass `mass` [kg] and the solver the mass matrix with it.

        The solver computes the system mass matrix once (`reuseConstantMassMatrix`, set in
        `simulation_settings`) and keeps it; the base's mass, which the thrust burns down
        (physics.md §5), is the only one that changes, and every change of it comes through
        here and is followed by `PostInitializeSolverSpecific`, which recomputes the stored
        matrix (for this model it does nothing else: there are no Lie-group nodes).  The
        next Newton residual uses the new mass, exactly as a solver that recomputes the
        matrix at every residual: runs are identical to the last bit (docs/exudyn.md §4)."""
        if mass == self.base_mass:
            return
        self.model.mbs.SetObjectParameter(self.model.base, "mass", mass)
        self.solver.PostInitializeSolverSpecific(self.model.mbs, self.settings)
        self.base_mass = mass

    def is_step(self, held) -> bool:
        """True when the inputs jump by more than `restart_threshold` of their limits (or
        thrust switches); threshold 0: at every change."""
        limit_m, limit_B, limit_T = self.step_limits
        old = self.state.held or ((0.0,) * 6, 0.0, 0.0)
        return (max(map(abs, map(operator.sub, held[0], old[0]))) > limit_m
                or abs(held[1] - old[1]) > limit_B or abs(held[2] - old[2]) > limit_T)


@njit(cache=True)
def all_finite(q, v) -> bool:  # pragma: no cover - compiled
    """Every entry of q and v finite (one pass, no temporaries: at every sample)."""
    for i in range(q.shape[0]):
        if not math.isfinite(q[i]):
            return False
    for i in range(v.shape[0]):
        if not math.isfinite(v[i]):
            return False
    return True


def _same_float(a: float, b: float) -> bool:
    """a and b are the same number, to the sign of zero (0.0 == -0.0 would hide a change of
    a load's bits)."""
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)
