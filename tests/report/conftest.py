"""A report rendered once per session from the test pool's runs (no extra simulation).

Two stand-alone cases run by both engines (free_drift, p1_rigid_gains: their short runs are
already in the pool for the cross-check) and the short mission run by the reference (the
pool's mission run for tests/cases/test_mission_phases.py) are stored the way
`rsmcheck.orchestration.collect` stores them; the verdict is computed from them as `collect` does, with
the Pinocchio rows of two random states per chain; then the page is rendered.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

CASES = ("free_drift", "p1_rigid_gains")
RUNS = pytest.mark.engine_runs(*[(c, e, True, ()) for c in CASES for e in ("reference", "exudyn")],
                               ("mission", "reference", True, ()))


@dataclass
class Rendered:
    folder: Path
    page: Path
    html: str
    verdict: dict
    runs: dict


@pytest.fixture(scope="session")
def rendered(run_pool, tmp_path_factory) -> Rendered:
    from pinocchio_check.compare import run_checks
    from rsmcheck.core.cases import load_case
    from rsmcheck.orchestration.collect import Collected, run_dir, verdict
    from rsmcheck.orchestration.runs import source_digest, store_runs
    from rsmcheck.report.build import render
    from rsmcheck.core.store import write_json

    folder = tmp_path_factory.mktemp("report")
    digest = source_digest()
    cases = [load_case(c) for c in CASES] + [load_case("mission")]
    runs = {}
    for case in cases[:-1]:
        runs[case.name] = {e: run_pool.get(case.name, e) for e in ("reference", "exudyn")}
        store_runs(run_dir(folder), case, True, runs[case.name], digest)
    runs["mission"] = {"reference": run_pool.get("mission", "reference").run}
    store_runs(run_dir(folder), cases[-1], True, runs["mission"], digest)
    write_json(folder / "pinocchio.json", {"checks": run_checks(n_states=2, open_arms=(1, 2)), "checker": "pinocchio"})
    res = Collected(folder, cases, True, ["reference", "exudyn"])
    doc = verdict(res, digest)
    write_json(folder / "verdict.json", doc)
    page = render(folder, folder / "report.html", [c.name for c in cases])
    return Rendered(folder, page, page.read_text(encoding="utf-8"), doc, runs)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(session, config, items):
    """Tests that use `rendered` declare its runs (before the root conftest orders the tests
    and submits the runs)."""
    for item in items:
        if "rendered" in getattr(item, "fixturenames", ()):
            item.add_marker(RUNS)
