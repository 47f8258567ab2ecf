"""Sensors and observables (docs/observables.md) from a reference-model state: energy,
momentum, the system COM, the wrist angles.

All positions are relative to the co-moving reference point O, inertial axes, unless the
suffix says otherwise (`_B`: base frame about the base COM).
"""

from __future__ import annotations

import math

import numpy as np

from reference_model import kinematics
from reference_model.build import Configuration, ReferenceModel
from reference_model.field import tidal_potential
from reference_model.link import links_tidal_potential
from reference_model.measures import (SENSE_COMB, SENSE_MASS, SENSE_PSI, SENSE_PSID, SENSE_PSIW, SENSE_RE,
                                      SENSE_RED, momentum, sense, sensor_values)
from reference_model.model_arrays import N_LINKS, U_TAU_B, U_TAU_M
from reference_model.solve import solve_constrained
from rsmcheck.core.engine import Sensors
from rsmcheck.core.geometry import rot


def momentum_of_state(model: ReferenceModel, x: np.ndarray, cfg: Configuration) -> np.ndarray:
    """(p_x, p_y, L_z): linear momentum and angular momentum about O of base, links, target
    (`measures.momentum`, exactly from the modal integrals; condensed static shapes at
    their values for the rest of x)."""
    return momentum(model.complete(x, cfg), *model.core_args(cfg))


def energy_of_state(model: ReferenceModel, x: np.ndarray, u: np.ndarray, cfg: Configuration,
                    Mg: np.ndarray) -> np.ndarray:
    """(kinetic, elastic, gravitational) [J].

    kinetic       ½ Ẏᵀ M_g Ẏ + ½ Σ B_m θ̇_m²        (M_g of eq. 6 is the exact kinetic metric)
    elastic       ½ Σ aᵀ K_ff a + ½ Σ K_m (θ_m − ψ_J)² + ½ k_w (|ψ_w| − ψ_lim)² beyond the stops
    gravitational tidal potential about O (orbit on), Gauss points along the links

    Condensed static shapes (condense.py) are taken at their values for the rest of x.
    """
    lay = model.layout
    prm = model.params
    x = model.complete(x, cfg)
    Yd = np.concatenate([x[lay.qd], x[lay.target_d]])
    kinetic = 0.5 * Yd @ Mg @ Yd + 0.5 * prm.motor.inertia * np.sum(x[lay.motors_d] ** 2)
    q = x[lay.q]
    kin = model.kinematics(q, x[lay.qd], cfg)
    el = 0.0
    for i in range(N_LINKS):
        n = lay.n_modes[i]
        a = q[lay.modes(i)]
        el += 0.5 * a @ model.arrays.k_ff[i, cfg.basis[i], :n, :n] @ a
    psi_J, _ = model.joint_section_angles(q, x[lay.qd], cfg)
    el += 0.5 * prm.motor.stiffness * np.sum((x[lay.motors] - psi_J) ** 2)
    psi_w, _ = wrist_angles(model, x, cfg, kin)
    for k in range(2):
        if cfg.grasp_on[k]:
            over = abs(psi_w[k]) - prm.wrist.limit
            if over > 0:
                el += 0.5 * prm.wrist.stiffness * over**2
    grav = 0.0
    if model.orbit:
        grav = tidal_energy(model, x, cfg, kin)
    return np.array([kinetic, el, grav])


def tidal_energy(model: ReferenceModel, x: np.ndarray, cfg: Configuration, kin: kinematics.Kinematics) -> float:
    """Tidal potential energy about O [J]: base and target at their COM, the links over
    their Gauss points (`link.links_tidal_potential`); `kin` the state's kinematics."""
    lay = model.layout
    prm = model.params
    q = x[lay.q]
    rO = x[lay.r_O]
    mB = prm.base.mass - x[lay.m_used]
    e = mB * tidal_potential(rO, q[0:2]) + prm.target.mass * tidal_potential(rO, x[lay.target][0:2])
    e += links_tidal_potential(q, kin.th, kin.R, rO, model.arrays, cfg.basis)
    return prm.orbit.mu * e


