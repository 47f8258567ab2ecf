"""What the Exudyn model reports: the sensors of the shared driver (rsmcheck.core.engine.Sensors)
and every observable (docs/physics.md §11) with energy and momentum, read from the ODE2
coordinates by the index tables of `exudyn_model.build`, and the grasp forces by the
index-1 solve of `exudyn_model.reactions`.  The reference's mirror is
`reference_model/observe.py`.

`ObserveMixin` is that part of `exudyn_model.engine.ExudynEngine`.
"""

from __future__ import annotations

import math

import numpy as np

from exudyn_model import field as fld
from exudyn_model import links, reactions
from exudyn_model.build import _perp
from exudyn_model.field import N_GAUSS_FIELD
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.geometry import rot


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


class ObserveMixin:
    """`ExudynEngine`'s sensors (`_sensors`) and observables (`_observables`)."""

    def _frame_angles(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        return q[self.i_frame], v[self.i_frame]

    def _end_effectors(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity of each arm's end effector (row k), inertial axes: the
        distal pin of its terminal link, for flexible links the tip node's x, y (`_i_ee`)."""
        if self._i_ee is not None:
            return q[self._i_ee], v[self._i_ee]
        L = self.params.link.length
        r = np.zeros((2, 2))
        rd = np.zeros((2, 2))
        for k in range(2):
            it = self.links[3 * k + 2]
            qi, vi = q[it.coords], v[it.coords]
            d = 0.5 * L * np.array([math.cos(qi[2]), math.sin(qi[2])])
            r[k] = qi[:2] + d
            rd[k] = vi[:2] + vi[2] * _perp(d)
        return r, rd

    def _com(self, q) -> tuple[np.ndarray, float]:
        """System COM (relative to O) and mass: m_B r_B + m_T r_T + Σ ∫ρ r dξ over the links,
        the link integrals as one matrix on all link coordinates (`_link_first`)."""
        p = self.params
        mB = self._mass_base()
        s = mB * q[self.i_base[:2]] + p.target.mass * q[self.i_target[:2]] + self._link_first @ q[self._link_coords]
        m = self._system_mass()
        return s / m, m

    def _system_mass(self) -> float:
        """m_B + m_T + 6 m_link [kg] (the base's present mass, `_mass_base`)."""
        p = self.params
        return self._mass_base() + p.target.mass + 6 * p.link.mass

    def _wrist_angles(self, q) -> np.ndarray:
        """ψ_w: θ_T relative to the distal hub of each terminal link."""
        return q[self.i_target[2]] - q[self._i_wrist_hub]

    def _sensors(self) -> Sensors:
        """At every control sample: the coordinates gathered in one index array
        (`_sensor_rows`, build.py `_index`), the sensors its slices and their differences."""
        q, v = self._qv()
        qs, vs = q[self._sensor_rows], v[self._sensor_rows]
        at = self._sensor_at
        if self._i_ee is not None:
            rE, rEd = qs[at["ee"]].reshape(2, 2), vs[at["ee"]].reshape(2, 2)
        else:
            rE, rEd = self._end_effectors(q, v)
        com, m = self._com(q)
        base, hub, hub_parent, frame, frame_parent = (at["base"], at["hub_prox"], at["hub_parent"], at["frame"],
                                                      at["frame_parent"])
        AB_T = rot(qs[base][2]).T
        return Sensors(
            time=self.t, base_pose_I=qs[base], base_rate_I=vs[base],
            joint_angles=qs[hub] - qs[hub_parent], joint_rates=vs[hub] - vs[hub_parent],
            joint_frame_angles=qs[frame] - qs[frame_parent], joint_frame_rates=vs[frame] - vs[frame_parent],
            wrist_angles=qs[at["target"]][2] - qs[at["wrist_hub"]],
            motor_angles=qs[at["rotor"]], motor_rates=vs[at["rotor"]],
            ee_pos_I=rE, ee_vel_I=rEd,
            target_pose_I=qs[at["target"]], target_rate_I=vs[at["target"]],
            com_pos_B=AB_T @ (com - qs[base][:2]), grasp_state=self.grasp_on.copy(),
            system_mass=m, orbit_r_I=self.r_O.copy(), orbit_v_I=self.v_O.copy())

    def _observables(self, inputs: Inputs) -> dict:
        p = self.params
        q, v = self._qv()
        th, om = self._frame_angles(q, v)
        s = self.sensors()
        rB = q[self.i_base[:2]]
        thB = q[self.i_base[2]]
        AB_T = rot(thB).T
        XT = q[self.i_target]
        rE, rEd = s.ee_pos_I, s.ee_vel_I
        cap = XT[:2] + rot(XT[2]) @ self.capture_point
        # grasp forces by the index-1 solve at this sample with the inputs held from it
        # (exudyn_model.reactions): the integrator's index-3 multipliers have a round-off
        # floor ∝ 1/h² (docs/exudyn.md §6) and belong to the last period's inputs
        reaction = reactions.grasp_forces(self, inputs)
        residual = np.zeros(4)
        for k in range(2):
            if self.grasp_on[k]:
                residual[2 * k:2 * k + 2] = rE[k] - (XT[:2] + rot(XT[2]) @ self.rho_G[k])
        deflection = np.zeros(6)
        for it in self.links:
            if not it.rigid:
                qi = q[it.coords]
                n = np.array([-math.sin(th[it.index]), math.cos(th[it.index])])
                deflection[it.index] = n @ (self.pos_mid @ qi - qi[:2])
        r_abs = self.r_O + rB
        radial = r_abs / np.linalg.norm(r_abs) if self.orbit else np.array([1.0, 0.0])
        along = np.array([-radial[1], radial[0]])
        d_T = XT[:2] - rB
        com = self._com(q)[0]
        return {
            "time": self.t,
            "base_pose_I": q[self.i_base].copy(),
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
            "grasp_state": self.grasp_on.astype(float),
            "energy": self._energy(q, v, s),
            "momentum_I": self._momentum(q, v),
            "altitude": float(np.linalg.norm(self.r_O + com) - p.orbit.earth_radius) if self.orbit else 0.0,
            "target_rel_lvlh": np.array([d_T @ radial, d_T @ along]),
            "system_mass": float(s.system_mass),
        }

    def _energy(self, q, v, s: Sensors) -> np.ndarray:
        p = self.params
        mB = self._mass_base()
        vb, vt = v[self.i_base], v[self.i_target]
        kin = 0.5 * mB * (vb[0] ** 2 + vb[1] ** 2) + 0.5 * p.base.inertia_z * vb[2] ** 2
        kin += 0.5 * p.target.mass * (vt[0] ** 2 + vt[1] ** 2) + 0.5 * p.target.inertia_z * vt[2] ** 2
        el = 0.0
        ei, ea = p.link.ei, p.link.axial_to_bending * p.link.ei
        for it in self.links:
            qi, vi = q[it.coords], v[it.coords]
            if it.rigid:
                kin += 0.5 * p.link.mass * (vi[0] ** 2 + vi[1] ** 2) + 0.5 * p.link.inertia_z * vi[2] ** 2
            else:
                kin += 0.5 * vi @ self.mass_ancf @ vi + 0.5 * p.link.inertia_extra * v[self.i_frame[it.index]] ** 2
                el += self.mesh.strain_energy(qi, ei, ea)
        kin += 0.5 * p.motor.inertia * float(np.sum(s.motor_rates**2))
        el += 0.5 * p.motor.stiffness * float(np.sum((s.motor_angles - s.joint_angles) ** 2))
        psi_w = self._wrist_angles(q)
        for k in range(2):
            if self.grasp_on[k]:
                over = abs(psi_w[k]) - p.wrist.limit
                if over > 0:
                    el += 0.5 * p.wrist.stiffness * over**2
        grav = self._tidal_energy(q) if self.orbit else 0.0
        return np.array([kin, el, grav])

    def _tidal_energy(self, q) -> float:
        p = self.params
        mu = p.orbit.mu
        e = self._mass_base() * float(fld.tidal_potential(mu, self.r_O, q[self.i_base[:2]]))
        e += p.target.mass * float(fld.tidal_potential(mu, self.r_O, q[self.i_target[:2]]))
        for it in self.links:
            qi = q[it.coords]
            if it.rigid:
                L = p.link.length
                xs, ws = links.gauss(8, -0.5 * L, 0.5 * L)
                pts = qi[:2] + np.outer(xs, [math.cos(qi[2]), math.sin(qi[2])])
            else:
                _, ws, pts = self.mesh.points(qi, N_GAUSS_FIELD)
            e += p.link.rho_a * float(np.sum(ws * fld.tidal_potential(mu, self.r_O, pts)))
        return e

    def _momentum(self, q, v) -> np.ndarray:
        p = self.params
        mB = self._mass_base()
        qb, vb, qt, vt = q[self.i_base], v[self.i_base], q[self.i_target], v[self.i_target]
        lin = mB * vb[:2] + p.target.mass * vt[:2]
        ang = mB * _cross(qb[:2], vb[:2]) + p.base.inertia_z * vb[2]
        ang += p.target.mass * _cross(qt[:2], vt[:2]) + p.target.inertia_z * vt[2]
        for it in self.links:
            qi, vi = q[it.coords], v[it.coords]
            if it.rigid:
                lin = lin + p.link.mass * vi[:2]
                ang += p.link.mass * _cross(qi[:2], vi[:2]) + p.link.inertia_z * vi[2]
            else:
                lin = lin + self.first @ vi
                _, ws, rs = self.mesh.points(qi, N_GAUSS_FIELD)
                _, _, vs = self.mesh.points(vi, N_GAUSS_FIELD)
                ang += p.link.rho_a * float(np.sum(ws * (rs[:, 0] * vs[:, 1] - rs[:, 1] * vs[:, 0])))
                ang += p.link.inertia_extra * v[self.i_frame[it.index]]
        return np.array([lin[0], lin[1], ang])
