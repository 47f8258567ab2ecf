"""Analytic Euler–Bernoulli modal bases of a link, eq. (1): w(ξ, t) = Σ_j A_j(t) φ_j(ξ).

Two bases (Sect. 4, Table 2):

* **PP** (pinned-pinned) for a link pinned at both ends.  Frame: the chord joining the
  two pins, so w(0) = w(L) = 0.  φ_j = sin(jπξ/L), β_j L = jπ.
* **PF** (pinned-free) for the terminal link of a free arm.  Frame: the rigid rotation
  about the pin, mass-orthogonal to the elastic modes (∫ρ ξ φ_j dξ = 0), w(0) = 0.
  φ_j = sin βξ + (sin βL / sinh βL) sinh βξ with tan βL = tanh βL.

Both satisfy w'' = 0 at the pins.  Every shape is scaled to max |φ| = 1 on [0, L], so an
amplitude is the peak transverse displacement of its mode [m].  The modal integrals the
floating-frame equations need (docs/physics.md §3) are computed by Gauss–Legendre
quadrature with enough points to be exact to round-off for these smooth shapes; the
stiffness is computed from the curvature integral ∫ EI φ_i'' φ_j'' dξ, not from ω², so that
the eigenfrequency test of Table 2 checks the shapes and the quadrature as well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

PP = 0
PF = 1
BASIS_NAMES = {PP: "PP", PF: "PF"}

#: Quadrature used for the modal integrals (exact to round-off for β L ≤ ~30).
_N_GAUSS_INTEGRALS = 64
#: Gauss points per link for distributed loads (tidal gravity, thrust inertia).
N_GAUSS_LOADS = 8


def beta_l(kind: int, j: int) -> float:
    """j-th (1-based) root β_j L of the frequency equation of basis `kind`.

    PP: sin βL = 0 → jπ.  PF: tan βL = tanh βL → (j + 1/4)π − ε, ε < 1e-7 for j ≥ 2.
    """
    if kind == PP:
        return j * math.pi
    guess = (j + 0.25) * math.pi
    return brentq(lambda b: math.tan(b) - math.tanh(b), guess - 0.3, guess + 1e-9, xtol=1e-15)


def _shape(kind: int, beta: float, length: float, x: np.ndarray, deriv: int) -> np.ndarray:
    """φ (deriv 0) or φ'' (deriv 2) of the unscaled mode with wavenumber β at points x."""
    if kind == PP:
        s = np.sin(beta * x)
        return s if deriv == 0 else -beta**2 * s
    c = math.sin(beta * length) / math.sinh(beta * length)
    if deriv == 0:
        return np.sin(beta * x) + c * np.sinh(beta * x)
    return beta**2 * (-np.sin(beta * x) + c * np.sinh(beta * x))


@dataclass(frozen=True)
class ModalBasis:
    """Modal data of one link in one basis, for `n` modes.

    Integrals are over the link's material abscissa ξ ∈ [0, L] of the link frame; ρ is the
    mass per length ρA.  Array shapes are (n,), (n, n) or (n_gauss, n).
    """

    kind: int
    n: int
    length: float
    rho_a: float
    omega: np.ndarray  # ω_j = (β_j)² sqrt(EI/ρA) [rad/s]
    phi_bar: np.ndarray  # ∫ρ φ_j dξ [kg]
    phi_x: np.ndarray  # ∫ρ ξ φ_j dξ [kg·m]  (0 for PF: mass-orthogonal to the frame rotation)
    m_ff: np.ndarray  # ∫ρ φ_i φ_j dξ [kg]
    k_ff: np.ndarray  # ∫EI φ_i'' φ_j'' dξ [N/m]
    phi_tip: np.ndarray  # φ_j(L) (0 for PP)
    phi_mid: np.ndarray  # φ_j(L/2)
    x_gauss: np.ndarray  # load quadrature abscissae [m]
    w_gauss: np.ndarray  # load quadrature weights [m]
    phi_gauss: np.ndarray  # φ_j at the load abscissae

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2.0 * math.pi)


def mode_shapes(kind: int, n: int, length: float, x: np.ndarray) -> np.ndarray:
    """The n scaled shapes φ_j(x) of basis `kind` at points x, shape (x.size, n)."""
    fine = np.linspace(0.0, length, 4001)
    out = np.empty((np.size(x), n))
    for j in range(n):
        b = beta_l(kind, j + 1) / length
        out[:, j] = _shape(kind, b, length, np.asarray(x, float), 0) / np.max(np.abs(_shape(kind, b, length, fine, 0)))
    return out


def quadrature(length: float, n: int = _N_GAUSS_INTEGRALS) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre abscissae and weights on [0, length]."""
    xg, wg = np.polynomial.legendre.leggauss(n)
    return 0.5 * length * (xg + 1.0), 0.5 * length * wg


def modal_basis(kind: int, n: int, length: float, rho_a: float, ei: float) -> ModalBasis:
    """Build the `kind` (PP or PF) basis with `n` ≥ 0 modes for a uniform beam."""
    if kind not in (PP, PF):
        raise ValueError(f"basis kind must be PP ({PP}) or PF ({PF}), got {kind}")
    if n < 0:
        raise ValueError(f"number of modes must be >= 0, got {n}")
    xg, wg = np.polynomial.legendre.leggauss(_N_GAUSS_INTEGRALS)
    x = 0.5 * length * (xg + 1.0)
    w = 0.5 * length * wg
    xl, wl = np.polynomial.legendre.leggauss(N_GAUSS_LOADS)
    x_loads = 0.5 * length * (xl + 1.0)
    w_loads = 0.5 * length * wl

    betas = np.array([beta_l(kind, j) / length for j in range(1, n + 1)])
    fine = np.linspace(0.0, length, 4001)
    scale = np.array([1.0 / np.max(np.abs(_shape(kind, b, length, fine, 0))) for b in betas])

    def table(points: np.ndarray, deriv: int) -> np.ndarray:
        out = np.empty((points.size, n))
        for j, b in enumerate(betas):
            out[:, j] = scale[j] * _shape(kind, b, length, points, deriv)
        return out

    phi = table(x, 0)
    phi2 = table(x, 2)
    return ModalBasis(
        kind=kind,
        n=n,
        length=length,
        rho_a=rho_a,
        omega=betas**2 * math.sqrt(ei / rho_a),
        phi_bar=rho_a * w @ phi,
        phi_x=rho_a * (w * x) @ phi,
        m_ff=rho_a * (phi.T * w) @ phi,
        k_ff=ei * (phi2.T * w) @ phi2,
        phi_tip=table(np.array([length]), 0)[0],
        phi_mid=table(np.array([0.5 * length]), 0)[0],
        x_gauss=x_loads,
        w_gauss=w_loads,
        phi_gauss=table(x_loads, 0),
    )
