"""The paper's robot from MuJoCo's own elements, as an `rsmcheck.core.engine.Engine`.

    build.py      the MJCF model (pieces, hinges, rotors, frame tendons, grasps) and its index
    links.py      one link alone: its frequencies from MuJoCo's M, K and pin Jacobian
    field.py      the orbit of O, the tidal field and its potential
    observe.py    sensors and observables from MuJoCo's state
    switching.py  capture, release, basis switch, plastic impact
    modes.py      coupled frequencies of the robot at rest

Forces that depend on the state within a step (the wrist stop, the tidal field, the thrust
along the base's axis and the co-moving frame's inertia) are written in MuJoCo's
`mjcb_passive` / `mjcb_control` callbacks, so that every integrator stage sees them; the
callbacks are process-global in MuJoCo's bindings, so they are installed for one advance
(or one forward) and removed after.  The held motor and base torques are constant
generalised forces (`qfrc_applied`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mujoco_model import field as fld
from mujoco_model import switching
from mujoco_model.build import N_SEGMENTS_DEFAULT, build_model, initial_basis, set_basis
from mujoco_model.observe import Observer
from rsmcheck.core.cases import Case, first_given
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.errors import SimulationDiverged
from rsmcheck.core.params import Params
from rsmcheck.core.plugins import settings_of
from rsmcheck.core.store import package_versions
from rsmcheck.driver.initial import StartState, build_initial

#: MuJoCo's step [s] at N = 8 segments: the highest chain mode is 1.7 kHz there (RK4 is
#: stable to ≈ 0.26 ms); at 0.1 ms RK4's own error is below the segments' (flex_arm_step:
#: the same rows to 3 digits at 25 µs, docs/mujoco.md)
TIMESTEP_DEFAULT = 1e-4
INTEGRATOR_DEFAULT = "rk4"


def default_timestep(n: int) -> float:
    """The step for N segments: the highest chain mode grows as N² and its Kelvin–Voigt
    damping rate η ω² as N⁴, which bounds RK4 (≈ 14 µs at N = 16): (8/N)^(10/3) × 0.1 ms,
    9.9 µs at N = 16."""
    return TIMESTEP_DEFAULT * min(1.0, (N_SEGMENTS_DEFAULT / n) ** (10.0 / 3.0))


@dataclass
class EngineState:
    """What changes during a run besides MuJoCo's qpos/qvel."""

    t: float
    grasp_on: np.ndarray
    rho_G: np.ndarray
    basis: list
    r_O: np.ndarray
    v_O: np.ndarray
    m_used: float
    start_label: str
    stats: dict = field(default_factory=lambda: {"steps": 0, "stop_substeps": 0})


