"""The sampled closed loop of a programme case, linearised: growth rates of its modes in
both engines (p1_rigid_gains: docs/controllers.md, docs/records.md).

Each engine supplies its own continuous plant at rest in the case's initial configuration
(orbit off): ẋ = A x + B u, y = C x (`modes.linear_plant` of each engine package, the same
function in both: rsmcheck/core/engine.py).  The rest is the shared controller's laws
(rsmcheck.driver.controllers, physics.md §6), linearised about a hold of that configuration:

    r_k = (1 − α) r_{k−1} + α ψ̇_J(t_k)                 rate filter (a case option), α = 1 − e^{−2π f_c Δt}
                                                      (α = 1 without it: eq. 14 as written)
    τ_k = −J_EEᵀ K_p e_EE(t_k) − K_d r_k (each arm),     eq. (14), ψ̇_J the link-side joint rates
    τ_B,k = −k_p θ_B(t_k) − k_d θ̇_B(t_k)                 eq. (13)

held over [t_k, t_k+Δt) (zero-order hold), so that with Φ = e^{AΔt}, Γ = ∫₀^Δt e^{As} ds B
(one matrix exponential of [[A, B], [0, 0]]Δt) the loop is x_{k+1} = Φ x_k + Γ u_k.  The
closed-loop multipliers μ of [x_k, r_{k−1}] give s = ln μ / Δt: σ = Re s [1/s], f = Im s/2π.
The saturation is left out (a linear analysis).

    python -m rsmcheck.orchestration.closed_loop [CASE] [--modes N] [--elements N]
"""

from __future__ import annotations

import argparse
import math
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.linalg import expm

from rsmcheck.core.cases import at_rest, load_case, without_orbit
from rsmcheck.core.plugins import default_engines, plugin
from rsmcheck.driver.controllers import ArmModel, measure

N_INPUTS = 7  # τ_m1..6, τ_B
#: y = [θ_J (6), θ̇_J (6), x, y, φ of end effector 1 and 2 in the base frame (6), θ_B, θ̇_B]
I_RATES = slice(6, 12)
I_EE = 12
I_BASE = 18


def _outputs(arms):
    def outputs(s) -> np.ndarray:
        m = measure(s, arms, "measured")
        return np.concatenate([s.joint_angles, s.joint_rates, m.ee_B[0], m.ee_B[1],
                               [s.base_pose_I[2], s.base_rate_I[2]]])
    return outputs


def controller_gains(case, joint_angles) -> tuple[np.ndarray, np.ndarray, float]:
    """(K_y, K_r, α): τ = −K_y y − K_r r of the hold (eqs. 13, 14 linearised), filter α."""
    spec, params = case.controller, case.params
    dt = case.solver.control_period
    ky, kr = np.zeros((N_INPUTS, 20)), np.zeros((N_INPUTS, 6))
    for k, gains in enumerate((spec.arm1, spec.arm2)):
        jac = ArmModel(params, k + 1).jacobian(np.asarray(joint_angles[3 * k:3 * k + 3]))
        ky[3 * k:3 * k + 3, I_EE + 3 * k:I_EE + 3 * k + 3] = jac.T @ np.diag(gains.kp)
        kr[3 * k:3 * k + 3, 3 * k:3 * k + 3] = np.diag(gains.kd)
    ky[6, I_BASE], ky[6, I_BASE + 1] = spec.base.kp, spec.base.kd
    fc = spec.rate_filter_hz
    alpha = 1.0 - math.exp(-2.0 * math.pi * fc * dt) if fc > 0 else 1.0
    return ky, kr, alpha


def closed_loop_exponents(A, B, C, ky, kr, alpha: float, dt: float) -> np.ndarray:
    """s = ln μ / Δt of the sampled loop (module docstring)."""
    n = A.shape[0]
    aug = expm(np.block([[A, B], [np.zeros((N_INPUTS, n + N_INPUTS))]]) * dt)
    phi, gam = aug[:n, :n], aug[:n, n:]
    cr = C[I_RATES]
    if alpha == 1.0:
        # no filter: r_k = C_r x_k, no state of its own;  x_{k+1} = Φ x_k − Γ (K_y C + K_r C_r) x_k
        mu = np.linalg.eigvals(phi - gam @ (ky @ C + kr @ cr))
    else:
        # r_k = (1−α) r_{k−1} + α C_r x_k;  x_{k+1} = Φ x_k − Γ (K_y C x_k + K_r r_k)
        top = np.hstack([phi - gam @ ky @ C - alpha * gam @ kr @ cr, -(1 - alpha) * gam @ kr])
        bottom = np.hstack([alpha * cr, (1 - alpha) * np.eye(6)])
        mu = np.linalg.eigvals(np.vstack([top, bottom]))
    mu = mu[mu != 0.0]  # a state the hold maps to zero in one sample (no dynamics to report)
    return np.log(mu.astype(complex)) / dt


def rotor_modes(s: np.ndarray, f_lo: float = 60.0, f_hi: float = 200.0, sigma_max: float = 200.0) -> np.ndarray:
    """The exponents with f in [f_lo, f_hi] Hz and |σ| < sigma_max: the rotor modes (81–89 Hz
    open loop: each rotor against its joint spring and the links' end sections; the sampled
    rate feedback moves them, up to 140 Hz at p1's rigid-model gains), by frequency (the
    axial modes of the FE links alias into the band but decay at ~1e4/s)."""
    keep = (s.imag > 2 * np.pi * f_lo) & (s.imag < 2 * np.pi * f_hi) & (np.abs(s.real) < sigma_max)
    s = s[keep]
    return s[np.argsort(s.imag)]


def analyse(case, options: Mapping[str, Mapping[str, Any]] | None = None,
            engines: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Closed-loop rotor-mode exponents of `case` (at rest, initial configuration) in each
    engine (default: the default engines), each from its plug-in's `linear_plant` with its
    `options`: {engine: s}."""
    options = options or {}
    case = without_orbit(at_rest(case))
    arms = (ArmModel(case.params, 1), ArmModel(case.params, 2))  # arms are numbered 1 and 2
    outputs = _outputs(arms)
    q_joint = np.radians(case.initial.joint_angles_deg)
    ky, kr, alpha = controller_gains(case, q_joint)
    dt = case.solver.control_period
    out = {}
    for name in engines or default_engines():
        plant = plugin(name).linear_plant(case, outputs, N_INPUTS, **options.get(name, {}))
        out[name] = rotor_modes(closed_loop_exponents(*plant, ky, kr, alpha, dt))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m rsmcheck.orchestration.closed_loop",
                                description=__doc__.split("\n")[0])
    p.add_argument("case", nargs="?", default="p1_rigid_gains")
    args = p.parse_args(argv)
    res = analyse(load_case(args.case))
    print(f"{args.case}: closed-loop rotor modes at rest in the initial configuration")
    print("".join(f" {'f ' + e[:8] + ' [Hz]':>15s} {'σ ' + e[:8] + ' [1/s]':>15s}" for e in res))
    for modes in zip(*res.values()):
        print("".join(f" {s.imag / 2 / np.pi:15.4f} {s.real:+15.5f}" for s in modes))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
