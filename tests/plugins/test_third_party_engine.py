"""A third party's engine plug-in, installed the way a third party would install it.

tests/plugins/twomode/ is a distribution of its own (`rsmcheck-twomode`, docs/plugins.md):
the reference model at the paper's two eigenmodes per link without the static correction
shapes (docs/physics.md §2.4), registered under the entry-point group ``rsmcheck.engines``
as ``twomode``, and two variants of the reference made with `rsmcheck.core.derived`:
``sameref`` (unchanged) and ``stiffref`` (EI + 3 %).  It is pip-installed once per session into a temporary folder, and the
command line runs in subprocesses with that folder on PYTHONPATH: the entry point is found
from the dist-info folder there, and the registry of this process (every other test) stays
as it was.  Through the command line only, as a user would: `rsmcheck engines`, `check`,
`bless` and `gate`, `report`, and a case file whose [twomode] table is wrong.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCE = Path(__file__).resolve().parent / "twomode"
CASE = "flex_arm_step"
ENGINES = ["reference", "twomode"]
#: the check of (b): the in-tree engines, the plug-in and the distribution's two variants of
#: the reference (rsmcheck_twomode/variants.py, made with rsmcheck.core.derived)
ALL = ["reference", "exudyn", "twomode", "sameref", "stiffref"]
#: the session's runs the check of (b) reuses (tests/conftest.py)
IN_TREE_RUNS = pytest.mark.engine_runs((CASE, "reference", True, ()), (CASE, "exudyn", True, ()))
#: the plug-in's line style in the report (rsmcheck_twomode/plugin.py, `style`)
TWOMODE_DASH = "dashdot"
TIMEOUT = 900


@pytest.fixture(scope="session")
def plugin_site(tmp_path_factory) -> Path:
    """The distribution pip-installed into a folder of its own (a copy of its source is
    built, so that the build leaves nothing in the checkout)."""
    work = tmp_path_factory.mktemp("twomode")
    src = work / "src"
    shutil.copytree(SOURCE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    site = work / "site"
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-build-isolation",
                           "--no-compile", "--disable-pip-version-check", "--quiet", "--target", str(site), str(src)],
                          capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stderr
    assert list(site.glob("rsmcheck_twomode-*.dist-info/entry_points.txt"))
    return site


def _env(site: Path | None) -> dict[str, str]:
    """This checkout's code, the plug-in's folder first on the path when `site` is given; the
    engine defaults and case folders of the environment left out."""
    env = {k: v for k, v in os.environ.items() if k not in ("RSMCHECK_ENGINES", "RSMCHECK_CASES_DIR")}
    path = [str(site)] if site is not None else []
    path += [str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join(path)
    return env


def rsmcheck(*args: str, site: Path | None, cwd: Path) -> subprocess.CompletedProcess:
    """`rsmcheck ARGS` in a subprocess with `_env(site)`."""
    return subprocess.run([sys.executable, "-m", "rsmcheck.cli", *args], capture_output=True, text=True,
                          cwd=cwd, env=_env(site), timeout=TIMEOUT)


def _lines(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ln.strip()]


# ---------------------------------------------------------------------------------------
# (a) the registry
# ---------------------------------------------------------------------------------------
def test_engines_lists_the_plugin_only_where_it_is_installed(plugin_site, tmp_path):
    with_it = rsmcheck("engines", site=plugin_site, cwd=tmp_path)
    assert with_it.returncode == 0, with_it.stderr
    (line,) = [ln for ln in with_it.stdout.splitlines() if ln.split()[:1] == ["twomode"]]
    assert "two modes" in line  # its label
    assert "simulates" in line and "available" in line and "[twomode]" in line
    assert "rsmcheck_twomode.plugin" in line
    lines = with_it.stdout.splitlines()
    (stiff,) = [k for k, ln in enumerate(lines) if ln.split()[:1] == ["stiffref"]]
    assert "variant of reference" in lines[stiff] and "refined_options" in "".join(lines[stiff + 1:stiff + 3])
    assert "reference's code and case settings; differs: the links' bending stiffness EI 3 % higher" \
        in lines[stiff + 1]
    without = rsmcheck("engines", site=None, cwd=tmp_path)
    assert without.returncode == 0, without.stderr
    assert "reference" in without.stdout
    assert not [ln for ln in without.stdout.splitlines() if ln.split()[:1] == ["twomode"]]


# ---------------------------------------------------------------------------------------
# (b) a cross-check, reference against the plug-in
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def checked(plugin_site, tmp_path_factory, run_pool):
    """`rsmcheck check CASE --short --engines reference,exudyn,twomode,sameref,stiffref
    --json`, the runs stored where the report of (d) finds them (its folder's runs/).  The
    in-tree engines' runs are the session's (the pool's), stored there first as `check
    --out` stores them, with the source digest of the plug-in's environment: `check` reuses
    them as it reuses any current stored run, and flies the plug-in's three engines."""
    from rsmcheck.core.cases import load_case
    from rsmcheck.orchestration.runs import store_runs

    folder = tmp_path_factory.mktemp("report")
    digest = subprocess.run([sys.executable, "-c", "from rsmcheck.orchestration.runs import source_digest; "
                             "print(source_digest())"], capture_output=True, text=True, check=True, cwd=folder,
                            env=_env(plugin_site)).stdout.strip()
    store_runs(folder / "runs", load_case(CASE), True, {e: run_pool.get(CASE, e) for e in ("reference", "exudyn")},
               digest, {"reference": {}, "exudyn": {}})
    proc = rsmcheck("check", CASE, "--short", "--engines", ",".join(ALL), "--json",
                    "--out", str(folder / "runs"), site=plugin_site, cwd=folder)
    return proc, folder


@pytest.mark.crosscheck
@IN_TREE_RUNS
def test_check_compares_the_reference_with_the_plugin(checked):
    """Both engines run and every row compares them; the static shapes matter, by a bounded
    amount.

    Lower bound: the cross-check's own tolerance of link_deflection (1e-7 m in the case
    file) is set by the difference between two converged models (the reference with its
    static shapes against Exudyn's FE links).  Leaving the static shapes out stiffens every
    link under the joint couples (end slope 24 % low with 2 eigenmodes alone, rotor modes
    5–9 % too high, docs/physics.md §2.4), a modelling change of the first order: the
    difference must be far above that tolerance, more than 10 ×.

    Upper bound: both models carry the same loads (one 10 N·m shoulder step) and the same
    rigid motion.  Quasi-statically the mid-span deflection under end couples is within
    3 % with the first eigenmode alone (§2.4, Σ ±1/j³).  The step rings the links at the
    coupled rotor modes with an amplitude up to the quasi-static bending w_s (a step
    response is w_s(1 − cos ωt), peak 2 w_s), and a frequency error δ ≤ 9 % moves that
    ringing by at most δ·ωt·w_s ≤ 2π·0.09·w_s ≈ 0.57 w_s over the first period, when
    the deflection peaks: 0.28 of the peak 2 w_s, with the 3 % less than 1/3 of it.
    Later the ringing decays (Kelvin–Voigt damping, ζ ≥ 1 %, §2.2) while the phase error
    keeps growing, so the bound is taken against the largest deflection of the run: the
    largest difference over every link and sample must stay below 1/3 of the reference's
    largest deflection.  A plug-in that ran another case, another model or blew up fails
    it.
    """
    proc, folder = checked
    assert proc.returncode in (0, 1), proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["engines"] == ALL and doc["short"] is True
    rows = [r for r in doc["checks"] if r["engines"] == ENGINES]
    assert rows and {tuple(r["engines"]) for r in doc["checks"]} == {("reference", e) for e in ALL[1:]}
    assert proc.returncode == (1 if any(not r["pass"] for r in doc["checks"]) else 0)
    assert set(doc["runs"][0]["wall_s"]) >= set(ALL)

    from rsmcheck.core.store import read_run

    runs, _ = read_run(folder / "runs" / f"{CASE}.h5")
    assert set(runs) == set(ALL)
    ref, two = runs["reference"], runs["twomode"]
    assert two.engine == "twomode"
    # what each engine was: the case's 4 eigenmodes with static shapes; the plug-in's 2, none
    assert ref.solver["n_modes"] == "4,4,4,4,4,4" and int(ref.solver["static_modes"]) == 1
    assert two.solver["n_modes"] == "2,2,2,2,2,2" and int(two.solver["static_modes"]) == 0
    assert two.solver["steps"] > 0 and "jacobians" in two.solver  # its work counters
    np.testing.assert_array_equal(ref.observables["time"], two.observables["time"])

    (row,) = [r for r in rows if r["observable"] == "link_deflection"]
    w_ref = np.asarray(ref.observables["link_deflection"], float)
    w_two = np.asarray(two.observables["link_deflection"], float)
    change = float(np.max(np.abs(w_two - w_ref)))
    assert change == pytest.approx(row["error"], rel=1e-12)  # the row's metric is max_abs
    peak = float(np.max(np.abs(w_ref)))
    assert change > 10 * row["tolerance"], (change, row["tolerance"])
    assert change < peak / 3, (change, peak)
    # twomode has no refinement: its error counts 0, and the row says so
    assert row["tolerance_parts"]["errors"]["twomode"]["source"] == "not measured"
    assert "twomode integration not measured (no refined_options: taken as 0)" in row["why"]


@pytest.mark.crosscheck
@IN_TREE_RUNS
def test_each_pair_is_judged_by_its_own_tolerance(checked):
    """The pair model (rsmcheck.core.tolerances), on one check of five engines:

    * the reference–Exudyn rows are exactly those of a check of the two alone (computed
      here from the same stored runs, without the plug-ins): error, tolerance, why;
    * sameref, the reference under another name, differs by exactly 0 on every row and
      passes; its tolerance is the allowance plus the reference's recorded error plus its
      own, measured now by its refinement (the reference's own refined_options);
    * stiffref (EI + 3 %) fails the rows that see the links' stiffness, of its own pair
      only; momentum_I, which the joint couples cannot change, passes.
    """
    from rsmcheck.core.cases import load_case
    from rsmcheck.core.store import read_run
    from rsmcheck.orchestration.compare import case_rows

    proc, folder = checked
    doc = json.loads(proc.stdout)
    by_pair: dict[str, dict[str, dict]] = {}
    for r in doc["checks"]:
        by_pair.setdefault(r["engines"][1], {})[r["observable"]] = r

    runs, _ = read_run(folder / "runs" / f"{CASE}.h5")
    two = {r.observable: r.as_dict() for r in case_rows(load_case(CASE), True, runs, ["reference", "exudyn"])}
    assert set(two) == set(by_pair["exudyn"])
    for obs, r in by_pair["exudyn"].items():
        assert r == two[obs], obs
        assert r["pass"] and r["tolerance_parts"]["stated"]

    spec = {s.observable: s for s in load_case(CASE).variant(True).compare}
    for obs, r in by_pair["sameref"].items():
        assert r["error"] == 0.0 and r["pass"], obs
        parts = r["tolerance_parts"]
        assert not parts["stated"] and parts["errors"]["sameref"]["source"] == "measured"
        assert parts["errors"]["reference"]["value"] == spec[obs].errors["reference"]
        assert parts["errors"]["reference"]["source"] == "recorded"
        assert "exudyn" not in parts["errors"]  # never another engine's error
        expected = parts["factor"] * (spec[obs].allowance + spec[obs].errors["reference"]
                                      + parts["errors"]["sameref"]["value"])
        assert r["tolerance"] == pytest.approx(expected, rel=1e-12)
        assert r["why"].startswith("reference against sameref: budget")

    stiff = by_pair["stiffref"]
    assert not stiff["link_deflection"]["pass"] and stiff["link_deflection"]["margin"] < 0.1
    assert stiff["momentum_I"]["pass"]
    assert all(r["pass"] for pair in ("exudyn", "sameref") for r in by_pair[pair].values())


# ---------------------------------------------------------------------------------------
# (c) the gate: bless a golden of the plug-in, then gate against it
# ---------------------------------------------------------------------------------------
@pytest.mark.gate
def test_bless_then_gate_the_plugin(plugin_site, tmp_path):
    goldens = tmp_path / "goldens"
    reason = "third-party plug-in test: first golden of twomode"
    bless = rsmcheck("bless", CASE, "--engines", "twomode", "--reason", reason, "--goldens", str(goldens),
                     "--code-paths", "blas-1-thread",
                     site=plugin_site, cwd=tmp_path)
    assert bless.returncode == 0, bless.stderr
    assert f"{CASE} / twomode: new golden" in bless.stdout
    assert (goldens / f"{CASE}.twomode.h5").is_file()
    assert not list(goldens.glob(f"{CASE}.reference.*"))
    assert reason in (goldens / "CHANGELOG.md").read_text()

    gate = rsmcheck("gate", CASE, "--engines", "twomode", "--goldens", str(goldens), site=plugin_site, cwd=tmp_path)
    assert gate.returncode == 0, gate.stdout + gate.stderr
    assert f"{CASE} / twomode: unchanged" in gate.stdout and "1 of 1 runs unchanged" in gate.stdout

    # the tolerances were measured with the plug-in's own perturbations: its step_perturbed
    # (rtol × 1.001) reached its engine, whose steps then moved the run
    tol = rsmcheck("gate", CASE, "--engines", "twomode", "--goldens", str(goldens), "--tolerances", "--json",
                   site=plugin_site, cwd=tmp_path)
    assert tol.returncode == 0, tol.stderr
    rows = json.loads(tol.stdout)["tolerances"]
    assert {r["engine"] for r in rows} == {"twomode"}
    assert max(r["step_change"] for r in rows) > 0.0
    assert max(r["perturbation_change"] for r in rows) > 0.0

    # the same golden read by a gate that does not know the engine: one line, exit 2
    unknown = rsmcheck("gate", CASE, "--engines", "twomode", "--goldens", str(goldens), site=None, cwd=tmp_path)
    assert unknown.returncode == 2
    assert "no such engine" in unknown.stderr and len(_lines(unknown.stderr)) == 1


# ---------------------------------------------------------------------------------------
# (d) the report draws the plug-in's curves in its own style
# ---------------------------------------------------------------------------------------
@pytest.mark.crosscheck
@IN_TREE_RUNS
def test_report_draws_the_plugin(plugin_site, checked):
    proc, folder = checked
    assert proc.returncode in (0, 1), proc.stderr
    page = folder / "report.html"
    stored = folder / "runs" / f"{CASE}.h5"
    before = stored.stat().st_mtime_ns
    rep = rsmcheck("report", "--short", "--cases", CASE, "--engines", "reference,exudyn,twomode",
                   "--out", str(page), site=plugin_site, cwd=folder)
    assert rep.returncode == 0, rep.stdout + rep.stderr
    # the runs (b) stored are reused and no table is made for a restricted report: no job
    assert "jobs" not in rep.stderr and stored.stat().st_mtime_ns == before, rep.stderr
    match = re.search(r'<script id="figures" type="application/json">(.*?)</script>', page.read_text(), re.S)
    assert match, "no figure data in the page"
    traces = [t for fig in json.loads(match.group(1)) for t in fig["data"]]
    # the curves of an engine are named "ENGINE LABEL" (report/plots.py, comparison_figure)
    ours = [t for t in traces if str(t.get("name", "")).startswith("twomode ") and t.get("x") != [None]]
    theirs = [t for t in traces if str(t.get("name", "")).startswith("reference ") and t.get("x") != [None]]
    assert ours and theirs
    assert {t["line"]["dash"] for t in ours} == {TWOMODE_DASH}
    assert {t["line"]["dash"] for t in theirs} == {"solid"}
    # its legend entry and the error curve between the two engines
    assert any(t.get("name") == "twomode" and t["line"]["dash"] == TWOMODE_DASH for t in traces)
    assert any(t.get("name") == "|reference − twomode|" for t in traces)
    assert len({t["name"] for t in ours}) >= 6  # link_deflection's six components, at least
    # three engines, two pairs: each difference panel draws both pairs, each with its own
    # tolerance line; the variants checked in (b) but not asked for are not drawn
    assert any(t.get("name") == "|reference − exudyn|" for t in traces)
    tolerances = {t["name"] for t in traces if str(t.get("name", "")).startswith("tolerance of ")}
    assert any("exudyn" in n for n in tolerances) and any("twomode" in n for n in tolerances)
    assert not any(str(t.get("name", "")).startswith(("sameref", "stiffref")) for t in traces)


@pytest.mark.crosscheck
@IN_TREE_RUNS
def test_the_report_of_three_engines_shows_every_pairs_rows(plugin_site, checked, chromium):
    """The page of reference, Exudyn and twomode, read by Chromium: the verdict table holds
    each observable once per pair (no row of one pair hides the other's), each with its own
    tolerance; the title names the engines by the registry's labels."""
    proc, folder = checked
    page = folder / "three.html"
    rep = rsmcheck("report", "--short", "--cases", CASE, "--engines", "reference,exudyn,twomode",
                   "--out", str(page), site=plugin_site, cwd=folder)
    assert rep.returncode == 0, rep.stdout + rep.stderr
    dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=60000",
                          "--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=TIMEOUT).stdout
    assert re.search(r'<pre id="js-errors">\s*</pre>', dom), "a JavaScript error on the page"
    title = re.search(r"<h1>(.*?)</h1>", dom, re.S).group(1)
    assert "reference" in title and "Exudyn" in title and "two modes" in title, title
    table = re.search(r'<table id="verdict-table">(.*?)</table>', dom, re.S).group(1)
    cells = [re.findall(r"<td[^>]*>(.*?)</td>", row, re.S) for row in re.findall(r"<tr[^>]*>(.*?)</tr>", table, re.S)]
    cross = [c for c in cells if c and c[0] == "cross-check"]
    pairs = {}
    for c in cross:
        pairs.setdefault(c[2], {})[c[3]] = c[6]  # quantity → pair → tolerance
    doc = {(r["observable"], " vs ".join(r["engines"])): r for r in json.loads(proc.stdout)["checks"]}
    assert pairs and all(set(p) == {"reference vs exudyn", "reference vs twomode"} for p in pairs.values()), pairs
    for obs, by_pair in pairs.items():
        for pair, tol in by_pair.items():
            assert float(tol) == pytest.approx(doc[(obs, pair)]["tolerance"], rel=0.01), (obs, pair, tol)


# ---------------------------------------------------------------------------------------
# (e) the plug-in's case table: validated, errors naming file and key
# ---------------------------------------------------------------------------------------
GOOD_TABLE = '[twomode]\nn_modes = 3\nwhy = "a study at three eigenmodes"\n'


def _case_file(folder: Path, table: str, name: str = "twomode_case") -> Path:
    """A copy of CASE named `name` with `table` appended, in `folder`."""
    text = (ROOT / "cases" / f"{CASE}.toml").read_text(encoding="utf-8")
    text = re.sub(r'(?m)^name = ".*"$', f'name = "{name}"', text)
    assert f'name = "{name}"' in text
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.toml"
    path.write_text(text + "\n" + table, encoding="utf-8")
    return path


@pytest.mark.parametrize("table, key, reason", [
    ('[twomode]\nn_modes = 9\nwhy = "x"\n', "twomode.n_modes", "integer 1..6"),
    ('[twomode]\nn_modes = [2, 2]\nwhy = "x"\n', "twomode.n_modes", "list of six"),
    ('[twomode]\nrtol = 0.5\nwhy = "x"\n', "twomode.rtol", "too loose"),
    ('[twomode]\nrtol = "tight"\nwhy = "x"\n', "twomode.rtol", "must be a number"),
    ('[twomode]\nn_modes = 3\n', "twomode.why", "missing"),
    ('[twomode]\nmodes = 3\n', "twomode.modes", "unknown key"),
    ('[short.twomode]\nn_modes = 0\nwhy = "x"\n', "short.twomode.n_modes", "integer 1..6"),
])
def test_a_bad_twomode_table_is_one_line_naming_file_and_key(plugin_site, tmp_path, table, key, reason):
    path = _case_file(tmp_path / "cases", table)
    proc = rsmcheck("--cases-dir", str(path.parent), "check", "twomode_case", "--short", "--engines",
                    ",".join(ENGINES), site=plugin_site, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    (line,) = _lines(proc.stderr)
    assert str(path) in line and f": {key}: " in line and reason in line, line
    assert "Traceback" not in proc.stderr and proc.stdout == ""


def test_a_good_twomode_table_is_read_and_needs_the_plugin(plugin_site, tmp_path):
    path = _case_file(tmp_path / "cases", GOOD_TABLE)
    listed = rsmcheck("--cases-dir", str(path.parent), "cases", site=plugin_site, cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    assert any(ln.split()[:1] == ["twomode_case"] for ln in listed.stdout.splitlines())
    # without the plug-in nobody owns [twomode]: the file is a bad input, not silently read
    alone = rsmcheck("--cases-dir", str(path.parent), "cases", site=None, cwd=tmp_path)
    assert alone.returncode == 2
    (line,) = _lines(alone.stderr)
    assert str(path) in line and "twomode" in line, line
