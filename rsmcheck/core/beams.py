"""Analytic Euler–Bernoulli frequencies of a uniform link (docs/physics.md §2): the check
values the engines' link modes are compared with (`rsmcheck modes`, the Exudyn element
convergence study).

f_j = (β_j L)² sqrt(EI/ρA) / (2π L²), with β_j L = jπ for a pinned-pinned link (PP) and the
roots of tan βL = tanh βL, just below (j + 1/4)π, for a pinned-free one (PF).

The reference model derives its own modal basis and roots (reference_model/beam_modes.py):
this analytic column is one of the checks on it, so it does not use them.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def beta_l(basis: str, j: int) -> float:
    """j-th (1-based) root β_j L of the frequency equation of `basis` ("PP" or "PF")."""
    if basis == "PP":
        return j * math.pi
    return brentq(lambda b: math.tan(b) - math.tanh(b), (j + 0.25) * math.pi - 0.3,
                  (j + 0.25) * math.pi + 1e-9, xtol=1e-15)


def analytic_frequencies(link, basis: str, n: int = 2) -> np.ndarray:
    """The first `n` frequencies [Hz] of a link (`rsmcheck.core.params.LinkParams`: length, EI,
    ρA) in `basis` ("PP" or "PF")."""
    c = math.sqrt(link.ei / link.rho_a)
    return np.array([b * b * c / (2 * math.pi * link.length**2) for b in (beta_l(basis, j) for j in range(1, n + 1))])
