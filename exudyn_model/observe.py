"""What the Exudyn model reports: the sensors of the shared driver (rsmcheck.core.engine.Sensors)
and every observable (docs/observables.md) with energy and momentum, read from the ODE2
coordinates by the index tables of `exudyn_model.build`, and the grasp forces by the
index-1 solve of `exudyn_model.reactions`.  The reference's mirror is
`reference_model/observe.py`.

`Observer` is the engine's observing part: it reads the built model and the run's state
and changes neither (the grasp forces set the coming period's inputs into the mbs for
their solve and put the old ones back, `reactions.held_inputs`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from exudyn_model import field as fld
from exudyn_model import links, reactions
from exudyn_model.build import perp
from exudyn_model.field import N_GAUSS_FIELD
from exudyn_model.indices import SENSOR_SIZE
from exudyn_model.state import EngineState, base_mass, coordinates, system_mass
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.geometry import rot


@njit(cache=True)
def gather_sensors(q, v, table, com_x, com_y, out):  # pragma: no cover - compiled
    """The sensors of one sample into `out` (`indices.SENSOR_LAYOUT`), in one call: row j of
    `table` (`indices.sensor_table`) = (0: q, 1: q̇; i; k) gives out[j] = x[i] − x[k], or
    x[i] for k < 0; then the system COM in base axes, A(θ_B)ᵀ (r_COM − r_B) =
    (c d_x + s d_y, −s d_x + c d_y), from the COM (com_x, com_y) and base_pose_I (out[0:3])."""
    for j in range(table.shape[0]):
        x = q if table[j, 0] == 0 else v
        i, k = table[j, 1], table[j, 2]
        out[j] = x[i] - x[k] if k >= 0 else x[i]
    c, s = math.cos(out[2]), math.sin(out[2])
    dx, dy = com_x - out[0], com_y - out[1]
    out[58] = c * dx + s * dy
    out[59] = -s * dx + c * dy


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def end_effectors(model, q, v) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity of each arm's end effector (row k), inertial axes: the distal
    pin of its terminal link, for flexible links the tip node's x, y (`index.ee`)."""
    ee = model.index.ee
    if ee is not None:
        return q[ee], v[ee]
    L = model.params.link.length
    r = np.zeros((2, 2))
    rd = np.zeros((2, 2))
    for k in range(2):
        it = model.links[3 * k + 2]
        qi, vi = q[it.coords], v[it.coords]
        d = 0.5 * L * np.array([math.cos(qi[2]), math.sin(qi[2])])
        r[k] = qi[:2] + d
        rd[k] = vi[:2] + vi[2] * perp(d)
    return r, rd


