"""What the MuJoCo model reports: the driver's sensors and every observable of
docs/observables.md, rebuilt from MuJoCo's state (qpos, qvel, body positions and
velocities, the mass matrix, the equality forces) by the conventions of docs/physics.md.

Link frames (docs/physics.md §2.1), from the pieces' material lines r(s) (exact, not the
linearised frame tendon): PP, the chord through both pins; PF, the rigid-mode frame, whose
x-axis is V = ∫ρ s (r(s) − R) ds.  Each piece is straight, so V is a closed sum.
"""

from __future__ import annotations

import math

import numpy as np

from mujoco_model import field as fld
from mujoco_model.build import MujocoModel, frame_inertia
from rsmcheck.core.engine import Inputs, Sensors
from rsmcheck.core.geometry import rot


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _perp(a):
    return np.stack([-a[..., 1], a[..., 0]], axis=-1)


class Kinematics:
    """The pieces of the six links at the current state (arrays (2, 3, N + 1, …)): origin
    positions and velocities, directions, absolute angles and rates; the frames' angles
    and rates (2, 3); the distal pins (2, 3, 2) and their velocities."""

    def __init__(self, mm: MujocoModel, d, basis: list[str]):
        ix, b = mm.index, mm.bounds
        pb = ix.piece_body
        self.ang = ix.angle @ d.qpos
        self.rate = ix.angle @ d.qvel
        self.e = np.stack([np.cos(self.ang), np.sin(self.ang)], axis=-1)
        self.o = d.xpos[pb][..., :2]
        root = mm.model.body_rootid[pb]
        cv = d.cvel[pb]
        lever = d.xpos[pb] - d.subtree_com[root]
        self.od = cv[..., 3:5] + cv[..., 2:3] * _perp(lever[..., :2])
        a, bb = b[:, 0], b[:, 1]
        length = (bb - a)[:, None]
        self.distal = self.o[:, :, -1] + length[-1] * self.e[:, :, -1]
        self.distal_v = self.od[:, :, -1] + length[-1] * self.rate[:, :, -1, None] * _perp(self.e[:, :, -1])
        R, Rd = self.o[:, :, 0], self.od[:, :, 0]
        # PP: the chord; PF: V = Σ_p (o_p − R − a_p e_p)(b_p² − a_p²)/2 + e_p (b_p³ − a_p³)/3
        c1 = ((bb**2 - a**2) / 2.0)[:, None]
        c2 = ((bb**3 - a**3) / 3.0)[:, None]
        ed = self.rate[..., None] * _perp(self.e)
        V = np.sum((self.o - R[:, :, None] - a[:, None] * self.e) * c1 + self.e * c2, axis=2)
        Vd = np.sum((self.od - Rd[:, :, None] - a[:, None] * ed) * c1 + ed * c2, axis=2)
        chord, chord_d = self.distal - R, self.distal_v - Rd
        pf = np.array([[basis[3 * k + i] == "PF" for i in range(3)] for k in range(2)])
        X = np.where(pf[..., None], V, chord)
        Xd = np.where(pf[..., None], Vd, chord_d)
        e0 = self.e[:, :, 0]
        self.frame = self.ang[:, :, 0] + np.arctan2(_cross(e0, X), np.sum(e0 * X, axis=-1))
        self.frame_rate = _cross(X, Xd) / np.sum(X * X, axis=-1)
        self.bounds = b

    def point(self, s: float) -> np.ndarray:
        """(2, 3, 2) the material point at abscissa s of every link."""
        p = int(np.searchsorted(self.bounds[:, 1], s))
        p = min(p, self.bounds.shape[0] - 1)
        return self.o[:, :, p] + (s - self.bounds[p, 0]) * self.e[:, :, p]


