"""`rsmcheck modes`: link and arm eigenfrequencies — analytic, reference, Exudyn.

Links (one link, basis PP = pinned-pinned, PF = pinned-free, modes 1–2):

* analytic: Euler–Bernoulli, f_j = (β_j L)² sqrt(EI/ρA) / (2π L²), with EI derived from
  Table 2's PP f1 (docs/physics.md §2; `rsmcheck.params`), βL = jπ (PP) or the roots of
  tan βL = tanh βL (PF), from `rsmcheck.beams`;
* reference: the generalised eigenvalues of the reference's modal stiffness and mass
  matrices K_ff, M_ff (`reference_model.beam_modes.modal_basis`, quadrature of the scaled
  shapes: it checks the shapes and integrals the reference simulates with);
* Exudyn: the link as ANCF cable elements, pinned ends removed, Exudyn's own eigenvalue
  solver (`exudyn_model.links.link_frequencies`).

Arms (the whole robot linearised at rest in a case's initial configuration, undamped,
orbit off): the reference's ODE linearised by central differences of its right-hand side
(`ReferenceModel.rhs`, its public API: the oscillatory eigenvalues; Baumgarte's real ones
drop out), against Exudyn's eigenvalues of its own M, K on the constraint null space
(`exudyn_model.modes.coupled_frequencies`).  The Exudyn numbers come from Exudyn alone.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from rsmcheck.cases import at_rest, undamped, without_orbit

#: (name, case, what it is) of the configurations `rsmcheck modes` linearises
CONFIGURATIONS = (
    ("open", "free_drift", "arm 1 holds the target, arm 2 free (terminal link PF)"),
    ("closed", "closed_squeeze", "both arms hold the target (all links PP)"),
    ("free_arms", "flex_arm_step", "target away: two free arms on the base"),
    ("stretched_closed", "thrust_burn", "thrust configuration: arms nearly stretched, both holding"),
)
N_ARM_MODES = 6


def reference_link_hz(params, basis: str, n: int = 2) -> np.ndarray:
    from scipy.linalg import eigh

    from reference_model.beam_modes import PF, PP, modal_basis

    link = params.link
    b = modal_basis(PP if basis == "PP" else PF, max(n, 2), link.length, link.rho_a, link.ei)
    lam = eigh(b.k_ff, b.m_ff, eigvals_only=True)
    return np.sqrt(np.sort(lam)[:n]) / (2 * math.pi)


def link_rows(params=None, n_elements: int | None = None) -> list[dict[str, Any]]:
    from exudyn_model import links
    from rsmcheck.beams import analytic_frequencies
    from rsmcheck.params import TABLE2_HZ, Params

    params = params or Params()
    n_el = n_elements or links.N_ELEMENTS_DEFAULT
    rows = []
    for basis in ("PP", "PF"):
        fa, fr = analytic_frequencies(params.link, basis), reference_link_hz(params, basis)
        fx = links.link_frequencies(params, basis, n_el)
        for j in range(2):
            rows.append({"basis": basis, "mode": j + 1, "analytic_hz": float(fa[j]), "reference_hz": float(fr[j]),
                         "exudyn_hz": float(fx[j]), "table2_hz": TABLE2_HZ[basis][j],
                         "reference_rel": float(fr[j] / fa[j] - 1), "exudyn_rel": float(fx[j] / fa[j] - 1),
                         "exudyn_elements": n_el})
    return rows


def modal_case(case):
    """`case` at rest in its initial configuration, undamped, without orbit."""
    return without_orbit(undamped(at_rest(case)))


def reference_coupled_hz(case, n: int = N_ARM_MODES, n_modes=None) -> np.ndarray:
    """The first `n` oscillatory frequencies [Hz] of the reference linearised at the initial
    state of `case` (use `modal_case` first), by central differences of its ODE."""
    jac, _, _ = reference_linear_plant(case, lambda s: np.zeros(0), n_modes=n_modes)
    lam = np.linalg.eigvals(jac)
    return np.sort(np.abs(lam.imag[lam.imag > 2 * np.pi]))[:n] / (2 * np.pi)


def reference_linear_plant(case, outputs, n_inputs: int = 7, n_modes=None, eps: float = 1e-7):
    """(A, B, C) of the reference linearised at the initial state of `case` (damping kept):
    ẋ = A x + B u on x = (Y*, Ẏ*), u = (τ_m1..6, τ_B), y = `outputs(sensors)`; central
    differences of its ODE and of its sensors (the counterpart of
    `exudyn_model.modes.linear_plant`)."""
    from reference_model import core
    from reference_model.engine import ReferenceEngine

    ref = ReferenceEngine(case, n_modes=n_modes)
    model, x0, cfg = ref.model, ref.x.copy(), ref.cfg
    m = 2 * model.layout.ns
    u0 = np.zeros(core.N_INPUTS)
    A, B, cols = np.zeros((m, m)), np.zeros((m, n_inputs)), []
    for i in range(m):
        e = eps * max(1.0, abs(x0[i]))
        dx = np.zeros_like(x0)
        dx[i] = e
        A[:, i] = (model.rhs(x0 + dx, u0, cfg)[:m] - model.rhs(x0 - dx, u0, cfg)[:m]) / (2 * e)
        ys = []
        for sign in (1.0, -1.0):
            ref.x = x0 + sign * dx
            ys.append(outputs(ref.sensors()))
        cols.append((ys[0] - ys[1]) / (2 * e))
    ref.x = x0
    for j in range(n_inputs):
        u = u0.copy()
        u[core.U_TAU_M + j if j < 6 else core.U_TAU_B] = 1.0
        B[:, j] = model.rhs(x0, u, cfg)[:m] - model.rhs(x0, u0, cfg)[:m]
    return A, B, np.array(cols).T


def arm_rows(configurations: Sequence[tuple[str, str, str]] = CONFIGURATIONS, n: int = N_ARM_MODES,
             n_modes=None, n_elements: int | None = None) -> list[dict[str, Any]]:
    from exudyn_model import links
    from exudyn_model.modes import coupled_frequencies
    from rsmcheck.cases import load_case

    rows = []
    for label, case_name, what in configurations:
        case = modal_case(load_case(case_name))
        fr = reference_coupled_hz(case, n, n_modes)
        fx = coupled_frequencies(case, n, n_elements=n_elements or links.N_ELEMENTS_DEFAULT)
        for j in range(min(len(fr), len(fx))):
            rows.append({"configuration": label, "case": case_name, "description": what, "mode": j + 1,
                         "reference_hz": float(fr[j]), "exudyn_hz": float(fx[j]),
                         "rel_difference": float(fx[j] / fr[j] - 1),
                         "reference_modes": list(case.n_modes) if n_modes is None else n_modes})
    return rows


def modes_report(n_modes=None, n_elements: int | None = None) -> dict[str, Any]:
    """The JSON object of `rsmcheck modes --json` (README, command line)."""
    return {"links": link_rows(n_elements=n_elements), "arms": arm_rows(n_modes=n_modes, n_elements=n_elements)}
