"""The per-sample arithmetic of the shared driver, compiled (numba): the programme
controller's laws (eqs. 13–14 with their references, rate filter and saturations,
`rsmcheck.driver.controllers`) and the supervisor's measurements of the runner (the IF
conditions of capture, the bistop contact state, the capture gap; `rsmcheck.driver.runner`).

Every engine runs through these functions at every control sample (1 ms): one compiled call
in place of some hundred numpy and float operations on small arrays and Python objects
(25–30 µs per sample for the controller alone).  The Python classes of controllers.py keep
the configuration and the programme's logic (segments, references, events) and describe
it to these kernels in flat float arrays (layouts below); the Python formulas there
(`measure`, `base_pd`, `jacobian_transpose`, the references' `__call__`) state the same
equations and are the readable reference the tests compare these kernels with.

Every operation is written in the order and with the rounding of those formulas, and each
rounding is pinned, so that the kernels compute the same bits on every CPU: left-to-right
sums and products as there, ψ reduced by IEEE `remainder` (`_remainder`: CPython's
`math.remainder`), `hypot` correctly rounded as CPython's (`_hypot`), and the 2×2 products
A(a) v that the Python code leaves to numpy written as fma(A_i0, v_0, A_i1 v_1) (`_rot`),
an exact fused multiply-add, as OpenBLAS's x86-64 kernels round them; A(a)ᵀ v plainly.
numpy itself rounds those products as the CPU's kernel family makes it (OpenBLAS's
SkylakeX kernels fuse A(a)ᵀ v too), so the Python formulas equal the kernels to round-off,
not to the bit, on another CPU.  tests/rsmcheck/test_control_kernels.py checks the blocks to
the bit against references that round alike everywhere (CPython's floats and math, exact
rationals), and the laws against their Python formulas to round-off.

Layouts (float64 arrays, filled by `controllers.ProgrammeController`):

* `law` (LAW_SIZE): the controller's constants and base mode, `L_*` offsets;
* `refs` (2, REF_SIZE): one row per arm, `refs[k, 0]` the kind (`REF_*`), then its
  parameters (`reference_row` of each kind in controllers.py);
* `filt` (7): the rate filter's state: time of the last sample (NaN before the first), the
  six filtered joint rates;
* `out` (7): τ_m (6) and τ_B, saturated.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

TWO_PI = 2.0 * math.pi

# ---- the law's constants: offsets in `law` ------------------------------------------------
L_MOUNT = 0  # (x, y) of arm 1's mount, then arm 2's, base frame [m]
L_LENGTH = 4  # link length L [m]
L_KP = 5  # K_p of arm 1 (x, y, φ), then arm 2
L_KD = 11  # K_d of arm 1 (joints 1–3), then arm 2
L_BASE_KP = 17  # k_p,B of eq. (13)
L_BASE_KD = 18  # k_d,B
L_MU = 19  # μ of the Earth (the retrograde attitude)
L_TAU_M_MAX = 20  # |τ_m| ≤ τ_m,max (Table 4)
L_TAU_B_MAX = 21  # |τ_B| ≤ τ_B,max (Table 3)
L_KINEMATIC = 22  # 1: e_EE from the rigid model's tip (feedback = "kinematic"), 0: measured
L_FILTER_HZ = 23  # f_c of the rate filter, 0: none
L_PERIOD = 24  # the control period (the rate filter's first interval) [s]
L_BASE_MODE = 25  # BASE_*
L_BASE_GOAL = 26  # θ_B^des of BASE_GOAL [rad]
LAW_SIZE = 27

# ---- the base modes ---------------------------------------------------------------------
BASE_OFF = 0  # τ_B = 0
BASE_GOAL = 1  # eq. (13) about a fixed attitude (hold, freeze, angle)
BASE_RETROGRADE = 2  # eq. (13) about the retrograde attitude and its rate

# ---- the arm references: refs[k, 0], parameters from refs[k, 1] ---------------------------
REF_OPEN = 0  # no feedback: open-loop torques (3) (modes off, torque)
REF_FIXED = 1  # desired pose (3)
REF_MOVE = 2  # quintic p0 (3), p1 (3), t0, T
REF_APPROACH = 3  # entry pose (3), point ρ (2) of the target, φ goal, t0, T
REF_HELD = 4  # target pose: TARGET_* kind, x0 (3), x1 (3), t0, T; grasp point ρ (2), ψ0
REF_SIZE = 16

TARGET_FIXED = 0  # the desired target pose is x0
TARGET_QUINTIC = 1  # x0 + s(t)(x1 − x0)


# ---------------------------------------------------------------------------------------
# Floating-point building blocks (each the rounding of the Python formula it stands for)
# ---------------------------------------------------------------------------------------
@intrinsic
def fma(typingctx, a, b, c):
    """a·b + c rounded once (IEEE fused multiply-add)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True, inline="always")
