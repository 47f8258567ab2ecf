"""The generated blocks of README.md and docs/*.md say what their data says now
(rsmcheck.orchestration.doc_tables).

A data file (docs/data/*.json, a case file, departures.toml, the observable schema) that
changes without `python -m rsmcheck.orchestration.doc_tables` leaves a stale block: the
first test names it.  The others show that the check can fail and that every block is
placed once.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rsmcheck.orchestration import doc_tables

ROOT = Path(__file__).resolve().parents[2]


def _blocks(text: str) -> dict[str, str]:
    return {m["name"]: m["body"] for m in doc_tables.BLOCK.finditer(text)}


def test_every_generated_block_is_what_its_data_makes_now():
    found = doc_tables.stale(ROOT)
    assert not found, ("generated blocks out of date with their data (run "
                       "`python -m rsmcheck.orchestration.doc_tables`):\n" + "\n".join(found))


def test_every_block_is_placed_once_and_every_placed_block_is_known():
    where: dict[str, list[str]] = {}
    for page in doc_tables.documents(ROOT):
        for name in _blocks(page.read_text(encoding="utf-8")):
            where.setdefault(name, []).append(page.name)
    assert set(where) <= set(doc_tables.BLOCKS), f"unknown blocks: {sorted(set(where) - set(doc_tables.BLOCKS))}"
    missing = sorted(set(doc_tables.BLOCKS) - set(where))
    assert not missing, f"blocks no page shows: {missing}"
    twice = {n: pages for n, pages in where.items() if len(pages) > 1}
    assert not twice, f"blocks shown on more than one page (a figure is quoted in one place): {twice}"


def test_a_changed_data_file_makes_its_block_stale(tmp_path):
    """The check can fail: one error in a copy of the stored check changes the rendering,
    and a page whose block was edited by hand is named by `stale`."""
    data = tmp_path / "data"
    shutil.copytree(doc_tables.DATA, data)
    doc = json.loads((data / "check_short.json").read_text(encoding="utf-8"))
    doc["checks"][0]["error"] *= 1.5
    (data / "check_short.json").write_text(json.dumps(doc), encoding="utf-8")
    assert doc_tables.check_short(data) != doc_tables.check_short()

    root = tmp_path / "tree"
    (root / "docs").mkdir(parents=True)
    for page in doc_tables.documents(ROOT):
        shutil.copy(page, root / page.relative_to(ROOT))
    page = root / "docs" / "exudyn.md"
    text = page.read_text(encoding="utf-8")
    body = _blocks(text)["check_short"]
    page.write_text(text.replace(body, body.replace("| pass |", "| FAIL |", 1)), encoding="utf-8")
    assert doc_tables.stale(root) == ["docs/exudyn.md: block check_short"]
    fixed, changed = doc_tables.regenerate(page.read_text(encoding="utf-8"))
    assert changed == ["check_short"] and fixed == text


def test_an_unknown_block_is_refused():
    with pytest.raises(ValueError, match="unknown generated block 'nope'"):
        doc_tables.regenerate("<!-- generated:nope -->\nx\n<!-- /generated:nope -->\n")


def test_the_command_checks_the_tree():
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.orchestration.doc_tables", "--check"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr


def test_the_stored_check_has_the_case_files_tolerances():
    """The stored check (docs/data/check_short.json, shown in docs/exudyn.md §8) was made
    with the tolerances and metrics the case files give now (re-run
    `rsmcheck check --short --json` when a tolerance changes)."""
    from rsmcheck.core.cases import load_case

    stored = json.loads((doc_tables.DATA / "check_short.json").read_text(encoding="utf-8"))
    assert stored["short"] is True
    problems = []
    for c in stored["checks"]:
        rows = {s.observable: s for s in load_case(c["case"]).variant(short=True).compare}
        spec = rows.get(c["observable"])
        if spec is None:
            problems.append(f"{c['case']}.{c['observable']}: no longer compared by the case file")
        elif (spec.tolerance, spec.metric) != (c["tolerance"], c["metric"]):
            problems.append(f"{c['case']}.{c['observable']}: case file {spec.metric} {spec.tolerance:g}, "
                            f"stored check {c['metric']} {c['tolerance']:g}")
    assert not problems, "docs/data/check_short.json was made with other tolerances:\n" + "\n".join(problems)
