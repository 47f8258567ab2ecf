"""README.md and the reference pages (docs/*.md but records.md) say what is true now.

* No commit hash and no date: a dated run belongs to docs/records.md, the one page with
  dates; a page that quotes a run says "the stored bench", and the figure comes from
  docs/data through a generated block.
* No figure of a data file outside a generated block: a value of docs/data/*.json written
  in scientific notation (2.99e-08, 2.99e-8) or with four or more significant digits
  (1.0005) is quoted only inside `<!-- generated:NAME -->` blocks, which
  tests/docs/test_doc_tables.py keeps equal to their data.
* Short pages and lines: README ≤ 150 lines, every other page ≤ 400; prose lines ≤ 100
  characters, hand-written table rows ≤ 400 (code blocks and generated blocks aside).
* Every reference page has the sections What it is / How to use it / What it guarantees /
  Limits.

Each check is a function of a text; the tests below run them on the pages and on
examples that must be caught and must be left alone.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "docs" / "data"
RECORDS = "records.md"
README_MAX, PAGE_MAX = 150, 400
PROSE_MAX, ROW_MAX = 100, 400
SECTIONS = ("## What it is", "## How to use it", "## What it guarantees", "## Limits")

GENERATED = re.compile(r"<!-- generated:(?P<name>[\w-]+) -->\n.*?<!-- /generated:(?P=name) -->\n?", re.S)
#: a git object name: 7–40 hex digits, at least one a digit; not a number in scientific
#: notation (5000e3) and not one side of a digest change printed as "old → new"
HEX = re.compile(r"(?<![\w.\-/])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w.])")
SCIENTIFIC = re.compile(r"\d+e\d+")
DATE = re.compile(r"\b20\d\d-[01]\d(?:-[0-3]\d)?\b")
NUMBER = re.compile(r"(?<![\w.])\d+\.\d+(?:e-?\d+)?(?![\w.])|(?<![\w.])\d+e-?\d+(?![\w.])")


def pages() -> list[Path]:
    return [ROOT / "README.md"] + [p for p in sorted((ROOT / "docs").glob("*.md")) if p.name != RECORDS]


def outside_generated(text: str) -> str:
    """`text` with every generated block emptied (its lines kept blank, so that line
    numbers stay)."""
    return GENERATED.sub(lambda m: "\n" * m.group(0).count("\n"), text)


def commit_hashes(text: str) -> list[str]:
    out = []
    for line in text.splitlines():
        for m in HEX.finditer(line):
            token = m.group(0)
            around = line[max(0, m.start() - 3):m.end() + 3]
            if SCIENTIFIC.fullmatch(token) or "→" in around:
                continue
            out.append(token)
    return out


def dates(text: str) -> list[str]:
    return DATE.findall(text)


def long_lines(text: str) -> list[tuple[int, int]]:
    """(line number, length) of prose lines over PROSE_MAX and table rows over ROW_MAX,
    outside code fences and generated blocks."""
    out, fenced = [], False
    for number, line in enumerate(outside_generated(text).splitlines(), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        limit = ROW_MAX if line.startswith("|") else PROSE_MAX
        if not fenced and len(line) > limit:
            out.append((number, len(line)))
    return out


def _floats(x):
    if isinstance(x, dict):
        for v in x.values():
            yield from _floats(v)
    elif isinstance(x, list):
        for v in x:
            yield from _floats(v)
    elif isinstance(x, float) and math.isfinite(x) and x != 0.0:
        yield x


#: data files no page quotes, whose thousands of values would only collide with other
#: figures: the randomized campaign's rows (shown in the report, docs/fuzz.md)
UNQUOTED = ("fuzz.json",)


def data_figures(data: Path = DATA) -> dict[str, str]:
    """Every value of the data files as a page would write it, → the file it is from:
    `2.99e-08` and `2.99e-8` (three significant digits, scientific), and decimals with four
    or more significant digits (`1.0005`)."""
    out: dict[str, str] = {}
    for path in sorted(data.glob("*.json")):
        if path.name in UNQUOTED:
            continue
        for x in _floats(json.loads(path.read_text(encoding="utf-8"))):
            sci = f"{abs(x):.2e}"
            mantissa, exponent = sci.split("e")
            if not mantissa.endswith(".00"):
                out.setdefault(sci, path.name)
                out.setdefault(f"{mantissa}e{int(exponent)}", path.name)
            for digits in (4, 5, 6):
                s = f"{abs(x):.{digits}g}"
                significant = s.replace(".", "").lstrip("0")
                if "e" not in s and "." in s and len(significant) >= 4 and not s.endswith("0"):
                    out.setdefault(s, path.name)
    return out


def loose_figures(text: str, figures: dict[str, str]) -> list[tuple[int, str, str]]:
    """(line, figure, data file) for each figure of a data file outside a generated block."""
    return [(number, t, figures[t]) for number, line in enumerate(outside_generated(text).splitlines(), 1)
            for t in NUMBER.findall(line) if t in figures]


# ---------------------------------------------------------------------------------------
# the pages
# ---------------------------------------------------------------------------------------
def _problems(check) -> list[str]:
    out = []
    for page in pages():
        out += [f"{page.relative_to(ROOT)}: {hit}" for hit in check(page.read_text(encoding="utf-8"))]
    return out


def test_there_are_pages():
    names = {p.name for p in pages()}
    assert {"README.md", "physics.md", "cases.md", "exudyn.md", "gate.md"} <= names, names


def test_no_commit_hash():
    found = _problems(commit_hashes)
    assert not found, "commit hashes belong to docs/records.md:\n" + "\n".join(found)


def test_no_date():
    found = _problems(dates)
    assert not found, "dates belong to docs/records.md:\n" + "\n".join(found)


def test_no_long_line():
    found = _problems(long_lines)
    assert not found, (f"lines over {PROSE_MAX} characters (table rows over {ROW_MAX}), as (line, length):\n"
                       + "\n".join(found))


def test_no_figure_of_a_data_file_outside_a_generated_block():
    figures = data_figures()
    assert len(figures) > 1000, "docs/data/ not found or empty"
    found = _problems(lambda text: loose_figures(text, figures))
    assert not found, ("figures of docs/data quoted by hand (put them in a generated block, "
                       "rsmcheck.orchestration.doc_tables, or link the file):\n" + "\n".join(found))


def test_pages_are_short():
    long = {p.name: n for p in pages()
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > (README_MAX if p.name == "README.md" else PAGE_MAX)}
    assert not long, f"README ≤ {README_MAX} lines, a reference page ≤ {PAGE_MAX}: {long}"


@pytest.mark.parametrize("name", ["physics.md", "observables.md", "cases.md", "controllers.md", "exudyn.md",
                                  "gate.md", "plugins.md", "benchmarks.md", "cluster.md", "commands.md"])
def test_reference_page_has_the_fixed_sections(name):
    lines = (ROOT / "docs" / name).read_text(encoding="utf-8").splitlines()
    missing = [s for s in SECTIONS if s not in lines]
    assert not missing, f"docs/{name} lacks {missing}"


# ---------------------------------------------------------------------------------------
# the checks themselves: what they must catch and what they must leave alone
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("text", ["at 863fb19 on a fresh clone", "the bench of 8116426", "(commit a39fe3f1618a41188d85788653167efb5c85a19d)"])
def test_a_commit_hash_is_caught(text):
    assert commit_hashes(text), text


@pytest.mark.parametrize("text", ["hi=50000e3", "parameter set changed (33b54840996e → d390ecaa0191)",
                                  "a facade over the parts", "1 118 s", "`exudyn_model/`", "a deadbeef word"])
def test_not_a_commit_hash(text):
    assert not commit_hashes(text), text


def test_a_date_is_caught_and_a_range_is_not():
    assert dates("measured 2026-11-26 on the EPYC") == ["2026-11-26"]
    assert dates("the bench of 2026-11") == ["2026-11"]
    assert not dates("margins 2.54–3.12, 2 000–3 000 steps")


def test_a_long_line_is_caught_but_not_in_code_or_generated_blocks():
    prose = "word " * 30
    assert long_lines(prose) == [(1, len(prose))]
    assert not long_lines("```\n" + prose + "\n```\n")
    assert not long_lines(f"<!-- generated:x -->\n{prose}\n<!-- /generated:x -->\n")
    assert not long_lines("| " + "cell | " * 40)
    assert long_lines("| " + "cell | " * 80)


def test_a_figure_of_a_data_file_is_caught_outside_a_generated_block():
    figures = data_figures()
    stored = json.loads((DATA / "check_short.json").read_text(encoding="utf-8"))["checks"][0]["error"]
    sci = f"{stored:.2e}"
    assert sci in figures
    text = f"The capture gap differs by {sci} m.\n"
    assert [(n, f) for n, f, _ in loose_figures(text, figures)] == [(1, sci)]
    short = f"{sci.split('e')[0]}e{int(sci.split('e')[1])}"
    assert loose_figures(f"by {short} m", figures)
    assert not loose_figures(f"<!-- generated:x -->\nby {sci} m\n<!-- /generated:x -->\n", figures)
    assert not loose_figures("ρ∞ = 0.6, 1e-3 N, 15.6 µs, margin 3.12", figures)
