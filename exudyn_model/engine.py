"""The paper's robot from Exudyn's general items, as an `rsmcheck.core.engine.Engine`: a facade
over parts that each own their data, named by their job as in `reference_model/` (so the
two engines read side by side).  As in Pinocchio, what does not change during a run (the
model) is kept apart from what does (the state), and the algorithms are functions or
objects that are handed both:

    options.py     EngineOptions: the resolved options (fixed for a run)
    build.py       ExudynModel: the mbs (base, target, links, hubs, joints, rotors, grasps,
                   bistops, actuators, the field carrier), the numbers of its items, the link
                   mesh's matrices; `build_model` makes it (`links.py`: one link's elements)
    indices.py     IndexTables: the global ODE2 indices the engine reads (model.index)
    state.py       EngineState: time, grasps and grasp points, the links' bases, the orbit
                   of O, the propellant used, the held inputs, the sample's coordinates,
                   the solver's counters
    stepper.py     Stepper: the implicit solver and its settings, advance, restarts,
                   retries, setting the held inputs into the mbs
    worker.py      Worker: the continuous run across control periods (a greenlet)
    field.py       FieldForces: the tidal field and the thrust inertia as generalised
                   forces, the orbit of O
    switching.py   capture, release, basis switch, plastic impact (functions)
    observe.py     Observer: sensors, observables, energy, momentum
    reactions.py   ConstraintForces: grasp forces by an index-1 solve with Exudyn's own M, G, f
    exact_state.py export and import of the exact state for phase chaining
    modes.py       linearisation: the linear plant, coupled frequencies
    stepping.py    rhs_timing, the cost of one right-hand side

`ExudynEngine` resolves the options, makes the parts (the model, the state, the field
forces, the stepper, the constraint forces, the observer; each receives the others it
needs) and answers the Engine protocol by delegating to them.  The model and its reasons:
`build.py` and docs/exudyn.md.
"""

from __future__ import annotations

import math

import numpy as np

from exudyn_model import exact_state, links, switching
from exudyn_model.build import build_model, initial_basis
from exudyn_model.field import FieldForces
from exudyn_model.observe import Observer
from exudyn_model.options import EngineOptions
from exudyn_model.reactions import ConstraintForces
from exudyn_model.state import EngineState, coordinates
from exudyn_model.stepper import Stepper
from rsmcheck.core.cases import Case, first_given
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.plugins import settings_of
from rsmcheck.driver.initial import StartState, build_initial
from rsmcheck.core.params import Params
from rsmcheck.core.store import package_versions

#: Default solver settings (convergence study in docs/exudyn.md).
SUBSTEPS_DEFAULT = 2  # generalized-α steps per 1 ms control period
SPECTRAL_RADIUS_DEFAULT = 0.6  # docs/exudyn.md §4: ≤ 0.6 keeps switched multipliers clean
#: seconds of flight between the Newton Jacobians of the continuous stepping (docs/exudyn.md
#: §4, "The Jacobian's age"): modified Newton keeps a Jacobian until an iteration contracts
#: by less than ½, long after it has aged enough to cost a second iteration per step
JACOBIAN_PERIOD_DEFAULT = 0.2
NEWTON_RTOL_DEFAULT = 1e-8
#: Absolute Newton tolerance of the flexible model [N], per N of axial stiffness EA: the
#: ANCF axial forces carry a round-off floor ∝ ε_mach·EA (EA·ε·|q|/le and the cancellation
#: in the strain of a stiff element), so a purely relative test stalls whenever a step's
#: initial residual is small (smooth drift).  Measured: 100·ε·EA stalls (flex_arm_step,
#: EA = 1e5·EI), 1000·ε·EA runs every case: 1.0e-3 N at EA = 1e5·EI, an acceleration of
#: 3e-5 m/s² on a 36 kg link for one step.  Rigid links have no such floor.
NEWTON_ATOL_PER_EA = 1000 * np.finfo(float).eps
NEWTON_ATOL_RIGID = 1e-10
#: restart generalized-α when a held input jumps by more than this fraction of its limit:
#: a jump carried by the algorithmic acceleration leaves an O(h) error; below the threshold
#: (the sample-to-sample changes of a feedback controller) it is left to the integrator,
#: which makes controlled cases converge at first order in h (docs/exudyn.md §6);
#: 0 restarts at every change (second order again, one factorisation per period)
RESTART_THRESHOLD_DEFAULT = 0.01


