"""Rigid equivalence: with rigid links in both engines (reference with 0 modes, Exudyn with
`rigid=True`) every observable of every feature case agrees to 1e-5 of its scale,

    error = max_t max_c |exudyn − reference| / max(max_t |reference|, SCALE_FLOORS[obs]).

Both engines then solve the same rigid multibody ODE, so the difference is the integrators'.
The reference runs at rtol 1e-12 (checked against 1e-11 in rsmcheck.studies: its own error
is ≤ 3e-6 of every scale); Exudyn's generalized-α is second order and the undamped 92 Hz
rotor ripple (ζ = 1.4e-5) accumulates its phase error ≈ (ωh)²/12·ωt, so Exudyn runs at the
step that the step study (docs/exudyn.md §6, docs/data/rigid_steps_index3.json) showed to
reach 1e-5 on each short case (rsmcheck.studies.RIGID_SUBSTEPS), with a tight Newton
tolerance and a restart at every change of the held inputs (rsmcheck.studies.RIGID_EXUDYN).
Measured errors: docs/data/rigid_equivalence.json (`python -m rsmcheck.studies equivalence`).

Reaction forces: the index-3 multipliers of generalized-α carry a round-off floor
∝ ε·M·|q|/h² that grows as the phase error shrinks (measured ×4 per halving of h below
0.06 ms), so there is no step at which they reach 1e-5 where a grasp is on; those tests are
xfail(strict) with the measured minimum (KNOWN).
"""

from __future__ import annotations

import pytest

from rsmcheck.compare import compare_runs
from rsmcheck.observables import NAMES
from rsmcheck.studies import RIGID_REFERENCE, RIGID_SUBSTEPS, RIGID_TOLERANCE, rigid_options

OBSERVABLES = [n for n in NAMES if n != "time"]
#: (case, observable) -> why 1e-5 is out of reach, with the measured size
_FLOOR = ("index-3 multipliers: the rotor-phase error (∝ h²) meets a round-off floor ∝ ε·M·|q|/h² "
          "(free_drift: 1.2e-2 at 0.5 ms, 5.3e-3 at 62.5 µs, then ×4 per halving of h), so no step "
          "reaches 1e-5; measured here: ")
KNOWN: dict[tuple[str, str], str] = {
    ("free_drift", "reaction_forces_I"): _FLOOR + "1.2e-2 of 0.18 N at h = 0.5 ms",
    ("closed_squeeze", "reaction_forces_I"): _FLOOR + "3.8e-3 of 21 N at 7.8 µs",
    ("capture", "reaction_forces_I"): _FLOOR + "2.5e-2 of 2.5 N at 7.8 µs",
    ("release", "reaction_forces_I"): _FLOOR + "2.5e-3 of 21 N at 7.8 µs",
    ("wrist_bistop", "reaction_forces_I"): _FLOOR + "1.8e-2 of 16 N at 3.9 µs (5.7e-3 at 7.8 µs)",
    ("gravity_gradient", "reaction_forces_I"): _FLOOR + "1.4e-1 of the 0.01 N floor at 31 µs",
    ("thrust_burn", "reaction_forces_I"): _FLOOR + "2.1e-2 of 64 N at 7.8 µs",
    ("thrust_burn", "momentum_I"):
        "zero-order hold of the thrust-inertia field (docs/exudyn.md §5.5): its direction follows θ_B "
        "with one control period of lag, T·ω_B·Δt/2 ≈ 1e-4 N of net force: 1.8e-5 of 6.8 (1.2e-4 kg·m/s), "
        "independent of h (1.8e-5 at 31 µs and 7.8 µs)",
}


def _jobs(case: str) -> tuple:
    return ((case, "reference", True, tuple(sorted(RIGID_REFERENCE.items()))),
            (case, "exudyn", True, tuple(sorted(rigid_options(case).items()))))


def _params():
    out = []
    for case in RIGID_SUBSTEPS:
        for obs in OBSERVABLES:
            marks = [pytest.mark.engine_runs(*_jobs(case))]
            if (case, obs) in KNOWN:
                marks.append(pytest.mark.xfail(strict=True, reason=KNOWN[(case, obs)]))
            out.append(pytest.param(case, obs, marks=marks, id=f"{case}-{obs}"))
    return out


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
