"""The benchmark for tools outside rsmcheck (rsmcheck.orchestration.benchmark, docs/problems.md):
results files that read back bit for bit, `judge` on the in-tree engines' own exports giving
`check`'s rows to the bit, a perturbed column failing its row alone, and every kind of bad
results file one line, exit 2."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.results import Results, columns, read_results, results_text, write_results, write_results_h5
from rsmcheck.core.store import Event
from rsmcheck.orchestration import benchmark
from rsmcheck.orchestration.compare import check_runs

CASE = "flex_arm_step"
ENGINES = ("exudyn", "mujoco")


def _tiny(tmp_path: Path) -> Results:
    t = np.linspace(0.0, 0.1, 11)
    obs = {"time": t, "ee2_pos_B": np.column_stack([np.sin(t) / 3, np.cos(t) * 1e-17]), "ee2_speed": t**2 / 7}
    return Results(tmp_path / "x.csv", CASE, "mytool", "short", "2.3", {"step_s": 1e-4, "order": "fourth"}, 1.25,
                   "2-core test machine", [Event(0.05, "capture", "arm=2 gap_m=0.001")], obs)


@pytest.mark.parametrize("writer", [write_results, write_results_h5])
def test_a_results_file_reads_back_bit_for_bit(tmp_path, writer):
    res = _tiny(tmp_path)
    path = writer(tmp_path / ("x.csv" if writer is write_results else "x.h5"), res)
    back = read_results(path)
    for name, values in res.observables.items():
        np.testing.assert_array_equal(back.observables[name], values)
    assert (back.case, back.tool, back.tool_version, back.settings, back.cpu_time_s, back.machine) == (
        CASE, "mytool", "2.3", {"step_s": 1e-4, "order": "fourth"}, 1.25, "2-core test machine")
    assert [(e.time, e.kind, e.detail) for e in back.events] == [(0.05, "capture", "arm=2 gap_m=0.001")]
    assert not list(tmp_path.glob("*.tmp"))


def _bad_text(tmp_path: Path, edit) -> Path:
    path = tmp_path / "bad.csv"
    path.write_text(edit(results_text(_tiny(tmp_path))), encoding="utf-8")
    return path


def _cell(text: str, row: int, col: int, value: str) -> str:
    """`text` with data row `row` (0: the first sample), column `col` set to `value`."""
    lines = text.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("time,")) + 1
    cells = lines[first + row].split(",")
    cells[col] = value
    lines[first + row] = ",".join(cells)
    return "\n".join(lines) + "\n"


#: (what is wrong, the edit, the field the one line names)
BAD = [
    ("format line", lambda s: s.replace("# rsmcheck-results 1", "# results v2"), "format"),
    ("units", lambda s: s.replace("# units: SI", "# units: mm"), "units"),
    ("no tool", lambda s: s.replace("# tool: mytool\n", ""), "tool"),
    ("unknown header key", lambda s: s.replace("# machine:", "# computer:"), "computer"),
    ("misnamed column", lambda s: s.replace("ee2_pos_B[1]", "ee2_pos[1]"), "ee2_pos[1]"),
    ("component out of range", lambda s: s.replace("ee2_pos_B[1]", "ee2_pos_B[2]"), "ee2_pos_B[2]"),
    ("NaN", lambda s: _cell(s, 3, 1, "nan"), "ee2_pos_B[0]"),
    ("not a number", lambda s: _cell(s, 3, 2, "1,5"), "line"),
    ("time not increasing", lambda s: _cell(s, 2, 0, "0.0"), "time"),
]


@pytest.mark.parametrize("what,edit,field", BAD, ids=[b[0] for b in BAD])
def test_a_bad_results_file_names_its_field(tmp_path, what, edit, field):
    with pytest.raises(InputError) as err:
        read_results(_bad_text(tmp_path, edit))
    assert field in str(err.value) and "bad.csv" in str(err.value), str(err.value)


# ---------------------------------------------------------------------------------------
# judge on known answers: the engines' own runs, exported
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def exported(run_pool, tmp_path_factory):
    """flex_arm_step's problem, exported with the pool's runs of every engine installed."""
    import importlib.util

    engines = ["reference", "exudyn"] + (["mujoco"] if importlib.util.find_spec("mujoco") else [])
    runs = {e: run_pool.get(CASE, e) for e in engines}
    out = tmp_path_factory.mktemp("problems")
    benchmark.export_case(load_case(CASE), True, runs, out)
    return out, runs


@pytest.mark.crosscheck
@pytest.mark.engine_runs((CASE, "reference", True, ()), (CASE, "exudyn", True, ()), (CASE, "mujoco", True, ()))
@pytest.mark.parametrize("engine", ENGINES)
def test_judge_on_an_engines_export_gives_checks_rows(exported, engine):
    out, runs = exported
    if engine not in runs:
        pytest.skip(f"{engine} is not installed")
    j = benchmark.judge_file(out / CASE / f"{engine}.csv", out)
    rows = check_runs(load_case(CASE).variant(True), runs["reference"], runs[engine])
    assert [(r.observable, r.error, r.tolerance, r.passed) for r in j.rows] == [
        (r.observable, r.error, r.tolerance, r.passed) for r in rows]
    assert j.tool == engine and j.passed == all(r.passed for r in rows)


@pytest.mark.crosscheck
@pytest.mark.engine_runs((CASE, "reference", True, ()), (CASE, "exudyn", True, ()), (CASE, "mujoco", True, ()))
def test_a_perturbed_column_fails_its_row_alone(exported, tmp_path):
    out, runs = exported
    res = read_results(out / CASE / "exudyn.csv")
    base = {r.observable: r for r in benchmark.judge_file(res.path, out).rows}
    assert all(r.passed for r in base.values())
    row = base["ee2_pos_B"]
    obs = dict(res.observables)
    obs["ee2_pos_B"] = obs["ee2_pos_B"] + np.array([2.0 * row.tolerance, 0.0])
    path = write_results(tmp_path / "perturbed.csv", replace(res, observables=obs))
    judged = {r.observable: r for r in benchmark.judge_file(path, out).rows}
    assert [o for o, r in judged.items() if not r.passed] == ["ee2_pos_B"]
    assert judged["ee2_pos_B"].error == pytest.approx(2.0 * row.tolerance, rel=0.5)


@pytest.mark.crosscheck
@pytest.mark.engine_runs((CASE, "reference", True, ()), (CASE, "exudyn", True, ()), (CASE, "mujoco", True, ()))
def test_an_outside_tool_gets_the_allowance_and_the_references_error(exported, tmp_path):
    """Renamed, the Exudyn run is a tool rsmcheck does not know: its rows hold the allowance
    and the reference's recorded error, its own error not measured (taken as 0, and said);
    with a refined file (here the same run: own error 0, measured) the parts say so."""
    out, runs = exported
    res = read_results(out / CASE / "exudyn.csv")
    path = write_results(tmp_path / "other.csv", replace(res, tool="othertool"))
    j = benchmark.judge_file(path, out)
    for r in j.rows:
        parts = r.tolerance_parts
        if parts.allowance is not None:
            assert {e.engine: e.source for e in parts.errors} == {"reference": "recorded", "othertool": "not measured"}
            assert "no refined results file" in parts.formula() or "not measured" in parts.formula()
    fine = benchmark.judge_file(path, out, refined=path)
    assert all(e.source == "measured" for r in fine.rows if r.tolerance_parts.allowance is not None
               for e in r.tolerance_parts.errors if e.engine == "othertool")


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rsmcheck.cli", *args], capture_output=True, text=True)


@pytest.mark.crosscheck
@pytest.mark.engine_runs((CASE, "reference", True, ()), (CASE, "exudyn", True, ()), (CASE, "mujoco", True, ()))
def test_judge_on_the_command_line(exported, tmp_path):
    """exit 0 for the export that passes, 1 with a failing row, 2 and one line for each kind
    of bad file (unknown case, missing column, another time grid), nothing written."""
    out, runs = exported
    good = _cli("judge", str(out / CASE / "exudyn.csv"), "--problems", str(out))
    assert good.returncode == 0, good.stdout + good.stderr
    assert "acceptable" in good.stdout and "threshold" in good.stdout
    res = read_results(out / CASE / "exudyn.csv")
    bad = {
        "case": replace(res, case="no_such_case"),
        columns("ee2_pos_B")[0]: replace(res, observables={k: v for k, v in res.observables.items()
                                                           if k != "ee2_pos_B"}),
        "time": replace(res, observables={k: v[::2] for k, v in res.observables.items()}),
    }
    before = sorted(p.name for p in tmp_path.iterdir())
    for field, r in bad.items():
        path = write_results(tmp_path / f"bad_{len(before)}_{abs(hash(field))}.csv", r)
        proc = _cli("judge", str(path), "--problems", str(out))
        assert proc.returncode == 2, (field, proc.stdout, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and field in lines[0] and path.name in lines[0], lines
        assert proc.stdout == ""