class MujocoEngine:
    """The system of docs/physics.md built from MuJoCo elements, stepping through a case.

    Options: n_segments (rigid segments per link; default the case's [mujoco] table, else
    8), timestep (MuJoCo's step; default the table's, else 0.1 ms × (8/N)²), integrator
    ("rk4" or "implicitfast"), start (a previous run's end state)."""

    name = "mujoco"

    def __init__(self, case: Case, params: Params | None = None, n_segments: int | None = None,
                 timestep: float | None = None, integrator: str | None = None,
                 start: StartState | None = None):
        import mujoco

        self._mj = mujoco
        self.case = case
        self.params = p = params or case.params
        given = settings_of(case, self.name)
        self.n_segments = int(first_given(n_segments, given.n_segments, N_SEGMENTS_DEFAULT))
        self.timestep = float(first_given(timestep, given.timestep, default_timestep(self.n_segments)))
        self.integrator = str(first_given(integrator, given.integrator, INTEGRATOR_DEFAULT))
        if self.integrator not in ("rk4", "implicitfast"):
            raise ValueError(f"integrator must be 'rk4' or 'implicitfast', got {self.integrator!r}")
        self.orbit = bool(case.orbit)
        self.dt = case.solver.control_period
        init = build_initial(case, p, start)
        self.state = EngineState(
            t=0.0, grasp_on=np.array(init.grasp, dtype=np.int64), rho_G=np.array(init.rho_G, float),
            basis=initial_basis(init.grasp), r_O=np.array(init.orbit_r, float),
            v_O=np.array(init.orbit_v, float), m_used=float(init.m_used),
            start_label="initial" if start is None else "rigid end state")
        self.mm = build_model(p, self.n_segments, self.timestep,
                              "RK4" if self.integrator == "rk4" else "implicitfast",
                              self.state.rho_G, p.base.mass - self.state.m_used, self.state.basis)
        self.d = mujoco.MjData(self.mm.model)
        self._place(init)
        self._inputs = Inputs()
        self._period: fld.OrbitPeriod | None = None
        self._fresh = False
        self.observer = Observer(self, capture_arm=case.capture.arm,
                                 capture_point=np.asarray(p.geometry.grasp_T(case.capture.arm), float))

    # ---- the initial state -----------------------------------------------------------------
    def _place(self, init) -> None:
        """qpos/qvel from the rigid initial configuration: straight links, θ_m at the motor
        angles (default: the joint angles), s = ψ_J − θ_m."""
        ix, d = self.mm.index, self.d
        d.qpos[:] = 0.0
        d.qvel[:] = 0.0
        d.qpos[ix.base] = init.base_pose
        d.qvel[ix.base] = init.base_rate
        d.qpos[ix.target] = init.target_pose
        d.qvel[ix.target] = init.target_rate
        qj = np.asarray(init.joint_angles, float).reshape(2, 3)
        qjd = np.asarray(init.joint_rates, float).reshape(2, 3)
        qm = qj if init.motor_angles is None else np.asarray(init.motor_angles, float).reshape(2, 3)
        qmd = qjd if init.motor_rates is None else np.asarray(init.motor_rates, float).reshape(2, 3)
        d.qpos[ix.rotor] = qm
        d.qvel[ix.rotor] = qmd
        d.qpos[ix.spring] = qj - qm
        d.qvel[ix.spring] = qjd - qmd
        for k in range(2):
            d.eq_active[ix.grasp_eq[k]] = bool(self.state.grasp_on[k])
        self._mj.mj_forward(self.mm.model, d)
        self._fresh = True

    # ---- forces ------------------------------------------------------------------------------
    def frame_rows(self) -> np.ndarray:
        """(6, nv): the frame tendons of the links' current bases as rows on q̇."""
        fr = self.mm.index.frame_row
        return np.array([fr[c // 3, c % 3, 0 if b == "PP" else 1] for c, b in enumerate(self.state.basis)])

    def _passive(self, m, d) -> None:
        """The wrist bistop of each holding arm (docs/physics.md §4.3): +τ on θ_T, −τ on the
        terminal link's distal piece."""
        p, ix = self.params.wrist, self.mm.index
        for k in range(2):
            if not self.state.grasp_on[k]:
                continue
            w = ix.wrist[k]
            psi = d.qpos[ix.target[2]] - w @ d.qpos
            if abs(psi) <= p.limit:
                continue
            sgn = 1.0 if psi > 0 else -1.0
            delta = abs(psi) - p.limit
            ddelta = sgn * (d.qvel[ix.target[2]] - w @ d.qvel)
            tau = -sgn * max(0.0, p.stiffness * delta + p.contact_damping * delta * ddelta)
            d.qfrc_passive[ix.target[2]] += tau
            d.qfrc_passive[:] -= tau * w

    def _control(self, m, d) -> None:
        """Thrust along the base's x-axis, the co-moving frame's inertia −m a_T and the tidal
        field (docs/physics.md §5), as forces at the bodies' COMs (`xfrc_applied`)."""
        ix = self.mm.index
        xf = d.xfrc_applied
        xf[:] = 0.0
        T = self._inputs.thrust
        if T != 0.0:
            th = d.qpos[ix.base[2]]
            xf[ix.base_body, 0] += T * math.cos(th)
            xf[ix.base_body, 1] += T * math.sin(th)
        per = self._period
        if per is None:
            return
        aT = per.a_thrust(d.time)
        mass = m.body_mass
        xf[:, 0] -= mass * aT[0]
        xf[:, 1] -= mass * aT[1]
        r_O = per.r_O(d.time)
        mu = self.params.orbit.mu
        # base and target at their COMs
        for b in (ix.base_body, ix.target_body):
            xf[b, :2] += mass[b] * fld.tidal(mu, r_O, d.xipos[b, :2])
        # link pieces: two Gauss points each, force and torque about the piece's COM
        pb = self._pieces
        ex = d.xmat[pb][:, [0, 3]]
        arm = (0.5 * self._piece_len)[:, None, None] * fld.GAUSS[None, :, None] * ex[:, None, :]
        pts = d.xipos[pb][:, None, :2] + arm
        g = fld.tidal(mu, r_O, pts.reshape(-1, 2)).reshape(pts.shape) * (0.5 * mass[pb])[:, None, None]
        xf[pb, 0] += g[:, :, 0].sum(axis=1)
        xf[pb, 1] += g[:, :, 1].sum(axis=1)
        xf[pb, 5] += (arm[..., 0] * g[..., 1] - arm[..., 1] * g[..., 0]).sum(axis=1)

    def _install(self):
        mj = self._mj
        mj.set_mjcb_passive(self._passive if self.state.grasp_on.any() else None)
        mj.set_mjcb_control(self._control if (self.orbit or self._inputs.thrust != 0.0) else None)

    def _remove(self):
        self._mj.set_mjcb_passive(None)
        self._mj.set_mjcb_control(None)

    @property
    def _pieces(self):
        return self.mm.index.piece_body.reshape(-1)

    @property
    def _piece_len(self):
        b = self.mm.bounds
        return np.tile(b[:, 1] - b[:, 0], 6)

    def _contact_steps(self, span: float) -> int:
        """Steps over `span` that keep RK4 stable under the wrist stop's damping λδ, which
        acts on the distal end piece (inertia ρA(ℓ/2)³/3 about the held tip): the damping rate
        λδ/I must stay below 2/h (δ bounded by its value and rate over the period)."""
        st, d, ix = self.state, self.d, self.mm.index
        if not st.grasp_on.any():
            return 1
        w = self.params.wrist
        ell = self.params.link.length / self.n_segments
        inertia = self.params.link.rho_a * (0.5 * ell) ** 3 / 3.0
        worst = 0.0
        for k in range(2):
            if st.grasp_on[k]:
                psi = d.qpos[ix.target[2]] - ix.wrist[k] @ d.qpos
                rate = d.qvel[ix.target[2]] - ix.wrist[k] @ d.qvel
                worst = max(worst, abs(psi) - w.limit + 2.0 * abs(rate) * span)
        if worst <= 0.0:
            return 1
        h = 2.0 * inertia / (w.contact_damping * worst)
        n = int(math.ceil(span / h))
        st.stats["stop_substeps"] += max(0, n - int(math.ceil(span / self.timestep - 1e-9)))
        return n

    def _set_inputs(self, inputs: Inputs) -> None:
        ix, d = self.mm.index, self.d
        self._inputs = inputs
        d.qfrc_applied[:] = 0.0
        d.qfrc_applied[ix.rotor.reshape(-1)] = np.asarray(inputs.tau_m, float)
        d.qfrc_applied[ix.base[2]] = float(inputs.tau_B)

    def _set_base_mass(self, m_used: float) -> None:
        m = self.mm.model
        new = self.params.base.mass - m_used
        if m.body_mass[self.mm.index.base_body] != new:
            m.body_mass[self.mm.index.base_body] = new
            self._mj.mj_setConst(m, self.d)

    def _burn_rate(self, inputs: Inputs) -> float:
        a = self.params.actuators
        return float(inputs.thrust) / (a.isp * a.g0)

    # ---- Engine protocol -------------------------------------------------------------------
    def time(self) -> float:
        return self.state.t

    def refresh(self) -> None:
        """MuJoCo's positions and velocities of bodies for the current qpos, qvel."""
        if not self._fresh:
            m, d = self.mm.model, self.d
            self._mj.mj_kinematics(m, d)
            self._mj.mj_comPos(m, d)
            self._mj.mj_comVel(m, d)
            self._fresh = True

    def forward(self, inputs: Inputs) -> None:
        """mj_forward at the current state with `inputs` held (the equality forces)."""
        st = self.state
        self._set_inputs(inputs)
        self._period = self._orbit_period(st.t, st.t, inputs) if self.orbit else None
        self._install()
        try:
            self._mj.mj_forward(self.mm.model, self.d)
        finally:
            self._remove()
        self._fresh = True

    def _orbit_period(self, t0, t1, inputs) -> fld.OrbitPeriod:
        st, d, ix = self.state, self.d, self.mm.index
        m_sys = float(self.mm.model.body_mass.sum())
        return fld.OrbitPeriod(self.params.orbit.mu, t0, t1, st.r_O, st.v_O, float(inputs.thrust), m_sys,
                               float(d.qpos[ix.base[2]]), float(d.qvel[ix.base[2]]))

    def advance(self, t_next: float, inputs: Inputs) -> None:
        st, m, d = self.state, self.mm.model, self.d
        span = t_next - st.t
        if span <= 0.0:
            return
        n = max(1, int(math.ceil(span / self.timestep - 1e-9)), self._contact_steps(span))
        m.opt.timestep = span / n
        burn = self._burn_rate(inputs)
        if burn:
            self._set_base_mass(st.m_used + 0.5 * burn * span)
        self._set_inputs(inputs)
        self._period = self._orbit_period(st.t, t_next, inputs) if self.orbit else None
        d.time = st.t
        self._install()
        try:
            self._mj.mj_step(m, d, nstep=n)
        finally:
            self._remove()
        st.stats["steps"] += n
        self._fresh = False
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))) or np.max(np.abs(d.qvel)) > 1e6:
            raise SimulationDiverged(self.name, t_next, self.case.name, "max |qvel|", float(np.max(np.abs(d.qvel))))
        if self._period is not None:
            st.r_O, st.v_O = self._period.r1.copy(), self._period.v1.copy()
        st.m_used += burn * span
        st.t = t_next
        d.time = t_next

    def sensors(self) -> Sensors:
        return self.observer.sensors()

    def observe(self, inputs: Inputs) -> dict:
        return self.observer.observables(inputs)

    def grasp_forces(self) -> np.ndarray:
        """R_cl (4): the force on the target at each held point, inertial axes, from the
        `connect` equality's rows (after `forward`)."""
        return switching.grasp_forces(self)

    def mass_matrix(self) -> np.ndarray:
        m = self.mm.model
        M = np.zeros((m.nv, m.nv))
        self._mj.mj_fullM(m, self.d, M)
        return M

    def capture(self, arm: int) -> dict[str, float]:
        return switching.capture(self, arm)

    def release(self, arm: int) -> dict[str, float]:
        return switching.release(self, arm)

    def set_basis(self, basis: list) -> None:
        self.state.basis = list(basis)
        set_basis(self.mm, self.state.basis)

    def solver_settings(self) -> dict:
        return {"integrator": f"MuJoCo {self.integrator}, fixed step", "step": self.timestep,
                "n_segments": self.n_segments, "control_period": self.dt,
                "links": f"{self.n_segments} rigid segments", "grasp": "soft connect equality",
                "steps": int(self.state.stats["steps"]), "stop_substeps": int(self.state.stats["stop_substeps"]),
                "start": self.state.start_label}

    def versions(self) -> dict[str, str]:
        return package_versions("rsmcheck", "mujoco", "numpy")

    def export_state(self) -> dict:
        st = self.state
        return {"engine": self.name, "n_segments": self.n_segments, "qpos": self.d.qpos.copy(),
                "qvel": self.d.qvel.copy(), "grasp_on": st.grasp_on.copy(), "rho_G": st.rho_G.copy(),
                "basis": list(st.basis)}

    def import_state(self, exact: dict) -> None:
        """Continue from `export_state()` of the same model (same segments, grasps and bases);
        O's shift between the phases moves every position by the base's shift.  Another
        model: the rigid start stays."""
        st, d, ix = self.state, self.d, self.mm.index
        same = (exact.get("engine") == self.name and int(exact.get("n_segments", -1)) == self.n_segments
                and len(exact.get("qpos", ())) == len(d.qpos)
                and list(exact.get("grasp_on", ())) == list(st.grasp_on)
                and list(exact.get("basis", ())) == list(st.basis))
        if not same:
            return
        q = np.array(exact["qpos"], float)
        v = np.array(exact["qvel"], float)
        shift = d.qpos[ix.base[:2]] - q[ix.base[:2]]
        vshift = d.qvel[ix.base[:2]] - v[ix.base[:2]]
        q[ix.base[:2]] += shift
        q[ix.target[:2]] += shift
        v[ix.base[:2]] += vshift
        v[ix.target[:2]] += vshift
        d.qpos[:] = q
        d.qvel[:] = v
        st.rho_G = np.array(exact["rho_G"], float)
        for k in range(2):
            self.mm.model.site_pos[ix.hold_site[k], :2] = st.rho_G[k]
        self._mj.mj_forward(self.mm.model, d)
        self._fresh = True