def _rot(a_cos, a_sin, vx, vy):  # pragma: no cover - compiled
    """A(a) v, A = [[c, −s], [s, c]], rounded as numpy's product rot(a) @ v (module docstring)."""
    return fma(a_cos, vx, -a_sin * vy), fma(a_sin, vx, a_cos * vy)


@njit(cache=True, inline="always")
def _rot_t(a_cos, a_sin, vx, vy):  # pragma: no cover - compiled
    """A(a)ᵀ v = (c v_x + s v_y, −s v_x + c v_y)."""
    return a_cos * vx + a_sin * vy, -a_sin * vx + a_cos * vy


@njit(cache=True)
def _remainder(x, y):  # pragma: no cover - compiled
    """IEEE 754 remainder x − n y, n the integer nearest x/y (ties to even): `math.remainder`,
    by the same exact steps (fmod is exact; so is the half-way correction)."""
    if math.isfinite(x) and math.isfinite(y):
        if y == 0.0:
            return math.nan
        absx = abs(x)
        absy = abs(y)
        m = np.fmod(absx, absy)
        c = absy - m
        if m < c:
            r = m
        elif m > c:
            r = -c
        else:  # half way: the r of the even quotient
            r = m - 2.0 * np.fmod(0.5 * (absx - m), absy)
        return math.copysign(1.0, x) * r
    if math.isnan(x):
        return x
    if math.isnan(y):
        return y
    if math.isinf(x):
        return math.nan
    return x


@njit(cache=True)
def _hypot(x, y):  # pragma: no cover - compiled
    """√(x² + y²) correctly rounded, as `math.hypot` (CPython's is correctly rounded in all
    but vanishingly rare cases; libm's need not be): h from the fused sum, then one Newton
    correction with the exact residual x² + y² − h² (Borges 2019, "An improved algorithm
    for hypot(a, b)", fused variant)."""
    x = abs(x)
    y = abs(y)
    if math.isinf(x) or math.isinf(y):
        return math.inf
    if math.isnan(x) or math.isnan(y):
        return math.nan
    if x < y:
        x, y = y, x
    if y == 0.0:
        return x
    # scale by a power of two so that the squares neither overflow nor underflow
    _, e = math.frexp(x)
    scale = math.ldexp(1.0, -e)
    x *= scale
    y *= scale
    h = math.sqrt(fma(x, x, y * y))
    h_sq = h * h
    x_sq = x * x
    delta = fma(-y, y, h_sq - x_sq) + fma(h, h, -h_sq) - fma(x, x, -x_sq)
    h = h - delta / (2.0 * h)
    return h / scale


@njit(cache=True)
def quintic_s(t, t0, duration):  # pragma: no cover - compiled
    """s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ = τ³ (10 + τ(−15 + 6τ)), τ = (t − t0)/T clipped to [0, 1]
    (`rsmcheck.core.trajectories.quintic`, its first value)."""
    if duration <= 0.0:
        return 1.0
    tau = (t - t0) / duration
    if tau <= 0.0:
        return 0.0
    if tau >= 1.0:
        return 1.0
    return tau ** 3.0 * (10.0 + tau * (-15.0 + 6.0 * tau))


@njit(cache=True)
def wrap_near(angle, reference):  # pragma: no cover - compiled
    """angle + 2πk closest to `reference` (k = round((reference − angle)/2π), ties to even)."""
    return angle + TWO_PI * np.rint((reference - angle) / TWO_PI)


@njit(cache=True)
def retrograde_attitude(rx, ry, vx, vy, mu):  # pragma: no cover - compiled
    """θ = atan2(−v), θ̇ = (v × a)/|v|², a = −μ r/|r|³ (`controllers.retrograde_attitude`)."""
    if vx == 0.0 and vy == 0.0:
        return 0.0, 0.0
    rn3 = _hypot(rx, ry) ** 3.0
    ax = -mu * rx / rn3
    ay = -mu * ry / rn3
    return math.atan2(-vy, -vx), (vx * ay - vy * ax) / (vx * vx + vy * vy)


