"""The reference model as an `rsmcheck.core.engine.Engine`: a facade over the modules that do
the work, each named by its job as in `exudyn_model/` (so the two engines read side by side).

The engine holds three parts, the Pinocchio way: the model, which does not change during a
run (`ReferenceModel`: parameters, modal bases, the kernels' arrays); the state, which the
algorithms read and write (`x`, the switching configuration `cfg`, time `t`); and the
`Stepper`, which owns the integrators' settings, carried steps, counters and kept
matrices.  Observing and switching are functions of (model, state).

    build.py         parameters → the model (`ReferenceModel`), the state layout, the
                     switching configuration, the initial state
    model_arrays.py  the data of the compiled kernels: the ODE state's coordinates, the
                     indices of the scalar and input vectors, `ModelArrays`, `Switches`
    kinematics.py    kinematics (A.1, A.2): frames, Jacobians, J̇q̇; joint and wrist angles
    link.py          one link in Newtonian coordinates (A.3) and the field over its mass
    system.py        the coupled system (3)–(12): M_g, f, the constraint rows
    solve.py         its constraint forces (11) and accelerations (6)
    ode.py           the right-hand side ẋ = rhs(x, u)
    measures.py      compiled sensor values and momentum of a state
    field.py         the tidal field about the co-moving point O (kernels of link, system)
    stepper.py       the `Stepper`: one control interval by DP5(4) (dopri5.py), TR-BDF2
                     (trbdf2.py) or the IMEX pair (imex.py, integration.py); a quiet
                     segment's by the quiet integrator
    stepping.py      `rhs_timing`, the cost of one right-hand side (rsmcheck bench)
    switching.py     capture, release, basis switch, plastic impact
    observe.py       sensors, observables, energy, momentum
    modes.py         linearisation: the linear plant, coupled frequencies
    beam_modes.py    the links' modal bases (shapes, integrals)
    simulate.py      one call from a case to a trajectory
"""

from __future__ import annotations

import numpy as np

from reference_model import observe, switching
from reference_model.build import STATIC_MODES_DEFAULT, Configuration, ReferenceModel, initial_state
from reference_model.measures import sense
from reference_model.model_arrays import input_vector
from reference_model.settings import INTEGRATORS
from reference_model.stepper import Stepper
from rsmcheck.core.cases import Case, first_given
from rsmcheck.core.plugins import settings_of
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.driver.initial import StartState, build_initial, orbit_start
from rsmcheck.core.params import Params
from rsmcheck.core.store import package_versions

H_MAX = 0.05  # s, explicit DP5(4): stability bounds h near 2.5 ms anyway
H_MAX_IMPLICIT = 1.0  # s, TR-BDF2 and IMEX: accuracy bounds the step


