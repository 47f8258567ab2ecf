"""The paper's robot from Exudyn's general items, as an `rsmcheck.core.engine.Engine`: a facade
over the modules that do the work, each named by its job as in `reference_model/` (so the
two engines read side by side):

    build.py      the mbs: base, target, links (`links.py`), hubs, joints, rotors, grasps,
                  bistops, actuators, the field carrier; index tables; solver settings
    stepping.py   advance: the solver's greenlet (`_Worker`), restarts, retries, inputs
    field.py      the tidal field and the thrust inertia as generalised forces, the orbit of O
    switching.py  capture, release, basis switch, plastic impact
    observe.py    sensors, observables, energy, momentum
    reactions.py  grasp forces by an index-1 solve with Exudyn's own M, G, f
    modes.py      linearisation: the linear plant, coupled frequencies

`ExudynEngine` is composed of one mixin per module (`BuildMixin`, `SteppingMixin`,
`FieldMixin`, `SwitchingMixin`, `ObserveMixin`); it holds the options and the state between
control samples (the mbs, time t, grasps, held points, the orbit of O, the propellant
used), answers the Engine protocol and exports/imports the exact state for chaining.
The model and its reasons: `build.py` and docs/exudyn.md.
"""

from __future__ import annotations

import math

import numpy as np

from exudyn_model import links
from exudyn_model.build import PP, BuildMixin
from exudyn_model.field import FieldMixin
from exudyn_model.observe import ObserveMixin
from exudyn_model.stepping import SteppingMixin, _Worker
from exudyn_model.switching import SwitchingMixin
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


