"""The table of docs/exudyn.md §8 says what the stored check says, and the stored check was
made with the case files' present tolerances.

docs/data/check_short.json is the output of `rsmcheck check --short --json` on every case
with a [compare] table; §8 shows it to people.  A tolerance tightened in a case file, or a
check re-run, without the other two following, leaves the reader with figures that no
longer describe the suite: this test names each row that disagrees.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from rsmcheck.core.cases import load_case

ROOT = Path(__file__).resolve().parents[1]
STORED = ROOT / "docs" / "data" / "check_short.json"
DOC = ROOT / "docs" / "exudyn.md"

#: | case | observable | metric | error | tolerance | margin | result |
ROW = re.compile(r"^\|\s*(\w+)\s*\|\s*(\w+)\s*\|\s*(\w+)\s*\|\s*([0-9.e+-]+)\s*\|\s*([0-9.e+-]+)\s*\|"
                 r"\s*([0-9.e+-]+|∞)\s*\|\s*(pass|FAIL)\s*\|\s*$")


def section_8_rows() -> dict[tuple[str, str], tuple[str, ...]]:
    text = DOC.read_text(encoding="utf-8")
    start = text.index("\n## 8. ")
    end = text.index("\n## ", start + 1)
    rows = {}
    for line in text[start:end].splitlines():
        m = ROW.match(line)
        if m:
            rows[(m[1], m[2])] = m.groups()[2:]
    return rows


def test_section_8_shows_the_stored_check():
    stored = json.loads(STORED.read_text(encoding="utf-8"))["checks"]
    shown = section_8_rows()
    assert len(shown) == len(stored), (f"docs/exudyn.md §8 shows {len(shown)} rows, "
                                       f"docs/data/check_short.json has {len(stored)}")
    problems = []
    for c in stored:
        key = (c["case"], c["observable"])
        if key not in shown:
            problems.append(f"{key}: stored, not shown")
            continue
        metric, error, tolerance, _margin, result = shown[key]
        expected = (c["metric"], f"{c['error']:.2e}", float(c["tolerance"]), "pass" if c["pass"] else "FAIL")
        got = (metric, error, float(tolerance), result)
        if got != expected:
            problems.append(f"{key}: shown {got}, stored {expected}")
    assert not problems, "docs/exudyn.md §8 differs from docs/data/check_short.json:\n" + "\n".join(problems)


def test_stored_check_has_the_case_files_tolerances():
    stored = json.loads(STORED.read_text(encoding="utf-8"))
    assert stored["short"] is True
    problems = []
    for c in stored["checks"]:
        case = load_case(c["case"]).variant(short=True)
        rows = {s.observable: s for s in case.compare}
        spec = rows.get(c["observable"])
        if spec is None:
            problems.append(f"{c['case']}.{c['observable']}: no longer compared by the case file")
        elif (spec.tolerance, spec.metric) != (c["tolerance"], c["metric"]):
            problems.append(f"{c['case']}.{c['observable']}: case file {spec.metric} {spec.tolerance:g}, "
                            f"stored check {c['metric']} {c['tolerance']:g}")
    assert not problems, ("docs/data/check_short.json was made with other tolerances than the case files "
                          "now give (re-run `rsmcheck check --short --json`):\n" + "\n".join(problems))
