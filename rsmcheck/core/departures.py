"""The known departures from the paper, as data: rsmcheck/core/departures.toml.

One row per departure, with the columns of docs/physics.md §9: the paper (section /
equation), what the suite does, why, and the measured size of the difference.  The file
is the one source: the report reads it (shipped in the package), and the table of
docs/physics.md §9 is a generated block rendered from it
(`python -m rsmcheck.orchestration.doc_tables` rewrites it, tests/docs/test_doc_tables.py
checks it);

    python -m rsmcheck.core.departures --markdown      # print the table
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from importlib import resources
from typing import Sequence

from rsmcheck.core.errors import InputError

#: the data file, inside this package
DATA = "departures.toml"
#: the keys of a row, in the order of the table's columns
KEYS = ("paper", "suite", "why", "size")


def table() -> tuple[list[str], list[list[str]]]:
    """(column titles, rows) of the data file; each row's cells in the order of KEYS."""
    where = f"rsmcheck/core/{DATA}"
    doc = tomllib.loads((resources.files("rsmcheck.core") / DATA).read_text(encoding="utf-8"))
    columns = doc.get("columns")
    if not isinstance(columns, list) or len(columns) != len(KEYS):
        raise InputError(where, "columns", f"must list {len(KEYS)} column titles")
    rows = []
    for i, row in enumerate(doc.get("departure", [])):
        if sorted(row) != sorted(KEYS):
            raise InputError(where, f"departure[{i}]", f"must have exactly the keys {', '.join(KEYS)}")
        rows.append([str(row[k]) for k in KEYS])
    return [str(c) for c in columns], rows


def markdown() -> str:
    """The table as Markdown, one line per row."""
    head, rows = table()
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rsmcheck.core.departures", description=__doc__.split("\n")[0])
    parser.add_argument("--markdown", action="store_true", required=True, help="print the table as Markdown")
    parser.parse_args(argv)
    sys.stdout.write(markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
