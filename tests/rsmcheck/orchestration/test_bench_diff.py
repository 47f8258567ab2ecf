"""rsmcheck.orchestration.bench_diff: a bench document against a stored one."""

from __future__ import annotations

import json

import pytest

from rsmcheck.cli import main as cli
from rsmcheck.core.errors import InputError
from rsmcheck.orchestration.bench import SOLVER_KEYS
from rsmcheck.orchestration.bench import main as bench
from rsmcheck.orchestration.bench_diff import COUNT_KEYS, SETTING_KEYS, compare, diff_table, read_bench

EPYC = {"cpu": "AMD EPYC (family 25, model 17)", "logical_cpus": 2, "cpu_mhz": 2596.0}
XEON = {"cpu": "Intel Xeon (family 6, model 85)", "logical_cpus": 2}


def _ref(case, wall, steps, rejected, **solver):
    return {"case": case, "engine": "reference", "variant": "full", "wall_s": wall, "sim_s": 10.0, "peak_mb": 1.0,
            "solver": {"steps": steps, "rejected_steps": rejected, "rtol": 1e-7, "h_max": 0.05, **solver}}


def _exu(case, wall, iterations, jacobians, **solver):
    return {"case": case, "engine": "exudyn", "variant": "full", "wall_s": wall, "sim_s": 10.0, "peak_mb": 1.0,
            "solver": {"steps": 20000, "newton_iterations": iterations, "jacobians": jacobians, "step": 5e-4,
                       **solver}}


def _doc(runs, machine=EPYC, commit="a" * 40):
    return {"commit": commit, "utc": "2026-11-27T10:00:00Z", "machine": machine,
            "engines": ["reference", "exudyn"], "runs": runs}


def test_same_work_and_wall_ratios_only_between_alike_machines():
    """Unchanged counts are the same work; the wall ratio is given on the same kind of
    machine and left out (a dash, and the head says why) on another."""
    base = _doc([_ref("p1", 100.0, 10000, 100), _exu("p1", 300.0, 22000, 40)])
    new = _doc([_ref("p1", 120.0, 10000, 100), _exu("p1", 330.0, 22000, 40)])
    cmp = compare(new, base, "old.json")
    assert [r["verdict"] for r in cmp["rows"]] == ["same work", "same work"]
    assert cmp["same_machine"] and cmp["rows"][0]["wall_ratio"] == pytest.approx(1.2)
    assert cmp["rows"][0]["work"] == "step attempts" and cmp["rows"][0]["work_count"] == 10100
    assert cmp["rows"][1]["work"] == "Newton iterations" and cmp["rows"][1]["work_ratio"] == 1.0
    other = compare(dict(new, machine=XEON), base, "old.json")
    assert not other["same_machine"] and all(r["wall_ratio"] is None for r in other["rows"])
    text = diff_table(other)
    assert "wall times not compared" in text.splitlines()[0] and "old.json (aaaaaaa" in text
    assert text.splitlines()[4].split()[-4:] == ["1.0000", "—", "same", "work"]
    assert compare(new, dict(base, machine=None))["rows"][0]["wall_ratio"] is None


def test_more_work_names_its_ratio_and_what_changed():
    """5 % more step attempts is more work; the changed setting and the largest change are
    named; fewer Newton iterations is less work."""
    base = _doc([_ref("p1", 100.0, 10000, 100), _exu("p4", 300.0, 20000, 40)])
    new = _doc([_ref("p1", 100.0, 10500, 105, rtol=1e-8), _exu("p4", 300.0, 15000, 40)])
    cmp = compare(new, base)
    ref, exu = cmp["rows"]
    assert ref["verdict"] == "more work" and ref["work_ratio"] == pytest.approx(10605 / 10100)
    assert ref["settings"] == ["rtol 1e-07 → 1e-08"] and ref["counts"] == ["steps 10000 → 10500"]
    assert exu["verdict"] == "less work" and exu["counts"] == ["newton_iterations 20000 → 15000"]
    last = diff_table(cmp).splitlines()[-1]
    assert "1 more work" in last and "1 less work" in last and "largest change p4 exudyn full × 0.750" in last