# ---------------------------------------------------------------------------------------
# The programme controller
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def _desired(ref, t, tgt_x, tgt_y, tgt_th, out):  # pragma: no cover - compiled
    """Desired (x, y, φ) of one end effector at t (base frame about the base COM) for the
    reference row `ref`, the target measured at (tgt_x, tgt_y, tgt_th) in the base frame:

      fixed     p
      move      p0 + s(t) (p1 − p0)
      approach  (x, y) = p0 + s(t) (r_T + A(θ_T) ρ − p0),  φ = φ0 + s(t) (φ1 − φ0)
      held      x_T(t) the desired target pose (fixed or a quintic);
                (x, y) = x_T + A(θ_T) ρ,  φ = θ_T − ψ0
    """
    kind = int(ref[0])
    if kind == REF_FIXED:
        out[0], out[1], out[2] = ref[1], ref[2], ref[3]
    elif kind == REF_MOVE:
        s = quintic_s(t, ref[7], ref[8])
        for i in range(3):
            out[i] = ref[1 + i] + s * (ref[4 + i] - ref[1 + i])
    elif kind == REF_APPROACH:
        s = quintic_s(t, ref[7], ref[8])
        c, sn = math.cos(tgt_th), math.sin(tgt_th)
        lx, ly = _rot(c, sn, ref[4], ref[5])
        out[0] = ref[1] + s * ((tgt_x + lx) - ref[1])
        out[1] = ref[2] + s * ((tgt_y + ly) - ref[2])
        out[2] = ref[3] + s * (ref[6] - ref[3])
    else:  # REF_HELD
        if int(ref[1]) == TARGET_QUINTIC:
            s = quintic_s(t, ref[8], ref[9])
            x = ref[2] + s * (ref[5] - ref[2])
            y = ref[3] + s * (ref[6] - ref[3])
            th = ref[4] + s * (ref[7] - ref[4])
        else:
            x, y, th = ref[2], ref[3], ref[4]
        c, sn = math.cos(th), math.sin(th)
        lx, ly = _rot(c, sn, ref[10], ref[11])
        out[0] = x + lx
        out[1] = y + ly
        out[2] = th - ref[12]


@njit(cache=True)
def _saturate(x, limit):  # pragma: no cover - compiled
    """x clipped to [−limit, limit]; NaN stays NaN (as numpy's minimum/maximum)."""
    if x < -limit:
        return -limit
    if x > limit:
        return limit
    return x


@njit(cache=True)
def programme_inputs(t, base_pose, base_rate, joint_angles, joint_rates, ee_pos, target_pose, orbit_r, orbit_v,
                     law, refs, filt, out):  # pragma: no cover - compiled
    """The programme controller's inputs at one sample (`ProgrammeController.__call__`), into
    `out` = (τ_m1..6, τ_B), saturated; updates the rate filter `filt`.

    Measurements, base frame about the base COM (A(θ_B)ᵀ of the inertial differences):
      e_k = (A(θ_B)ᵀ (r_EE,k − r_B), ψ_J1 + ψ_J2 + ψ_J3)  (measured), or the rigid model's
            tip from ψ_J (kinematic: pins p_0 = mount, p_s = p_{s−1} + L (cos, sin)(Σ ψ));
      target (A(θ_B)ᵀ (r_T − r_B), θ_T − θ_B).
    Rate filter (first order, exact for the sample interval Δt):
      r ← r + α (ψ̇_J − r),  α = 1 − exp(−2π f_c Δt)  (α = 1 without the filter).
    Eq. (14), each arm with a reference (e = e_k − e_des, e_φ reduced to (−π, π]):
      τ_s = (e − p_s)_y K_p,x e_x − (e − p_s)_x K_p,y e_y − K_p,φ e_φ − K_d,s r_s,
      e the tip p_3 of the rigid model (J_EEᵀ K_p e with the columns (−(e − p_s)_y, (e − p_s)_x, 1));
      an arm without a reference: its open-loop torques.
    Eq. (13):  τ_B = −k_p,B (θ_B − θ_B^des) − k_d,B (θ̇_B − θ̇_B^des),
      θ^des fixed (θ̇^des = 0) or the retrograde attitude and rate (wrapped next to θ_B).
    Saturation: |τ_m| ≤ τ_m,max, |τ_B| ≤ τ_B,max.
    """
    xb, yb, th = base_pose[0], base_pose[1], base_pose[2]
    c, sn = math.cos(th), math.sin(th)
    length = law[L_LENGTH]
    dx, dy = target_pose[0] - xb, target_pose[1] - yb
    tgt_x, tgt_y = _rot_t(c, sn, dx, dy)
    tgt_th = target_pose[2] - th
    # the rate filter
    t_prev = filt[0]
    dt = law[L_PERIOD] if math.isnan(t_prev) or t <= t_prev else t - t_prev
    filt[0] = t
    fc = law[L_FILTER_HZ]
    alpha = 1.0 - math.exp(-2.0 * math.pi * fc * dt) if fc > 0 else 1.0
    for j in range(6):
        filt[1 + j] += alpha * (joint_rates[j] - filt[1 + j])
    desired = np.empty(3)
    px = np.empty(4)
    py = np.empty(4)
    for k in range(2):
        ref = refs[k]
        if int(ref[0]) == REF_OPEN:
            for s in range(3):
                out[3 * k + s] = ref[1 + s]
            continue
        q0, q1, q2 = joint_angles[3 * k], joint_angles[3 * k + 1], joint_angles[3 * k + 2]
        # the rigid model's pins (arm_pins): mount, elbows, tip
        px[0], py[0] = law[L_MOUNT + 2 * k], law[L_MOUNT + 2 * k + 1]
        theta = 0.0
        for s in range(3):
            theta += joint_angles[3 * k + s]
            px[s + 1] = px[s] + length * math.cos(theta)
            py[s + 1] = py[s] + length * math.sin(theta)
        if law[L_KINEMATIC] != 0.0:
            ex, ey = px[3], py[3]
        else:
            ex, ey = _rot_t(c, sn, ee_pos[k, 0] - xb, ee_pos[k, 1] - yb)
        ephi = q0 + q1 + q2
        _desired(ref, t, tgt_x, tgt_y, tgt_th, desired)
        err_x = ex - desired[0]
        err_y = ey - desired[1]
        err_phi = _remainder(ephi - desired[2], TWO_PI)
        fx = law[L_KP + 3 * k] * err_x
        fy = law[L_KP + 3 * k + 1] * err_y
        fphi = law[L_KP + 3 * k + 2] * err_phi
        for s in range(3):
            tau = (py[3] - py[s]) * fx - (px[3] - px[s]) * fy - fphi - law[L_KD + 3 * k + s] * filt[1 + 3 * k + s]
            out[3 * k + s] = tau
    tau_b = 0.0
    mode = int(law[L_BASE_MODE])
    if mode != BASE_OFF:
        if mode == BASE_RETROGRADE:
            goal, rate = retrograde_attitude(orbit_r[0], orbit_r[1], orbit_v[0], orbit_v[1], law[L_MU])
            goal = wrap_near(goal, th)
        else:
            goal, rate = law[L_BASE_GOAL], 0.0
        tau_b = -law[L_BASE_KP] * (th - goal) - law[L_BASE_KD] * (base_rate[2] - rate)
    tm = law[L_TAU_M_MAX]
    for j in range(6):
        out[j] = _saturate(out[j], tm)
    out[6] = _saturate(tau_b, law[L_TAU_B_MAX])


