"""The fault list of `make faults` (rsmcheck.orchestration.faults) stays applicable as the code changes:
every fault's text occurs exactly once where it says, and nowhere else in the code a run
executes; the faults cover the reference, the Exudyn model, the shared inputs, the closed
chain and the capture, and one control fault changes no arithmetic.  The matrix runs every
case of the project and the mission, and records fault × case × check; the report draws it."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

import rsmcheck.orchestration.faults as faults
from rsmcheck.core import cases as case_files
from rsmcheck.core.cases import list_cases, load_case
from rsmcheck.orchestration.faults import (CASE_CHECKS, CHECKS, ROOT, _cells, _failed_tests, apply, catalogue,
                                           caught_by, cell_letters, matrix_cases, revert, select_cases)
from rsmcheck.orchestration.runs import RunSet

ITEMS = catalogue()
FAULTS = [i.fault for i in ITEMS]


def test_every_fault_applies_exactly_once():
    for f in FAULTS:
        text = (ROOT / f.path).read_text()
        assert text.count(f.old) == 1, f"{f.name}: {f.old!r} occurs {text.count(f.old)} times in {f.path}"
        assert f.old != f.new and f.what.strip()


#: where a run's code and inputs are: the plug-ins' packages, the shared core and driver, the
#: case files (not the orchestration, whose analyses may state a formula again, nor the tests)
RUN_CODE = ("reference_model/", "exudyn_model/", "mujoco_model/", "pinocchio_check/", "rsmcheck/core/", "rsmcheck/driver/", "cases/")


def test_every_fault_text_occurs_once_in_the_code_a_run_executes():
    """A text that occurs twice would leave a copy of the code unfaulted; a catalogue module
    (*/faults.py) holds every text once more, as data."""
    listed = subprocess.run(["git", "ls-files", *RUN_CODE], cwd=ROOT, capture_output=True, text=True, check=True)
    files = [f for f in listed.stdout.splitlines() if f.endswith((".py", ".toml")) and not f.endswith("/faults.py")]
    texts = {f: (ROOT / f).read_text(encoding="utf-8") for f in files}
    for f in FAULTS:
        where = {path: text.count(f.old) for path, text in texts.items() if f.old in text}
        assert where == {f.path: 1}, f"{f.name}: {f.old!r} occurs {where}"


def test_the_faults_cover_every_layer_the_closed_chain_the_capture_and_one_control():
    layers = [i.layer for i in ITEMS]
    assert sum(layer != "none" for layer in layers) >= 21
    assert {"reference", "exudyn", "shared"} <= set(layers)
    assert layers.count("none") == 1
    assert len({f.name for f in FAULTS}) == len(FAULTS)
    # the reactions, the constraint and the capture's projection, in each engine
    paths = {f.path for f in FAULTS}
    assert {"reference_model/observe.py", "reference_model/switching.py", "exudyn_model/reactions.py",
            "exudyn_model/switching.py"} <= paths
    assert sum(f.path == "reference_model/system.py" and "S_BETA" in f.old for f in FAULTS) == 1


def test_apply_and_revert_on_a_copy(tmp_path):
    f = FAULTS[0]
    dest = tmp_path / f.path
    dest.parent.mkdir(parents=True)
    dest.write_text((ROOT / f.path).read_text())
    apply(f, tmp_path)
    assert f.new in dest.read_text() and f.old not in dest.read_text()
    revert(f, ROOT, tmp_path)
    assert dest.read_text() == Path(ROOT / f.path).read_text()


def test_every_run_in_the_copy_starts_from_an_empty_numba_cache(tmp_path, monkeypatch):
    """numba keys a cached function on its own file, not on the files it calls: a cache kept
    from an unfaulted run hid faults of core.py's `rhs` behind the cached integrator."""
    stale = tmp_path / ".numba_cache" / "reference_model_x" / "stepping.dp5.nbi"
    stale.parent.mkdir(parents=True)
    stale.write_text("compiled against the unfaulted core")
    seen = {}

    def fake_run(cmd, cwd, env, **kw):
        seen.update(cmd=cmd, cwd=cwd, cache=env["NUMBA_CACHE_DIR"], path=env["PYTHONPATH"],
                    cache_left=Path(env["NUMBA_CACHE_DIR"]).exists())
        return subprocess.CompletedProcess(cmd, 0, "{}", "")

    monkeypatch.setattr(faults.subprocess, "run", fake_run)
    faults._in_copy(tmp_path, "probe", FAULTS[0].name)
    assert seen["cache"] == str(tmp_path / ".numba_cache") and not seen["cache_left"]
    assert seen["path"] == str(tmp_path) and seen["cwd"] == tmp_path and seen["cmd"][-2:] == ["probe", FAULTS[0].name]


