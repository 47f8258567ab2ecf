"""The command line (docs/commands.md): bad input exits 2 with exactly one line on
stderr naming the file and the field, no traceback and nothing written (an output path that
is a file included, checked before anything runs); `cases` lists the cases; `run` writes a
readable HDF5 file with every observable; a reader that goes away (`| head -1`) ends a
command quietly; every --json output is strict JSON."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.cli import main
from rsmcheck.core.options import ALIAS_NOTE
from rsmcheck.core.observables import NAMES
from rsmcheck.core.store import read_run

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


@pytest.mark.parametrize("argv", [["run"], ["frobnicate"], []],
                         ids=["run_without_case", "unknown_command", "no_command"])
def test_usage_errors_exit_2_with_one_line(capsys, argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert_one_clean_line(capsys.readouterr().err, "rsmcheck")


def test_an_engine_no_plug_in_registers_exits_2_naming_the_registered_ones(capsys, tmp_path):
    assert main(["run", "free_drift", "--engines", "warp", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert_one_clean_line(err, "warp")
    assert "registered: reference, exudyn" in err


@pytest.mark.parametrize("argv", [["run", "free_drift", "--out", "OUT"], ["gate", "free_drift"],
                                  ["bless", "free_drift", "--reason", "r"], ["report", "--out", "OUT/r.html"],
                                  ["bench", "--cases", "free_drift"]])
def test_engine_is_the_old_spelling_of_engines_and_says_so(capsys, tmp_path, argv):
    """Every command that takes engines takes `--engines`; `--engine` is read as it for one
    release, with one line on stderr.  (An unknown engine stops each before any run.)"""
    argv = [a.replace("OUT", str(tmp_path)) for a in argv]
    assert main(argv + ["--engines", "warp"]) == 2
    err = capsys.readouterr().err
    assert_one_clean_line(err, "--engines: warp: no such engine")
    assert main(argv + ["--engine", "warp"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(ALIAS_NOTE) and "--engines: warp: no such engine" in err.splitlines()[1]


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
    from rsmcheck.core.cases import load_case

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
    from rsmcheck.core.cases import load_case

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


# ---------------------------------------------------------------------------------------
# a reader that goes away: `rsmcheck cases | head -1`
# ---------------------------------------------------------------------------------------
def _closed_pipe_run(argv: list[str], buffered: bool, read_first_line: bool) -> tuple[int, bytes, str]:
    """Run `python -m rsmcheck.cli ARGV` with its stdout a pipe whose reader closes it (at
    once, or after the first line); (exit status, first line, stderr)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    if not buffered:
        env["PYTHONUNBUFFERED"] = "1"
    proc = subprocess.Popen([sys.executable, "-m", "rsmcheck.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)
    first = proc.stdout.readline() if read_first_line else b""
    proc.stdout.close()  # the reader goes away; what the command writes next meets a broken pipe
    err = proc.stderr.read().decode()
    proc.stderr.close()
    return proc.wait(timeout=120), first, err


@pytest.mark.parametrize("buffered", [True, False], ids=["buffered", "unbuffered"])
@pytest.mark.parametrize("argv", [["cases"], ["--help"], ["run", "--help"], ["bench", "--help"]],
                         ids=["cases", "help", "run_help", "bench_help"])
def test_closed_pipe_ends_quietly(argv, buffered):
    """The reader closes the pipe before the command writes: exit 0 (a listing, a help),
    nothing on stderr (it was 'Exception ignored ... BrokenPipeError' and exit 120)."""
    code, _, err = _closed_pipe_run(argv, buffered, read_first_line=False)
    assert "Traceback" not in err and "BrokenPipe" not in err, err
    assert err == ""
    assert code == 0


def test_cases_into_head_1():
    """`rsmcheck cases | head -1`: the first line arrives, then the command ends quietly."""
    from rsmcheck.core.cases import list_cases

    code, first, err = _closed_pipe_run(["cases"], buffered=False, read_first_line=True)
    assert first.split() and first.split()[0].decode() in {p.stem for p in list_cases()}
    assert err == "" and code == 0


def test_exit_code_of_a_command_cut_short(capsys):
    """A command that had not finished when its reader left exits `cut_short` (1: not all
    done, so not 'all good'; 0 for a listing); one that had finished keeps its own code."""
    from rsmcheck.core.errors import exit_code

    def cut():
        raise BrokenPipeError(32, "Broken pipe")

    assert exit_code("x", cut) == 1
    assert exit_code("x", cut, cut_short=0) == 0

    class Broken:  # stdout whose flush finds the reader gone: the command itself had finished
        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

        def fileno(self):
            raise OSError("no descriptor")

    import rsmcheck.core.errors as errors

    real = sys.stdout
    try:
        errors.sys.stdout = Broken()
        assert exit_code("x", lambda: 1, cut_short=0) == 1
        assert exit_code("x", lambda: 0) == 0
    finally:
        errors.sys.stdout = real
    assert capsys.readouterr().err == ""


# ---------------------------------------------------------------------------------------
# output paths: an existing file where a directory is wanted is a bad input, before any run
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [["run", "free_drift", "--out", "{f}"], ["check", "free_drift", "--out", "{f}"],
                                  ["run", "free_drift", "--out", "{f}/sub"],
                                  ["bless", "free_drift", "--reason", "r", "--goldens", "{f}"]],
                         ids=["run", "check", "run_below_a_file", "bless_goldens"])
def test_output_dir_that_is_a_file_exits_2(tmp_path, capsys, argv):
    f = tmp_path / "results.txt"
    f.write_text("mine\n")
    argv = [a.replace("{f}", str(f)) for a in argv]
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 2
    field = argv[argv.index("--goldens") if "--goldens" in argv else argv.index("--out")]
    assert_one_clean_line(captured.err, str(f), field)
    assert captured.out == ""
    assert f.read_text() == "mine\n"  # untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.txt"]


def test_run_out_file_in_a_real_process(tmp_path):
    """--out naming a file is one line and exit 2 in a real process, not a traceback."""
    f = tmp_path / "results.txt"
    f.write_text("")
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "run", "free_drift", "--out", str(f)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert_one_clean_line(proc.stderr, str(f), "--out")


def test_bench_out_that_is_a_directory_exits_2_before_running(tmp_path, capsys, monkeypatch):
    import rsmcheck.orchestration.bench as bench

    def no_run(*a, **k):
        raise AssertionError("a run started before --out was checked")

    monkeypatch.setattr(bench, "bench_run", no_run)
    monkeypatch.setattr(bench, "rhs_timings", no_run)
    code = main(["bench", "--cases", "free_drift", "--out", str(tmp_path)])
    assert code == 2
    assert_one_clean_line(capsys.readouterr().err, str(tmp_path), "--out")


# ---------------------------------------------------------------------------------------
# --json: strict JSON (RFC 8259 has no NaN or Infinity)
# ---------------------------------------------------------------------------------------
def strict_loads(text: str):
    """json.loads that refuses NaN, Infinity and -Infinity (Python's accepts them)."""

    def refuse(name):
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


NAN, INF = float("nan"), float("inf")


def test_dumps_json_is_strict():
    from rsmcheck.core.store import dumps_json

    doc = {"a": NAN, "b": INF, "c": -INF, "d": [np.float64(NAN), np.float32(1.5), np.int64(3)],
           "e": np.array([1.0, INF]), "f": (True, None, "x"), "g": {"h": np.bool_(True)}}
    expected = {"a": None, "b": "inf", "c": "-inf", "d": [None, 1.5, 3], "e": [1.0, "inf"],
                "f": [True, None, "x"], "g": {"h": True}}
    assert strict_loads(dumps_json(doc)) == expected
    assert strict_loads(dumps_json(doc, indent=None)) == expected


def test_write_json_is_strict(tmp_path):
    from rsmcheck.core.store import write_json

    path = write_json(tmp_path / "x.json", {"wall_s": NAN, "margin": INF})
    assert strict_loads(path.read_text()) == {"wall_s": None, "margin": "inf"}


def _fake_bench(monkeypatch):
    import rsmcheck.orchestration.bench as bench

    monkeypatch.setattr(bench, "bench_run", lambda case, engine, variant: {
        "case": case, "engine": engine, "variant": variant, "wall_s": NAN, "sim_s": NAN, "peak_mb": NAN,
        "error": "RuntimeError: boom"})
    monkeypatch.setattr(bench, "rhs_timings", lambda: {"reference_compiled": 1.0, "pinocchio_aba": NAN})


def _fake_check(monkeypatch):
    import rsmcheck.orchestration.compare as compare

    def check_cases(cases, short, options, run_dir=None, **kw):
        return [compare.CaseCheck(case.name, rows=[compare.Check(case.name, "momentum_I", 0.0, 1e-6),
                                                   compare.Check(case.name, "energy", NAN, 1e-6)],
                                  duration=0.1, wall_s={"reference": NAN, "exudyn": INF}) for case in cases]

    monkeypatch.setattr(compare, "check_cases", check_cases)


def _fake_gate(monkeypatch):
    import rsmcheck.orchestration.gate as gate

    def fake(cases, engines, root=None, progress=None):
        return [gate.GateResult(c.name, e, moved=[gate.Moved("energy", 1.0, 0.0, 0.1, 0)], largest_ratio=INF)
                for c in cases for e in engines]

    monkeypatch.setattr(gate, "gate", fake)
    monkeypatch.setattr(gate, "tolerance_table", lambda cases, engines, root: [
        {"case": "free_drift", "engine": "reference", "observable": "energy", "tolerance": 1e-9,
         "perturbation_change": NAN, "largest_value": INF}])


def _fake_modes(monkeypatch):
    import rsmcheck.orchestration.modes as modes

    monkeypatch.setattr(modes, "link_rows", lambda options=None, engines=None: [
        {"basis": "PP", "mode": 1, "analytic_hz": 30.16, "reference_hz": 30.16, "exudyn_hz": NAN}])
    monkeypatch.setattr(modes, "arm_rows", lambda options=None, engines=None: [
        {"configuration": "x", "mode": 1, "reference_hz": 1.0, "exudyn_hz": INF, "against": "reference", "exudyn_rel": INF}])


def _fake_pinocchio(monkeypatch):
    import pinocchio_check.compare as pc

    monkeypatch.setattr(pc, "run_checks", lambda **k: [
        {"quantity": "M", "chain": "open", "states": 1, "max_rel_error": NAN, "tolerance": INF, "pass": False,
         "seed": 0, "entry": "", "n_modes": 0, "holding": "arm1"}])


@pytest.mark.parametrize("argv, fake, key", [
    (["bench", "--json", "--cases", "free_drift", "--engines", "reference"], _fake_bench, "runs"),
    (["check", "free_drift", "--json"], _fake_check, "checks"),
    (["gate", "free_drift", "--engines", "reference", "--json"], _fake_gate, "gate"),
    (["gate", "free_drift", "--engines", "reference", "--json", "--tolerances"], _fake_gate, "tolerances"),
    (["modes", "--json"], _fake_modes, "links"),
    (["pinocchio", "--json", "--modes", "0"], _fake_pinocchio, "checks"),
], ids=["bench", "check", "gate", "gate_tolerances", "modes", "pinocchio"])
def test_every_json_output_is_strict(monkeypatch, capsys, argv, fake, key):
    """Every --json writer, fed NaN and infinities (a failed run, a zero error, a zero
    tolerance): the output parses as strict JSON, NaN as null and inf as "inf"."""
    fake(monkeypatch)
    main(argv)
    doc = strict_loads(capsys.readouterr().out)
    assert doc[key]
    text = json.dumps(doc)
    assert "null" in text or '"inf"' in text  # the non-finite values came through, spelled out


def test_bench_json_spells_out_a_failed_run(monkeypatch, capsys, tmp_path):
    _fake_bench(monkeypatch)
    out = tmp_path / "bench.json"
    assert main(["bench", "--json", "--cases", "free_drift", "--engines", "reference", "--out", str(out)]) == 1
    doc = strict_loads(capsys.readouterr().out)
    assert doc["runs"][0]["wall_s"] is None and doc["runs"][0]["error"] == "RuntimeError: boom"
    assert doc["rhs_us"]["pinocchio_aba"] is None
    assert strict_loads(out.read_text()) == doc


# ---------------------------------------------------------------------------------------
# output paths where nothing can be created (/proc: root passes access(), mkdir fails)
# ---------------------------------------------------------------------------------------
UNWRITABLE = "/proc/nope"
needs_proc = pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="no /proc")