# ---------------------------------------------------------------------------------------
# The runner's supervisor
# ---------------------------------------------------------------------------------------
@njit(cache=True)
def capture_point(target_pose, target_rate, rho_x, rho_y):  # pragma: no cover - compiled
    """Inertial position and velocity of the target point ρ (target frame, about the COM):
    p = r_T + A(θ_T) ρ,  v = ṙ_T + θ̇_T (−l_y, l_x), l = A(θ_T) ρ."""
    c, sn = math.cos(target_pose[2]), math.sin(target_pose[2])
    lx, ly = _rot(c, sn, rho_x, rho_y)
    w = target_rate[2]
    return target_pose[0] + lx, target_pose[1] + ly, target_rate[0] + w * -ly, target_rate[1] + w * lx


@njit(cache=True)
def supervise(target_pose, target_rate, ee_pos, ee_vel, wrist_angles, grasp_state, arm, rho, wrist_limit,
              out):  # pragma: no cover - compiled
    """What the runner checks at every sample, into `out`:

      out[0], out[1]  bistop contact of arm 1, 2 (1.0: the arm holds the target and
                      |ψ_w| > ψ_lim);
      out[2], out[3]  for the armed capture (`arm` 1 or 2, 0: none) at the target point ρ:
                      gap |r_EE − p| and relative speed |ṙ_EE − v| (`capture_point`),
                      the two IF conditions' measures (Sect. 2).
    """
    for k in range(2):
        out[k] = 1.0 if grasp_state[k] != 0 and abs(wrist_angles[k]) > wrist_limit else 0.0
    if arm == 0:
        out[2] = out[3] = math.nan
        return
    px, py, vx, vy = capture_point(target_pose, target_rate, rho[0], rho[1])
    dx, dy = ee_pos[arm - 1, 0] - px, ee_pos[arm - 1, 1] - py
    ux, uy = ee_vel[arm - 1, 0] - vx, ee_vel[arm - 1, 1] - vy
    out[2] = math.sqrt(dx * dx + dy * dy)
    out[3] = math.sqrt(ux * ux + uy * uy)


@njit(cache=True)
def capture_gap(base_pose, target_pose, ee_pos, arm, rho, out):  # pragma: no cover - compiled
    """End effector `arm` minus the target point ρ, base axes: A(θ_B)ᵀ (r_EE − p)."""
    c, sn = math.cos(target_pose[2]), math.sin(target_pose[2])
    lx, ly = _rot(c, sn, rho[0], rho[1])
    dx = ee_pos[arm - 1, 0] - (target_pose[0] + lx)
    dy = ee_pos[arm - 1, 1] - (target_pose[1] + ly)
    cb, sb = math.cos(base_pose[2]), math.sin(base_pose[2])
    out[0], out[1] = _rot_t(cb, sb, dx, dy)