def test_failed_analytic_tests_are_named(tmp_path):
    """The `analytic` column lists the tests that fail, by name; a pytest that could not run
    them is an error, not a clean result."""
    f = tmp_path / "test_probe_sample.py"
    f.write_text("def test_holds():\n    assert 1 + 1 == 2\n\n\ndef test_broken():\n    assert 1 + 1 == 3\n")
    assert _failed_tests((str(f),)) == ["test_broken"]
    with pytest.raises(RuntimeError, match="did not run"):
        _failed_tests((str(tmp_path / "no_such_file.py"),))


# ---------------------------------------------------------------------------------------
# the matrix: every case, fault × case × check
# ---------------------------------------------------------------------------------------
def test_the_matrix_runs_every_stand_alone_case_then_the_mission():
    names = matrix_cases()
    cases = {p.stem: load_case(p) for p in list_cases()}
    assert names[-1] == "mission" and cases["mission"].phases
    assert set(names[:-1]) == {n for n, c in cases.items() if not c.phases}
    assert {"capture", "closed_squeeze", "p2_capture_regrasp", "p5_release"} <= set(names)
    assert select_cases(["mission", "capture"]) == ["capture", "mission"]  # the matrix's order
    assert select_cases(None) == names
    with pytest.raises(SystemExit, match="no_such_case"):
        select_cases(["capture", "no_such_case"])


def test_the_matrix_columns_follow_the_case_files(tmp_path, monkeypatch):
    """Not a list in the code: a case file added to the project's folder is a column; a
    user's folder's is not (it has no goldens)."""
    text = (case_files.CASES_DIR / "free_drift.toml").read_text(encoding="utf-8")
    for name in ("free_drift", "another_drift"):
        (tmp_path / "own" / f"{name}.toml").parent.mkdir(exist_ok=True)
        (tmp_path / "own" / f"{name}.toml").write_text(text.replace('name = "free_drift"', f'name = "{name}"'))
    (tmp_path / "user").mkdir()
    (tmp_path / "user" / "my_drift.toml").write_text(text.replace('name = "free_drift"', 'name = "my_drift"'))
    monkeypatch.setattr(case_files, "CASES_DIR", tmp_path / "own")
    monkeypatch.setenv(case_files.CASES_ENV, str(tmp_path / "user"))
    assert matrix_cases() == ["another_drift", "free_drift"]


def test_a_fault_is_caught_by_a_check_on_some_case_or_by_a_check_of_no_case():
    result = {"cases": {"capture": {"crosscheck": [], "gate": ["reference: energy 3×"]},
                        "mission": {"crosscheck": ["p3_com_alignment: com_pos_B 1e-3 > 2e-6"], "gate": []},
                        "free_drift": {"crosscheck": [], "gate": []}},
              "rigid": [], "analytic": ["test_baumgarte_returns_a_violated_constraint_along_eq_12"]}
    assert caught_by(result) == ["crosscheck", "gate", "analytic"]
    assert [cell_letters(c) for c in result["cases"].values()] == ["G", "C", ""]
    assert cell_letters({"crosscheck": ["x"], "gate": ["y"]}) == "CG"
    assert caught_by({"cases": {"capture": {"crosscheck": [], "gate": []}}, "rigid": [], "analytic": []}) == []


def _failed_everywhere(names, engines):
    """A RunSet in which every run of `names` failed (no simulation)."""
    got = RunSet()
    for n in names:
        got.runs[n] = {}
        for e in engines:
            got.errors[(n, e)] = RuntimeError(f"{n} diverged")
    return got


def test_a_failed_run_is_caught_by_the_gate_and_by_the_cross_check_where_the_case_has_rows():
    """closed_squeeze has no [compare] rows (`rsmcheck check` skips it): its failed run is
    the gate's only; the mission's cross-check is its chained flight, its gate its phases'
    stand-alone runs."""
    mission = load_case("mission")
    phases = list(mission.variant(True).phases)
    got = _failed_everywhere(["capture", "closed_squeeze", "mission", *phases], ["reference"])
    cells = _cells(got, [load_case("capture"), load_case("closed_squeeze"), mission], ["reference"], {})
    assert set(cells) == {"capture", "closed_squeeze", "mission"}
    assert all(set(cell) == set(CASE_CHECKS) for cell in cells.values())
    assert cells["capture"]["crosscheck"] == cells["capture"]["gate"] == ["reference: run failed: RuntimeError: capture diverged"]
    assert cells["closed_squeeze"] == {"crosscheck": [], "gate": ["reference: run failed: RuntimeError: closed_squeeze diverged"]}
    assert cells["mission"]["crosscheck"] == ["reference: run failed: RuntimeError: mission diverged"]
    assert cells["mission"]["gate"] == [f"{p}/reference: run failed: RuntimeError: {p} diverged" for p in phases]


