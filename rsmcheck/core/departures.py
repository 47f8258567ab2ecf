"""The known departures from the paper, as data: rsmcheck/core/departures.toml.

One row per departure, with the columns of docs/physics.md §9: the paper (section /
equation), what the suite does, why, and the measured size of the difference.  The file
is the one source: the report reads it (shipped in the package), and the table of
docs/physics.md §9 is generated from it,

    python -m rsmcheck.core.departures --markdown      # print the table
    python -m rsmcheck.core.departures --write FILE    # replace the table in FILE

(tests/rsmcheck/test_departures.py checks that docs/physics.md shows this rendering).
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from importlib import resources
from pathlib import Path
from typing import Sequence

from rsmcheck.core.errors import InputError

#: the data file, inside this package
DATA = "departures.toml"
#: the keys of a row, in the order of the table's columns
KEYS = ("paper", "suite", "why", "size")
#: the comment line above the generated table in a Markdown document
MARKER = "<!-- generated from rsmcheck/core/departures.toml: python -m rsmcheck.core.departures --write docs/physics.md -->"


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
    """The table as Markdown, one line per row, with the marker comment above it."""
    head, rows = table()
    lines = [MARKER, "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def table_in(text: str) -> str:
    """The generated table of a document: the marker line and the table lines after it
    ('' when the document has no marker)."""
    lines = text.splitlines(keepends=True)
    start = next((i for i, line in enumerate(lines) if line.rstrip("\n") == MARKER), None)
    if start is None:
        return ""
    end = start + 1
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    return "".join(lines[start:end])


def replace_table(text: str) -> str:
    """`text` with its generated table (`table_in`) replaced by `markdown()`."""
    old = table_in(text)
    if not old:
        raise InputError("document", "departures", f"no line '{MARKER}' to put the table after")
    return text.replace(old, markdown(), 1)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rsmcheck.core.departures", description=__doc__.split("\n")[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    group.add_argument("--write", metavar="FILE", help="replace the generated table in FILE (docs/physics.md)")
    args = parser.parse_args(argv)
    if args.markdown:
        sys.stdout.write(markdown())
        return 0
    path = Path(args.write)
    try:
        path.write_text(replace_table(path.read_text(encoding="utf-8")), encoding="utf-8")
    except InputError as exc:
        sys.stderr.write(f"{parser.prog}: {path}: {exc.reason}\n")
        return 2
    print(f"wrote the departures table into {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
