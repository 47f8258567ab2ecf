"""The reference model as an `rsmcheck.engine.Engine`: state, stepping, switching, output."""

from __future__ import annotations

import math

import numpy as np

from reference_model import core, switching
from reference_model.dopri5 import integrate_dopri5
from reference_model.trbdf2 import integrate_trbdf2
from reference_model.build import STATIC_MODES_DEFAULT, Configuration, ReferenceModel, terminal_basis
from reference_model.observe import observe
from rsmcheck.cases import Case
from rsmcheck.engine import Inputs, Sensors
from rsmcheck.errors import SimulationDiverged
from rsmcheck.initial import InitialConfiguration, build_initial, orbit_start
from rsmcheck.params import Params
from rsmcheck.store import package_versions

#: error-control scale per kind of state component: atol_i = rtol · scale_i
ATOL_SCALE = {
    "rigid": 1.0,  # m, rad
    "modal": 1e-3,  # m (amplitudes are micrometres to millimetres)
    "rigid_rate": 1.0,  # m/s, rad/s
    "modal_rate": 1e-1,  # m/s (ω · amplitude)
    "orbit_r": 1e4,  # m (|r_O| ≈ 7e6 m)
    "orbit_v": 1e1,  # m/s
    "mass": 1.0,  # kg
}
H_MAX = 0.05  # s, explicit DP5(4): stability bounds h near 2.5 ms anyway
H_MAX_IMPLICIT = 1.0  # s, TR-BDF2 in quiet phases
INTEGRATORS = ("dopri5", "trbdf2")


