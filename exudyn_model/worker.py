"""Continuous integration of the Exudyn model across control periods: one `SolveSteps`
in a greenlet, suspended at every control sample by a post-step function (`Worker`), so
that the generalized-α state and the modified-Newton Jacobian carry over from one control
period to the next.  Used by `exudyn_model.stepper.Stepper` with `stepping="continuous"`.
"""

from __future__ import annotations

import math
import threading

import greenlet


def allow_step(it, h: float) -> None:
    """Let Exudyn's solver take the step h [s]: it clips every step to `maxStepSize`, which
    `InitializeSolver` and every restart set from the settings (control_period/substeps, to
    round-off: (t + Δt − t)/substeps, 1e-11 off at t = 60 s).  Raised only for a longer
    step (a quiet segment's), so that the default steps stay bit for bit what they were."""
    if it.maxStepSize < h * (1.0 - 1e-6):
        it.maxStepSize = h


# the thread's suspended `Worker` run, at most one (`Worker`'s docstring: pybind11's call stack)
_SUSPENDED = threading.local()


class Worker:
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

    A greenlet switch stays on one thread: a worker thread handed over with two events
    costs a round trip of 45–66 µs on a 2-core machine (a wake-up across cores), ~10 % of a
    sample (docs/exudyn.md §4, "Continuous stepping").

    One suspended run per thread: pybind11 keeps a per-thread stack of the calls in
    progress (`loader_life_support`), and a `SolveSteps` that returns while another
    engine's, started after it, is still suspended pops that stack out of order and aborts
    the process.  So starting a run ends the thread's other suspended run, if any, at its
    sample (`_SUSPENDED`); that engine's next interval starts a new `SolveSteps` (a new
    Jacobian).  Only engines advanced in turn on one thread (tests) meet this.  For the same
    reason nothing ends a run from a finalizer (it may run inside a pybind11 call): the run
    of a dropped engine stays suspended until the next run on its thread ends it.
    """

    def __init__(self, mbs, solver, settings, h: float, jacobian_period: float | None):
        """`mbs` with its implicit `solver` and `settings`; `h` the step [s];
        `jacobian_period` [s] of flight between Newton Jacobians, None: when Exudyn's modified
        Newton asks for one.  Holds no reference to the engine or its parts (the suspended
        greenlet would keep them alive)."""
        self.mbs, self.solver, self.settings = mbs, solver, settings
        self.h = h  # the fixed step of the running SolveSteps
        self.target = math.inf  # suspend at the end of the step that reaches this time
        self.command = "continue"
        self.run: greenlet.greenlet | None = None
        self.ok = True
        self.t_start = 0.0
        # a new Jacobian every `jacobian_period` s of flight (None: when Exudyn asks for one)
        self.jacobian_period = jacobian_period
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
        matched to 1e-6 h, a run would go one step past a sample once the drift exceeds
        5e-10 s, and that step would count as a failed step and a retry."""
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
            allow_step(solver.it, self.h)
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