class ReferenceEngine:
    """Kane–Newton reference model stepping through a case.

    Options: n_modes (eigenmodes per link, default the case's), rtol, integrator ("dopri5",
    "trbdf2" or "imex"), quiet_integrator (that of the control intervals longer than the
    case's control period, docs/physics.md §7), h_max (largest step), static_modes
    (docs/physics.md §2.4); each defaults to the case's [solver] / [reference] table, else
    the engine's default.  `start`: the
    end state of a previous run this run continues from (rsmcheck.driver.initial.StartState), None
    to start from the case's [initial].

    Parts: `model` (`ReferenceModel`, fixed for the run); the state `x` (ODE state), `cfg`
    (switching `Configuration`) and `t`, which `advance`, `capture`, `release` and
    `import_state` change; `stepper` (`Stepper`), which owns the step sizes, counters and
    kept matrices of the integrators.  The options as resolved against the case (`rtol`,
    `integrator`, `quiet_integrator`, `h_max` of the integrator) stay readable here; the
    stepper is built from them and reads only its own copies.
    """

    name = "reference"

    def __init__(self, case: Case, params: Params | None = None, n_modes=None, rtol: float | None = None,
                 integrator: str | None = None, h_max: float | None = None, static_modes: bool | None = None,
                 quiet_integrator: str | None = None, start: StartState | None = None):
        self.params = params or case.params
        self.case = case
        self.start = start
        given = settings_of(case, self.name)  # the case's [reference] and [solver] rtol, integrator
        static_modes = first_given(static_modes, given.static_modes, STATIC_MODES_DEFAULT)
        self.model = ReferenceModel(self.params, n_modes if n_modes is not None else given.n_modes,
                                    orbit=case.orbit, static_modes=static_modes)
        self.rtol = rtol if rtol is not None else given.rtol
        self.integrator = integrator or given.integrator
        self.quiet_integrator = quiet_integrator or given.quiet_integrator or self.integrator
        for name in (self.integrator, self.quiet_integrator):
            if name not in INTEGRATORS:
                raise ValueError(f"integrator must be one of {INTEGRATORS}, got {name!r}")
        # largest step: explicit option > the case's [reference] table > the integrator's default
        self._h_max = {name: float(first_given(h_max, given.h_max,
                                               H_MAX if name == "dopri5" else H_MAX_IMPLICIT))
                       for name in (self.integrator, self.quiet_integrator)}
        self.h_max = self._h_max[self.integrator]
        init = build_initial(case, self.params, start)
        self.x, self.cfg = initial_state(self.model, init)
        self.t = 0.0
        self._sensed: np.ndarray | None = None  # measures.sense of the state after `advance`
        self.stepper = Stepper(self.model, self.cfg, integrator=self.integrator,
                               quiet_integrator=self.quiet_integrator, rtol=self.rtol, h_max=self._h_max,
                               engine_name=self.name)
        self.capture_arm = case.capture.arm
        self.capture_point = np.asarray(self.params.geometry.grasp_T(case.capture.arm), float)

    # ---- Engine protocol (rsmcheck.core.engine.Engine) ------------------------------------
    def time(self) -> float:
        return self.t

    def advance(self, t_next: float, inputs: Inputs) -> None:
        # an interval longer than the case's control period belongs to a quiet segment
        quiet = self.case.solver.is_quiet(t_next - self.t)
        x = self.stepper.advance(self.model, self.cfg, self.x, self.t, t_next, input_vector(inputs), quiet)
        # the state completed (condensed static shapes, condense.py) and what the sensors
        # read of it, in one compiled call; `sensors` returns that while the state is x
        v = sense(x, *self.model.core_args(self.cfg))
        self.x = v[:self.model.layout.nx].copy()
        self._sensed = v
        self.t = t_next

    def sensors(self) -> Sensors:
        v = self._sensed
        if v is not None and np.array_equal(v[:self.model.layout.nx], self.x):
            return observe.sensors_of(self.model, self.t, v, self.cfg)
        return observe.sensors(self.model, self.t, self.x, self.cfg)

    def observe(self, inputs: Inputs) -> dict:
        return observe.observables(self.model, self.t, self.x, input_vector(inputs), self.cfg,
                                   self.capture_arm, self.capture_point)

    def capture(self, arm: int) -> dict[str, float]:
        self.stepper.new_system()
        self._sensed = None
        return switching.capture(self.model, self.x, self.cfg, arm)

    def release(self, arm: int) -> dict[str, float]:
        self.stepper.new_system()
        self._sensed = None
        return switching.release(self.model, self.x, self.cfg, arm)

    # ---- exact state for phase chaining (rsmcheck.orchestration.chain) ----------------------------
    def export_state(self) -> dict:
        """Everything needed to continue this run in a new reference engine of the same model
        size: the ODE state (with the modal amplitudes), link bases, grasp flags, held points."""
        return {"engine": self.name, "x": self.x.copy(), "basis": self.cfg.basis.copy(),
                "grasp_on": self.cfg.grasp_on.copy(), "rho_G": self.cfg.rho_G.copy(),
                "n_modes": list(self.model.layout.n_modes), "orbit": bool(self.model.orbit)}

    def import_state(self, exact: dict) -> None:
        """Continue from `export_state()` of an engine of the same layout (else keep the rigid
        start of the case, already built).  A case that enters an orbit the previous phase
        did not have places O on its orbit at the system COM (rsmcheck.driver.initial.place_on_orbit):
        positions and velocities move by the COM's (the rigid part of the chained end state)."""
        self._sensed = None
        lay = self.model.layout
        if exact.get("engine", self.name) != self.name or "x" not in exact \
                or list(exact.get("n_modes", [])) != list(lay.n_modes):
            return
        x = np.array(exact["x"], float)
        if x.shape != (lay.nx,):
            return
        case = self.case
        if case.orbit and not np.any(x[lay.r_O]):
            if self.start is None:
                raise ValueError("an exact state entering an orbit needs the rigid part of its end state "
                                 "(build the engine with start=StartState(...))")
            rigid = self.start.rigid
            com = np.asarray(rigid["com_I"], float)
            vcom = np.asarray(rigid["com_vel_I"], float)
            if case.orbit_spec.centre_on_com:
                x[0:2] -= com
                x[lay.nq:lay.nq + 2] -= com
                x[lay.ns:lay.ns + 2] -= vcom
                x[lay.ns + lay.nq:lay.ns + lay.nq + 2] -= vcom
            x[lay.r_O], x[lay.v_O] = orbit_start(case, self.params, float(x[2]))
        self.cfg = Configuration(grasp_on=np.array(exact["grasp_on"], dtype=np.int64),
                                 rho_G=np.array(exact["rho_G"], float),
                                 basis=np.array(exact["basis"], dtype=np.int64))
        self.x = self.model.complete(x, self.cfg)
        self.t = 0.0

    def solver_settings(self) -> dict:
        names = {"dopri5": "Dormand-Prince 5(4), embedded error control",
                 "trbdf2": "TR-BDF2 (L-stable ESDIRK), embedded 3rd-order error estimate",
                 "imex": "ARK5(4)8L[2]SA IMEX (stiff shapes implicit), embedded error control"}
        stepper = self.stepper
        quiet = {} if stepper.quiet_integrator == stepper.integrator else {
            "quiet_integrator": names[stepper.quiet_integrator], "quiet_steps": stepper.quiet_steps}
        return {"integrator": names[stepper.integrator], **quiet, "rtol": stepper.rtol,
                "h_max": stepper.h_max[stepper.integrator],
                "jacobians": stepper.jacobians(),
                "control_period": self.case.solver.control_period,
                "n_modes": ",".join(str(n) for n in self.model.n_eigen),
                "static_modes": int(self.model.static_modes),
                "static_shapes": self.model.static_shapes,
                "steps": stepper.steps, "rejected_steps": stepper.rejected,
                "wall_integrator_s": stepper.integrator_wall}

    def versions(self) -> dict[str, str]:
        return package_versions("rsmcheck", "numpy", "numba", "scipy")

    # ---- the stepper's counters, read by the orchestration and the tests -----------------
    @property
    def steps(self) -> int:
        return self.stepper.steps

    @property
    def rejected(self) -> int:
        return self.stepper.rejected

    @property
    def quiet_steps(self) -> int:
        return self.stepper.quiet_steps

    @property
    def integrator_wall(self) -> float:
        return self.stepper.integrator_wall
