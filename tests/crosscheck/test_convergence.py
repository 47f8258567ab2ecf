"""Flexible agreement converges: the reference with more modes per link and Exudyn with
more ANCF elements per link approach each other (docs/exudyn.md §7; the full study, modes
1…4 × elements 2…16, is `python -m rsmcheck.orchestration.studies convergence`, stored in
docs/data/convergence_*.json).

flex_arm_step (short, 1 s), Exudyn at h = 62.5 µs (16 steps per control period) so that the
rotor-ripple phase error of generalized-α (docs/exudyn.md §4) stays below the
discretisation differences: the mid-span deflection differs by ~8 % of its size with 2
elements per link and ~2 % with 8; by ~5 % with 1 mode per link and ~2 % with 2.
"""

from __future__ import annotations

import pytest

from rsmcheck.orchestration.compare import relative_errors

CASE = "flex_arm_step"
SUBSTEPS = 16
EXU = {n: (("n_elements", n), ("stepping", "period"), ("substeps", SUBSTEPS)) for n in (2, 8)}
REF = {n: (("n_modes", n),) for n in (1, 2)}
JOBS = [(CASE, "exudyn", True, o) for o in EXU.values()] + [(CASE, "reference", True, o) for o in REF.values()]


@pytest.fixture(scope="module")
def errors(run_pool):
    out = {}
    for n, ro in REF.items():
        ref = run_pool.get(CASE, "reference", True, **dict(ro))
        for m, eo in EXU.items():
            exu = run_pool.get(CASE, "exudyn", True, **dict(eo))
            out[n, m] = relative_errors(CASE, ref, exu, ["link_deflection", "joint_angles", "ee2_pos_B"])
    return out


@pytest.mark.crosscheck
@pytest.mark.engine_runs(*JOBS)
def test_more_elements_reduce_the_difference(errors):
    e2, e8 = errors[2, 2]["link_deflection"], errors[2, 8]["link_deflection"]
    assert e8 < 0.5 * e2, (e2, e8)
    assert e8 < 0.04, e8


@pytest.mark.crosscheck
@pytest.mark.engine_runs(*JOBS)
def test_more_modes_reduce_the_difference(errors):
    e1, e2 = errors[1, 8]["link_deflection"], errors[2, 8]["link_deflection"]
    assert e2 < 0.7 * e1, (e1, e2)
    # the joint angles feel the truncation too (1 mode: 2.6e-7, 2 modes: 3.7e-8 of 2.1 rad)
    assert errors[2, 8]["joint_angles"] < 0.5 * errors[1, 8]["joint_angles"], errors


@pytest.mark.crosscheck
@pytest.mark.engine_runs(*JOBS)
def test_converged_flexible_agreement(errors):
    """With 2 modes and 8 elements the rigid-body observables agree to ~1e-7 of their size."""
    assert errors[2, 8]["joint_angles"] < 1e-6, errors[2, 8]
    assert errors[2, 8]["ee2_pos_B"] < 1e-6, errors[2, 8]
