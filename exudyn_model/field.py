"""The acceleration field felt in the co-moving frame of the reference point O
(docs/physics.md §5), written for this engine from the formulas of physics.md (no code of
the reference model is used).

A mass element at ρ (relative to O, inertial axes) feels the exact tidal acceleration
    Δg(ρ) = g(r_O + ρ) − g(r_O),  g(r) = −μ r/|r|³,
evaluated without cancellation: q = (2 r_O·ρ + ρ·ρ)/|r_O|², F = −expm1(−1.5 log1p q),
Δg = μ (F (r_O + ρ) − ρ)/|r_O|³,
and the uniform inertial field −a_thr of the thrust acceleration of O.  The tidal
potential energy per unit mass, −∇_ρ U = Δg (r_O fixed), is
    U = −μ/|r_O+ρ| + μ/|r_O| − μ r_O·ρ/|r_O|³ = μ (h(q) + |ρ|²/(2|r_O|²))/|r_O|,
    h(q) = 1 − (1+q)^(−1/2) − q/2,
to second order −μ ρᵀ(3 r̂r̂ᵀ − I)ρ/(2|r_O|³) (negative along the radial: it stretches).

The machinery that applies it (docs/physics.md §5, docs/exudyn.md §1): one
`ObjectGenericODE2` without matrices, the *carrier* (`build.py`), over every mass
coordinate (base, target, the links' nodes) receives the field's generalised forces: the
tidal part at the positions of the middle of each control period (extrapolated from its
start), held over the period (`FieldForces.tidal_forces`, set by
`stepper.Stepper.set_inputs`), and the uniform thrust inertia
(`FieldForces.uniform_field_matrix`), set at every time step by `_ThrustInertia`; the
co-moving point O follows its orbit with the period's mean thrust acceleration
(`FieldForces.advance_orbit`).  `FieldForces` is the engine's field part: its quadrature
and the places in the carrier's vector are fixed at build, its thrust inertia and the
cached uniform-field matrix change with the thrust and the propellant.
"""

from __future__ import annotations

import contextlib
import io
import math
import sys

import numpy as np
from numba import njit

sys.exudynFast = True  # the engine's build: import order must not matter
# exudyn announces the fast build on stdout: keep it out of `--json` output
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu  # noqa: E402

from exudyn_model import links  # noqa: E402
from rsmcheck.driver.control_kernels import fma  # noqa: E402

N_GAUSS_FIELD = 4  # Gauss points per element for the tidal field, energy and momentum
#: the base node's outputs the thrust inertia reads at every step of a burn
_COORDINATES, _COORDINATES_T = exu.OutputVariableType.Coordinates, exu.OutputVariableType.Coordinates_t


def tidal(mu: float, r_o: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Δg at points ρ (shape (..., 2)) [m/s²]."""
    rho = np.asarray(rho, float)
    r2 = float(r_o @ r_o)
    q = (2.0 * rho @ r_o + np.sum(rho * rho, axis=-1)) / r2
    f = -np.expm1(-1.5 * np.log1p(q))
    return mu * (f[..., None] * (r_o + rho) - rho) / (r2 * np.sqrt(r2))


@njit(cache=True, inline="always")
def _tidal_at(px, py, rx, ry, r2):  # pragma: no cover - compiled
    """Δg · |r_O|³/μ at one point ρ = (px, py) (`tidal`, on floats)."""
    qq = (2.0 * (px * rx + py * ry) + px * px + py * py) / r2
    f = -math.expm1(-1.5 * math.log1p(qq))
    return f * (rx + px) - px, f * (ry + py) - py


@njit(cache=True)
def tidal_carrier_forces(q, v, s, flex_coords, carrier_flex, cols, vals, weights, points, carrier_points, masses,
                         r_o, mu, out):  # pragma: no cover - compiled
    """Generalised forces of the tidal field [N] at the positions q + s q̇, written into the
    carrier's vector `out` (zeroed by the caller; called every control sample: compiled,
    one call, no temporaries).

    * flexible link i (`flex_coords[i]`: its coordinates in q, `carrier_flex[i]`: their
      places in `out`): Gauss points r_g = S(ξ_g) q_i, rows 2g (x) and 2g+1 (y) of S given
      by their non-zero entries (`cols`, `vals`: an ANCF position depends on 4
      coordinates), forces Σ_g S(ξ_g)ᵀ ρA w_g Δg(r_g) (`weights` = ρA w_g);
    * point masses k (base and target at their COM: `points[k]` their x, y in q,
      `carrier_points[k]` in `out`, `masses[k]`): m_k Δg(ρ_k);
    Δg as in `tidal`, point by point."""
    rx, ry = r_o[0], r_o[1]
    r2 = rx * rx + ry * ry
    scale = mu / (r2 * math.sqrt(r2))
    n_g = weights.shape[0]
    for i in range(flex_coords.shape[0]):
        ci = flex_coords[i]
        oi = carrier_flex[i]
        for g in range(n_g):
            px = 0.0
            py = 0.0
            for j in range(cols.shape[1]):
                kx = ci[cols[2 * g, j]]
                ky = ci[cols[2 * g + 1, j]]
                px += vals[2 * g, j] * (q[kx] + s * v[kx])
                py += vals[2 * g + 1, j] * (q[ky] + s * v[ky])
            gx, gy = _tidal_at(px, py, rx, ry, r2)
            gx *= weights[g] * scale
            gy *= weights[g] * scale
            for j in range(cols.shape[1]):
                out[oi[cols[2 * g, j]]] += vals[2 * g, j] * gx
                out[oi[cols[2 * g + 1, j]]] += vals[2 * g + 1, j] * gy
    for k in range(points.shape[0]):
        ix, iy = points[k, 0], points[k, 1]
        gx, gy = _tidal_at(q[ix] + s * v[ix], q[iy] + s * v[iy], rx, ry, r2)
        out[carrier_points[k, 0]] = masses[k] * scale * gx
        out[carrier_points[k, 1]] = masses[k] * scale * gy


@njit(cache=True, inline="always")
def _orbit_acc(x, y, ax, ay, mu):  # pragma: no cover - compiled
    """g(r) + a_thr at r = (x, y), g = −μ r/|r|³ (μ = 0: no gravity)."""
    r = math.sqrt(x * x + y * y)
    k = mu / (r * r * r) if mu != 0.0 else 0.0
    return ax - k * x, ay - k * y


@njit(cache=True)
def orbit_rk4(x, y, vx, vy, ax, ay, mu, h):  # pragma: no cover - compiled
    """One classical Runge–Kutta step h [s] of r̈ = g(r) + a_thr from r = (x, y),
    ṙ = (vx, vy), a_thr = (ax, ay) held; returns (x, y, vx, vy) at t + h (on floats:
    called every control sample)."""
    a1x, a1y = _orbit_acc(x, y, ax, ay, mu)
    a2x, a2y = _orbit_acc(x + 0.5 * h * vx, y + 0.5 * h * vy, ax, ay, mu)
    v2x, v2y = vx + 0.5 * h * a1x, vy + 0.5 * h * a1y
    a3x, a3y = _orbit_acc(x + 0.5 * h * v2x, y + 0.5 * h * v2y, ax, ay, mu)
    v3x, v3y = vx + 0.5 * h * a2x, vy + 0.5 * h * a2y
    a4x, a4y = _orbit_acc(x + h * v3x, y + h * v3y, ax, ay, mu)
    v4x, v4y = vx + h * a3x, vy + h * a3y
    return (x + h / 6 * (vx + 2 * v2x + 2 * v3x + v4x), y + h / 6 * (vy + 2 * v2y + 2 * v3y + v4y),
            vx + h / 6 * (a1x + 2 * a2x + 2 * a3x + a4x), vy + h / 6 * (a1y + 2 * a2y + 2 * a3y + a4y))


def tidal_potential(mu: float, r_o: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """U at points ρ [J/kg] (series for h when |q| is small, to keep full precision)."""
    rho = np.asarray(rho, float)
    r2 = float(r_o @ r_o)
    rho2 = np.sum(rho * rho, axis=-1)
    q = (2.0 * rho @ r_o + rho2) / r2
    small = np.abs(q) < 1e-3
    h_series = q * q * (-3.0 / 8.0 + q * (5.0 / 16.0 + q * (-35.0 / 128.0 + q * 63.0 / 256.0)))
    h_exact = 1.0 - 1.0 / np.sqrt(1.0 + np.where(small, 0.0, q)) - 0.5 * q
    h = np.where(small, h_series, h_exact)
    return mu * (h + 0.5 * rho2 / r2) / np.sqrt(r2)


class FieldForces:
    """The field and thrust part of an engine built with the field machinery: the tidal
    forces' quadrature on the links and the places of every part in the carrier's vector
    (fixed at build), the uniform-field matrix of the last base mass, the thrust inertia
    (`_ThrustInertia`, the solver's pre-step function while there is thrust)."""

    def __init__(self, model, orbit: bool, theta_ref: float):
        """`model`: the built `ExudynModel` (with its carrier); `orbit`: the case has one
        (else no tidal field: zero); `theta_ref`: the base's θ at build (the reference of
        its node's rotation coordinate)."""
        p = model.params
        self.params = p
        self.model = model
        self.orbit = bool(orbit)
        L = p.link.length
        self.rigid_gauss = links.gauss(8, -0.5 * L, 0.5 * L)  # a rigid link's field points
        self.rigid_links = [it for it in model.links if it.rigid]
        # the tidal field's quadrature on the flexible links (tidal_carrier_forces)
        self.flex = [i for i, it in enumerate(model.links) if not it.rigid]
        self.flex_coords = np.array([model.links[i].coords for i in self.flex], dtype=np.int64).reshape(
            len(self.flex), model.mesh.nq)
        _, ws_flex, D = model.mesh.sample(N_GAUSS_FIELD)  # rows x_g, y_g of every Gauss point
        self.weights = p.link.rho_a * ws_flex  # ρA w_g [kg]
        # D by its non-zero entries per row (a point of an element: 4 of the link's coordinates)
        width = int(np.max(np.count_nonzero(D, axis=1)))
        cols = np.argsort(D == 0.0, axis=1, kind="stable")[:, :width]
        self.S = (np.ascontiguousarray(cols), np.ascontiguousarray(np.take_along_axis(D, cols, axis=1)))
        ix = model.index
        self.points = np.array([ix.i_base[:2], ix.i_target[:2]], dtype=np.int64)
        # places in the carrier's vector (base, target, then the links: `field_nodes`'s order)
        # of the base's and target's x, y, of each link's coordinates, of the flexible ones
        ends = 6 + np.cumsum([3 if it.rigid else len(it.coords) for it in model.links])
        self.n_carrier = int(ends[-1])
        self.carrier_points = np.array([[0, 1], [3, 4]], dtype=np.int64)
        self.carrier_links = [slice(int(e) - (3 if it.rigid else len(it.coords)), int(e))
                              for it, e in zip(model.links, ends)]
        self.carrier_flex = np.array([np.arange(self.n_carrier)[self.carrier_links[i]] for i in self.flex],
                                     dtype=np.int64).reshape(len(self.flex), model.mesh.nq)
        self.uniform: tuple[float, np.ndarray] | None = None  # (base mass, U) of the last build
        # its pre-step function is registered while there is thrust (`Stepper.advance`)
        self.thrust_inertia = _ThrustInertia(model.carrier, model.base_node, theta_ref)

    def advance_orbit(self, state, h: float, a_thr) -> None:
        """O of `state` over one control interval: r̈_O = g(r_O) + a_thr (physics.md §5),
        classical RK4 (`orbit_rk4`; a_thr (x, y: an array or two floats), the interval's mean
        thrust acceleration, held)."""
        ax, ay = float(a_thr[0]), float(a_thr[1])
        if not self.orbit and ax == 0.0 and ay == 0.0:
            return
        mu = self.params.orbit.mu if self.orbit else 0.0
        (x, y), (vx, vy) = state.r_O.tolist(), state.v_O.tolist()
        x, y, vx, vy = orbit_rk4(x, y, vx, vy, ax, ay, mu, h)
        state.r_O = np.array([x, y])
        state.v_O = np.array([vx, vy])

    def uniform_field_matrix(self, m_base: float) -> np.ndarray:
        """U with U a = generalised forces of a uniform acceleration field a on every mass
        element (physics.md §5: M_X[:, R] a), carrier coordinates × 2, for the base mass
        `m_base` [kg].  Built once; when that mass (propellant, at every sample of a burn)
        has changed, a copy with the base's two entries replaced (the last U may still be
        held by a `_ThrustInertia`)."""
        if self.uniform is not None:
            if self.uniform[0] == m_base:
                return self.uniform[1]
            U = self.uniform[1].copy()
            U[0, 0] = U[1, 1] = m_base
            self.uniform = (m_base, U)
            return U
        p = self.params
        blocks = [np.array([[m, 0.0], [0.0, m], [0.0, 0.0]]) for m in (m_base, p.target.mass)]
        for it in self.model.links:
            if it.rigid:
                # about the link COM a uniform field has no moment
                blocks.append(np.array([[p.link.mass, 0.0], [0.0, p.link.mass], [0.0, 0.0]]))
            else:
                blocks.append(self.model.first.T)
        self.uniform = (m_base, np.vstack(blocks))
        return self.uniform[1]

    def tidal_forces(self, q, v, s: float, r_O: np.ndarray, m_base: float) -> np.ndarray:
        """Generalised forces of the exact tidal field at the positions q + s q̇ (`v` = q̇,
        `s` [s]: the positions s ahead on their tangent; s = 0: at q) about the orbit point
        r_O (zero without an orbit), the base of mass `m_base` [kg], carrier coordinates:
        base and target at their COM, a flexible link over its Gauss points
        (`tidal_carrier_forces`, the same S for every link: one mesh), a rigid link over its
        own Gauss points with the moment about its centre.  Each part is written into its
        place of the carrier's vector (`carrier_points`, `carrier_flex`, `carrier_links`;
        called every control sample)."""
        out = np.zeros(self.n_carrier)
        if not self.orbit:
            return out
        p = self.params
        mu = p.orbit.mu
        r_O = np.asarray(r_O, float)
        cols, vals = self.S
        tidal_carrier_forces(q, v, float(s), self.flex_coords, self.carrier_flex, cols, vals, self.weights,
                             self.points, self.carrier_points, np.array([m_base, p.target.mass]), r_O, mu, out)
        xs_rigid, ws_rigid = self.rigid_gauss
        for it in self.rigid_links:
            qi = q[it.coords] + s * v[it.coords]
            pts = qi[:2] + np.outer(xs_rigid, [math.cos(qi[2]), math.sin(qi[2])])
            f = p.link.rho_a * ws_rigid[:, None] * tidal(mu, r_O, pts)
            lever = pts - qi[:2]
            out[self.carrier_links[it.index]] = (f[:, 0].sum(), f[:, 1].sum(),
                                                 np.sum(lever[:, 0] * f[:, 1] - lever[:, 1] * f[:, 0]))
        return out


@njit(cache=True)
def held_minus_uniform(q_held, U, ax, ay, out):  # pragma: no cover - compiled
    """out = Q − U a for a = (ax, ay) (at every sample, and at every step of a burn: one pass,
    no temporaries), row i rounded as numpy's product U @ a (OpenBLAS: fma(U_i0, a_x, U_i1 a_y);
    on this model's U, one entry per row, it is also the plain sum)."""
    for i in range(U.shape[0]):
        out[i] = q_held[i] - fma(U[i, 0], ax, U[i, 1] * ay)


class _ThrustInertia:
    """The uniform thrust-inertia field −(T/m_sys) A(θ_B) e_x of physics.md §5, evaluated at
    every time step (a `PreStepUserFunction`): its direction follows the base attitude
    within the control period, as in the reference, where it is part of the right-hand
    side.  θ_B is taken at the end of the step (θ_B + h ω_B from the start of the step:
    generalized-α balances forces at t_n+1), so the direction lags by O(h²).  The tidal
    part and the masses are held over the control interval (`hold`).

    Holds no reference to the engine (the suspended solver run keeps this object alive).
    """

    def __init__(self, carrier: int, base_node: int, theta_ref: float):
        self.carrier, self.base_node, self.theta_ref = carrier, base_node, theta_ref
        self.q_held = np.zeros(0)
        self.U = np.zeros((0, 2))
        self.accel = 0.0  # T/m_sys [m/s²]
        # ∫ (T/m_sys) A(θ_B) e_x dt over the current interval [m/s], x and y as floats (summed
        # at every time step in the solver's thread)
        self.impulse = [0.0, 0.0]
        self.elapsed = 0.0  # Σ h of the steps that made `impulse` [s], by the solver's clock
        self.t_last = 0.0

    def hold(self, tidal: np.ndarray, U: np.ndarray, accel: float, t_start: float) -> None:
        self.q_held, self.U, self.accel = tidal, U, float(accel)
        self.impulse = [0.0, 0.0]
        self.elapsed = 0.0
        self.t_last = t_start

    def forces(self, theta_b: float) -> np.ndarray:
        """The carrier's forces with the base at attitude θ_B: Q_tidal − U a,
        a = (T/m_sys)(cos θ_B, sin θ_B) (`held_minus_uniform`)."""
        out = np.empty(len(self.q_held))
        held_minus_uniform(self.q_held, self.U, self.accel * math.cos(theta_b), self.accel * math.sin(theta_b), out)
        return out

    def __call__(self, mbs, t: float) -> bool:
        if self.accel == 0.0:
            return True
        h = t - self.t_last  # t: the end of the step about to be taken (the state: its start)
        self.t_last = t
        # θ_B and ω_B at the start of the step, as floats (numpy scalars cost twice the arithmetic)
        th = self.theta_ref + float(mbs.GetNodeOutput(self.base_node, _COORDINATES)[2])
        om = float(mbs.GetNodeOutput(self.base_node, _COORDINATES_T)[2])
        mbs.SetObjectParameter(self.carrier, "forceVector", self.forces(th + h * om))
        th_mid = th + 0.5 * h * om
        dv = h * self.accel
        self.impulse[0] += dv * math.cos(th_mid)
        self.impulse[1] += dv * math.sin(th_mid)
        self.elapsed += h
        return True

    def mean_acceleration(self, span: float) -> np.ndarray:
        """The thrust acceleration of O averaged over the interval just integrated: the
        impulse divided by the time it was summed over, both by the solver's clock.

        That clock is Exudyn's own sum t += h (its round-off drifts from the runner's
        samples: +1.0e-13 s per 0.5 ms step for t in [2048, 4096) s), while the first step
        of an interval is measured from the runner's t (`hold`): the sum of h telescopes to
        span + δ, δ the clock's offset at the interval's end.  Divided by `span`, the mean
        took a relative error δ/span that grows with the offset (p4_hohmann's burn 2:
        δ = 1.1e-7 s after 535 s, 1.1e-4 of the thrust acceleration, 6.0e-3 m/s along
        the thrust, 0.69 m of altitude at 3500 s); divided by `elapsed`, δ cancels."""
        return np.array(self.mean_acceleration_xy(span))

    def mean_acceleration_xy(self, span: float) -> tuple[float, float]:
        """`mean_acceleration` as two floats (x, y) [m/s²] (at every control sample: no array)."""
        ix, iy = self.impulse
        if self.elapsed > 0.0:
            return ix / self.elapsed, iy / self.elapsed
        return (ix / span, iy / span) if span > 0.0 else (0.0, 0.0)
