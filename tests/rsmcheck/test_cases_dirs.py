"""Where case files are found (rsmcheck.core.cases): the packaged cases, plus a user's
folders given by `--cases-dir DIR` (before or after the command) or $RSMCHECK_CASES_DIR
(os.pathsep-separated).  A name in two folders, or a folder that is not there, is one line
on stderr and exit 2."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rsmcheck.cli import main
from rsmcheck.core.cases import CASES_DIR, CASES_ENV, case_index, list_cases, load_case


def user_case(folder: Path, name: str = "my_drift") -> Path:
    """free_drift under another name, in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    text = (CASES_DIR / "free_drift.toml").read_text(encoding="utf-8")
    assert 'name = "free_drift"' in text
    path = folder / f"{name}.toml"
    path.write_text(text.replace('name = "free_drift"', f'name = "{name}"'), encoding="utf-8")
    return path


def listed(out: str) -> set[str]:
    return {line.split()[0] for line in out.splitlines() if line.strip()}


def one_line(err: str, *must_contain: str) -> None:
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for text in must_contain:
        assert text in lines[0], (text, lines[0])


@pytest.fixture(autouse=True)
def no_user_folders(monkeypatch):
    monkeypatch.delenv(CASES_ENV, raising=False)


def test_without_user_folders_only_the_packaged_cases():
    assert {p.parent for p in list_cases()} == {CASES_DIR}
    assert "free_drift" in case_index() and "my_drift" not in case_index()


@pytest.mark.parametrize("where", ["before", "after", "equals"])
def test_cases_dir_adds_a_folder(tmp_path, capsys, where):
    user_case(tmp_path / "mine")
    folder = str(tmp_path / "mine")
    argv = {"before": ["--cases-dir", folder, "cases"], "after": ["cases", "--cases-dir", folder],
            "equals": [f"--cases-dir={folder}", "cases"]}[where]
    assert main(argv) == 0
    names = listed(capsys.readouterr().out)
    assert {"my_drift", "free_drift", "mission"} <= names
    assert os.environ.get(CASES_ENV) is None  # main() leaves the environment as it was
    assert main(["cases"]) == 0
    assert "my_drift" not in listed(capsys.readouterr().out)


def test_the_environment_variable_adds_folders(tmp_path, monkeypatch, capsys):
    user_case(tmp_path / "a", "drift_a")
    user_case(tmp_path / "b", "drift_b")
    monkeypatch.setenv(CASES_ENV, os.pathsep.join([str(tmp_path / "a"), "", str(tmp_path / "b")]))
    assert main(["cases"]) == 0
    assert {"drift_a", "drift_b", "free_drift"} <= listed(capsys.readouterr().out)
    case = load_case("drift_b")
    assert Path(case.path) == tmp_path / "b" / "drift_b.toml"
    assert case.duration == load_case("free_drift").duration


def test_a_users_case_runs(tmp_path, capsys):
    user_case(tmp_path / "mine")
    out = tmp_path / "results"
    assert main(["run", "my_drift", "--short", "--out", str(out), "--cases-dir", str(tmp_path / "mine")]) == 0
    assert (out / "my_drift.h5").is_file()
    assert "my_drift" in capsys.readouterr().out


@pytest.mark.parametrize("how", ["option", "environment"])
def test_the_same_name_in_two_folders_is_one_line_naming_both(tmp_path, monkeypatch, capsys, how):
    shadow = user_case(tmp_path / "mine", "free_drift")
    if how == "option":
        code = main(["--cases-dir", str(tmp_path / "mine"), "cases"])
    else:
        monkeypatch.setenv(CASES_ENV, str(tmp_path / "mine"))
        code = main(["cases"])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    one_line(captured.err, str(shadow), str(CASES_DIR / "free_drift.toml"))


def test_the_same_name_in_two_user_folders(tmp_path, capsys):
    a, b = user_case(tmp_path / "a"), user_case(tmp_path / "b")
    assert main(["run", "my_drift", "--out", str(tmp_path / "out"),
                 "--cases-dir", str(tmp_path / "a"), "--cases-dir", str(tmp_path / "b")]) == 2
    one_line(capsys.readouterr().err, str(a), str(b))
    assert not (tmp_path / "out").exists()


def test_one_folder_named_twice_is_not_a_duplicate(tmp_path, capsys):
    user_case(tmp_path / "mine")
    folder = str(tmp_path / "mine")
    assert main(["--cases-dir", folder, "cases", "--cases-dir", folder]) == 0
    assert "my_drift" in listed(capsys.readouterr().out)


def test_a_missing_cases_dir_is_one_line(tmp_path, capsys):
    missing = tmp_path / "nope"
    assert main(["cases", "--cases-dir", str(missing)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    one_line(captured.err, "--cases-dir", str(missing))


def test_a_missing_folder_in_the_variable_is_one_line(tmp_path, monkeypatch, capsys):
    missing = tmp_path / "nope"
    monkeypatch.setenv(CASES_ENV, str(missing))
    assert main(["cases"]) == 2
    one_line(capsys.readouterr().err, CASES_ENV, str(missing))


def test_delegated_commands_take_the_option_too(tmp_path, capsys):
    """bench parses its own arguments: --cases-dir is taken out before (a missing folder is
    reported before bench runs anything)."""
    for argv in (["--cases-dir", str(tmp_path / "nope"), "bench"], ["bench", "--cases-dir", str(tmp_path / "nope")]):
        assert main(argv) == 2
        one_line(capsys.readouterr().err, "--cases-dir", str(tmp_path / "nope"))


def test_in_a_real_process(tmp_path):
    user_case(tmp_path / "mine")
    env = {**os.environ, CASES_ENV: str(tmp_path / "mine")}
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "cases"], capture_output=True, text=True,
                          env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "my_drift" in listed(proc.stdout)
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "cases", "--cases-dir", str(tmp_path / "nope")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    one_line(proc.stderr, "--cases-dir", str(tmp_path / "nope"))
