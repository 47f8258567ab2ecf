"""The compiled solve of the coupled system (solve.py): the mass matrix's structure that the envelope
Cholesky relies on, and the constrained solve of eqs. (6) and (11) against a dense one."""

from __future__ import annotations

import numpy as np
import pytest

from reference_model.model_arrays import N_INPUTS
from reference_model.solve import solve_constrained
from reference_model.system import assemble, assemble_reduced
from reference_model.engine import ReferenceEngine
from rsmcheck.core.cases import load_case


def _random_state(name: str, seed: int, **options) -> tuple[ReferenceEngine, np.ndarray, np.ndarray]:
    engine = ReferenceEngine(load_case(name).variant(True), **options)
    rng = np.random.default_rng(seed)
    lay = engine.model.layout
    x = engine.x.copy()
    x[: 2 * lay.ns] += 1e-2 * rng.standard_normal(2 * lay.ns)  # off the rest pose, moving
    return engine, x, rng.standard_normal(N_INPUTS)


def _system(engine, x, u):
    """The system the solve takes: over Y, or over z = [Y, θ_m] with slaved static shapes."""
    m, sw = engine.model.core_args(engine.cfg)
    return (assemble_reduced if engine.model.condensed else assemble)(x, u, m, sw)


@pytest.mark.parametrize("name, options", [("p1_transport", {"static_modes": "explicit"}),
                                           ("closed_squeeze", {"n_modes": 4, "static_modes": "explicit"}),
                                           ("capture", {"static_modes": False}),
                                           ("p1_transport", {}), ("closed_squeeze", {"n_modes": 4})])
def test_mass_matrix_has_no_entries_outside_the_elimination_envelope(name, options):
    """The two arms never couple and the target couples only with itself (eq. A.6, eq. 3):
    in the elimination order every row is zero left of its envelope.  With the static
    shapes slaved (the default) the order runs over z = [Y, θ_m] without them, each arm's
    rotors in its block."""
    engine, x, u = _random_state(name, 1, **options)
    m, sw = engine.model.core_args(engine.cfg)
    order, first = m.order, m.first
    lay = engine.model.layout
    want = list(engine.model.coordinates) + (list(range(lay.ny, lay.ny + 6)) if engine.model.condensed else [])
    assert sorted(order.tolist()) == want
    Mg = _system(engine, x, u)[0]
    P = Mg[np.ix_(order, order)]
    outside = [(r, c) for r in range(len(order)) for c in range(first[r]) if P[r, c] != 0.0]
    assert outside == []
    # and the envelope is not trivially the whole lower triangle
    assert sum(first) > 0.25 * len(order) ** 2


@pytest.mark.parametrize("static_modes", ["explicit", "condensed"])
@pytest.mark.parametrize("name", ["p1_transport", "p2_capture_regrasp", "free_drift"])
def test_constrained_solve_matches_a_dense_solve(name, static_modes):
    """Ÿ and R_cl of eqs. (6), (11) from the envelope Cholesky against numpy's dense LU on the
    bordered system [[Mg, Gᵀ], [G, 0]] [Ÿ; R_cl] = [f; B*] (W = −Gᵀ), over the rows of the
    elimination order (slaved static shapes: z = [Y, θ_m] without them)."""
    engine, x, u = _random_state(name, 2, static_modes=static_modes)
    m, sw = engine.model.core_args(engine.cfg)
    Mg, f, G, _, _, Bs, *_ = _system(engine, x, u)
    ydd, Rcl = solve_constrained(Mg, f, G, Bs, m)
    r = np.sort(m.order)
    assert np.all(np.delete(ydd, r) == 0.0)
    Mg, f, G, ydd = Mg[np.ix_(r, r)], f[r], G[:, r], ydd[r]
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
