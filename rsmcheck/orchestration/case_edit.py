"""Minimal text edits of a case file's [compare] rows (`rsmcheck budget --apply`).

A row `[compare.OBS]` (or `[short.compare.OBS]`) gets a new `tolerance` and `why`: only the
value of those two lines changes; the comments, the order, the other keys and every other
line stay as they were.  The edit is refused (the file untouched, the reason returned)
where it cannot be that small: no such table header, a `why` that is not a one-line basic
string.  The new text must parse to the old file's data with exactly those values changed,
and load as a case, before it replaces the file (atomically, `store.write_text`).
"""

from __future__ import annotations

import copy
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

from rsmcheck.core.cases import Case, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.store import write_text

#: a table header `[a.b.c]` (not an array of tables), with an optional comment
HEADER = re.compile(r"^\s*\[(?!\[)\s*([^\]]+?)\s*\]\s*(?:#.*)?$")
#: `tolerance = NUMBER  # comment`
TOLERANCE = re.compile(r"^(?P<head>\s*tolerance\s*=\s*)(?P<value>[^\s#]+)(?P<tail>\s*(?:#.*)?)$")
#: `why = "one-line basic string"  # comment`
WHY = re.compile(r'^(?P<head>\s*why\s*=\s*)(?P<value>"(?:[^"\\]|\\.)*")(?P<tail>\s*(?:#.*)?)$')
WHY_KEY = re.compile(r"^\s*why\s*=")


def compare_table(case: Case, short: bool) -> str | None:
    """The table the rows of `case`'s variant come from: "short.compare" or "compare"; None
    for a short variant that takes the full case's rows (an edit there would change the
    full case, measured on another run)."""
    if not short:
        return "compare"
    return "short.compare" if "compare" in case.raw.get("short", {}) else None


def toml_float(x: float) -> str:
    """`x` as a TOML float with its two significant figures (1.2, 1.8e-07, 42.0)."""
    text = f"{x:.2g}"
    return text if any(c in text for c in ".e") else text + ".0"


def toml_string(text: str) -> str:
    """`text` as a one-line TOML basic string."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + "".join(c if c >= " " and c != "\x7f" else f"\\u{ord(c):04x}" for c in escaped) + '"'


@dataclass
class Edit:
    """What `apply_rows` did to one file: the rows changed and the rows refused, with why."""

    path: Path
    changed: list[str] = field(default_factory=list)
    refused: dict[str, str] = field(default_factory=dict)


def edit_text(text: str, table: str, rows: Mapping[str, tuple[float, str]]) -> tuple[str, list[str], dict[str, str]]:
    """(`text` with each [table.OBS] of `rows` given its (tolerance, why), the observables
    changed, observable → why it was refused)."""
    lines = text.splitlines(keepends=True)
    current = None
    found: dict[str, dict[str, int]] = {}
    for i, line in enumerate(lines):
        m = HEADER.match(line.rstrip("\r\n"))
        if m:
            current = "".join(m.group(1).split())
            continue
        for obs in rows:
            if current == f"{table}.{obs}":
                body = line.rstrip("\r\n")
                if TOLERANCE.match(body):
                    found.setdefault(obs, {})["tolerance"] = i
                elif WHY.match(body):
                    found.setdefault(obs, {})["why"] = i
                elif WHY_KEY.match(body):
                    found.setdefault(obs, {})["why_other"] = i
    changed, refused = [], {}
    for obs, (tolerance, why) in rows.items():
        at = found.get(obs, {})
        if "tolerance" not in at and "why" not in at and "why_other" not in at:
            refused[obs] = f"no [{table}.{obs}] table with tolerance and why lines"
            continue
        if "why" not in at:
            refused[obs] = f"[{table}.{obs}] why is not a one-line basic string: edit it by hand"
            continue
        if "tolerance" not in at:
            refused[obs] = f"[{table}.{obs}] has no one-line tolerance"
            continue
        for key, value in (("tolerance", toml_float(tolerance)), ("why", toml_string(why))):
            i = at[key]
            ending = lines[i][len(lines[i].rstrip("\r\n")):]
            m = (TOLERANCE if key == "tolerance" else WHY).match(lines[i].rstrip("\r\n"))
            lines[i] = m.group("head") + value + m.group("tail") + ending
        changed.append(obs)
    return "".join(lines), changed, refused


def apply_rows(case: Case, short: bool, rows: Mapping[str, tuple[float, str]]) -> Edit:
    """Give the rows of `case`'s variant (observable → (tolerance, why)) their new values
    in its file, when that can be done by `edit_text` and checks out (module doc)."""
    path = Path(case.path)
    edit = Edit(path)
    table = compare_table(case, short)
    if table is None:
        edit.refused = {obs: "the short variant takes the full case's [compare] rows: apply a full budget"
                        for obs in rows}
        return edit
    old = path.read_text(encoding="utf-8")
    new, edit.changed, edit.refused = edit_text(old, table, rows)
    if not edit.changed:
        return edit
    expected = copy.deepcopy(tomllib.loads(old))
    for obs in edit.changed:
        row = expected
        for part in table.split("."):
            row = row[part]
        row[obs]["tolerance"], row[obs]["why"] = float(toml_float(rows[obs][0])), rows[obs][1]
    if tomllib.loads(new) != expected:
        raise InputError(str(path), table, "the edited file does not parse to the intended rows: not written")
    write_text(path, new)
    try:
        load_case(str(path))
    except InputError:
        write_text(path, old)  # put back what was there: the edit made it an invalid case
        raise
    return edit