class ExudynEngine:
    """The system of docs/physics.md built from Exudyn items, stepping through a case.

    Parts (attributes): `options` (EngineOptions), `model` (build.ExudynModel, with
    `model.index`), `state` (state.EngineState), `field_forces` (field.FieldForces, None
    without the field machinery), `stepper` (stepper.Stepper), `constraint_forces`
    (reactions.ConstraintForces), `observer` (observe.Observer).  The resolved options are
    also attributes of their own (`substeps`, `newton_atol`, ...).

    Options:
      rigid           rigid links (the rigid-equivalence check against the reference with 0 modes)
      n_elements      ANCF elements per link (default: the case's [exudyn] table, else 8)
      substeps        generalized-α steps per control period (h = control_period/substeps;
                      default: the case's [exudyn] table, else 2; so are constraints and
                      restart_threshold)
      quiet_substeps  steps per control interval of a quiet segment (an interval longer
                      than the case's control period, e.g. a coast sampled at 5 ms); None
                      (default): the step h of the other intervals.  A study option: no case
                      can afford a longer step there (docs/exudyn.md §4, "Quiet segments")
      spectral_radius ρ∞ of generalized-α
      newton_rtol     relative Newton tolerance
      field           build the field/thrust machinery (default: when the case has an orbit)
      stepping        "continuous" (one SolveSteps across control periods) or "period"
      constraints     "index3": generalized-α with position-level constraints (default);
                      "index2": Newmark/trapezoidal with velocity-level constraints, whose
                      multipliers (reaction forces) have a round-off floor ∝ 1/h, not 1/h²
      axial_damping   factor on the axial Kelvin–Voigt damping η·EA of the links (default 1)
      restart_threshold  input jump (fraction of its limit) that restarts the integrator
      newton_atol     absolute Newton tolerance [N] (default: the case's [exudyn] table, else
                      1000·ε·EA for flexible links, 1e-10 N for rigid ones), times the case's
                      `exudyn.newton_atol_scale` (1; the gate's decision perturbation)
      jacobian_per_step  a new Newton Jacobian at the start of every step (Exudyn's
                      modifiedNewtonJacUpdatePerStep; default: the case's [exudyn] table, else
                      False: modified Newton keeps it across steps).  Modified Newton stops
                      just below newton_atol, and the torque of that residual about the origin
                      drifts the angular momentum by ~h·wᵀr per step (docs/exudyn.md §8)
      jacobian_period a new Newton Jacobian every this many seconds of flight in the
                      continuous stepping [s] (default 0.2); None or inf: only when
                      Exudyn's modified Newton asks for one (contractivity > ½).  Without
                      effect with jacobian_per_step
      start           the end state of a previous run this run continues from
                      (rsmcheck.driver.initial.StartState), None: the case's [initial]
    """

    name = "exudyn"

    def __init__(self, case: Case, params: Params | None = None, rigid: bool = False,
                 n_elements: int | None = None, substeps: int | None = None,
                 quiet_substeps: int | None = None,
                 spectral_radius: float = SPECTRAL_RADIUS_DEFAULT, newton_rtol: float = NEWTON_RTOL_DEFAULT,
                 newton_atol: float | None = None, jacobian_per_step: bool | None = None,
                 jacobian_period: float | None = JACOBIAN_PERIOD_DEFAULT,
                 field: bool | None = None, restart_on_input_change: bool = True,
                 stepping: str = "continuous", constraints: str | None = None, axial_damping: float = 1.0,
                 restart_threshold: float | None = None, start: StartState | None = None):
        self.case = case
        self.params = params or case.params
        self.rigid = bool(rigid)
        # explicit options > the case's [exudyn] table > the engine defaults
        given = settings_of(case, self.name)  # the case's [exudyn]
        self.n_elements = int(first_given(n_elements, given.n_elements, links.N_ELEMENTS_DEFAULT))
        self.substeps = int(first_given(substeps, given.substeps, SUBSTEPS_DEFAULT))
        self.quiet_substeps = None if quiet_substeps is None else int(quiet_substeps)
        if self.quiet_substeps is not None and self.quiet_substeps < 1:
            raise ValueError(f"quiet_substeps must be ≥ 1, got {quiet_substeps!r}")
        self.spectral_radius = float(spectral_radius)
        self.newton_rtol = float(newton_rtol)
        p = self.params
        self.newton_atol = float(NEWTON_ATOL_RIGID if newton_atol is None and self.rigid else
                                 first_given(newton_atol, given.newton_atol,
                                             NEWTON_ATOL_PER_EA * p.link.axial_to_bending * p.link.ei)
                                 ) * first_given(given.newton_atol_scale, 1.0)
        self.jacobian_per_step = bool(first_given(jacobian_per_step, given.jacobian_per_step, False))
        if jacobian_period is not None and not (isinstance(jacobian_period, (int, float)) and jacobian_period > 0.0):
            raise ValueError(f"jacobian_period must be a positive number of seconds, inf or None, got {jacobian_period!r}")
        self.jacobian_period = (None if self.jacobian_per_step or jacobian_period is None or math.isinf(jacobian_period)
                                else float(jacobian_period))
        self.orbit = bool(case.orbit)
        self.field = self.orbit if field is None else bool(field)
        self.restart_on_input_change = bool(restart_on_input_change)
        self.restart_threshold = float(first_given(restart_threshold, given.restart_threshold,
                                                   RESTART_THRESHOLD_DEFAULT))
        if stepping not in ("continuous", "period"):
            raise ValueError(f"stepping must be 'continuous' or 'period', got {stepping!r}")
        self.stepping = stepping
        constraints = first_given(constraints, given.constraints, "index3")
        if constraints not in ("index3", "index2"):
            raise ValueError(f"constraints must be 'index3' or 'index2', got {constraints!r}")
        self.constraints = constraints
        self.axial_damping = float(axial_damping)
        self.dt = case.solver.control_period
        # ---- the parts -------------------------------------------------------------------
        self.options = EngineOptions(
            rigid=self.rigid, n_elements=self.n_elements, substeps=self.substeps, quiet_substeps=self.quiet_substeps,
            spectral_radius=self.spectral_radius, newton_rtol=self.newton_rtol, newton_atol=self.newton_atol,
            jacobian_per_step=self.jacobian_per_step, jacobian_period=self.jacobian_period, orbit=self.orbit,
            field=self.field, restart_on_input_change=self.restart_on_input_change,
            restart_threshold=self.restart_threshold, stepping=self.stepping, constraints=self.constraints,
            axial_damping=self.axial_damping, dt=self.dt)
        init = build_initial(case, p, start)
        self.state = EngineState(
            t=0.0, grasp_on=np.array(init.grasp, dtype=np.int64), rho_G=np.array(init.rho_G, float),
            basis=initial_basis(init.grasp), r_O=np.array(init.orbit_r, float), v_O=np.array(init.orbit_v, float),
            m_used=float(init.m_used), start_label="initial" if start is None else "rigid end state")
        self._base_start = (np.asarray(init.base_pose, float), np.asarray(init.base_rate, float))
        self.model = build_model(p, init, self.state.rho_G, self.state.basis, self.rigid, self.n_elements,
                                 self.axial_damping, self.field)
        self.field_forces = FieldForces(self.model, self.orbit, float(init.base_pose[2])) if self.field else None
        self.stepper = Stepper(self.model, self.options, self.state, self.field_forces,
                               is_quiet=case.solver.is_quiet, name=self.name)
        self.constraint_forces = ConstraintForces(self.model.mbs)
        self.observer = Observer(self.model, self.state, self.stepper, self.constraint_forces, self.orbit,
                                 capture_arm=case.capture.arm,
                                 capture_point=np.asarray(p.geometry.grasp_T(case.capture.arm), float))

    # ---- the parts' data the orchestration and the tests read ----------------------------
    @property
    def mbs(self):
        """The Exudyn system (`model.mbs`)."""
        return self.model.mbs

    @property
    def stats(self) -> dict:
        """The solver's counters (`state.stats`)."""
        return self.state.stats

    def coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """Absolute ODE2 coordinates q and velocities q̇ (read-only; `state.coordinates`)."""
        return coordinates(self.model, self.state)

    # ---- Engine protocol (rsmcheck.core.engine.Engine) ------------------------------------
    def time(self) -> float:
        return self.state.t

    def advance(self, t_next: float, inputs: Inputs) -> None:
        self.stepper.advance(t_next, inputs)

    def sensors(self) -> Sensors:
        return self.observer.sensors()

    def observe(self, inputs: Inputs) -> dict:
        return self.observer.observables(inputs)

    def capture(self, arm: int) -> dict[str, float]:
        return switching.capture(self.model, self.state, self.stepper, self.constraint_forces, arm)

    def release(self, arm: int) -> dict[str, float]:
        return switching.release(self.model, self.state, self.stepper, self.constraint_forces, arm)

    def solver_settings(self) -> dict:
        stats = self.state.stats
        return {"integrator": "Exudyn generalized-alpha, index 3, fixed step",
                "step": self.dt / self.substeps, "substeps": self.substeps,
                "spectral_radius": self.spectral_radius, "newton_rtol": self.newton_rtol, "newton_atol": self.newton_atol,
                "jacobian_per_step": self.jacobian_per_step, "control_period": self.dt,
                "links": "rigid bodies" if self.rigid else f"ANCFCable2D x {self.n_elements}",
                "steps": stats["steps"], "newton_iterations": stats["newton_iterations"],
                "jacobians": stats["jacobians"], "restarts": stats["restarts"],
                "newton_retries": stats["newton_retries"],
                "wall_integrator_s": stats["wall_integrator_s"],
                "stepping": self.stepping, "constraints": self.constraints,
                "axial_damping": self.axial_damping,
                "restart_threshold": self.restart_threshold, "start": self.state.start_label,
                **({} if self.quiet_substeps is None else {"quiet_substeps": self.quiet_substeps}),
                **({} if self.jacobian_period is None else {"jacobian_period": self.jacobian_period})}

    def versions(self) -> dict[str, str]:
        return package_versions("rsmcheck", "exudyn", "numpy")

    # ---- exact state for phase chaining (rsmcheck.orchestration.chain) -------------------------------
    def export_state(self) -> dict:
        """The exact state (`exact_state.export_state`)."""
        return exact_state.export_state(self.name, self.model, self.state)

    def import_state(self, exact: dict) -> None:
        """Continue from `export_state()` of an engine of the same model
        (`exact_state.import_state`; another model size: from the rigid end state)."""
        exact_state.import_state(self.name, self.model, self.state, self.stepper, exact, self._base_start)
