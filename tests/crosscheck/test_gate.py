"""The regression gate inside `make test` (docs/gate.md): every stand-alone case's short run,
as the cross-check tests already make it (the shared run pool, no second simulation),
against its golden in goldens/.  A model change that moves results fails here until it is
blessed with a reason (`rsmcheck bless CASE --reason TEXT`)."""

from __future__ import annotations

import pytest

from rsmcheck.orchestration.gate import compare_with_golden, gated_cases, golden_path, read_golden

ENGINES = ("reference", "exudyn")
CASES = [c.name for c in gated_cases()]


@pytest.mark.gate
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("case_name", [pytest.param(n, marks=pytest.mark.engine_runs(
    (n, "reference", True, ()), (n, "exudyn", True, ()))) for n in CASES])
def test_run_matches_its_golden(case_name, engine, run_pool):
    from rsmcheck.core.cases import load_case

    case = load_case(case_name).variant(True)
    golden = read_golden(golden_path(case_name, engine), engine)
    res = compare_with_golden(case, run_pool.get(case_name, engine), golden)
    lines = res.inputs_changed + res.structure + [
        f"{m.observable}: changed by {m.change:.3e} > gate tolerance {m.tolerance:.3e} ({m.ratio:.3g} ×), "
        f"first at t = {m.first_time:.4g} s" for m in res.moved] + [
        f"more work: {w.describe()} > limit {w.limit}" for w in res.more_work]
    assert res.unchanged, (f"{case_name} / {engine} moved from its golden "
                           f"({golden.attrs.get('blessed_utc')}, {golden.attrs.get('reason')!r}): "
                           + "; ".join(lines) + ". If intended: rsmcheck bless "
                           f"{case_name} --reason TEXT")