@needs_proc
@pytest.mark.parametrize("argv, option", [
    (["run", "free_drift", "--out", UNWRITABLE], "--out"),
    (["run", "free_drift", "--short", "--out", UNWRITABLE + "/sub"], "--out"),
    (["check", "free_drift", "--short", "--out", UNWRITABLE], "--out"),
    (["report", "--short", "--out", UNWRITABLE + "/report.html"], "--out"),
    (["report", "--render-only", "--out", UNWRITABLE + "/report.html"], "--out"),
    (["bench", "--cases", "free_drift", "--out", UNWRITABLE + "/bench.json"], "--out"),
    (["bless", "free_drift", "--reason", "r", "--goldens", UNWRITABLE], "--goldens"),
], ids=["run", "run_sub", "check", "report", "report_render_only", "bench", "bless_goldens"])
def test_an_output_path_that_cannot_be_created_exits_2_before_running(monkeypatch, capsys, argv, option):
    import rsmcheck.orchestration.bench as bench
    import rsmcheck.orchestration.compare as compare_mod
    import rsmcheck.orchestration.gate as gate_mod
    from rsmcheck import cli

    def no_run(*a, **k):
        raise AssertionError("a run started before the output path was checked")

    for module, name in ((cli, "run_case"), (compare_mod, "check_cases"), (bench, "bench_run"),
                         (bench, "rhs_timings"), (gate_mod, "bless")):
        monkeypatch.setattr(module, name, no_run)
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 2
    assert_one_clean_line(captured.err, option, argv[argv.index(option) + 1])
    assert captured.out == ""


@needs_proc
def test_run_out_in_proc_in_a_real_process():
    """--out in an unwritable place is one line and exit 2 in a real process, not a
    FileNotFoundError traceback from mkdir."""
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "run", "free_drift", "--out", UNWRITABLE],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert_one_clean_line(proc.stderr, "--out", UNWRITABLE)
    assert proc.stdout == ""


def test_checking_an_output_path_leaves_nothing_behind(tmp_path):
    """The check creates (and removes) a probe: the folder holds what it held."""
    from rsmcheck.core.store import output_dir, output_file

    (tmp_path / "mine.txt").write_text("x")
    output_dir(tmp_path / "a" / "b", "--out")
    output_file(tmp_path / "c" / "report.html", "--out")
    output_dir(tmp_path, "--out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt"]
