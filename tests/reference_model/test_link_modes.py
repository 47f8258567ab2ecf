"""Table 2 of the paper and the beam data of docs/physics.md §2, through the model's own matrices.

The frequencies are not read from `beam_modes.omega` (that is ω = β² sqrt(EI/ρA), the
formula the data were derived with).  They come from the floating-frame mass matrix that
`link.link_newton` builds for one link at zero deflection and from the stiffness the same
function applies (V_A = −K_ff A, extracted column by column with unit amplitudes), i.e. from
the curvature integral ∫EI φ''φ'' of the scaled shapes and the 64-point quadrature.
Boundary conditions of Table 2:

* PF (pinned-free): the proximal pin is fixed (R = 0), the frame rotation θ stays a
  coordinate next to the modal amplitudes: the generalized eigenproblem on (θ, A) has one
  zero root (the rigid rotation) and the elastic roots.  J_extra sits on θ only, so it
  must not move the elastic roots — this is tested, not assumed.
* PP (pinned-pinned): both pins fixed, so the chord frame cannot rotate: (A) only.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import eigh

from reference_model.beam_modes import PF, PP, beta_l
from reference_model.build import Configuration, ReferenceModel
from reference_model.link import link_newton
from rsmcheck.core.params import TABLE2_HZ, Params

TABLE2_REL_TOL = 5e-4  # 0.05 %


def _link_matrices(model: ReferenceModel, basis: int, link: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """(M, K) of link `link` in `basis` at zero deflection and rest, Newtonian coordinates
    X = [R_x, R_y, θ, A_1..A_n], from link.link_newton."""
    lay = model.layout
    cfg = Configuration()
    cfg.basis[:] = basis
    nq = lay.nq
    n = lay.n_modes[link]

    def newton(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        qd = np.zeros(nq)
        th, om = model.kinematics(q, qd, cfg)[:2]
        M, V = np.empty((3 + n, 3 + n)), np.empty(3 + n)
        link_newton(link, q, qd, th, om, model.arrays, cfg.basis, M, V)
        return M, V

    q0 = np.zeros(nq)
    M, V0 = newton(q0)
    assert np.all(V0 == 0.0), "no force at zero deflection and rest"
    K = np.zeros((3 + n, 3 + n))
    for j in range(n):
        q = q0.copy()
        q[lay.modes(link).start + j] = 1.0  # V_A is linear in A at rest: −K_ff[:, j]
        K[3:, 3 + j] = -newton(q)[1][3:]
    return M, K


def _frequencies_hz(M: np.ndarray, K: np.ndarray) -> np.ndarray:
    lam = eigh(K, M, eigvals_only=True)
    return np.sqrt(np.clip(lam, 0.0, None)) / (2.0 * math.pi)


@pytest.mark.parametrize("n_modes", [2, 4])
def test_table2_pp_from_model_matrices(n_modes):
    model = ReferenceModel(Params(), n_modes)
    M, K = _link_matrices(model, PP)
    assert np.allclose(K, K.T, rtol=0, atol=1e-9 * np.abs(K).max())
    f = _frequencies_hz(M[3:, 3:], K[3:, 3:])  # both pins fixed: chord frame fixed
    for got, want in zip(f[:2], TABLE2_HZ["PP"]):
        assert abs(got - want) / want <= TABLE2_REL_TOL, (got, want)
    assert f[1] / f[0] == pytest.approx(4.0, rel=1e-9)  # PP f2 = 4 f1 exactly (β2 L = 2π)


@pytest.mark.parametrize("n_modes", [2, 4])
def test_table2_pf_from_model_matrices(n_modes):
    model = ReferenceModel(Params(), n_modes)
    M, K = _link_matrices(model, PF)
    sub = slice(2, None)  # proximal pin fixed: keep the frame rotation and the modes
    f = _frequencies_hz(M[sub, sub], K[sub, sub])
    assert f[0] < 1e-6, "the frame rotation is the rigid mode of the pinned-free link"
    for got, want in zip(f[1:3], TABLE2_HZ["PF"]):
        assert abs(got - want) / want <= TABLE2_REL_TOL, (got, want)


def test_pf_rigid_mode_is_mass_orthogonal_and_j_extra_only_on_rotation():
    """M_θA = ∫ρξφ = 0 for PF, and M_θθ = mL²/3 + J_extra: J_extra cannot touch Table 2."""
    p = Params()
    model = ReferenceModel(p, 2)
    M, _ = _link_matrices(model, PF)
    scale = math.sqrt(M[2, 2] * M[3, 3])
    assert np.all(np.abs(M[2, 3:]) <= 1e-12 * scale)
    lk = p.link
    assert M[2, 2] == pytest.approx(lk.mass * lk.length**2 / 3 + lk.inertia_extra, rel=1e-14)
    # about the link COM: mL²/3 − m(L/2)² + J_extra = Table 1's J_z
    assert M[2, 2] - lk.mass * (lk.length / 2) ** 2 == pytest.approx(lk.inertia_z, rel=1e-12)
    # the PP frame (chord) is not mass-orthogonal: M_θA ≠ 0 there, which is why PP keeps
    # the frame fixed for Table 2
    Mpp, _ = _link_matrices(model, PP)
    assert abs(Mpp[2, 3]) > 1e-3 * math.sqrt(Mpp[2, 2] * Mpp[3, 3])


def _half_unit(printed: str) -> float:
    """Half a unit of the last printed digit of `printed`."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return 0.5 * 10.0**-decimals


@pytest.mark.parametrize(
    "name, value, printed",
    [
        ("rho_a", lambda p: p.link.rho_a, "24.327"),
        ("sqrt(EI/rhoA)", lambda p: math.sqrt(p.link.ei / p.link.rho_a), "43.201"),
        ("EI", lambda p: p.link.ei, "45401.5"),
        ("J_extra", lambda p: p.link.inertia_extra, "0.388"),
        ("PF beta1 L", lambda p: beta_l(PF, 1), "3.92660"),
        ("PF beta2 L", lambda p: beta_l(PF, 2), "7.06858"),
        ("uniform beam mL^2/12", lambda p: p.link.mass * p.link.length**2 / 12, "6.842"),
    ],
)
def test_derived_numbers_as_printed(name, value, printed):
    """The derived numbers of docs/physics.md §2, to the digits printed there (half a unit of the last)."""
    got = value(Params())
    assert abs(got - float(printed)) <= _half_unit(printed), (name, got, printed)


def test_pf_roots_solve_the_frequency_equation_and_analytic_frequencies():
    for j in (1, 2):
        b = beta_l(PF, j)
        assert abs(math.tan(b) - math.tanh(b)) < 1e-12
    p = Params().link
    c = math.sqrt(p.ei / p.rho_a)
    f_pf = [beta_l(PF, j) ** 2 * c / (2 * math.pi * p.length**2) for j in (1, 2)]
    assert abs(f_pf[0] - 47.116) <= 5e-4 and abs(f_pf[1] - 152.685) <= 5e-4
    f_pp = [beta_l(PP, j) ** 2 * c / (2 * math.pi * p.length**2) for j in (1, 2)]
    assert f_pp[0] == pytest.approx(30.16, rel=1e-14)
    assert f_pp[1] == pytest.approx(4 * 30.16, rel=1e-14)