class Observer:
    """Sensors and observables of the engine's model and state (`engine` gives `mm`, `d`,
    `state`; `forward(inputs)` refreshes MuJoCo's derived quantities with the inputs held)."""

    def __init__(self, engine, capture_arm: int, capture_point: np.ndarray):
        self.engine = engine
        self.capture_arm = capture_arm
        self.capture_point = np.asarray(capture_point, float)

    def kin(self) -> Kinematics:
        e = self.engine
        return Kinematics(e.mm, e.d, e.state.basis)

    def sensors(self) -> Sensors:
        e = self.engine
        e.refresh()
        mm, d, st = e.mm, e.d, e.state
        ix = mm.index
        kin = self.kin()
        q, v = d.qpos, d.qvel
        psi = (q[ix.rotor] + q[ix.spring]).reshape(6)
        psid = (v[ix.rotor] + v[ix.spring]).reshape(6)
        thB, omB = q[ix.base[2]], v[ix.base[2]]
        fr = np.concatenate([[thB], kin.frame[0], [thB], kin.frame[1]])
        frd = np.concatenate([[omB], kin.frame_rate[0], [omB], kin.frame_rate[1]])
        theta_J = np.concatenate([np.diff(fr[:4]), np.diff(fr[4:])])
        theta_Jd = np.concatenate([np.diff(frd[:4]), np.diff(frd[4:])])
        XT = q[ix.target].copy()
        wrist = XT[2] - kin.ang[:, 2, -1]
        m = mm.model
        mass = m.body_mass
        com = mass @ d.xipos[:, :2] / float(mass.sum())
        return Sensors(
            time=st.t, base_pose_I=q[ix.base].copy(), base_rate_I=v[ix.base].copy(), joint_angles=psi,
            joint_rates=psid, joint_frame_angles=theta_J, joint_frame_rates=theta_Jd,
            motor_angles=q[ix.rotor].reshape(6).copy(), motor_rates=v[ix.rotor].reshape(6).copy(),
            ee_pos_I=kin.distal[:, 2].copy(), ee_vel_I=kin.distal_v[:, 2].copy(),
            target_pose_I=XT, target_rate_I=v[ix.target].copy(),
            com_pos_B=rot(thB).T @ (com - q[ix.base[:2]]), wrist_angles=wrist,
            grasp_state=st.grasp_on.copy(), system_mass=float(mass.sum()),
            orbit_r_I=st.r_O.copy(), orbit_v_I=st.v_O.copy())

    def observables(self, inputs: Inputs) -> dict:
        e = self.engine
        s = self.sensors()
        e.forward(inputs)  # the equality forces with the coming period's inputs held
        mm, d, st = e.mm, e.d, e.state
        p, ix = mm.params, mm.index
        kin = self.kin()
        q = d.qpos
        rB, thB = q[ix.base[:2]], q[ix.base[2]]
        AB_T = rot(thB).T
        XT = q[ix.target]
        rE = s.ee_pos_I
        cap = XT[:2] + rot(XT[2]) @ self.capture_point
        reaction = e.grasp_forces()
        residual = np.zeros(4)
        for k in range(2):
            if st.grasp_on[k]:
                residual[2 * k:2 * k + 2] = rE[k] - (XT[:2] + rot(XT[2]) @ st.rho_G[k])
        mid = kin.point(0.5 * p.link.length)
        n_frame = np.stack([-np.sin(kin.frame), np.cos(kin.frame)], axis=-1)
        deflection = np.sum(n_frame * (mid - kin.o[:, :, 0]), axis=-1).reshape(6)
        com = mm.model.body_mass @ d.xipos[:, :2] / s.system_mass
        r_abs = st.r_O + rB
        radial = r_abs / np.linalg.norm(r_abs) if e.orbit else np.array([1.0, 0.0])
        along = np.array([-radial[1], radial[0]])
        d_T = XT[:2] - rB
        return {
            "time": st.t,
            "base_pose_I": q[ix.base].copy(),
            "target_pose_B": np.array([*(AB_T @ d_T), XT[2] - thB]),
            "ee1_pos_B": AB_T @ (rE[0] - rB),
            "ee2_pos_B": AB_T @ (rE[1] - rB),
            "ee2_speed": float(np.linalg.norm(s.ee_vel_I[1])),
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
            "grasp_state": st.grasp_on.astype(float),
            "energy": self.energy(s),
            "momentum_I": self.momentum(),
            "altitude": float(np.linalg.norm(st.r_O + com) - p.orbit.earth_radius) if e.orbit else 0.0,
            "target_rel_lvlh": np.array([d_T @ radial, d_T @ along]),
            "system_mass": float(s.system_mass),
        }

    def energy(self, s: Sensors) -> np.ndarray:
        """Kinetic (½ q̇ᵀ M q̇ with MuJoCo's M: bodies, rotor armature, frame tendons),
        elastic (bending hinges, joint springs, the wrist stop of a holding arm) and tidal
        potential energy [J]."""
        e = self.engine
        mm, d = e.mm, e.d
        m, ix, p = mm.model, mm.index, mm.params
        M = e.mass_matrix()
        kin_e = 0.5 * float(d.qvel @ M @ d.qvel)
        el = 0.5 * float(np.sum(m.jnt_stiffness[m.dof_jntid] * d.qpos**2))
        for k in range(2):
            if e.state.grasp_on[k]:
                over = abs(s.wrist_angles[k]) - p.wrist.limit
                if over > 0:
                    el += 0.5 * p.wrist.stiffness * over**2
        grav = self.tidal_energy() if e.orbit else 0.0
        return np.array([kin_e, el, grav])

    def _quadrature(self):
        """Points (…, 2) and masses (…) of every body: base and target at their COM, each
        link piece at its two Gauss points."""
        e = self.engine
        mm, d = e.mm, e.d
        m, ix = mm.model, mm.index
        pb = ix.piece_body.reshape(-1)
        le = np.tile(mm.bounds[:, 1] - mm.bounds[:, 0], 6)
        ex = d.xmat[pb][:, [0, 3]]
        c = d.xipos[pb][:, :2]
        pts = c[:, None, :] + (0.5 * le)[:, None, None] * fld.GAUSS[None, :, None] * ex[:, None, :]
        w = np.repeat((0.5 * m.body_mass[pb])[:, None], 2, axis=1)
        pts = np.concatenate([pts.reshape(-1, 2), d.xipos[[ix.base_body, ix.target_body]][:, :2]])
        w = np.concatenate([w.reshape(-1), m.body_mass[[ix.base_body, ix.target_body]]])
        return pts, w

    def tidal_energy(self) -> float:
        e = self.engine
        pts, w = self._quadrature()
        return float(w @ fld.tidal_potential(e.mm.params.orbit.mu, e.state.r_O, pts))

    def momentum(self) -> np.ndarray:
        """Linear and angular momentum about O of the bodies, plus the frame tendons' J
        (J_extra and the pieces' left-out rotary inertia) at the tendons' rates; the rotors'
        own momentum is outside, as in the reduced model (docs/physics.md §3.4)."""
        e = self.engine
        mm, d = e.mm, e.d
        m, ix = mm.model, mm.index
        bodies = np.arange(1, m.nbody)
        cv = d.cvel[bodies]
        root = m.body_rootid[bodies]
        lever = d.xipos[bodies] - d.subtree_com[root]
        v = cv[:, 3:5] + cv[:, 2:3] * _perp(lever[:, :2])
        mass = m.body_mass[bodies]
        lin = mass @ v
        izz = m.body_inertia[bodies, 2]
        ang = float(np.sum(mass * _cross(d.xipos[bodies, :2], v)) + izz @ cv[:, 2])
        rows = e.frame_rows()
        ang += frame_inertia(mm.params, mm.n) * float(np.sum(rows @ d.qvel))
        return np.array([lin[0], lin[1], ang])


def wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi
