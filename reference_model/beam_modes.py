"""Modal bases of a link, eq. (1): w(ξ, t) = Σ_j A_j(t) φ_j(ξ).

Two bases (Sect. 4, Table 2):

* **PP** (pinned-pinned) for a link pinned at both ends.  Frame: the chord joining the
  two pins, so w(0) = w(L) = 0.  φ_j = sin(jπξ/L), β_j L = jπ.
* **PF** (pinned-free) for the terminal link of a free arm.  Frame: the rigid rotation
  about the pin, mass-orthogonal to the elastic modes (∫ρ ξ φ_j dξ = 0), w(0) = 0.
  φ_j = sin βξ + (sin βL / sinh βL) sinh βξ with tan βL = tanh βL.

Both sets of eigenmodes satisfy w'' = 0 at the pins: they carry no moment there.  A joint
torque is a couple on the end section (docs/physics.md §3.3), and under an end couple the
eigenmode series converges slowly: the end slope of a PP link under a couple C at ξ = 0 is
Σ_j 2CL/(EI j²π²) → CL/(3EI), 24 % low with 2 modes and 7 % low with 8 (the mid-span
deflection, Σ 1/j³, is within 3 % with one).  The optional **static correction shapes**
(`n_static = 2`, docs/physics.md §2.4) close that: the quasi-static responses of the link
to a unit couple at each end —

* PP: the cubics with w(0) = w(L) = 0, spanned by ξ(L − ξ) and ξ²(L − ξ);
* PF: with the inertia relief of the free link (the couple spins the rigid mode, whose
  acceleration loads the beam with ρξθ̈): EI w'''' ∝ ξ, w'''(L) = 0, spanned by ξ² and
  ξ³L²/12 − ξ⁵/120, made mass-orthogonal to the rigid rotation (∫ρ ξ w dξ = 0) —

each made mass-orthogonal to the retained eigenmodes (which also makes them
stiffness-orthogonal: the eigenmodes are moment-free at both ends, so the boundary terms
of ∫EI φ_j'' χ'' vanish), then diagonalised among themselves (their Ritz frequencies,
well above the retained modes, are reported in `omega`).  The basis then represents the
static bending by any pair of end couples exactly, and the dynamics by Rayleigh–Ritz.

Every shape is scaled to max |φ| = 1 on [0, L], so an amplitude is the peak transverse
displacement of its shape [m].  The modal integrals the floating-frame equations need
(docs/physics.md §3) are computed by Gauss–Legendre quadrature with enough points to be
exact to round-off for these smooth shapes; the stiffness is computed from the curvature
integral ∫ EI φ_i'' φ_j'' dξ, not from ω², so that the eigenfrequency test of Table 2
checks the shapes and the quadrature as well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import Polynomial
from scipy.linalg import eigh
from scipy.optimize import brentq

PP = 0
PF = 1
BASIS_NAMES = {PP: "PP", PF: "PF"}

#: Quadrature used for the modal integrals (exact to round-off for β L ≤ ~30).
_N_GAUSS_INTEGRALS = 64
#: Gauss points per link for distributed loads (tidal gravity, thrust inertia).
N_GAUSS_LOADS = 8
#: Points on which each shape is scaled to max |φ| = 1.
_N_SCALE = 4001


def beta_l(kind: int, j: int) -> float:
    """j-th (1-based) root β_j L of the frequency equation of basis `kind`.

    PP: sin βL = 0 → jπ.  PF: tan βL = tanh βL → (j + 1/4)π − ε, ε < 1e-7 for j ≥ 2.
    """
    if kind == PP:
        return j * math.pi
    guess = (j + 0.25) * math.pi
    return brentq(lambda b: math.tan(b) - math.tanh(b), guess - 0.3, guess + 1e-9, xtol=1e-15)


def _eigen_shape(kind: int, beta: float, length: float, x: np.ndarray, deriv: int) -> np.ndarray:
    """φ, φ' or φ'' (deriv 0, 1, 2) of the unscaled eigenmode of wavenumber β at points x."""
    if kind == PP:
        return (np.sin(beta * x), beta * np.cos(beta * x), -beta**2 * np.sin(beta * x))[deriv]
    c = math.sin(beta * length) / math.sinh(beta * length)
    if deriv == 0:
        return np.sin(beta * x) + c * np.sinh(beta * x)
    if deriv == 1:
        return beta * (np.cos(beta * x) + c * np.cosh(beta * x))
    return beta**2 * (-np.sin(beta * x) + c * np.sinh(beta * x))


def _static_polynomials(kind: int, length: float) -> list[Polynomial]:
    """The two polynomials spanning the static response to unit end couples (module doc),
    in ξ [m], dimensionless (divided by the matching power of L)."""
    L = length
    xi = Polynomial([0.0, 1.0 / L])  # ξ/L
    if kind == PP:
        return [xi * (1 - xi), xi * xi * (1 - xi)]
    quintic = xi**3 / 12 - xi**5 / 120
    raw = [xi * xi, quintic]
    # mass-orthogonal to the rigid rotation (the PF frame): subtract c·ξ with c = ∫ξp/∫ξ²
    out = []
    for p in raw:
        c = (p * Polynomial([0.0, 1.0])).integ()(L) / (L**3 / 3.0)
        out.append(p - Polynomial([0.0, c]))
    return out


@dataclass(frozen=True)
class ShapeFunctions:
    """The n = n_eigen + n_static shapes of one basis, evaluable anywhere on [0, L].

    shapes(x) = [E(x), (P(x) − E(x) Cᵀ) T] · diag(scale): E the scaled eigenmodes, P the
    static polynomials, C their mass projection on the eigenmodes, T the diagonalising
    transform of what remains.
    """

    kind: int
    length: float
    betas: np.ndarray  # (n_eigen,) wavenumbers β_j [1/m]
    eigen_scale: np.ndarray  # (n_eigen,)
    polynomials: tuple[Polynomial, ...]  # (n_static,)
    projection: np.ndarray  # C (n_static, n_eigen)
    transform: np.ndarray  # T (n_static, n_static), columns scaled

    @property
    def n_eigen(self) -> int:
        return self.betas.size

    @property
    def n(self) -> int:
        return self.n_eigen + len(self.polynomials)

    def eigen(self, x: np.ndarray, deriv: int = 0) -> np.ndarray:
        x = np.atleast_1d(np.asarray(x, float))
        out = np.empty((x.size, self.n_eigen))
        for j, b in enumerate(self.betas):
            out[:, j] = self.eigen_scale[j] * _eigen_shape(self.kind, b, self.length, x, deriv)
        return out

    def __call__(self, x: np.ndarray, deriv: int = 0) -> np.ndarray:
        """(x.size, n) values of the shapes (deriv 0), slopes (1) or curvatures (2)."""
        x = np.atleast_1d(np.asarray(x, float))
        e = self.eigen(x, deriv)
        if not self.polynomials:
            return e
        p = np.stack([poly.deriv(deriv)(x) if deriv else poly(x) for poly in self.polynomials], axis=1)
        return np.hstack([e, (p - e @ self.projection.T) @ self.transform])


def _shape_functions(kind: int, n_eigen: int, n_static: int, length: float, rho_a: float,
                     ei: float) -> ShapeFunctions:
    x, w = quadrature(length)
    fine = np.linspace(0.0, length, _N_SCALE)
    betas = np.array([beta_l(kind, j) / length for j in range(1, n_eigen + 1)])
    scale = np.array([1.0 / np.max(np.abs(_eigen_shape(kind, b, length, fine, 0))) for b in betas])
    sf = ShapeFunctions(kind, length, betas, scale, (), np.zeros((0, n_eigen)), np.zeros((0, 0)))
    if n_static == 0:
        return sf
    if n_static != 2:
        raise ValueError(f"static correction shapes: 0 or 2 (one per end couple), got {n_static}")
    polys = tuple(_static_polynomials(kind, length))
    e = sf.eigen(x)
    p = np.stack([poly(x) for poly in polys], axis=1)
    # C = (∫ρ P Eᵀ) diag(∫ρ E²)⁻¹: the mass projection on the (mass-orthogonal) eigenmodes
    proj = ((p.T * w) @ e) / np.sum(w[:, None] * e * e, axis=0)
    r = p - e @ proj.T
    r2 = np.stack([poly.deriv(2)(x) for poly in polys], axis=1) - sf.eigen(x, 2) @ proj.T
    m_r = rho_a * (r.T * w) @ r
    k_r = ei * (r2.T * w) @ r2
    _, vec = eigh(k_r, m_r)
    trial = ShapeFunctions(kind, length, betas, scale, polys, proj, vec)
    values = trial(fine)[:, n_eigen:]
    peak = values[np.argmax(np.abs(values), axis=0), np.arange(n_static)]
    return ShapeFunctions(kind, length, betas, scale, polys, proj, vec / peak)


