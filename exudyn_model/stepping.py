"""Stepping of the Exudyn model: one control interval at a time with the inputs held
(zero-order hold, docs/physics.md §6), exactly to the next sample.

Integration: Exudyn's generalized-α (index 3) with a fixed step, `substeps` per control
period.  One `SolveSteps` runs across control periods in a greenlet, suspended at every
control sample by a post-step function (`_Worker`), so the algorithmic state and the
modified-Newton Jacobian carry over; `stepping="period"` calls `SolveSteps` once per period
instead.  No Python user function runs inside a Newton iteration.

Also here: setting the held inputs into the mbs (`_set_inputs`), restarts of the
integrator after a change of the model or its state or a jump of the inputs (`_restart`,
`_is_step`), and the retry of a step whose Newton iteration stalled (`_retry_looser`).
The reference's mirror is `reference_model/stepping.py`; so is `rhs_timing`, the cost of one
right-hand side.
"""

from __future__ import annotations

import contextlib
import io
import math
import sys
import threading
import time
import timeit

import greenlet
import numpy as np

sys.exudynFast = True  # the engine's build: import order must not matter
# exudyn announces the fast build on stdout: keep it out of `--json` output
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu  # noqa: E402

from exudyn_model.field import _ThrustInertia  # noqa: E402
from rsmcheck.core.engine import Inputs  # noqa: E402
from rsmcheck.core.errors import SimulationDiverged  # noqa: E402


