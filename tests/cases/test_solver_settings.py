"""The case files' solver settings keep the reference's integration error below what their
rows compare (docs/cases.md §1, "Solver")."""

from __future__ import annotations

import pytest

from rsmcheck.core.cases import list_cases, load_case

#: the largest rtol at which the reference's reaction forces are quiet enough to compare:
#: over p2's full hold their sample-to-sample noise is 2.4e-3 N at most at 1e-7 (above the
#: 1e-3 N row it failed) and 2.2e-4 N at 1e-8 (docs/cases.md §1)
REACTION_RTOL = 1e-8


#: every case with a solver of its own (a sequence's phases carry theirs)
SIMULATED = [p for p in list_cases() if not load_case(p.stem).phases]


@pytest.mark.parametrize("path", SIMULATED, ids=lambda p: p.stem)
def test_a_case_comparing_reaction_forces_runs_the_reference_at_rtol_1e_8_or_tighter(path):
    case = load_case(path.stem)
    for short in (False, True):
        variant = case.variant(short)
        if any(s.observable == "reaction_forces_I" for s in variant.compare):
            assert variant.engine_settings["reference"].rtol <= REACTION_RTOL, (
                f"{path.name}{' [short]' if short else ''}: compares reaction_forces_I at rtol "
                f"{variant.engine_settings['reference'].rtol:g}; the reference's reaction forces carry its DP5 error in the "
                f"stiff static shapes (docs/cases.md §1): rtol must be ≤ {REACTION_RTOL:g}")
