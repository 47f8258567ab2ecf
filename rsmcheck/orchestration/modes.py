"""`rsmcheck modes`: link and arm eigenfrequencies — analytic, reference, Exudyn.

Links (one link, basis PP = pinned-pinned, PF = pinned-free, modes 1–2):

* analytic: Euler–Bernoulli, f_j = (β_j L)² sqrt(EI/ρA) / (2π L²), with EI derived from
  Table 2's PP f1 (docs/physics.md §2; `rsmcheck.core.params`), βL = jπ (PP) or the roots of
  tan βL = tanh βL (PF), from `rsmcheck.core.beams`;
* reference: the generalised eigenvalues of the reference's modal stiffness and mass
  matrices K_ff, M_ff (`reference_model.beam_modes.modal_basis`, quadrature of the scaled
  shapes: it checks the shapes and integrals the reference simulates with);
* Exudyn: the link as ANCF cable elements, pinned ends removed, Exudyn's own eigenvalue
  solver (`exudyn_model.links.link_frequencies`).

Arms (the whole robot linearised at rest in a case's initial configuration, undamped,
orbit off): each engine's `modes.coupled_frequencies` (the same function in both packages,
rsmcheck/core/engine.py) — the reference's ODE linearised by central differences of its
right-hand side (the oscillatory eigenvalues; Baumgarte's real ones drop out), against
Exudyn's eigenvalues of its own M, K on the constraint null space.  The Exudyn numbers come
from Exudyn alone.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
from scipy.linalg import eigh

from rsmcheck.core.beams import analytic_frequencies
from rsmcheck.core.cases import at_rest, load_case, undamped, without_orbit
from rsmcheck.core.params import TABLE2_HZ, Params

#: (name, case, what it is) of the configurations `rsmcheck modes` linearises
CONFIGURATIONS = (
    ("open", "free_drift", "arm 1 holds the target, arm 2 free (terminal link PF)"),
    ("closed", "closed_squeeze", "both arms hold the target (all links PP)"),
    ("free_arms", "flex_arm_step", "target away: two free arms on the base"),
    ("stretched_closed", "thrust_burn", "thrust configuration: arms nearly stretched, both holding"),
)
N_ARM_MODES = 6


def reference_link_hz(params, basis: str, n: int = 2) -> np.ndarray:
    # the engine packages are heavy optional imports: imported here, when used
    from reference_model.beam_modes import PF, PP, modal_basis

    link = params.link
    b = modal_basis(PP if basis == "PP" else PF, max(n, 2), link.length, link.rho_a, link.ei)
    lam = eigh(b.k_ff, b.m_ff, eigvals_only=True)
    return np.sqrt(np.sort(lam)[:n]) / (2 * math.pi)


def link_rows(params=None, n_elements: int | None = None) -> list[dict[str, Any]]:
    # the engine packages are heavy optional imports: imported here, when used
    from exudyn_model import links

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


def arm_rows(configurations: Sequence[tuple[str, str, str]] = CONFIGURATIONS, n: int = N_ARM_MODES,
             n_modes=None, n_elements: int | None = None) -> list[dict[str, Any]]:
    # the engine packages are heavy optional imports (numba, exudyn): imported here, when used
    from exudyn_model import links
    from exudyn_model import modes as exudyn_modes
    from reference_model import modes as reference_modes

    rows = []
    for label, case_name, what in configurations:
        case = modal_case(load_case(case_name))
        fr = reference_modes.coupled_frequencies(case, n, n_modes=n_modes)
        fx = exudyn_modes.coupled_frequencies(case, n, n_elements=n_elements or links.N_ELEMENTS_DEFAULT)
        for j in range(min(len(fr), len(fx))):
            rows.append({"configuration": label, "case": case_name, "description": what, "mode": j + 1,
                         "reference_hz": float(fr[j]), "exudyn_hz": float(fx[j]),
                         "rel_difference": float(fx[j] / fr[j] - 1),
                         "reference_modes": list(case.n_modes) if n_modes is None else n_modes})
    return rows


def modes_report(n_modes=None, n_elements: int | None = None) -> dict[str, Any]:
    """The JSON object of `rsmcheck modes --json` (README, command line)."""
    return {"links": link_rows(n_elements=n_elements), "arms": arm_rows(n_modes=n_modes, n_elements=n_elements)}
