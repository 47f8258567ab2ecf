"""The package stands alone: its wheel carries the case files and the departures table,
and, installed into a folder of its own, it lists and checks cases from a working
directory outside the checkout.  Outside the engine packages nothing imports Exudyn,
Pinocchio or greenlet when imported (they are the extras `exudyn` and `pinocchio`).

The wheel is built from a copy of the checkout's files (git ls-files: tracked and new, not
ignored), so that a stale build/ folder cannot put old files into it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def checkout_files() -> list[str]:
    out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                         capture_output=True, check=True).stdout
    return [n for n in out.decode().split("\0") if n and (ROOT / n).is_file()]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    for name in checkout_files():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, src / name)
    dist = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
                           "-q", "-w", str(dist), str(src)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (path,) = dist.glob("rsmcheck-*.whl")
    return path


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    target = tmp_path_factory.mktemp("site")
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q",
                           "--target", str(target), str(wheel)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return target


def outside_env(target: Path) -> dict[str, str]:
    """The environment of a user of the installed package: only `target` on the path."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "RSMCHECK_CASES_DIR")}
    env["PYTHONPATH"] = str(target)
    return env


def test_the_wheel_carries_the_case_files_and_the_departures(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    cases = sorted(p.name for p in (ROOT / "cases").glob("*.toml"))
    assert len(cases) > 10
    shipped = sorted(n.removeprefix("rsmcheck/case_files/") for n in names if n.startswith("rsmcheck/case_files/"))
    assert shipped == cases
    assert not [n for n in names if n.startswith("rsmcheck/case_files/") and n.endswith(".py")]
    assert "rsmcheck/core/departures.toml" in names and "rsmcheck/core/departures.py" in names
    assert "rsmcheck/report/page.html.j2" in names and "rsmcheck/report/build.py" in names
    for n in ("cases/free_drift.toml", "report/build.py", "tests/conftest.py"):
        assert n not in names, n  # no generic top-level names
    # the shipped files are the checkout's, byte for byte
    z = zipfile.ZipFile(wheel)
    assert z.read("rsmcheck/case_files/free_drift.toml") == (ROOT / "cases" / "free_drift.toml").read_bytes()
    assert z.read("rsmcheck/core/departures.toml") == (ROOT / "rsmcheck" / "core" / "departures.toml").read_bytes()


def test_the_engines_are_extras():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    base = " ".join(project["dependencies"])
    for name in ("exudyn", "pin", "greenlet", "mujoco"):
        assert name not in base.replace("pinocchio", ""), name
    extras = project["optional-dependencies"]
    assert any(d.startswith("exudyn") for d in extras["exudyn"])
    assert any(d.startswith("greenlet") for d in extras["exudyn"])
    assert any(d.startswith("pin") for d in extras["pinocchio"])
    assert any(d.startswith("mujoco") for d in extras["mujoco"])
    assert extras["all"] == ["rsmcheck[exudyn,pinocchio,mujoco]"]


#: every module outside the engine packages
BASE_MODULES = sorted(
    [f"rsmcheck.{p.parent.name + '.' if p.parent.name != 'rsmcheck' else ''}{p.stem}".removesuffix(".__init__")
     for folder in ("rsmcheck", "rsmcheck/core", "rsmcheck/driver", "rsmcheck/orchestration")
     for p in (ROOT / folder).glob("*.py")]
    + [f"rsmcheck.report.{p.stem}" for p in (ROOT / "report").glob("*.py") if p.stem != "__init__"])


def test_nothing_outside_the_engines_imports_an_engine_library(installed, tmp_path):
    """Every base module of the installed package imports with exudyn, pinocchio and
    greenlet made unimportable, and `rsmcheck cases` runs so.  (The installed package: in a
    checkout on PYTHONPATH, rsmcheck.report may resolve to another tree's report/.)"""
    assert "rsmcheck.cli" in BASE_MODULES and "rsmcheck.report.build" in BASE_MODULES
    assert "rsmcheck.core.cases" in BASE_MODULES and len(BASE_MODULES) > 30
    code = ("import sys\n"
            "for name in ('exudyn', 'pinocchio', 'greenlet'):\n"
            "    sys.modules[name] = None  # import raises ImportError\n"
            "import importlib\n"
            f"for m in {BASE_MODULES!r}:\n"
            "    importlib.import_module(m)\n"
            "from rsmcheck.cli import main\n"
            "raise SystemExit(main(['cases']))\n")
    code = code.replace("import importlib\n", "import importlib\nimport rsmcheck\n"
                        f"assert rsmcheck.__file__.startswith({str(installed)!r}), rsmcheck.__file__\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=outside_env(installed),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "free_drift" in proc.stdout


def test_the_base_install_names_the_extra_an_engine_needs(installed, tmp_path):
    """With the base install alone (Exudyn and Pinocchio not importable), asking for Exudyn
    or Pinocchio is one line naming the pip extra that brings it, exit 2, nothing written;
    `rsmcheck engines` says which extra each missing engine needs."""
    code = ("import sys\n"
            "for name in ('exudyn', 'pinocchio', 'greenlet'):\n"
            "    sys.modules[name] = None  # import raises ImportError, find_spec finds nothing\n"
            "from rsmcheck.cli import main\n"
            "raise SystemExit(main(sys.argv[1:]))\n")
    env = outside_env(installed)

    def rsmcheck(*argv):
        return subprocess.run([sys.executable, "-c", code, *argv], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=300)

    out = tmp_path / "out"
    run = rsmcheck("run", "free_drift", "--short", "--engines", "exudyn", "--out", str(out))
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and "Traceback" not in run.stderr, run.stderr
    assert "pip install 'rsmcheck[exudyn]'" in run.stderr and not out.exists()
    pin = rsmcheck("pinocchio", "--json")
    assert pin.returncode == 2 and "pip install 'rsmcheck[pinocchio]'" in pin.stderr, pin.stderr
    listing = rsmcheck("engines")
    assert listing.returncode == 0, listing.stderr
    assert "NOT INSTALLED: pip install 'rsmcheck[exudyn]'" in listing.stdout
    assert "NOT INSTALLED: pip install 'rsmcheck[pinocchio]'" in listing.stdout


def installed_command(target: Path) -> list[str]:
    script = target / "bin" / "rsmcheck"
    return [str(script)] if script.is_file() else [sys.executable, "-m", "rsmcheck.cli"]


def test_the_installed_package_lists_its_cases_outside_the_checkout(installed, tmp_path):
    """From a working folder outside the checkout, with only the installed folder on the
    path: the modules, the case files and the departures come from there, and `rsmcheck
    cases` lists the checkout's cases."""
    env = outside_env(installed)
    where = subprocess.run(
        [sys.executable, "-c",
         "import rsmcheck, rsmcheck.cli, rsmcheck.report.build as b, rsmcheck.core.cases as c, rsmcheck.core.departures as d\n"
         "print(rsmcheck.__file__); print(b.__file__); print(c.__file__); print(c.CASES_DIR); print(len(d.table()[1]))"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert where.returncode == 0, where.stderr
    *paths, n_departures = where.stdout.split("\n")[:5]
    for p in paths:
        assert Path(p).resolve().is_relative_to(installed.resolve()), (p, installed)
        assert not Path(p).resolve().is_relative_to(ROOT), p
    assert Path(paths[3]).name == "case_files" and int(n_departures) > 5

    cases = subprocess.run(installed_command(installed) + ["cases"], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=120)
    assert cases.returncode == 0, cases.stderr
    assert {p.stem for p in (ROOT / "cases").glob("*.toml")} == {ln.split()[0] for ln in cases.stdout.splitlines()}
    assert sorted(tmp_path.iterdir()) == []  # nothing written where it ran


@pytest.mark.slow
@pytest.mark.study
def test_the_installed_package_checks_a_case_outside_the_checkout(installed, tmp_path):
    """`rsmcheck check free_drift p1_rigid_gains --short` with the installed package only:
    both engines run (every kernel compiles afresh there, numba's cache being keyed to the
    source files' paths: minutes, so with the studies, `make study`); free_drift has no
    [compare] table, so p1_rigid_gains' comparisons make the exit code, and they pass."""
    env = outside_env(installed)
    check = subprocess.run(installed_command(installed) + ["check", "free_drift", "p1_rigid_gains", "--short"],
                           cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1800)
    assert check.returncode == 0, check.stdout + check.stderr
    assert "free_drift: NOT CHECKED" in check.stdout and "p1_rigid_gains (short" in check.stdout
    assert "comparisons pass" in check.stdout and "FAIL" not in check.stdout
    assert sorted(tmp_path.iterdir()) == []
