"""Random reference states that satisfy the grasp constraints, from Pinocchio's kinematics.

A reference state (q, qd, X_T, XT_d) with an active grasp must be consistent: end
effector k on grasp point k, and the velocities satisfying φ̇_k = 0.  States are drawn in
minimal coordinates of a Pinocchio tree and converted with Pinocchio's own kinematics
(`PinocchioRSM.reference_state`), never with the reference model.

Distributions (seeded, one ``numpy.random.default_rng(seed)`` per state):
* base pose x_B, y_B ∈ U(±0.2) m, θ_B ∈ U(±0.2) rad;
* joint angles: nominal arm 1 (60°, −120°, 60°), arm 2 (−60°, 120°, −60°) plus U(±π/2)
  — the nominal pair closes both grasps of the default geometry;
* wrist angles ψ ∈ U(±0.5) rad (the wrist's mechanical range, `params.wrist.limit`
  by default);
* all rates U(±0.3) (rad/s, m/s);
* inputs u_J ∈ U(±τ_max) per joint, τ_B ∈ U(±τ_B,max) (Tables 3, 4).

Closed chain: base, arm 1 and ψ_1 are drawn as above, the target is placed by the
wrist-1 tree, then arm 2's joint angles are solved by least-norm Newton,
Δθ = J⁺ (r_grasp2 − r_EE2), from the drawn arm-2 angles as the start.  A draw is
rejected when Newton does not converge to 1e-13 m, when the 2×3 position Jacobian of
arm 2 is near-singular (σ_min < 0.1 m), where the loop-closure force is ill-conditioned,
or when ψ_2 leaves the wrist range; about one draw in four is accepted.  Rates: a random ẏ projected onto the null space of the loop-closure
Jacobian, ẏ ← (I − A⁺A) ẏ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pinocchio_check.model import N_Q, PinocchioRSM, point_kinematics_y

NOMINAL_ARM1 = np.radians([60.0, -120.0, 60.0])
NOMINAL_ARM2 = np.radians([-60.0, 120.0, -60.0])
BASE_POSE_SPREAD = 0.2
JOINT_SPREAD_OPEN = np.pi / 2
RATE_SPREAD = 0.3
NEWTON_TOL = 1e-13
SIGMA_MIN = 0.1


@dataclass(frozen=True)
class RefState:
    """One consistent reference state with inputs, and the seed that produced it."""

    seed: int
    q: np.ndarray
    qd: np.ndarray
    X_T: np.ndarray
    XT_d: np.ndarray
    u_J: np.ndarray
    tau_B: float
    grasp: tuple[bool, bool]


def _inputs(rng: np.random.Generator, rsm: PinocchioRSM) -> tuple[np.ndarray, float]:
    u_J = rng.uniform(-1.0, 1.0, 6) * rsm.params.motor.torque_max
    tau_B = float(rng.uniform(-1.0, 1.0) * rsm.params.actuators.torque_max)
    return u_J, tau_B


def _base_and_arms(rng: np.random.Generator, spread1: float, spread2: float) -> np.ndarray:
    q = np.empty(N_Q)
    q[:3] = rng.uniform(-BASE_POSE_SPREAD, BASE_POSE_SPREAD, 3)
    q[3:6] = NOMINAL_ARM1 + rng.uniform(-spread1, spread1, 3)
    q[6:9] = NOMINAL_ARM2 + rng.uniform(-spread2, spread2, 3)
    return q


def open_state(rsm: PinocchioRSM, seed: int, arm: int = 1) -> RefState:
    """A state with arm `arm` holding the target (the other arm free), seeded."""
    rng = np.random.default_rng(seed)
    psi_max = rsm.params.wrist.limit
    y = np.append(_base_and_arms(rng, JOINT_SPREAD_OPEN, JOINT_SPREAD_OPEN), rng.uniform(-psi_max, psi_max))
    yd = rng.uniform(-RATE_SPREAD, RATE_SPREAD, N_Q + 1)
    q, qd, X_T, XT_d = rsm.reference_state(arm, y, yd)
    u_J, tau_B = _inputs(rng, rsm)
    return RefState(seed, q, qd, X_T, XT_d, u_J, tau_B, (arm == 1, arm == 2))


def solve_arm2(rsm: PinocchioRSM, y: np.ndarray, max_iter: int = 50) -> tuple[np.ndarray, bool]:
    """Least-norm Newton on arm 2's joint angles y[6:9] so that EE2 = grasp 2 (tree held
    by arm 1).  Returns (y, converged)."""
    pm = rsm.held[1]
    y = y.copy()
    zero = np.zeros_like(y)
    for _ in range(max_iter):
        r_ee, J_ee, _ = point_kinematics_y(pm, y, zero, "ee2")
        r_g, _, _ = point_kinematics_y(pm, y, zero, "grasp2")
        err = r_g - r_ee
        if np.max(np.abs(err)) < NEWTON_TOL:
            return y, True
        y[6:9] += np.linalg.pinv(J_ee[:, 6:9]) @ err
    return y, False


def closed_state(rsm: PinocchioRSM, seed: int, spread: float = JOINT_SPREAD_OPEN) -> RefState | None:
    """A state with both arms holding the target, or None if the seed's draw is rejected."""
    rng = np.random.default_rng(seed)
    psi_max = rsm.params.wrist.limit
    y0 = np.append(_base_and_arms(rng, spread, spread), rng.uniform(-psi_max, psi_max))
    yd0 = rng.uniform(-RATE_SPREAD, RATE_SPREAD, N_Q + 1)
    u_J, tau_B = _inputs(rng, rsm)
    y, ok = solve_arm2(rsm, y0)
    if not ok:
        return None
    pm = rsm.held[1]
    _, J_ee, _ = point_kinematics_y(pm, y, np.zeros_like(y), "ee2")
    if np.linalg.svd(J_ee[:, 6:9], compute_uv=False)[-1] < SIGMA_MIN:
        return None
    _, Jc, _ = rsm.closure_constraint(pm, y, np.zeros_like(y))
    A = Jc @ pm.chart.T(y)
    yd = yd0 - np.linalg.pinv(A) @ (A @ yd0)
    q, qd, X_T, XT_d = rsm.reference_state(1, y, yd)
    # ψ_2 must lie within the wrist range too; otherwise the draw is not a physical grasp.
    psi2 = X_T[2] - q[2] - q[6:9].sum()
    if abs(np.angle(np.exp(1j * psi2))) > psi_max:
        return None
    return RefState(seed, q, qd, X_T, XT_d, u_J, tau_B, (True, True))


def open_states(rsm: PinocchioRSM, n: int, first_seed: int = 0, arm: int = 1) -> list[RefState]:
    return [open_state(rsm, first_seed + i, arm) for i in range(n)]


def closed_states(rsm: PinocchioRSM, n: int, first_seed: int = 0, max_tries: int = 100_000) -> list[RefState]:
    """The first `n` accepted closed-chain states from seeds first_seed, first_seed + 1, …"""
    out: list[RefState] = []
    seed = first_seed
    while len(out) < n:
        if seed - first_seed >= max_tries:
            raise RuntimeError(f"only {len(out)} of {n} closed-chain states accepted in {max_tries} draws")
        s = closed_state(rsm, seed)
        if s is not None:
            out.append(s)
        seed += 1
    return out
