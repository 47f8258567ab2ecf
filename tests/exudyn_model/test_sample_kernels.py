"""The Exudyn engine's compiled per-sample helpers against the same arithmetic in numpy and
scipy, bit for bit: the saddle matrix's CSC gather (reactions.saddle_csc), the thrust
inertia's forces (field.held_minus_uniform) and the divergence check (stepper.all_finite).
The sensors' gather is checked on the engine (test_engine.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import sparse

from exudyn_model.field import held_minus_uniform
from exudyn_model.reactions import keep_heap_top_pad, saddle_csc
from exudyn_model.stepper import all_finite

RNG = np.random.default_rng(11)


def _saddle(n2: int, nae: int, ode2_block: bool):
    """A dense K (zero ODE2 block unless `ode2_block`) and M with ~2 % nonzeros, some
    entries of K + M cancelling to zero."""
    n = n2 + nae
    K = np.where(RNG.random((n, n)) < 0.02, RNG.normal(size=(n, n)), 0.0)
    M = np.where(RNG.random((n2, n2)) < 0.05, RNG.normal(size=(n2, n2)), 0.0)
    if ode2_block:
        K[:n2, :n2] = np.where(RNG.random((n2, n2)) < 0.02, RNG.normal(size=(n2, n2)), 0.0)
        K[3, 4], M[3, 4] = 1.5, -1.5  # K + M = 0: not a nonzero
    else:
        K[:n2, :n2] = 0.0
    return K, M


@pytest.mark.parametrize("ode2_block", [False, True])
def test_saddle_csc_is_scipys_canonical_csc_of_the_dense_sum(ode2_block):
    K, M = _saddle(60, 25, ode2_block)
    A = K.copy()
    A[:60, :60] += M
    rows, cols = np.nonzero(A)
    expected = sparse.csc_matrix((A[rows, cols], (rows, cols)), shape=A.shape)
    indptr = np.empty(86, dtype=np.int32)
    small = np.empty(3, dtype=np.int32), np.empty(3)
    nnz = saddle_csc(K, M, indptr, *small)
    assert nnz == expected.nnz > 3  # too little room: only counted
    indices, data = np.empty(nnz, dtype=np.int32), np.empty(nnz)
    assert saddle_csc(K, M, indptr, indices, data) == nnz
    assert np.array_equal(indptr, expected.indptr) and np.array_equal(indices, expected.indices)
    assert np.array_equal(data.view(np.int64), expected.data.view(np.int64))


def test_held_minus_uniform_is_numpys_q_minus_U_a():
    U = RNG.normal(size=(50, 2))
    U[::3, 1] = 0.0  # rows with one entry, as the model's
    for accel in (0.0, 0.37, 2.5):
        q = RNG.normal(size=50)
        theta = RNG.normal() * 3.0
        out = np.empty(50)
        held_minus_uniform(q, U, accel * math.cos(theta), accel * math.sin(theta), out)
        expected = q - U @ (accel * np.array([math.cos(theta), math.sin(theta)]))
        np.testing.assert_allclose(out, expected, rtol=0.0, atol=4e-16 * np.max(np.abs(U)) * max(accel, 1e-300))
        assert np.array_equal(out[::3], expected[::3])  # one entry per row: the same bits everywhere


def test_all_finite():
    q, v = np.zeros(10), np.ones(7)
    assert all_finite(q, v)
    for bad in (math.nan, math.inf, -math.inf):
        w = v.copy()
        w[6] = bad
        assert not all_finite(q, w) and not all_finite(w, q)


def test_heap_top_pad_is_set_where_the_allocator_has_it():
    assert keep_heap_top_pad() in (True, False)  # glibc: True; elsewhere nothing to do