class Observer:
    """The engine's sensors (`sensors`) and observables (`observables`) of `model` in
    `state`; the grasp forces by the index-1 solve of `constraint_forces` with the held
    inputs set through `stepper`."""

    def __init__(self, model, state: EngineState, stepper, constraint_forces: reactions.ConstraintForces,
                 orbit: bool, capture_arm: int, capture_point: np.ndarray):
        """`orbit`: the case has one; `capture_arm`, `capture_point`: the case's capture
        (its gap is an observable), the point in the target's frame [m]."""
        self.model, self.state, self.stepper = model, state, stepper
        self.constraint_forces = constraint_forces
        self.orbit = bool(orbit)
        self.capture_arm = capture_arm
        self.capture_point = capture_point
        ix = model.index
        # the COM's point masses (`com`): base and target x, y
        self.com_points = (int(ix.i_base[0]), int(ix.i_base[1]), int(ix.i_target[0]), int(ix.i_target[1]))

    def grasp_forces(self, inputs=None) -> np.ndarray:
        """`reaction_forces_I` at the current state (`reactions.grasp_forces`), with `inputs`
        held from it (None: the loads the mbs carries)."""
        return reactions.grasp_forces(self.constraint_forces, self.model, self.state.grasp_on, self.stepper,
                                      inputs)

    def com(self, q) -> tuple[np.ndarray, float]:
        """System COM (relative to O) and mass: m_B r_B + m_T r_T + Σ ∫ρ r dξ over the links,
        the link integrals as one matrix on all link coordinates (`index.link_first`)."""
        p, ix = self.model.params, self.model.index
        mB = base_mass(p, self.state)
        s = mB * q[ix.i_base[:2]] + p.target.mass * q[ix.i_target[:2]] + ix.link_first @ q[ix.link_coords]
        m = system_mass(p, self.state)
        return s / m, m

    def wrist_angles(self, q) -> np.ndarray:
        """ψ_w: θ_T relative to the distal hub of each terminal link."""
        ix = self.model.index
        return q[ix.i_target[2]] - q[ix.wrist_hub]

    def sensors(self) -> Sensors:
        """At every control sample: every coordinate, rate and difference in one compiled
        gather (`gather_sensors`, rows `index.sensor_table`) into one buffer whose slices are the
        sensors, with the COM of `com` (the same arithmetic, on floats)."""
        model, state = self.model, self.state
        q, v = coordinates(model, state)
        ix = model.index
        p = model.params
        mB = base_mass(p, state)
        m = system_mass(p, state)
        first = ix.link_first @ q[ix.link_coords]
        bx, by, tx, ty = self.com_points
        mT = p.target.mass
        buf = np.empty(SENSOR_SIZE)
        gather_sensors(q, v, ix.sensor_table, (mB * q[bx] + mT * q[tx] + first[0]) / m,
                       (mB * q[by] + mT * q[ty] + first[1]) / m, buf)
        if ix.ee is None:
            rE, rEd = end_effectors(model, q, v)
            buf[44:48], buf[48:52] = rE.reshape(-1), rEd.reshape(-1)
        return Sensors(
            time=state.t, base_pose_I=buf[0:3], base_rate_I=buf[3:6], joint_angles=buf[6:12],
            joint_rates=buf[12:18], joint_frame_angles=buf[18:24], joint_frame_rates=buf[24:30],
            wrist_angles=buf[30:32], motor_angles=buf[32:38], motor_rates=buf[38:44],
            ee_pos_I=buf[44:48].reshape(2, 2), ee_vel_I=buf[48:52].reshape(2, 2),
            target_pose_I=buf[52:55], target_rate_I=buf[55:58], com_pos_B=buf[58:60],
            grasp_state=state.grasp_on.copy(), system_mass=m, orbit_r_I=state.r_O.copy(),
            orbit_v_I=state.v_O.copy())

    def observables(self, inputs: Inputs) -> dict:
        """Every observable (docs/observables.md) at the current sample, `inputs` held from it."""
        model, state = self.model, self.state
        p, ix = model.params, model.index
        q, v = coordinates(model, state)
        th = q[ix.i_frame]
        s = self.sensors()
        rB = q[ix.i_base[:2]]
        thB = q[ix.i_base[2]]
        AB_T = rot(thB).T
        XT = q[ix.i_target]
        rE, rEd = s.ee_pos_I, s.ee_vel_I
        cap = XT[:2] + rot(XT[2]) @ self.capture_point
        # grasp forces by the index-1 solve at this sample with the inputs held from it
        # (exudyn_model.reactions): the integrator's index-3 multipliers have a round-off
        # floor ∝ 1/h² (docs/exudyn.md §6) and belong to the last period's inputs
        reaction = self.grasp_forces(inputs)
        residual = np.zeros(4)
        for k in range(2):
            if state.grasp_on[k]:
                residual[2 * k:2 * k + 2] = rE[k] - (XT[:2] + rot(XT[2]) @ state.rho_G[k])
        deflection = np.zeros(6)
        for it in model.links:
            if not it.rigid:
                qi = q[it.coords]
                n = np.array([-math.sin(th[it.index]), math.cos(th[it.index])])
                deflection[it.index] = n @ (model.pos_mid @ qi - qi[:2])
        r_abs = state.r_O + rB
        radial = r_abs / np.linalg.norm(r_abs) if self.orbit else np.array([1.0, 0.0])
        along = np.array([-radial[1], radial[0]])
        d_T = XT[:2] - rB
        com = self.com(q)[0]
        return {
            "time": state.t,
            "base_pose_I": q[ix.i_base].copy(),
            "target_pose_B": np.array([*(AB_T @ d_T), XT[2] - thB]),
            "ee1_pos_B": AB_T @ (rE[0] - rB),
            "ee2_pos_B": AB_T @ (rE[1] - rB),
            "ee2_speed": float(np.linalg.norm(rEd[1])),
            "capture_gap_B": AB_T @ (rE[self.capture_arm - 1] - cap),
            "com_pos_B": AB_T @ (com - rB),
            "joint_angles": s.joint_angles,
            "joint_frame_angles": s.joint_frame_angles,
            "wrist_angles": s.wrist_angles,
            "motor_angles": s.motor_angles,
            "motor_torques": np.asarray(inputs.tau_m, float).copy(),
            "base_torque": float(inputs.tau_B),
            "link_deflection": deflection,
            "target_attitude": float(XT[2]),
            "reaction_forces_I": reaction,
            "constraint_residual": residual,
            "grasp_state": state.grasp_on.astype(float),
            "energy": self.energy(q, v, s),
            "momentum_I": self.momentum(q, v),
            "altitude": float(np.linalg.norm(state.r_O + com) - p.orbit.earth_radius) if self.orbit else 0.0,
            "target_rel_lvlh": np.array([d_T @ radial, d_T @ along]),
            "system_mass": float(s.system_mass),
        }

    def energy(self, q, v, s: Sensors) -> np.ndarray:
        """Kinetic, elastic and tidal potential energy [J] at q, q̇ (`s`: their sensors)."""
        model = self.model
        p, ix = model.params, model.index
        mB = base_mass(p, self.state)
        vb, vt = v[ix.i_base], v[ix.i_target]
        kin = 0.5 * mB * (vb[0] ** 2 + vb[1] ** 2) + 0.5 * p.base.inertia_z * vb[2] ** 2
        kin += 0.5 * p.target.mass * (vt[0] ** 2 + vt[1] ** 2) + 0.5 * p.target.inertia_z * vt[2] ** 2
        el = 0.0
        ei, ea = p.link.ei, p.link.axial_to_bending * p.link.ei
        for it in model.links:
            qi, vi = q[it.coords], v[it.coords]
            if it.rigid:
                kin += 0.5 * p.link.mass * (vi[0] ** 2 + vi[1] ** 2) + 0.5 * p.link.inertia_z * vi[2] ** 2
            else:
                kin += 0.5 * vi @ model.mass_ancf @ vi + 0.5 * p.link.inertia_extra * v[ix.i_frame[it.index]] ** 2
                el += model.mesh.strain_energy(qi, ei, ea)
        kin += 0.5 * p.motor.inertia * float(np.sum(s.motor_rates**2))
        el += 0.5 * p.motor.stiffness * float(np.sum((s.motor_angles - s.joint_angles) ** 2))
        psi_w = self.wrist_angles(q)
        for k in range(2):
            if self.state.grasp_on[k]:
                over = abs(psi_w[k]) - p.wrist.limit
                if over > 0:
                    el += 0.5 * p.wrist.stiffness * over**2
        grav = self.tidal_energy(q) if self.orbit else 0.0
        return np.array([kin, el, grav])

    def tidal_energy(self, q) -> float:
        """The tidal potential energy [J] of every mass element about O."""
        model, r_O = self.model, self.state.r_O
        p, ix = model.params, model.index
        mu = p.orbit.mu
        e = base_mass(p, self.state) * float(fld.tidal_potential(mu, r_O, q[ix.i_base[:2]]))
        e += p.target.mass * float(fld.tidal_potential(mu, r_O, q[ix.i_target[:2]]))
        for it in model.links:
            qi = q[it.coords]
            if it.rigid:
                L = p.link.length
                xs, ws = links.gauss(8, -0.5 * L, 0.5 * L)
                pts = qi[:2] + np.outer(xs, [math.cos(qi[2]), math.sin(qi[2])])
            else:
                _, ws, pts = model.mesh.points(qi, N_GAUSS_FIELD)
            e += p.link.rho_a * float(np.sum(ws * fld.tidal_potential(mu, r_O, pts)))
        return e

    def momentum(self, q, v) -> np.ndarray:
        """Linear and angular momentum (about O) [kg·m/s, kg·m²/s], inertial axes."""
        model = self.model
        p, ix = model.params, model.index
        mB = base_mass(p, self.state)
        qb, vb, qt, vt = q[ix.i_base], v[ix.i_base], q[ix.i_target], v[ix.i_target]
        lin = mB * vb[:2] + p.target.mass * vt[:2]
        ang = mB * _cross(qb[:2], vb[:2]) + p.base.inertia_z * vb[2]
        ang += p.target.mass * _cross(qt[:2], vt[:2]) + p.target.inertia_z * vt[2]
        for it in model.links:
            qi, vi = q[it.coords], v[it.coords]
            if it.rigid:
                lin = lin + p.link.mass * vi[:2]
                ang += p.link.mass * _cross(qi[:2], vi[:2]) + p.link.inertia_z * vi[2]
            else:
                lin = lin + model.first @ vi
                _, ws, rs = model.mesh.points(qi, N_GAUSS_FIELD)
                _, _, vs = model.mesh.points(vi, N_GAUSS_FIELD)
                ang += p.link.rho_a * float(np.sum(ws * (rs[:, 0] * vs[:, 1] - rs[:, 1] * vs[:, 0])))
                ang += p.link.inertia_extra * v[ix.i_frame[it.index]]
        return np.array([lin[0], lin[1], ang])