class ReferenceEngine:
    """Kane–Newton reference model stepping through a case."""

    name = "reference"

    def __init__(self, case: Case, params: Params | None = None, n_modes=None, rtol: float | None = None,
                 integrator: str | None = None, h_max: float | None = None, static_modes: bool | None = None):
        self.params = params or case.params
        self.case = case
        if static_modes is None:
            static_modes = case.reference.get("static_modes", STATIC_MODES_DEFAULT)
        self.model = ReferenceModel(self.params, n_modes if n_modes is not None else case.n_modes,
                                    orbit=case.orbit, static_modes=static_modes)
        self.rtol = rtol if rtol is not None else case.solver.rtol
        self.integrator = integrator or getattr(case.solver, "integrator", "dopri5")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {self.integrator!r}")
        # largest step: explicit option > the case's [reference] table > the integrator's default
        h_max = h_max if h_max is not None else case.reference.get("h_max")
        self.h_max = float(h_max if h_max is not None else (H_MAX if self.integrator == "dopri5" else H_MAX_IMPLICIT))
        init = build_initial(case, self.params)
        self.x, self.cfg = initial_state(self.model, init)
        self.t = 0.0
        self.h = 1e-4
        self.steps = 0
        self.rejected = 0
        self.atol = self._atol()
        n = self.model.layout.nx
        # TR-BDF2 iteration matrix, kept between control periods (implicit.integrate_trbdf2)
        self._jac = np.zeros((n, n))
        self._minv = np.zeros((n, n))
        self._work = np.zeros(4)
        self.capture_arm = case.capture.arm
        self.capture_point = np.asarray(self.params.geometry.grasp_T(case.capture.arm), float)

    def _atol(self) -> np.ndarray:
        lay = self.model.layout
        s = np.empty(lay.nx)
        s[:] = ATOL_SCALE["rigid"]
        s[9:lay.nq] = ATOL_SCALE["modal"]
        s[lay.ns:2 * lay.ns] = ATOL_SCALE["rigid_rate"]
        s[lay.ns + 9:lay.ns + lay.nq] = ATOL_SCALE["modal_rate"]
        s[lay.r_O] = ATOL_SCALE["orbit_r"]
        s[lay.v_O] = ATOL_SCALE["orbit_v"]
        s[lay.m_used] = ATOL_SCALE["mass"]
        return self.rtol * s

    # ---- Engine protocol -------------------------------------------------------------
    def time(self) -> float:
        return self.t

    def u_vector(self, inputs: Inputs) -> np.ndarray:
        u = np.zeros(core.N_INPUTS)
        u[core.U_TAU_M:core.U_TAU_M + 6] = inputs.tau_m
        u[core.U_TAU_B] = inputs.tau_B
        u[core.U_THRUST] = inputs.thrust
        return u

    def advance(self, t_next: float, inputs: Inputs) -> None:
        args = self.model.core_args(self.cfg)
        u = self.u_vector(inputs)
        if self.integrator == "dopri5":
            x, h, nacc, nrej, status = integrate_dopri5(
                self.x, self.t, t_next, self.h, self.rtol, self.atol, self.h_max, u, *args)
        else:
            x, h, nacc, nrej, status = integrate_trbdf2(
                self.x, self.t, t_next, self.h, self.rtol, self.atol, self.h_max, self._jac,
                self._minv, self._work, u, *args)
        self.steps += nacc
        self.rejected += nrej
        if status != 0 or not np.all(np.isfinite(x)):
            bad = int(np.argmax(~np.isfinite(x))) if not np.all(np.isfinite(x)) else int(np.argmax(np.abs(x)))
            raise SimulationDiverged(self.name, self.t, "?", f"state[{bad}] "
                                     + ("non-finite" if status == 1 else "step size underflow"), float(x[bad]))
        self.x, self.h, self.t = x, h, t_next

    def sensors(self) -> Sensors:
        lay = self.model.layout
        x = self.x
        q, qd = x[lay.q], x[lay.qd]
        rE, rEd, psi, psid, psi_w, com, m = core.sensor_values(x, *self.model.core_args(self.cfg))
        c, s = math.cos(q[2]), math.sin(q[2])
        d = com - q[0:2]
        return Sensors(
            time=self.t, base_pose_I=q[0:3].copy(), base_rate_I=qd[0:3].copy(),
            joint_angles=psi, joint_rates=psid, joint_frame_angles=q[3:9].copy(),
            joint_frame_rates=qd[3:9].copy(), wrist_angles=psi_w,
            motor_angles=x[lay.motors].copy(), motor_rates=x[lay.motors_d].copy(),
            ee_pos_I=rE.copy(), ee_vel_I=rEd.copy(),
            target_pose_I=x[lay.target].copy(), target_rate_I=x[lay.target_d].copy(),
            com_pos_B=np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]),
            grasp_state=self.cfg.grasp_on.copy(), system_mass=float(m),
            orbit_r_I=x[lay.r_O].copy(), orbit_v_I=x[lay.v_O].copy())

    def observe(self, inputs: Inputs) -> dict:
        return observe(self.model, self.t, self.x, self.u_vector(inputs), self.cfg,
                       self.capture_arm, self.capture_point)

    def capture(self, arm: int) -> dict[str, float]:
        self._work[0] = 0.0  # the system changed: the next implicit step needs a new Jacobian
        return switching.capture(self.model, self.x, self.cfg, arm)

    def release(self, arm: int) -> dict[str, float]:
        self._work[0] = 0.0
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
        did not have places O on its orbit at the system COM (rsmcheck.initial.place_on_orbit):
        positions and velocities move by the COM's (the rigid part of the chained end state)."""
        lay = self.model.layout
        if exact.get("engine", self.name) != self.name or "x" not in exact \
                or list(exact.get("n_modes", [])) != list(lay.n_modes):
            return
        x = np.array(exact["x"], float)
        if x.shape != (lay.nx,):
            return
        case = self.case
        if case.orbit and not np.any(x[lay.r_O]):
            rigid = case.start_state
            com = np.asarray(rigid["com_I"], float)
            vcom = np.asarray(rigid["com_vel_I"], float)
            if case.orbit_spec.centre_on_com:
                x[0:2] -= com
                x[lay.nq:lay.nq + 2] -= com
                x[lay.ns:lay.ns + 2] -= vcom
                x[lay.ns + lay.nq:lay.ns + lay.nq + 2] -= vcom
            x[lay.r_O], x[lay.v_O] = orbit_start(case, self.params, float(x[2]))
        self.x = x
        self.cfg = Configuration(grasp_on=np.array(exact["grasp_on"], dtype=np.int64),
                                 rho_G=np.array(exact["rho_G"], float),
                                 basis=np.array(exact["basis"], dtype=np.int64))
        self.t = 0.0

    def solver_settings(self) -> dict:
        names = {"dopri5": "Dormand-Prince 5(4), embedded error control",
                 "trbdf2": "TR-BDF2 (L-stable ESDIRK), embedded 3rd-order error estimate"}
        return {"integrator": names[self.integrator], "rtol": self.rtol,
                "h_max": self.h_max,
                "jacobians": int(self._work[2]),
                "control_period": self.case.solver.control_period,
                "n_modes": ",".join(str(n) for n in self.model.n_eigen),
                "static_modes": int(self.model.static_modes),
                "steps": self.steps, "rejected_steps": self.rejected}

    def versions(self) -> dict[str, str]:
        return package_versions("rsmcheck", "numpy", "numba", "scipy")


def initial_state(model: ReferenceModel, init: InitialConfiguration) -> tuple[np.ndarray, Configuration]:
    """ODE state and configuration from shared initial conditions: links undeformed and at
    rest relative to their frames, motors at the joint angles (springs relaxed)."""
    lay = model.layout
    x = model.zero_state()
    x[0:3] = init.base_pose
    x[3:9] = init.joint_angles
    x[lay.target] = init.target_pose
    x[lay.motors] = init.joint_angles
    x[lay.ns:lay.ns + 3] = init.base_rate
    x[lay.ns + 3:lay.ns + 9] = init.joint_rates
    x[lay.target_d] = init.target_rate
    x[lay.motors_d] = init.joint_rates
    x[lay.r_O] = init.orbit_r
    x[lay.v_O] = init.orbit_v
    cfg = Configuration(grasp_on=init.grasp.copy(), rho_G=init.rho_G.copy(), basis=terminal_basis(init.grasp))
    return x, cfg