class ExudynEngine(BuildMixin, SteppingMixin, FieldMixin, SwitchingMixin, ObserveMixin):
    """The system of docs/physics.md built from Exudyn items, stepping through a case.

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
        self.mesh = links.LinkMesh(self.n_elements, p.link.length, p.link.rho_a)
        self.I0 = p.link.mass * p.link.length**2 / 3.0
        init = build_initial(case, p, start)
        self.grasp_on = np.array(init.grasp, dtype=np.int64)
        self.rho_G = np.array(init.rho_G, float)
        self.r_O = np.array(init.orbit_r, float)
        self.v_O = np.array(init.orbit_v, float)
        self.m_used = float(init.m_used)
        self.t = 0.0
        self.capture_arm = case.capture.arm
        self.capture_point = np.asarray(p.geometry.grasp_T(case.capture.arm), float)
        self._held: tuple | None = None
        self._qv_sample: tuple[np.ndarray, np.ndarray] | None = None  # `_qv`
        self.stats = {"steps": 0, "newton_iterations": 0, "jacobians": 0, "restarts": 0, "newton_retries": 0,
                      "wall_integrator_s": 0.0}  # s waiting on Exudyn's solver (rsmcheck bench)
        self._restart_pending = False
        self._h_now: float | None = None  # the generalized-α step of the last interval [s]
        self.start_label = "initial" if start is None else "rigid end state"
        self._base_start = (np.asarray(init.base_pose, float), np.asarray(init.base_rate, float))
        self._build(init)
        self._index()
        self._init_solver()
        # a run left suspended when the engine is dropped is ended by the next run started on
        # this thread (`_Worker`: never from a finalizer, which may run inside a pybind11 call)
        self._worker = _Worker(self) if stepping == "continuous" else None

    # ---- Engine protocol (rsmcheck.core.engine.Engine) ------------------------------------
    def time(self) -> float:
        return self.t

    def advance(self, t_next: float, inputs: Inputs) -> None:
        self._advance(t_next, inputs)  # stepping.py

    def sensors(self) -> Sensors:
        return self._sensors()  # observe.py

    def observe(self, inputs: Inputs) -> dict:
        return self._observables(inputs)  # observe.py

    def capture(self, arm: int) -> dict[str, float]:
        return self._capture(arm)  # switching.py

    def release(self, arm: int) -> dict[str, float]:
        return self._release(arm)  # switching.py

    def solver_settings(self) -> dict:
        return {"integrator": "Exudyn generalized-alpha, index 3, fixed step",
                "step": self.dt / self.substeps, "substeps": self.substeps,
                "spectral_radius": self.spectral_radius, "newton_rtol": self.newton_rtol, "newton_atol": self.newton_atol,
                "jacobian_per_step": self.jacobian_per_step, "control_period": self.dt,
                "links": "rigid bodies" if self.rigid else f"ANCFCable2D x {self.n_elements}",
                "steps": self.stats["steps"], "newton_iterations": self.stats["newton_iterations"],
                "jacobians": self.stats["jacobians"], "restarts": self.stats["restarts"],
                "newton_retries": self.stats["newton_retries"],
                "wall_integrator_s": self.stats["wall_integrator_s"],
                "stepping": self.stepping, "constraints": self.constraints,
                "axial_damping": self.axial_damping,
                "restart_threshold": self.restart_threshold, "start": self.start_label,
                **({} if self.quiet_substeps is None else {"quiet_substeps": self.quiet_substeps}),
                **({} if self.jacobian_period is None else {"jacobian_period": self.jacobian_period})}

    def versions(self) -> dict[str, str]:
        return package_versions("rsmcheck", "exudyn", "numpy")

    # ---- exact state for phase chaining (rsmcheck.orchestration.chain) -------------------------------
    def export_state(self) -> dict:
        """Everything needed to continue this run in a new engine of the same model: absolute
        ODE2 coordinates and velocities (with the link deformation), the bistop data
        coordinates, grasp flags, held points, terminal-link bases."""
        q, v = self._qv()
        return {"engine": self.name, "rigid": self.rigid, "n_elements": self.n_elements,
                "q": q.copy(), "v": v.copy(), "data": np.asarray(self.mbs.systemData.GetDataCoordinates(), float),
                "grasp_on": self.grasp_on.copy(), "rho_G": self.rho_G.copy(),
                "basis": [it.basis for it in self.links], "base_pose": q[self.i_base].copy(),
                "base_rate": v[self.i_base].copy()}

    def import_state(self, exact: dict) -> None:
        """Continue from `export_state()` of an engine of the same model (same links, element
        count, grasps and bases: the model is built from the rigid part of the same end
        state).  A shift of O between the phases (placing O on the orbit at the system COM,
        rsmcheck.orchestration.chain) moves every position coordinate by the base's shift.  An exact state
        of another model size is not used: the run starts from the rigid end state."""
        q_new, v_new = self._qv()
        same = (exact.get("engine") == self.name and bool(exact.get("rigid")) == self.rigid
                and int(exact.get("n_elements", -1)) == self.n_elements
                and len(exact.get("q", ())) == len(q_new)
                and list(exact.get("grasp_on", ())) == list(self.grasp_on)
                and list(exact.get("basis", ())) == [it.basis for it in self.links])
        if not same:
            return
        shift = self._base_start[0][:2] - np.asarray(exact["base_pose"], float)[:2]
        shift_v = self._base_start[1][:2] - np.asarray(exact["base_rate"], float)[:2]
        q = np.asarray(exact["q"], float)
        v = np.asarray(exact["v"], float)
        for i in self._position_coordinates():
            q[i] += shift
            v[i] += shift_v
        for it in self.links:  # a PP link's P stays parked at this model's reference (build.py)
            if it.p_node is not None and it.basis == PP:
                q[it.p_coords], v[it.p_coords] = self.q_ref[it.p_coords], 0.0
        sd = self.mbs.systemData
        sd.SetODE2Coordinates(q - self.q_ref)
        sd.SetODE2Coordinates_t(v)
        sd.SetDataCoordinates(np.asarray(exact["data"], float))
        self.rho_G = np.asarray(exact["rho_G"], float).copy()
        for k in range(2):
            self.mbs.SetMarkerParameter(self.grasp_markers[k], "localPosition", [*self.rho_G[k], 0.0])
        self.start_label = "exact end state"
        self._restart()

    def _position_coordinates(self) -> list[np.ndarray]:
        """Global ODE2 indices (x, y) of every node position (rigid-body and ANCF nodes)."""
        out = []
        for n in range(self.mbs.systemData.NumberOfNodes()):
            if self.mbs.GetNode(n)["nodeType"] in ("RigidBody2D", "Point2DSlope1"):
                out.append(self.mbs.GetNodeODE2Index(n) + np.arange(2))
        return out