def test_the_driver_records_fault_by_case_by_check(tmp_path, monkeypatch):
    """`all` with --cases: the document's columns, per fault per column the rows of each
    per-case check, the per-fault checks and `caught_by`; a restricted run never writes
    over the stored matrix unless told to."""
    calls = []

    def fake_in_copy(tree, command, *args):
        calls.append((command, *args))
        cases = list(args[args.index("--cases") + 1:])
        if command == "baseline":
            doc = {"cases": {c: {"crosscheck": [], "gate": []} for c in cases}, "runs_wall_s": {c: {} for c in cases}}
        else:
            doc = {"cases": {c: {"crosscheck": [], "gate": [f"reference: {c} moved"] if c == "capture" else []}
                             for c in cases}, "rigid": [], "analytic": [], "engines": ["reference"], "runs_wall_s": {}}
        return subprocess.CompletedProcess(command, 0, "progress\n" + json.dumps(doc), "")

    monkeypatch.setattr(faults, "_in_copy", fake_in_copy)
    monkeypatch.setattr(faults, "make_copy", lambda root, dest: dest)
    monkeypatch.setattr(faults, "apply", lambda fault, tree: None)
    monkeypatch.setattr(faults, "revert", lambda fault, root, tree: None)
    name = FAULTS[0].name
    assert faults.main(["all", name, "--cases", "mission", "capture", "--tree", str(tmp_path / "tree")]) == 0
    assert calls == [("baseline", "--cases", "capture", "mission"), ("probe", name, "--cases", "capture", "mission")]
    doc = json.loads((tmp_path / "faults.json").read_text())  # beside the copy, not docs/data
    assert doc["cases"] == ["capture", "mission"] and doc["checks"] == list(CHECKS)
    assert doc["case_checks"] == list(CASE_CHECKS)
    (f,) = doc["faults"]
    assert f["name"] == name and f["cases"]["capture"]["gate"] == ["reference: capture moved"]
    assert f["cases"]["mission"] == {"crosscheck": [], "gate": []}
    assert f["caught_by"] == ["gate"] and f["rigid"] == f["analytic"] == []


# ---------------------------------------------------------------------------------------
# the report draws the matrix
# ---------------------------------------------------------------------------------------
SYNTHETIC = {"commit": "abc", "cases": ["capture", "closed_squeeze", "mission"], "checks": list(CHECKS),
             "case_checks": list(CASE_CHECKS), "faults": [
                 {"name": "ref_a", "layer": "reference", "what": "a", "rigid": [], "analytic": ["test_decay"],
                  "caught_by": ["crosscheck", "gate", "analytic"],
                  "cases": {"capture": {"crosscheck": ["reaction_forces_I 1.5 > 8e-3"], "gate": ["reference: x 3×"]},
                            "closed_squeeze": {"crosscheck": [], "gate": ["reference: y 9×"]},
                            "mission": {"crosscheck": [], "gate": []}}},
                 {"name": "exu_missed", "layer": "exudyn", "what": "b", "rigid": [], "analytic": [], "caught_by": [],
                  "cases": {c: {"crosscheck": [], "gate": []} for c in ("capture", "closed_squeeze", "mission")}},
                 {"name": "noop_c", "layer": "none", "what": "c", "rigid": [], "analytic": [], "caught_by": ["crosscheck"],
                  "cases": {"capture": {"crosscheck": [], "gate": []}, "closed_squeeze": {"crosscheck": [], "gate": []},
                            "mission": {"crosscheck": ["p3_com_alignment: z 1 > 0.1"], "gate": []}}}]}


def test_the_report_draws_the_matrix_from_a_stored_document(render_stored):
    from rsmcheck.report.build import fault_matrix

    m = fault_matrix(SYNTHETIC)
    assert m["cases"] == SYNTHETIC["cases"] and m["checks"] == ["rigid", "analytic"]
    assert [[c["text"] for c in r["cells"]] for r in m["rows"]] == [["CG", "G", "·", "·", "A"],
                                                                   ["·"] * 5,
                                                                   ["·", "·", "C", "·", "·"]]
    assert m["rows"][2]["cells"][2]["cls"] == "fm-false" and m["rows"][0]["cells"][0]["cls"] == "fm-cg"
    assert "reaction_forces_I 1.5 > 8e-3" in m["rows"][0]["cells"][0]["title"]
    assert [r["ok"] for r in m["rows"]] == [True, False, False]
    assert m["totals"] == [1, 1, 0, 0, 1]  # the control's catch is not counted
    assert fault_matrix({"faults": [{"name": "old", "crosscheck": [], "caught_by": []}]}) is None
    # the page: a tiny stored folder (no runs), the document as docs/data/faults.json
    page = render_stored({"faults.json": SYNTHETIC})
    section = page[page.index('<section id="faults">'):]
    section = section[:section.index("</section>")]
    table = section[section.index('<table class="faultmatrix">'):section.index("</table>")]
    assert table.count('<th class="vert') == 5 and '<span>closed_squeeze</span>' in table
    assert table.count("<tr") == 1 + 3 + 1  # head, a row per fault, the totals
    assert '<td class="fm-cg" title="ref_a on capture' in table and '<td class="fm-false"' in table
    assert table.count('class="fail">MISSED</span>') == 1 and table.count('class="fail">FALSE ALARM</span>') == 1