class SteppingMixin:
    """`ExudynEngine`'s stepping: `_advance` (the Engine protocol's advance), restarts,
    retries, the held inputs."""

    def _restart(self) -> None:
        """Restart the integrator from the current (modified) state: consistent
        accelerations are recomputed (after a capture, release or basis switch)."""
        tic = time.perf_counter()
        self._pause()
        self._current_to_initial()
        self.settings.timeIntegration.startTime = self.t
        self.settings.timeIntegration.endTime = self.t + self.dt
        self.solver.InitializeSolverInitialConditions(self.mbs, self.settings)
        self.stats["restarts"] += 1
        self.stats["wall_integrator_s"] += time.perf_counter() - tic

    def _current_to_initial(self) -> None:
        sd = self.mbs.systemData
        ini = exu.ConfigurationType.Initial
        sd.SetODE2Coordinates(sd.GetODE2Coordinates(), configuration=ini)
        sd.SetODE2Coordinates_t(sd.GetODE2Coordinates_t(), configuration=ini)
        sd.SetDataCoordinates(sd.GetDataCoordinates(), configuration=ini)

    def _pause(self) -> None:
        """Bring the continuous integration to a clean stop at the current control sample
        (before the state or the items are modified)."""
        self._qv_sample = None  # the state is about to change (build.py, `_qv`)
        if self._worker is not None:
            self._worker.stop()

    def _advance(self, t_next: float, inputs: Inputs) -> None:
        mbs = self.mbs
        if self._restart_pending:
            self._restart_pending = False
            self._restart()
        # plain floats: compared with the last held inputs and set into the mbs element by element
        held = (tuple(np.asarray(inputs.tau_m, float).tolist()), float(inputs.tau_B), float(inputs.thrust))
        thrust = held[2]
        if thrust != 0.0 and not self.field:
            raise SimulationDiverged(self.name, self.t, "?", "thrust without field (build with field=True)", thrust)
        span = t_next - self.t
        self._set_inputs(held, self._thrust_inertia if self.field else None, span, previous=self._held)
        self._qv_sample = None  # the solver is about to move the state
        if self.field and (thrust != 0.0) != self._pre_step_on:
            # the thrust inertia's pre-step function, registered only while there is thrust:
            # it has nothing to do without (a Python call per step, ~3 µs, 2.4 % of a coast)
            self._pre_step_on = thrust != 0.0
            mbs.SetPreStepUserFunction(self._thrust_inertia if self._pre_step_on else 0)
        if self._held is None and self.field:
            # the solver's initial accelerations were computed at build, without the field
            # forces just set: restart so that they include them (else the first steps take
            # the O(h) error of an input jump; docs/exudyn.md §5 item 5, "the first interval")
            self._restart()
        if held != self._held:
            if self.restart_on_input_change and self._is_step(held):
                # a step in the held inputs is a jump in the accelerations: restart the
                # integrator with accelerations consistent with the new inputs (else the
                # algorithmic acceleration of generalized-α carries the old ones and the
                # solution takes an O(h) error at the jump).  Small sample-to-sample changes
                # of a feedback controller are left to the integrator (O(h²) per change).
                self._restart()
        self._held = held  # also when equal: the mbs now carries these bits (-0.0 == 0.0)
        solver = self.solver
        # the runner may advance by other intervals than the case's control period (a
        # segment's own control_period, an interval clipped at a segment boundary): the step
        # stays h = control_period/substeps; an interval that is not a whole number of steps
        # is done on its own with equal steps ≤ h.  An interval longer than the control
        # period belongs to a quiet segment: with `quiet_substeps` it is cut into that many
        # steps (docs/exudyn.md §4, "Quiet segments"), and at every change of h the
        # integrator restarts with consistent accelerations
        h = self._step_length(span)
        if self._h_now is not None and abs(h - self._h_now) <= 1e-9 * h:
            h = self._h_now  # the same step: spans differ by the clock's round-off
        elif self._h_now is not None:
            self._restart()
        self._h_now = h
        n = span / h
        whole = round(n) >= 1 and abs(n - round(n)) < 1e-6
        n_steps = int(round(n)) if whole else max(1, math.ceil(n - 1e-6))
        tic = time.perf_counter()
        if self._worker is not None and whole:
            ok = self._worker.step(self.t, t_next, h)
            clock = float(mbs.systemData.GetTime())
            if ok and abs(clock - t_next) > 1e-2 * h:
                # a step count other than span/h lands a fraction h/n_steps off the sample;
                # the clock's own round-off drift stays below ~1e-7 s (docs/exudyn.md §5)
                raise SimulationDiverged(self.name, self.t, "?", f"Exudyn's clock at the sample {t_next!r} s "
                                         f"(steps of {h!r} s)", clock)
        else:
            self._pause()
            solver.it.startTime = self.t
            solver.it.endTime = t_next
            solver.it.currentStepSize = span / n_steps
            _allow_step(solver.it, h)
            solver.it.adaptiveStep = True  # (the worker turns it off) lets the last step land on t_next
            ok = solver.SolveSteps(mbs, self.settings)
        if not ok:
            ok = self._retry_looser(t_next)
        stats, it = self.stats, solver.it
        stats["wall_integrator_s"] += time.perf_counter() - tic
        stats["steps"] += n_steps
        stats["newton_iterations"] = int(it.newtonStepsCount)
        stats["jacobians"] = int(it.newtonJacobiCount)
        q, v = self._qv()
        if not ok or not (np.isfinite(q).all() and np.isfinite(v).all()):
            bad = int(np.argmax(~np.isfinite(q))) if not np.all(np.isfinite(q)) else -1
            raise SimulationDiverged(self.name, self.t, "?",
                                     "Newton failed (step reduction exhausted)" if ok is False else f"ODE2[{bad}]",
                                     float(q[bad]) if bad >= 0 else float("nan"))
        if self.field:
            self._advance_orbit(t_next - self.t, self._thrust_inertia.mean_acceleration(t_next - self.t))
            self.m_used += self._mass_flow(thrust) * (t_next - self.t)
        self.t = t_next
        q.flags.writeable = v.flags.writeable = False  # shared by every reader until it changes
        self._qv_sample = (q, v)  # the state at the sample, until it changes (`_qv`)

    def _step_length(self, span: float) -> float:
        """The generalized-α step h for a control interval of length `span` [s]:
        control_period/substeps, or span/quiet_substeps for the interval of a quiet segment
        (longer than the control period) when the engine is built with `quiet_substeps`."""
        if self.quiet_substeps is not None and self.case.solver.is_quiet(span):
            return span / self.quiet_substeps
        return self.dt / self.substeps

    def _retry_looser(self, t_next: float) -> bool:
        """Retry a step whose Newton iteration stalled, from the start of that step to
        t_next, with a 10× looser absolute tolerance; then restore it (the integrator is
        restarted at the next advance).  The stall is the round-off floor of the axial
        forces: seen in p4_hohmann chained from p3 (t = 52.43 s), the residual stuck at
        1.03e-3 N against 1.0e-3 with contractivity 0.996.  A looser tolerance everywhere
        costs accuracy (3e-3 N doubles release's momentum difference).  (Until 2026-11-24 the
        looser tolerance was set on the settings only, which the solver does not read after
        `InitializeSolver`: the retries ran at the same tolerance and passed on the fresh
        Jacobian of the new `SolveSteps`, docs/exudyn.md §4.)

        The failed step starts at t0 by Exudyn's clock, a running sum t += h that drifts
        from the runner's samples (docs/exudyn.md §5, item 5: −2.6e-11 s at 60 s of p1,
        up to ~1e-7 s in p4's burn 2), so t0 is matched to the interval within a quarter
        step, not to round-off: a 1e-12 s match refused the retry of a stall at 60.092 s
        of the full p1, 2.6e-11 s behind, and ended the mission there."""
        if self.rigid:
            return False
        sd = self.mbs.systemData
        sos = exu.ConfigurationType.StartOfStep
        q0 = np.asarray(sd.GetODE2Coordinates(configuration=sos))
        v0 = np.asarray(sd.GetODE2Coordinates_t(configuration=sos))
        t0 = float(sd.GetTime(sos))
        h = self._h_now
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(v0))):
            return False
        if not self.t - 0.25 * h <= t0 < t_next - 0.25 * h:
            raise SimulationDiverged(self.name, self.t, "?",
                                     f"Newton failed in a step that starts at {t0!r} s, not in the interval "
                                     f"[{self.t!r}, {t_next!r}) s (no retry)", t0)
        self._pause()
        sd.SetODE2Coordinates(q0)
        sd.SetODE2Coordinates_t(v0)
        sd.SetDataCoordinates(sd.GetDataCoordinates(configuration=sos))
        atol = self.newton_atol
        self._set_newton_atol(10.0 * atol)
        try:
            self._current_to_initial()
            self.settings.timeIntegration.startTime = t0
            self.settings.timeIntegration.endTime = t_next
            self.solver.InitializeSolverInitialConditions(self.mbs, self.settings)
            it = self.solver.it
            n = max(1, math.ceil((t_next - t0) / h - 1e-3))  # the clock's drift is not a step
            it.startTime, it.endTime = t0, t_next
            it.currentStepSize = (t_next - t0) / n
            _allow_step(it, h)
            it.adaptiveStep = True
            ok = bool(self.solver.SolveSteps(self.mbs, self.settings))
        finally:
            self._set_newton_atol(atol)
        self.stats["newton_retries"] += 1
        self._restart_pending = True
        return ok

    def _mass_flow(self, thrust: float) -> float:
        """Propellant flow ṁ = T/(I_sp g0) [kg/s] at thrust T [N] (physics.md §5)."""
        a = self.params.actuators
        return thrust / (a.isp * a.g0)

    def _set_newton_atol(self, atol: float) -> None:
        """The absolute Newton tolerance the solver uses from now on.  The solver keeps its
        own copy of the Newton settings, taken by `InitializeSolver` (a change of
        `settings.timeIntegration.newton` alone is not seen, not even after
        `InitializeSolverInitialConditions`), so both are set."""
        self.settings.timeIntegration.newton.absoluteTolerance = atol
        self.solver.newton.absoluteTolerance = atol

    def _set_inputs(self, held: tuple, thrust_inertia: "_ThrustInertia | None", span: float = 0.0,
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

        `previous`: the held inputs the mbs carries now (`_held`, as `advance` set them: whoever
        changes a load in between puts it back, `reactions.held_inputs`), None: unknown.  The
        thrust, constant over whole phases (the torques of a feedback controller change at
        every sample), is set only when it differs from that, to the sign of zero."""
        mbs = self.mbs
        tau_m, tau_B, thrust = held
        for j in range(6):
            mbs.SetLoadParameter(self.motor_loads[j], "load", float(tau_m[j]))
        mbs.SetLoadParameter(self.base_torque_load, "loadVector", [0.0, 0.0, float(tau_B)])
        if previous is None or not _same_float(thrust, previous[2]):
            mbs.SetLoadParameter(self.thrust_load, "loadVector", [float(thrust), 0.0, 0.0])
        if thrust_inertia is not None:
            q, v = self._qv()
            # the masses of the period's middle: m(t + span/2) = m(t) − ṁ span/2, ṁ = T/(I_sp g0)
            # (physics.md §5).  Held at the start, the mean thrust acceleration T/m would be
            # low by ṁ span/(2m), a first-order bias that the coasts turn into altitude
            # (docs/exudyn.md §5, item 5); at the middle 1/m misses its mean by O(span²).
            dm_half = 0.5 * span * self._mass_flow(thrust)
            m_base = self._mass_base() - dm_half
            self._set_base_mass(m_base)
            tidal = self._tidal_forces(q, v, 0.5 * span, self.r_O + 0.5 * span * self.v_O, m_base)
            thrust_inertia.hold(tidal, self._uniform_field_matrix(m_base), thrust / (self._system_mass() - dm_half),
                                self.t)
            mbs.SetObjectParameter(self.carrier, "forceVector", thrust_inertia.forces(q[self.i_base[2]]))

    def _set_base_mass(self, mass: float) -> None:
        """Give the base the mass `mass` [kg] and the solver the mass matrix with it.

        The solver computes the system mass matrix once (`reuseConstantMassMatrix`, set in
        `_settings`) and keeps it; the base's mass, which the thrust burns down (physics.md
        §5), is the only one that changes, and every change of it comes through here and is
        followed by `PostInitializeSolverSpecific`, which recomputes the stored matrix (for
        this model it does nothing else: there are no Lie-group nodes).  The next Newton
        residual uses the new mass, as it did when the matrix was recomputed at every
        residual; runs are identical to the last bit (docs/exudyn.md §4)."""
        if mass == self._base_mass:
            return
        self.mbs.SetObjectParameter(self.base, "mass", mass)
        self.solver.PostInitializeSolverSpecific(self.mbs, self.settings)
        self._base_mass = mass

    def _is_step(self, held) -> bool:
        """True when the inputs jump by more than `restart_threshold` of their limits (or
        thrust switches); threshold 0: at every change."""
        a = self.params.actuators
        f = self.restart_threshold
        old = self._held or ((0.0,) * 6, 0.0, 0.0)
        return (max(abs(x - y) for x, y in zip(held[0], old[0])) > f * self.params.motor.torque_max
                or abs(held[1] - old[1]) > f * a.torque_max or abs(held[2] - old[2]) > f * a.thrust)


def _allow_step(it, h: float) -> None:
    """Let Exudyn's solver take the step h [s]: it clips every step to `maxStepSize`, which
    `InitializeSolver` and every restart set from the settings (control_period/substeps, to
    round-off: (t + Δt − t)/substeps, 1e-11 off at t = 60 s).  Raised only for a longer
    step (a quiet segment's), so that the default steps stay bit for bit what they were."""
    if it.maxStepSize < h * (1.0 - 1e-6):
        it.maxStepSize = h


def _same_float(a: float, b: float) -> bool:
    """a and b are the same number, to the sign of zero (0.0 == -0.0 would hide a change of
    a load's bits)."""
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


# the thread's suspended `_Worker` run, at most one (`_Worker`'s docstring: pybind11's call stack)
_SUSPENDED = threading.local()


class _Worker:
    """Continuous integration across control periods.

    `SolveSteps` forces a new Jacobian (and factorisation) each time it is called: 75 % of
    the cost when it is called once per 1 ms control period.  Here one `SolveSteps` runs in
    a greenlet (a coroutine on the caller's own thread) over many periods, and a post-step
    function (Python, once per time step, no computation) switches back to the runner at
    every control sample: the runner reads sensors and observables and sets the held inputs
    while the solver is suspended, then switches in again to run to the next sample.  Before
    the model or its state is modified (capture, release, restart) the run is ended cleanly
    at the current sample (its end time is set to now).  Fixed steps (no step-size
    adaptation), so every control sample is a step boundary; a Newton failure ends the run
    and is reported as divergence.

    Until 2026-11-26 the solver ran in a worker thread handed over with two events: a
    round trip of 45–66 µs on this 2-core machine (a wake-up across cores), ~10 % of a
    sample; a greenlet switch stays on one thread (docs/exudyn.md §4, "Continuous stepping").

    One suspended run per thread: pybind11 keeps a per-thread stack of the calls in
    progress (`loader_life_support`), and a `SolveSteps` that returns while another
    engine's, started after it, is still suspended pops that stack out of order and aborts
    the process.  So starting a run ends the thread's other suspended run, if any, at its
    sample (`_SUSPENDED`); that engine's next interval starts a new `SolveSteps` (a new
    Jacobian).  Only engines advanced in turn on one thread (tests) meet this.  For the same
    reason nothing ends a run from a finalizer (it may run inside a pybind11 call): the run
    of a dropped engine stays suspended until the next run on its thread ends it.
    """

    def __init__(self, engine: SteppingMixin):
        # no reference to the engine itself (the suspended greenlet would keep it alive)
        self.mbs, self.solver, self.settings = engine.mbs, engine.solver, engine.settings
        self.h = engine.dt / engine.substeps  # the fixed step of the running SolveSteps
        self.target = math.inf  # suspend at the end of the step that reaches this time
        self.command = "continue"
        self.run: greenlet.greenlet | None = None
        self.ok = True
        self.t_start = 0.0
        # a new Jacobian every `jacobian_period` s of flight (None: when Exudyn asks for one)
        self.jacobian_period = engine.jacobian_period
        self.next_jacobian = math.inf  # the clock time after which the next step gets one
        self.jacobian_requested = False
        self.mbs.SetPostStepUserFunction(self._post_step)

    def _post_step(self, mbs, t: float) -> bool:
        run = self.run
        if run is None or greenlet.getcurrent() is not run or t <= self.t_start + 1e-12:
            return True  # a SolveSteps of the engine's own (a retry, `stepping="period"`)
        if self.jacobian_requested or t >= self.next_jacobian:
            self._age_jacobian(t)
        if not self.ends_interval(t):
            return True  # a step inside the interval
        try:
            run.parent.switch()  # to the runner, until `step` or `stop` switches back
        except greenlet.GreenletExit:  # the greenlet is collected while suspended
            self.command = "stop"
        if self.command == "stop":
            self.solver.it.endTime = t  # the run ends here, cleanly, at this sample
        return True

    def _age_jacobian(self, t: float) -> None:
        """Ask for a new Newton Jacobian at the start of the next step when the last one is
        `jacobian_period` old, and stop asking after that step (Exudyn's solver reads
        `modifiedNewtonJacUpdatePerStep` from its own Newton settings at every step).
        Modified Newton keeps its Jacobian until an iteration contracts by less than ½; one
        that has aged by the links' turning and bending still contracts by far more than
        that, but no longer takes a step's residual below the tolerance in one iteration
        (docs/exudyn.md §4, "The Jacobian's age")."""
        ask = not self.jacobian_requested
        self.solver.newton.modifiedNewtonJacUpdatePerStep = ask
        self.jacobian_requested = ask
        if ask:
            self.next_jacobian = t + self.jacobian_period

    def ends_interval(self, t: float) -> bool:
        """True for the step (ending at t by Exudyn's clock) that ends the current
        control interval.  Found within a quarter step: Exudyn's clock (t += h) drifts from
        the runner's samples by up to ~1e-7 s over a long run (docs/exudyn.md §5, item 5);
        matched to 1e-6 h it ran one step past a sample once the drift exceeded 5e-10 s,
        which then counted as a failed step and a retry."""
        return t >= self.target - 0.25 * self.h

    def _solve(self) -> None:
        try:
            self.ok = bool(self.solver.SolveSteps(self.mbs, self.settings))
        except Exception:  # noqa: BLE001 — reported to the runner as a failed run
            self.ok = False

    def step(self, t: float, t_next: float, h: float) -> bool:
        """Integrate from t to t_next (the next control sample, a whole number of steps h
        on); False when the solver failed (the caller checks that its clock is at t_next).
        A new h ends the running SolveSteps at t and starts one with the new step."""
        if h != self.h:
            self.stop()
            self.h = h
        self.target = t_next
        if self.run is None:
            other = getattr(_SUSPENDED, "worker", None)
            if other is not None and other is not self:
                other.stop()  # one suspended run per thread (class docstring)
            solver = self.solver
            solver.it.startTime = t
            solver.it.endTime = 1e30
            solver.it.adaptiveStep = False
            solver.it.currentStepSize = self.h
            _allow_step(solver.it, self.h)
            self.t_start = t
            # a new SolveSteps starts with a new Jacobian
            self.next_jacobian = math.inf if self.jacobian_period is None else t + self.jacobian_period
            self.ok = True
            self.run = greenlet.greenlet(self._solve)
            _SUSPENDED.worker = self
        else:
            self.command = "continue"
        self.run.switch()
        if self.run.dead or not self.ok:  # SolveSteps returned before the sample: failed
            self._ended()
            return False
        return True

    def stop(self) -> None:
        if self.run is not None and not self.run.dead:
            self.command = "stop"
            self.run.switch()  # SolveSteps ends at the current sample and returns
        self._ended()

    def _ended(self) -> None:
        self.run = None
        if self.jacobian_requested:  # not carried into another SolveSteps (a retry, a restart)
            self.solver.newton.modifiedNewtonJacUpdatePerStep = False
            self.jacobian_requested = False
        if getattr(_SUSPENDED, "worker", None) is self:
            _SUSPENDED.worker = None


def rhs_timing(case, n: int = 2000, **engine_options) -> dict[str, float]:
    """µs per evaluation of Exudyn's right-hand side at the initial state of `case` (best of
    3): `call_us` one `ComputeODE2RHS` from Python (through `reactions.ConstraintForces`),
    `compiled_us` NaN (the solver's own calls from C++ cannot be timed alone), `states` the
    size of the first-order state (2 × ODE2 coordinates).  `engine_options` go to
    `ExudynEngine`.  The mirror of `reference_model.stepping.rhs_timing`."""
    from exudyn_model.engine import ExudynEngine  # the engine imports this module
    from exudyn_model.reactions import ConstraintForces

    engine = ExudynEngine(case, **engine_options)
    cf = ConstraintForces(engine.mbs)
    cf.rhs()
    call = min(timeit.repeat(cf.rhs, number=n, repeat=3)) / n * 1e6
    return {"call_us": call, "compiled_us": math.nan, "states": 2 * cf.n2}
