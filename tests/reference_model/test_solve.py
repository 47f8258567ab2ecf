"""The compiled solve of the coupled system (solve.py): the mass matrix's structure that the envelope
Cholesky relies on, and the constrained solve of eqs. (6) and (11) against a dense one."""

from __future__ import annotations

import numpy as np
import pytest

from reference_model.model_arrays import N_INPUTS
from reference_model.solve import solve_constrained
from reference_model.system import assemble
from reference_model.engine import ReferenceEngine
from rsmcheck.core.cases import load_case


def _random_state(name: str, seed: int, **options) -> tuple[ReferenceEngine, np.ndarray, np.ndarray]:
    engine = ReferenceEngine(load_case(name).variant(True), **options)
    rng = np.random.default_rng(seed)
    lay = engine.model.layout
    x = engine.x.copy()
    x[: 2 * lay.ns] += 1e-2 * rng.standard_normal(2 * lay.ns)  # off the rest pose, moving
    return engine, x, rng.standard_normal(N_INPUTS)


@pytest.mark.parametrize("name, options", [("p1_transport", {}), ("closed_squeeze", {"n_modes": 4}),
                                           ("capture", {"static_modes": False})])
def test_mass_matrix_has_no_entries_outside_the_elimination_envelope(name, options):
    """The two arms never couple and the target couples only with itself (eq. A.6, eq. 3):
    in the elimination order every row is zero left of its envelope."""
    engine, x, u = _random_state(name, 1, **options)
    m, sw = engine.model.core_args(engine.cfg)
    order, first = m.order, m.first
    assert sorted(order.tolist()) == list(range(engine.model.layout.ny))
    Mg = assemble(x, u, m, sw)[0]
    P = Mg[np.ix_(order, order)]
    outside = [(r, c) for r in range(len(order)) for c in range(first[r]) if P[r, c] != 0.0]
    assert outside == []
    # and the envelope is not trivially the whole lower triangle
    assert sum(first) > 0.25 * len(order) ** 2


@pytest.mark.parametrize("name", ["p1_transport", "p2_capture_regrasp", "free_drift"])
def test_constrained_solve_matches_a_dense_solve(name):
    """Ÿ and R_cl of eqs. (6), (11) from the envelope Cholesky against numpy's dense LU on the
    bordered system [[Mg, Gᵀ], [G, 0]] [Ÿ; R_cl] = [f; B*] (W = −Gᵀ)."""
    engine, x, u = _random_state(name, 2)
    m, sw = engine.model.core_args(engine.cfg)
    Mg, f, G, _, _, Bs, *_ = assemble(x, u, m, sw)
    ydd, Rcl = solve_constrained(Mg, f, G, Bs, m)
    ny, nc = Mg.shape[0], G.shape[0]
    K = np.zeros((ny + nc, ny + nc))
    K[:ny, :ny] = Mg
    K[:ny, ny:] = G.T
    K[ny:, :ny] = G
    sol = np.linalg.solve(K, np.concatenate([f, Bs]))
    scale = np.max(np.abs(sol[:ny]))
    assert np.max(np.abs(ydd - sol[:ny])) < 1e-10 * scale
    if nc:
        assert np.max(np.abs(Rcl - sol[ny:])) < 1e-10 * np.max(np.abs(sol[ny:]))