def test_rejected_steps_are_weighed_against_the_whole_work():
    """The rejected steps move by several per cent of themselves between machines (7 % in
    the stored benches) but by their share of the attempts: 100 → 107 of 10 100 is the same
    work.  Jacobians weigh by their own size: 100 → 102 is a moved count."""
    base = _doc([_ref("p1", 1.0, 10000, 100), _exu("p1", 1.0, 20000, 100)])
    new = _doc([_ref("p1", 1.0, 10000, 107), _exu("p1", 1.0, 20000, 102)])
    ref, exu = compare(new, base)["rows"]
    assert ref["verdict"] == "same work" and ref["counts"] == []
    assert exu["verdict"] == "counts moved" and exu["counts"] == ["jacobians 100 → 102"]
    retry = compare(_doc([_exu("p1", 1.0, 20000, 100, newton_retries=1)]),
                    _doc([_exu("p1", 1.0, 20000, 100, newton_retries=0)]))
    assert retry["rows"][0]["counts"] == ["newton_retries 0 → 1"]


def test_failed_and_missing_runs_are_named_not_compared():
    base = _doc([_ref("p1", 1.0, 100, 1), dict(_ref("p2", 1.0, 100, 1), error="boom")])
    new = _doc([dict(_ref("p1", 1.0, 100, 1), error="diverged"), _ref("p2", 1.0, 100, 1),
                _ref("p3", 1.0, 100, 1)])
    cmp = compare(new, base)
    assert [r["verdict"] for r in cmp["rows"]] == ["failed", "failed in the baseline", "not in the baseline"]
    text = diff_table(cmp)
    assert "not in the baseline (1): p3 full reference" in text
    assert sum(line.startswith(("p1 ", "p2 ")) for line in text.splitlines()) == 2
    assert not any(line.startswith("p3 ") for line in text.splitlines())  # one line for the missing


def test_a_stored_document_must_be_a_bench(tmp_path):
    """Missing, not JSON, no runs, a run without its names: one InputError naming the file
    and the option."""
    with pytest.raises(InputError, match="no such file") as err:
        read_bench(tmp_path / "none.json")
    assert err.value.field == "--baseline"
    for text, field in (("{", "--stored"), ('{"runs": 3}', "--stored: runs"),
                        ('{"runs": [{"case": "p1"}]}', "--stored: runs[0]")):
        path = tmp_path / "bad.json"
        path.write_text(text)
        with pytest.raises(InputError) as err:
            read_bench(path, "--stored")
        assert err.value.where == str(path) and err.value.field == field


def test_bench_shows_a_stored_document_against_another(tmp_path, capsys):
    """`--stored A --baseline B` runs nothing: A's tables, then the comparison; `--json`
    carries it as `baseline`.  A run option beside --stored, or a missing baseline, is a bad
    input (exit 2, one line) before anything runs."""
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(_doc([_ref("p1", 110.0, 10000, 100)])))
    b.write_text(json.dumps(_doc([_ref("p1", 100.0, 10000, 100)], commit="b" * 40)))
    assert bench(["--stored", str(a), "--baseline", str(b)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("machine: AMD EPYC") and f"against {b} (bbbbbbb" in out
    assert "1.100  same work" in out
    assert bench(["--stored", str(a), "--baseline", str(b), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["baseline"]["rows"][0]["wall_ratio"] == pytest.approx(1.1)
    assert cli(["bench", "--stored", str(a), "--cases", "free_drift"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--stored" in err and "--cases" in err and len(err.splitlines()) == 1
    assert cli(["bench", "--baseline", str(tmp_path / "none.json"), "--cases", "free_drift"]) == 2
    err = capsys.readouterr().err.strip()
    assert "none.json" in err and "--baseline" in err and len(err.splitlines()) == 1


def test_every_solver_key_a_bench_stores_is_a_count_or_a_setting():
    """A key the bench starts storing is compared (a count) or named when it changes (a
    setting), never silently left out."""
    assert set(SOLVER_KEYS) == set(COUNT_KEYS) | set(SETTING_KEYS)
    assert not set(COUNT_KEYS) & set(SETTING_KEYS)
