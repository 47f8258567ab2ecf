"""The command line (README, "Command line"): bad input exits 2 with exactly one line on stderr naming the
file and the field, no traceback and nothing written; `cases` lists the cases; `run`
writes a readable HDF5 file with every observable."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.cli import main
from rsmcheck.observables import NAMES
from rsmcheck.store import read_run

GOOD = """\
name = "{name}"
description = "a tiny valid case"
duration = 0.02
[initial]
grasp = [1, 0]
[solver]
control_period = 1e-3
output_period = 1e-2
"""

# (id, case text, field the one stderr line must name)
BAD = [
    ("unknown_key", GOOD.replace("[solver]", "[solver]\nstep = 1.0"), "solver.step"),
    ("wrong_type", GOOD.replace("duration = 0.02", 'duration = "soon"'), "duration"),
    ("negative_mass", GOOD + "[params.target]\nmass = -400.0\n", "params.target.mass"),
    ("non_finite", GOOD + "[params.motor]\nstiffness = inf\n", "params.motor.stiffness"),
    ("missing_required", GOOD.replace('description = "a tiny valid case"\n', ""), "description"),
    ("name_not_stem", GOOD.replace('name = "{name}"', 'name = "not_the_stem"'), "name"),
    ("target_pose_with_grasp", GOOD.replace("grasp = [1, 0]", "grasp = [1, 0]\ntarget_pose = [5.0, 0.0, 0.0]"),
     "initial.target_pose"),
    ("output_period_not_multiple", GOOD.replace("output_period = 1e-2", "output_period = 1.5e-3"),
     "solver.output_period"),
    ("toml_syntax", GOOD + "= oops\n", "toml"),
]


def write_case(directory: Path, text: str, stem: str) -> Path:
    path = directory / f"{stem}.toml"
    path.write_text(text.replace("{name}", stem))
    return path


def files_under(directory: Path) -> list[Path]:
    return [p for p in directory.rglob("*") if p.is_file()] if directory.exists() else []


def assert_one_clean_line(err: str, *must_contain: str) -> None:
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for text in must_contain:
        assert text in lines[0], (text, lines[0])


@pytest.mark.parametrize("text, field", [(t, f) for _, t, f in BAD], ids=[i for i, _, _ in BAD])
def test_run_bad_case_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, text, field):
    path = write_case(tmp_path, text, "bad_case")
    out = tmp_path / "out"
    code = main(["run", str(path), "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    assert_one_clean_line(captured.err, str(path), field)
    assert captured.out == ""
    assert files_under(out) == []


def test_run_validates_every_case_before_running_any(tmp_path, capsys):
    good = write_case(tmp_path, GOOD, "good_case")
    bad = write_case(tmp_path, BAD[0][1], "bad_case")
    out = tmp_path / "out"
    code = main(["run", str(good), str(bad), "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    assert_one_clean_line(captured.err, str(bad), "solver.step")
    assert files_under(out) == []  # the good case was not run either: nothing half done


def test_run_unknown_case_name(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["run", "no_such_case", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    assert_one_clean_line(captured.err, "no_such_case")
    assert files_under(out) == []


@pytest.mark.parametrize("argv", [["run"], ["frobnicate"], ["run", "free_drift", "--engine", "warp"], []],
                         ids=["run_without_case", "unknown_command", "unknown_engine", "no_command"])
def test_usage_errors_exit_2_with_one_line(capsys, argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert_one_clean_line(capsys.readouterr().err, "rsmcheck")


def test_bad_case_in_a_real_process(tmp_path):
    """The installed entry point: exit status 2, one line, no traceback, no file."""
    path = write_case(tmp_path, BAD[5][1], "x")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "run", str(path), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert_one_clean_line(proc.stderr, str(path), "name")
    assert proc.stdout == ""
    assert files_under(out) == []


def test_cases_lists_the_shipped_cases(capsys):
    assert main(["cases"]) == 0
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    names = {line.split()[0] for line in lines if line.strip()}
    assert {"free_drift", "closed_squeeze"} <= names
    from cases.loader import load_case

    for name in ("free_drift", "closed_squeeze"):
        line = next(ln for ln in lines if ln.split()[0] == name)
        assert load_case(name).description in line  # one line each, with what it is
    assert captured.err == ""


def test_run_free_drift_short_writes_a_readable_run_file(tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["run", "free_drift", "--short", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    path = out / "free_drift.h5"
    assert str(path) in captured.out
    # the run file and the end state a chained phase starts from; no .tmp left over
    assert sorted(p.name for p in files_under(out)) == ["free_drift.h5", "free_drift.short.end.json"]
    runs, attrs = read_run(path)
    assert attrs["case_name"] == "free_drift"
    from cases.loader import load_case

    case = load_case("free_drift")
    assert attrs["case_hash"] == case.file_hash
    assert attrs["param_hash"] == case.params.digest()
    assert set(runs) == {"reference"}
    obs = runs["reference"].observables
    assert set(obs) == set(NAMES)
    short = case.run_duration(True)
    t = obs["time"]
    assert t[0] == 0.0 and t[-1] == pytest.approx(short)
    assert len(t) == int(round(short / case.solver.output_period)) + 1
    for name in NAMES:
        assert obs[name].shape[0] == len(t) and np.all(np.isfinite(obs[name])), name
    # free drift conserves momentum: the file holds a physically sensible run
    mom = obs["momentum_I"]
    assert np.abs(mom - mom[0]).max() <= 1e-9 * np.abs(mom[0]).max()
    assert runs["reference"].solver  # solver settings recorded
