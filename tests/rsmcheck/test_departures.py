"""The departures from the paper have one source, rsmcheck/core/departures.toml: the report
shows it, and the table of docs/physics.md §9 is a generated block rendered from it
(rsmcheck.orchestration.doc_tables; tests/docs/test_doc_tables.py checks the page)."""

from __future__ import annotations

import subprocess
import sys

from rsmcheck.core import departures


def test_the_data_file_has_every_column_of_each_row():
    head, rows = departures.table()
    assert head == ["paper (section / equation)", "the suite", "why", "measured size of the difference"]
    assert len(rows) >= 10 and all(len(r) == 4 and all(c.strip() for c in r) for r in rows)
    assert any("static correction shapes" in r[1] for r in rows)


def test_the_markdown_has_one_line_per_row_and_escapes_bars():
    head, rows = departures.table()
    lines = departures.markdown().splitlines()
    assert len(lines) == 2 + len(rows)
    assert lines[0] == "| " + " | ".join(head) + " |"
    assert any("\\|" in line for line in lines), "the bistop row's |ψ| must be escaped"


def test_the_command_prints_the_table():
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.core.departures", "--markdown"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout == departures.markdown()