@dataclass(frozen=True)
class ModalBasis:
    """Modal data of one link in one basis, for `n` shapes (n_eigen eigenmodes, then the
    static correction shapes).

    Integrals are over the link's material abscissa ξ ∈ [0, L] of the link frame; ρ is the
    mass per length ρA.  Array shapes are (n,), (n, n) or (n_gauss, n).
    """

    kind: int
    n: int
    n_eigen: int
    length: float
    rho_a: float
    shapes: ShapeFunctions
    omega: np.ndarray  # ω_j [rad/s]: β_j² sqrt(EI/ρA), and the Ritz values of the static shapes
    phi_bar: np.ndarray  # ∫ρ φ_j dξ [kg]
    phi_x: np.ndarray  # ∫ρ ξ φ_j dξ [kg·m]  (0 for PF: mass-orthogonal to the frame rotation)
    m_ff: np.ndarray  # ∫ρ φ_i φ_j dξ [kg]
    k_ff: np.ndarray  # ∫EI φ_i'' φ_j'' dξ [N/m]
    phi_tip: np.ndarray  # φ_j(L) (0 for PP)
    slope_0: np.ndarray  # φ_j'(0) [1/m]: rotation of the proximal end section per unit amplitude
    slope_L: np.ndarray  # φ_j'(L) [1/m]: rotation of the distal end section
    phi_mid: np.ndarray  # φ_j(L/2)
    x_gauss: np.ndarray  # load quadrature abscissae [m]
    w_gauss: np.ndarray  # load quadrature weights [m]
    phi_gauss: np.ndarray  # φ_j at the load abscissae

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2.0 * math.pi)


def quadrature(length: float, n: int = _N_GAUSS_INTEGRALS) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre abscissae and weights on [0, length]."""
    xg, wg = np.polynomial.legendre.leggauss(n)
    return 0.5 * length * (xg + 1.0), 0.5 * length * wg


def modal_basis(kind: int, n: int, length: float, rho_a: float, ei: float, n_static: int = 0) -> ModalBasis:
    """Build the `kind` (PP or PF) basis with `n` ≥ 0 eigenmodes and `n_static` (0 or 2)
    static correction shapes for a uniform beam."""
    if kind not in (PP, PF):
        raise ValueError(f"basis kind must be PP ({PP}) or PF ({PF}), got {kind}")
    if n < 0:
        raise ValueError(f"number of modes must be >= 0, got {n}")
    sf = _shape_functions(kind, n, n_static, length, rho_a, ei)
    x, w = quadrature(length)
    x_loads, w_loads = quadrature(length, N_GAUSS_LOADS)
    phi = sf(x)
    phi2 = sf(x, 2)
    m_ff = rho_a * (phi.T * w) @ phi
    k_ff = ei * (phi2.T * w) @ phi2
    omega = np.sqrt(np.clip(np.diag(k_ff) / np.diag(m_ff), 0.0, None)) if sf.n else np.zeros(0)
    omega[:n] = sf.betas**2 * math.sqrt(ei / rho_a)
    return ModalBasis(
        kind=kind,
        n=sf.n,
        n_eigen=n,
        length=length,
        rho_a=rho_a,
        shapes=sf,
        omega=omega,
        phi_bar=rho_a * w @ phi,
        phi_x=rho_a * (w * x) @ phi,
        m_ff=m_ff,
        k_ff=k_ff,
        phi_tip=sf(np.array([length]))[0],
        slope_0=sf(np.array([0.0]), 1)[0],
        slope_L=sf(np.array([length]), 1)[0],
        phi_mid=sf(np.array([0.5 * length]))[0],
        x_gauss=x_loads,
        w_gauss=w_loads,
        phi_gauss=sf(x_loads),
    )


def link_frequencies(params, basis: str, n: int = 2, **options) -> np.ndarray:
    """The first `n` bending frequencies [Hz] of one link in `basis` ("PP", "PF"): the
    generalised eigenvalues of the model's own modal matrices K_ff, M_ff (quadrature of the
    scaled shapes, the integrals the model simulates with; `rsmcheck modes`)."""
    link = params.link
    b = modal_basis(PP if basis == "PP" else PF, max(n, 2), link.length, link.rho_a, link.ei)
    lam = eigh(b.k_ff, b.m_ff, eigvals_only=True)
    return np.sqrt(np.sort(lam)[:n]) / (2 * math.pi)