def wrist_angles(model: ReferenceModel, x: np.ndarray, cfg: Configuration,
                 kin: kinematics.Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """ψ_w, ψ̇_w of both wrists: θ_T relative to the distal end section of the terminal link
    (docs/physics.md §4.3), whether or not the arm holds the target; `kin` the state's
    kinematics."""
    lay = model.layout
    q, qd = x[lay.q], x[lay.qd]
    return kinematics.wrist_angles(q, qd, x[lay.target], x[lay.target_d], kin.th, kin.om, model.arrays, cfg.basis)


def sensors(model: ReferenceModel, t: float, x: np.ndarray, cfg: Configuration) -> Sensors:
    """What the shared driver's controllers and supervisor read at time t (rsmcheck.core.engine.Sensors);
    condensed static shapes at their values for the rest of x (so that a perturbed state
    reads right, `modes.linear_plant`).  One compiled call (`measures.sense`)."""
    return sensors_of(model, t, sense(np.asarray(x, float), *model.core_args(cfg)), cfg)


def sensors_of(model: ReferenceModel, t: float, v: np.ndarray, cfg: Configuration) -> Sensors:
    """`sensors` from the vector `measures.sense` returned for the state; the fields are views
    of v, which the caller must not write."""
    lay = model.layout
    xc, o = v[:lay.nx], v[lay.nx:]
    q, qd = xc[lay.q], xc[lay.qd]
    return Sensors(
        time=t, base_pose_I=q[0:3], base_rate_I=qd[0:3],
        joint_angles=o[SENSE_PSI:SENSE_PSI + 6], joint_rates=o[SENSE_PSID:SENSE_PSID + 6],
        joint_frame_angles=q[3:9], joint_frame_rates=qd[3:9],
        wrist_angles=o[SENSE_PSIW:SENSE_PSIW + 2],
        motor_angles=xc[lay.motors], motor_rates=xc[lay.motors_d],
        ee_pos_I=o[SENSE_RE:SENSE_RE + 4].reshape(2, 2), ee_vel_I=o[SENSE_RED:SENSE_RED + 4].reshape(2, 2),
        target_pose_I=xc[lay.target], target_rate_I=xc[lay.target_d],
        com_pos_B=o[SENSE_COMB:SENSE_COMB + 2],
        grasp_state=cfg.grasp_on.copy(), system_mass=float(o[SENSE_MASS]),
        orbit_r_I=xc[lay.r_O], orbit_v_I=xc[lay.v_O])


def observables(model: ReferenceModel, t: float, x: np.ndarray, u: np.ndarray, cfg: Configuration,
                capture_arm: int, capture_point_T: np.ndarray) -> dict[str, np.ndarray | float]:
    """Every observable (docs/observables.md) at one instant.

    capture_arm / capture_point_T: the arm whose gap `capture_gap_B` reports and its
    designated capture point (target frame, about the target COM).
    """
    lay = model.layout
    prm = model.params
    x = model.complete(x, cfg)  # condensed static shapes at their values for the rest of x
    q = x[lay.q]
    XT = x[lay.target]
    Mg, f, A, phi, _, Bs, _, _, _, _ = model.assemble(x, u, cfg)
    if model.condensed:  # the accelerations (and R_cl) of the coordinates left, condense.py
        Mz, fz, Az, _, _, Bs, *_ = model.reduced(x, u, cfg)
        _, Rc = solve_constrained(Mz, fz, Az, Bs, model.arrays)
    else:
        _, Rc = solve_constrained(Mg, f, A, Bs, model.arrays)
    rE, rEd, psi_J, _, psi_w, com, msys = sensor_values(x, *model.core_args(cfg))
    AB_T = rot(q[2]).T
    rB = q[0:2]
    reaction = np.zeros(4)
    residual = np.zeros(4)
    row = 0
    for k in range(2):
        if cfg.grasp_on[k]:
            reaction[2 * k:2 * k + 2] = Rc[row:row + 2]
            residual[2 * k:2 * k + 2] = phi[row:row + 2]
            row += 2
    cap = XT[0:2] + rot(XT[2]) @ capture_point_T
    deflection = np.zeros(6)
    for i in range(N_LINKS):
        deflection[i] = model.bases[i][int(cfg.basis[i])].phi_mid @ q[lay.modes(i)]
    # LVLH of the base: x radial outward, y along-track; without an orbit, inertial axes
    r_abs = x[lay.r_O] + rB
    radial = r_abs / np.linalg.norm(r_abs) if model.orbit else np.array([1.0, 0.0])
    along = np.array([-radial[1], radial[0]])
    d_T = XT[0:2] - rB
    alt_vec = x[lay.r_O] + com
    return {
        "time": t,
        "base_pose_I": q[0:3].copy(),
        "target_pose_B": np.array([*(AB_T @ d_T), XT[2] - q[2]]),
        "ee1_pos_B": AB_T @ (rE[0] - rB),
        "ee2_pos_B": AB_T @ (rE[1] - rB),
        "ee2_speed": float(np.linalg.norm(rEd[1])),
        "capture_gap_B": AB_T @ (rE[capture_arm - 1] - cap),
        "com_pos_B": AB_T @ (com - rB),
        "joint_angles": psi_J,
        "joint_frame_angles": q[3:9].copy(),
        "wrist_angles": psi_w,
        "motor_angles": x[lay.motors].copy(),
        "motor_torques": u[U_TAU_M:U_TAU_M + 6].copy(),
        "base_torque": float(u[U_TAU_B]),
        "link_deflection": deflection,
        "target_attitude": float(XT[2]),
        "reaction_forces_I": reaction,
        "constraint_residual": residual,
        "grasp_state": cfg.grasp_on.astype(float),
        "energy": energy_of_state(model, x, u, cfg, Mg),
        "momentum_I": momentum_of_state(model, x, cfg),
        "altitude": float(np.linalg.norm(alt_vec) - prm.orbit.earth_radius) if model.orbit else 0.0,
        "target_rel_lvlh": np.array([d_T @ radial, d_T @ along]),
        "system_mass": float(msys),
    }
