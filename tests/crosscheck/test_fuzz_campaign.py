"""`rsmcheck fuzz` end to end: two drawn scenarios (seed CI_SEED: an open chain with a
torque step and a closed chain under sines, both in orbit), each run by both engines at
the scenario's resolution and refined, judged by the criterion of fuzz_ranges.toml.

The campaign of record (`make fuzz`, ≥ 100 scenarios) takes an hour on two cores
(docs/fuzz.md); these two scenarios (eight runs, about two minutes) run with the studies
(`make study`), outside `make test`'s ten minutes.  The judge, the drawing and the document
are tested without engines in tests/rsmcheck/orchestration/test_fuzz.py."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from rsmcheck.orchestration.fuzz_scenarios import draw

pytestmark = [pytest.mark.crosscheck, pytest.mark.study]

#: the scenarios CI runs: 2.25 s of flight in all (fuzz_scenarios.draw)
CI_SEED = 2094


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("fuzz")
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "fuzz", "--n", "2", "--seed", str(CI_SEED),
                           "--json", "--out", str(out)], capture_output=True, text=True, timeout=1200)
    return proc, out


def test_the_ci_scenarios_are_an_open_and_a_closed_chain():
    chains = {draw(CI_SEED, i).chain for i in range(2)}
    assert chains == {"open", "closed"}


def test_both_scenarios_pass_and_the_document_says_why(campaign):
    proc, out = campaign
    assert proc.returncode in (0, 1), proc.stderr[-3000:]
    doc = json.loads(proc.stdout)
    assert doc == json.loads((out / "fuzz.json").read_text())
    assert [s["index"] for s in doc["scenarios"]] == [0, 1] and doc["seed"] == CI_SEED
    for s in doc["scenarios"]:
        assert not s.get("errors"), s["errors"]
        assert s["rows"], s["name"]
        for r in s["rows"]:
            # a refinement change of exactly zero would be no estimate (an unrefined rerun)
            assert all(v > 0 for v in r["refinement"].values()), (s["name"], r)
    failed = [(s["name"], r["observable"], r["ratio"]) for s in doc["scenarios"] for r in s["rows"] if not r["passed"]]
    assert proc.returncode == 0 and not failed, failed


def test_the_scenario_files_are_cases_that_check_runs(campaign):
    _, out = campaign
    files = sorted((out / "scenarios").glob("*.toml"))
    assert [f.stem for f in files] == [f"fuzz_{CI_SEED}_0", f"fuzz_{CI_SEED}_1"]
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "cases", "--cases-dir", str(out / "scenarios")],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and f"fuzz_{CI_SEED}_0" in proc.stdout, proc.stderr
