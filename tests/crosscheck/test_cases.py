"""Every comparison of every case file, as a test: one per (case, observable) of the
`[compare]` table of the case's short variant (the same rows as `rsmcheck check --short`).

The case file is the single source of the tolerances; a failure names the case, the
observable, the error, the tolerance and the case's reason for it.  Where a case cannot
meet its stated tolerance for a derived reason, the test is `xfail(strict=True)` with that
reason and the measured size (KNOWN below, docs/exudyn.md §8): the tolerance is not widened,
and the test turns into a failure the day the engines do meet it.
"""

from __future__ import annotations

import pytest

from rsmcheck.core.cases import list_cases, load_case
from rsmcheck.orchestration.compare import check_runs

#: (case, observable) -> why it cannot pass at the case's tolerance, with the measured size
#: (Exudyn at the case's [exudyn] step, EA = 1e5·EI; docs/exudyn.md §5, §8)
KNOWN: dict[tuple[str, str], str] = {}


def _pairs() -> list:
    params = []
    for path in list_cases():
        case = load_case(path)
        if case.phases:
            continue
        variant = case.variant(True)
        for spec in variant.compare:
            marks = [pytest.mark.engine_runs((case.name, "reference", True, ()), (case.name, "exudyn", True, ()))]
            why = KNOWN.get((case.name, spec.observable))
            if why:
                marks.append(pytest.mark.xfail(strict=True, reason=why))
            params.append(pytest.param(case.name, spec.observable, marks=marks,
                                       id=f"{case.name}-{spec.observable}"))
    return params


PAIRS = _pairs()


def test_every_case_with_a_compare_table_is_covered():
    """Cases without a [compare] table are named here, not silently passed."""
    uncompared = sorted(load_case(p).name for p in list_cases()
                        if not load_case(p).phases and not load_case(p).variant(True).compare)
    covered = {p.values[0] for p in PAIRS}
    for path in list_cases():
        case = load_case(path)
        if case.variant(True).compare:
            assert case.name in covered
    # the feature cases compared elsewhere (rigid equivalence, tests/exudyn_model) only:
    assert set(uncompared) <= {"free_drift", "closed_squeeze"}, uncompared


@pytest.mark.crosscheck
@pytest.mark.parametrize("case_name,observable", PAIRS)
def test_engines_agree(case_name, observable, run_pool):
    case = load_case(case_name).variant(True)
    ref = run_pool.get(case_name, "reference")
    exu = run_pool.get(case_name, "exudyn")
    row = next(r for r in check_runs(case, ref, exu) if r.observable == observable)
    assert row.passed, (f"{case_name}: {observable} differs by {row.error:.3e} ({row.metric}, worst at "
                        f"t = {row.worst_time:.4g} s, component {row.worst_component}; reference range "
                        f"{row.reference_range:.3e}) > tolerance {row.tolerance:.3e}: {row.why}")
