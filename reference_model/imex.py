"""IMEX integrator of the reference: the additive Runge–Kutta pair ARK5(4)8L[2]SA of
Kennedy & Carpenter (2003) with error control (numba), the stiff shapes implicit.

Why it exists: the static correction shapes as Ritz states (`static_modes = "explicit"`,
docs/physics.md §2.4; slaved, the default, they are not states) put the flexible
model's highest eigenvalues near 0.8–0.9 kHz (damped at 23–27 %), which holds the explicit
Dormand–Prince pair (`dopri5.py`) by stability near 0.46 ms, two to three steps per 1 ms
control sample.  Here the right-hand side is split as

    ẋ = f(x) = f_E(x) + f_I(x),   f_I(x) = L x_S,   f_E(x) = f(x) − L x_S,

with S the state components of the stiff shapes (their amplitudes and rates: every shape
whose own frequency √(k_jj/m_jj)/2π exceeds `STIFF_HZ`) and L = ∂f/∂x_S, the Jacobian's
columns for them (finite differences, refreshed every `REFRESH_S` of simulated time and
whenever the system changes).  With L taken out, f_E's highest eigenvalue is a coupled
link mode (0.23 kHz at p1's start, 0.18 kHz in p4's coast, against 0.90 / 0.82 kHz for f:
the Jacobian's eigenvalues), so the explicit stages are stable at the 1 ms control period.
The splitting is exact (f_E + f_I = f for any L): L decides stability, never the solution
the method converges to.

The pair (8 stages, 5th order, embedded 4th order; ESDIRK part L-stable, stiffly accurate,
stage order 2, γ = 41/200) advances

    X_i = x_n + h Σ_{j<i} (a^E_ij F^E_j + a^I_ij F^I_j) + h γ F^I_i,     F_j = f_(E|I)(X_j)
    x_{n+1} = x_n + h Σ_j b_j (F^E_j + F^I_j),    error  h Σ_j (b_j − b̂_j)(F^E_j + F^I_j).

Since f_I is linear with L non-zero in the columns S only, each implicit stage is one
solve with the nS × nS matrix W = I − hγ L_SS (nS = 24 at 4 shapes per link):
X_S = W⁻¹ r_S, X = r + hγ L X_S.  The error estimate is filtered by (I − hγL)⁻¹ in the
same way (Shampine's device, as in `trbdf2.py`).  Eight right-hand sides per step (no
FSAL) against DP5's six.

What it buys (docs/records.md, "An L-stable integrator at equal accuracy"): one
step per 1 ms sample in the quiet phases at the cases' rtol, but its own error, then
controlled by rtol instead of hidden under a stability-bound step, is ten times DP5's
(p1_transport short: end effector 1.3e-7 against 1.3e-8 m from a 1e-10 solution); at
rtol 1e-8 it is as accurate as DP5 and as fast (11.0 against 11.3 s).  In the quiet
segments sampled at 5 ms (p4's coasts, p5's drift) it is faster at DP5's accuracy and the
cases' rtol: three steps per sample against nine once a shutdown has rung out; there p4
and p5 use it (`[reference] quiet_integrator = "imex"`, reference_model/stepping.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from reference_model.ode import rhs
from reference_model.integration import ACCEPTED, NON_FINITE, UNDERFLOW, jacobian_columns, judge_step, step_toward

#: shapes whose own frequency √(k/m)/2π is above this [Hz] are integrated implicitly: the
#: static correction shapes (383–844 Hz alone, 0.8–0.9 kHz coupled) and, with 4 eigenmodes
#: per link, the 4th (PP 483 Hz, PF 545 Hz); the 3rd (PP 271 Hz, PF 319 Hz) and everything
#: below stay explicit.  Between PF's 3rd and PP's 4th, so that S is the same in both bases
STIFF_HZ = 350.0
#: simulated seconds between two evaluations of L = ∂f/∂x_S (the configuration moves
#: little in that time; a change of the system forces one at once)
REFRESH_S = 0.2

# --- ARK5(4)8L[2]SA (Kennedy & Carpenter 2003, Appl. Numer. Math. 44, 139–181): 8 stages,
# c = [0, 41/100, c3, c4, 92/100, 24/100, 3/5, 1], γ = 41/200 --------------------------
_GAMMA = 41.0 / 200.0
_AE = np.zeros((8, 8))  # the explicit tableau
_AE[1, 0] = 41.0 / 100.0
_AE[2, 0] = 367902744464.0 / 2072280473677.0
_AE[2, 1] = 677623207551.0 / 8224143866563.0
_AE[3, 0] = 1268023523408.0 / 10340822734521.0
_AE[3, 2] = 1029933939417.0 / 13636558850479.0
_AE[4, 0] = 14463281900351.0 / 6315353703477.0
_AE[4, 2] = 66114435211212.0 / 5879490589093.0
_AE[4, 3] = -54053170152839.0 / 4284798021562.0
_AE[5, 0] = 14090043504691.0 / 34967701212078.0
_AE[5, 2] = 15191511035443.0 / 11219624916014.0
_AE[5, 3] = -18461159152457.0 / 12425892160975.0
_AE[5, 4] = -281667163811.0 / 9011619295870.0
_AE[6, 0] = 19230459214898.0 / 13134317526959.0
_AE[6, 2] = 21275331358303.0 / 2942455364971.0
_AE[6, 3] = -38145345988419.0 / 4862620318723.0
_AE[6, 4] = -1.0 / 8.0
_AE[6, 5] = -1.0 / 8.0
_AE[7, 0] = -19977161125411.0 / 11928030595625.0
_AE[7, 2] = -40795976796054.0 / 6384907823539.0
_AE[7, 3] = 177454434618887.0 / 12078138498510.0
_AE[7, 4] = 782672205425.0 / 8267701900261.0
_AE[7, 5] = -69563011059811.0 / 9646580694205.0
_AE[7, 6] = 7356628210526.0 / 4942186776405.0
#: the weights b (both tableaux) and the embedded 4th-order weights b̂
_B = np.array([-872700587467.0 / 9133579230613.0, 0.0, 0.0, 22348218063261.0 / 9555858737531.0,
               -1143369518992.0 / 8141816002931.0, -39379526789629.0 / 19018526304540.0,
               32727382324388.0 / 42900044865799.0, 41.0 / 200.0])
_BHAT = np.array([-975461918565.0 / 9796059967033.0, 0.0, 0.0, 78070527104295.0 / 32432590147079.0,
                  -548382580838.0 / 3424219808633.0, -33438840321285.0 / 15594753105479.0,
                  3629800801594.0 / 4656183773603.0, 4035322873751.0 / 18575991585200.0])
_AI = np.zeros((8, 8))  # the implicit (ESDIRK) tableau: γ on the diagonal from stage 2, last row b
_AI[1, 0] = 41.0 / 200.0
_AI[2, 0] = 41.0 / 400.0
_AI[2, 1] = -567603406766.0 / 11931857230679.0
_AI[3, 0] = 683785636431.0 / 9252920307686.0
_AI[3, 2] = -110385047103.0 / 1367015193373.0
_AI[4, 0] = 3016520224154.0 / 10081342136671.0
_AI[4, 2] = 30586259806659.0 / 12414158314087.0
_AI[4, 3] = -22760509404356.0 / 11113319521817.0
_AI[5, 0] = 218866479029.0 / 1489978393911.0
_AI[5, 2] = 638256894668.0 / 5436446318841.0
_AI[5, 3] = -1179710474555.0 / 5321154724896.0
_AI[5, 4] = -60928119172.0 / 8023461067671.0
_AI[6, 0] = 1020004230633.0 / 5715676835656.0
_AI[6, 2] = 25762820946817.0 / 25263940353407.0
_AI[6, 3] = -2161375909145.0 / 9755907335909.0
_AI[6, 4] = -211217309593.0 / 5846859502534.0
_AI[6, 5] = -4269925059573.0 / 7827059040749.0
_AI[7, :7] = _B[:7]
for _i in range(1, 8):
    _AI[_i, _i] = _GAMMA
_C = np.array([0.0, 41.0 / 100.0, 2935347310677.0 / 11292855782101.0, 1426016391358.0 / 7196633302097.0,
               92.0 / 100.0, 24.0 / 100.0, 3.0 / 5.0, 1.0])
_E = _B - _BHAT
N_STAGES = 8

#: slots of `work`, the bookkeeping of L and W carried between calls (floats)
W_HAVE_L = 0  # 1.0 while L belongs to the present system; the owner sets 0.0 when it changes
W_T_OF_L = 1  # the time L was evaluated at
W_H_OF_W = 2  # the step size Winv = (I − hγ L_SS)⁻¹ was formed for (−1.0: none)
W_JACOBIANS = 3  # evaluations of L so far
N_WORK = 4


def stiff_indices(k_diag: np.ndarray, m_diag: np.ndarray, offsets, ns: int, limit_hz: float = STIFF_HZ) -> np.ndarray:
    """State indices of the stiff shapes: the amplitude and the rate of every shape whose own
    frequency √(k_jj/m_jj)/2π exceeds `limit_hz`.  `k_diag`, `m_diag`: one array per link
    (the diagonal modal stiffness and mass), `offsets`: each link's first amplitude in q,
    `ns`: where the rates start in x."""
    pos = []
    for k, m, o in zip(k_diag, m_diag, offsets):
        for j in range(len(k)):
            if np.sqrt(k[j] / m[j]) / (2.0 * np.pi) > limit_hz:
                pos.append(o + j)
    pos = np.array(pos, dtype=np.int64)
    return np.concatenate([pos, pos + ns])


@njit(cache=True)
def _implicit_solve(r, L, S, Winv, hg, out):
    """out ← (I − hγ L)⁻¹ r for L non-zero in the columns S only:
    y_S = W⁻¹ r_S with W = I − hγ L_SS, then y = r + hγ L y_S."""
    nS = S.shape[0]
    rS = np.empty(nS)
    for k in range(nS):
        rS[k] = r[S[k]]
    yS = Winv @ rS
    out[:] = r
    if nS > 0:
        out += hg * (L @ yS)


@njit(cache=True)
def integrate_ark(x0, t0, t1, h, rtol, atol, hmax, S, L, Winv, work, refresh, u, m, sw):
    """Integrate from t0 to t1 with inputs u held: ARK5(4)8L[2]SA, f_I = L x_S implicit,
    error per component against atol_i + rtol·|x_i| (max norm), PI step control as DP5's
    (`integration.accepted_step`).

    L (nx × nS), Winv (nS × nS) and work (N_WORK: slots W_HAVE_L, W_T_OF_L, W_H_OF_W,
    W_JACOBIANS) carry between calls (mutated in place); L is re-evaluated at t0 when the
    system changed or `refresh` seconds have passed since it was.  Returns (x(t1), next
    step size, accepted steps, rejected steps, status); status 0 ok, 1 non-finite state,
    2 step size underflow.
    """
    x = x0.copy()
    nx = x.shape[0]
    nS = S.shape[0]
    t = t0
    f0 = rhs(x, u, m, sw)
    if nS > 0 and (work[W_HAVE_L] == 0.0 or t0 - work[W_T_OF_L] >= refresh):
        L[:, :] = jacobian_columns(x, f0, u, m, sw, S, atol, rtol)
        work[W_HAVE_L] = 1.0
        work[W_T_OF_L] = t0
        work[W_H_OF_W] = -1.0
        work[W_JACOBIANS] += 1.0
    FE = np.zeros((N_STAGES, nx))
    FI = np.zeros((N_STAGES, nx))
    X = np.empty(nx)
    r = np.empty(nx)
    nacc = 0
    nrej = 0
    h = min(h, hmax)
    err_old = 1e-4
    rejected = False
    f0_is_of_x = True  # f0 = f(x): false after an accepted step moved x
    while t < t1:
        h_nominal = h
        h, last = step_toward(t, t1, h)
        hg = h * _GAMMA
        if nS > 0 and abs(work[W_H_OF_W] - h) > 1e-9 * h:  # W for this step size
            W = np.eye(nS)
            for a in range(nS):
                for b in range(nS):
                    W[a, b] -= hg * L[S[a], b]
            Winv[:, :] = np.linalg.inv(W)
            work[W_H_OF_W] = h
        # stage 1 is explicit: X_1 = x_n
        if not f0_is_of_x:
            f0 = rhs(x, u, m, sw)
            f0_is_of_x = True
        for c in range(nx):
            FI[0, c] = 0.0
        for k in range(nS):
            for c in range(nx):
                FI[0, c] += L[c, k] * x[S[k]]
        FE[0] = f0 - FI[0]
        for st in range(1, N_STAGES):
            r[:] = x
            for j in range(st):
                ae = h * _AE[st, j]
                ai = h * _AI[st, j]
                for c in range(nx):
                    r[c] += ae * FE[j, c] + ai * FI[j, c]
            _implicit_solve(r, L, S, Winv, hg, X)  # X = r + hγ f_I(X)
            for c in range(nx):
                FI[st, c] = (X[c] - r[c]) / hg if nS > 0 else 0.0
            FE[st] = rhs(X, u, m, sw) - FI[st]
        xn = x.copy()
        est = np.zeros(nx)
        for j in range(N_STAGES):
            hb = h * _B[j]
            he = h * _E[j]
            for c in range(nx):
                fj = FE[j, c] + FI[j, c]
                xn[c] += hb * fj
                est[c] += he * fj
        _implicit_solve(est, L, S, Winv, hg, r)  # filtered: (I − hγL)⁻¹ est
        err = 0.0
        for c in range(nx):
            err = max(err, abs(r[c]) / (atol[c] + rtol * max(abs(x[c]), abs(xn[c]))))
        verdict, h_next, err_old = judge_step(err, h, h_nominal, err_old, rejected, last, hmax)
        if verdict == ACCEPTED:
            t = t1 if last else t + h
            x = xn
            f0_is_of_x = False
            nacc += 1
        elif verdict == NON_FINITE:
            return x, h, nacc, nrej, 1
        else:
            nrej += 1
        rejected = verdict != ACCEPTED
        h = h_next
        if verdict == UNDERFLOW:
            return x, h, nacc, nrej, 2
    return x, h, nacc, nrej, 0
