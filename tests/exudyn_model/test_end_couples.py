"""Joint torques bend the links in the Exudyn model too (docs/physics.md §3.3).

One link of ANCF cable elements pinned at both ends, couples on the massless hubs clamped
to its end sections (the items the engine's joints act on), Exudyn's static solver
(`links.static_end_couples`), against Euler–Bernoulli beam theory:

    w(L/2) = (C_0 − C_L) L² / (16 EI),  w'(0) = (2C_0 − C_L) L / (6 EI),  w'(L) = (2C_L − C_0) L / (6 EI).

The static deflection under end couples is a cubic, which cubic Hermite elements represent
exactly: one element is as good as eight.  What remains is the FE beam's axial compliance
(EA = 1e5·EI, docs/exudyn.md §5) and the Newton tolerance: measured 7.1e-6 of the
deflection, 4.6e-6 of the slopes; tolerance 5e-5.
"""

from __future__ import annotations

import pytest

from exudyn_model.links import static_end_couples
from rsmcheck.core.params import Params

PARAMS = Params()
L, EI = PARAMS.link.length, PARAMS.link.ei
REL_TOL = 5e-5


def beam_theory(c0: float, cl: float) -> dict[str, float]:
    return {"mid_m": (c0 - cl) * L**2 / (16 * EI), "slope_0": (2 * c0 - cl) * L / (6 * EI),
            "slope_L": (2 * cl - c0) * L / (6 * EI)}


@pytest.mark.parametrize("n_elements", [1, 2, 8])
@pytest.mark.parametrize("couples", [(5.0, 0.0), (0.0, -7.0), (5.0, 10.0)])
def test_link_under_end_couples_matches_beam_theory(n_elements, couples):
    got = static_end_couples(PARAMS, *couples, n_elements=n_elements)
    want = beam_theory(*couples)
    scale = max(abs(v) for k, v in want.items() if k != "mid_m")
    assert abs(got["mid_m"] - want["mid_m"]) <= REL_TOL * abs(want["mid_m"] or 1e-5 * L), (got, want)
    for key in ("slope_0", "slope_L"):
        assert abs(got[key] - want[key]) <= REL_TOL * scale, (key, got, want)
