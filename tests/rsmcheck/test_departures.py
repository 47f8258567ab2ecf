"""The departures from the paper have one source, rsmcheck/core/departures.toml: the report
shows it and the table of docs/physics.md §9 is its rendering
(`python -m rsmcheck.core.departures --write docs/physics.md` regenerates it)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rsmcheck.core import departures
from rsmcheck.core.errors import InputError

DOC = Path(__file__).resolve().parents[2] / "docs" / "physics.md"


def section_9(text: str) -> str:
    start = text.index("\n## 9. ")
    return text[start:text.index("\n## ", start + 1)]


def test_docs_physics_shows_the_data_file():
    text = DOC.read_text(encoding="utf-8")
    shown = departures.table_in(text)
    assert shown, f"no line {departures.MARKER!r} in {DOC}"
    assert shown in section_9(text), "the generated table is not in §9"
    assert shown == departures.markdown(), (
        "docs/physics.md §9 differs from rsmcheck/core/departures.toml: "
        "python -m rsmcheck.core.departures --write docs/physics.md")


def test_the_data_file_has_every_column_of_each_row():
    head, rows = departures.table()
    assert head == ["paper (section / equation)", "the suite", "why", "measured size of the difference"]
    assert len(rows) >= 10 and all(len(r) == 4 and all(c.strip() for c in r) for r in rows)
    assert any("static correction shapes" in r[1] for r in rows)


def test_a_changed_row_shows_as_a_difference():
    """The comparison can fail: one cell changed in the document is seen, and --write's
    replacement restores the data file's rendering."""
    text = DOC.read_text(encoding="utf-8")
    shown = departures.table_in(text)
    assert "J_extra = 0.388 kg·m²" in shown
    changed = text.replace(shown, shown.replace("J_extra = 0.388 kg·m²", "J_extra = 0.39 kg·m²"))
    assert changed != text
    assert departures.table_in(changed) != departures.markdown()
    assert departures.replace_table(changed) == text
    with pytest.raises(InputError):
        departures.replace_table("# no table here\n")


def test_the_command_prints_and_writes(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.core.departures", "--markdown"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout == departures.markdown()
    doc = tmp_path / "physics.md"
    doc.write_text(f"# x\n\n{departures.MARKER}\n| old | table |\n|---|---|\n\nafter\n", encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.core.departures", "--write", str(doc)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert doc.read_text(encoding="utf-8") == f"# x\n\n{departures.markdown()}\nafter\n"
