"""Rigid equivalence: with rigid links in both engines (reference with 0 modes, Exudyn with
`rigid=True`) every observable of every feature case agrees to 1e-5 of its scale,

    error = max_t max_c |exudyn − reference| / max(max_t |reference|, SCALE_FLOORS[obs]).

Both engines then solve the same rigid multibody ODE, so the difference is the integrators'.
The reference runs at rtol 1e-12 (checked against 1e-11 in rsmcheck.orchestration.studies: its own error
is ≤ 3e-6 of every scale); Exudyn's generalized-α is second order and the undamped 92 Hz
rotor ripple (ζ = 1.4e-5) accumulates its phase error ≈ (ωh)²/12·ωt, so Exudyn runs at the
step that the step study (docs/exudyn.md §6, docs/data/rigid_steps_index3.json) showed to
reach 1e-5 on each short case (rsmcheck.orchestration.studies.RIGID_SUBSTEPS), with a tight Newton
tolerance and a restart at every change of the held inputs (rsmcheck.orchestration.studies.RIGID_EXUDYN).
Measured errors: docs/data/rigid_equivalence.json (`python -m rsmcheck.orchestration.studies equivalence`).

Reaction forces: computed by Exudyn's index-1 solve at each sample (exudyn_model/reactions.py,
not the integrator's index-3 multipliers, whose round-off floor ∝ 1/h² grows as the step
shrinks), they are as accurate as the state and converge at second order; the grasp cases
need the finest steps (the 92 Hz ripple carries their reactions).  gravity_gradient's ripple
is only 5e-11 rad: the reference resolves it with its case's h_max = 0.5 ms (below DP5's
error scale the 1 ms steps damp it) and Exudyn with velocity-level constraints (the index-3
Newton iteration meets its round-off floor there; rsmcheck.orchestration.studies.RIGID_CASE_OPTIONS).
`make study`: ≈ 35–45 min on 2 cores.
"""

from __future__ import annotations

import pytest

from rsmcheck.orchestration.compare import compare_runs
from rsmcheck.core.observables import NAMES
from rsmcheck.orchestration.studies import RIGID_REFERENCE, RIGID_SUBSTEPS, RIGID_TOLERANCE, rigid_options

OBSERVABLES = [n for n in NAMES if n != "time"]


def _jobs(case: str) -> tuple:
    return ((case, "reference", True, tuple(sorted(RIGID_REFERENCE.items()))),
            (case, "exudyn", True, tuple(sorted(rigid_options(case).items()))))


def _params():
    return [pytest.param(case, obs, marks=[pytest.mark.engine_runs(*_jobs(case))], id=f"{case}-{obs}")
            for case in RIGID_SUBSTEPS for obs in OBSERVABLES]


@pytest.mark.crosscheck
@pytest.mark.slow
@pytest.mark.study
@pytest.mark.parametrize("case,observable", _params())
def test_rigid_equivalence(case, observable, run_pool):
    ref = run_pool.get(case, "reference", True, **RIGID_REFERENCE)
    exu = run_pool.get(case, "exudyn", True, **rigid_options(case))
    row = compare_runs(case, ref, exu, {observable: RIGID_TOLERANCE})[0]
    assert row.passed, (f"{case}: {observable} differs by {row.error:.2e} of its scale {row.scale:.3e} "
                        f"(worst at t = {row.worst_time:.4g} s, component {row.worst_component}), "
                        f"Exudyn h = {1e-3 / RIGID_SUBSTEPS[case]:.3g} s")
