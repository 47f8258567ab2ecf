"""Minimal text edits of a case file's [compare] rows (`rsmcheck budget --apply`).

A row `[compare.OBS]` (or `[short.compare.OBS]`) gets a new `tolerance` and `why`, and its
budget's parts `allowance` and `errors` (rsmcheck.core.tolerances): only the values of
those lines change (a part the row lacks is added after its tolerance); the comments, the
order, the other keys and every other line stay as they were.  The edit is refused (the file untouched, the reason returned)
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
from typing import Any, Mapping

from rsmcheck.core.cases import Case, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.store import write_text

#: a table header `[a.b.c]` (not an array of tables), with an optional comment
HEADER = re.compile(r"^\s*\[(?!\[)\s*([^\]]+?)\s*\]\s*(?:#.*)?$")
#: `KEY = VALUE  # comment` of the keys an edit may write (a one-line value: a number, an
#: inline table without '#', or the why, matched again by WHY)
KEY = re.compile(r"^(?P<head>\s*(?P<key>tolerance|allowance|errors|why)\s*=\s*)(?P<value>\{[^}#]*\}|[^\s#]+)"
                 r"(?P<tail>\s*(?:#.*)?)$")
KEY_NAME = re.compile(r"^\s*(tolerance|allowance|errors|why)\s*=")
#: `why = "one-line basic string"  # comment`
WHY = re.compile(r'^(?P<head>\s*why\s*=\s*)(?P<value>"(?:[^"\\]|\\.)*")(?P<tail>\s*(?:#.*)?)$')


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


def toml_value(key: str, value: Any) -> str:
    """A row's value as the file writes it: numbers to two significant figures, `errors` as
    a one-line inline table, `why` as a one-line basic string."""
    if key == "why":
        return toml_string(value)
    if key in ("errors", "engine_errors"):
        return "{ " + ", ".join(f"{e} = {toml_float(v)}" for e, v in value.items()) + " }"
    return toml_float(value)


def edit_text(text: str, table: str, rows: Mapping[str, Mapping[str, Any]]) -> tuple[str, list[str], dict[str, str]]:
    """(`text` with each [table.OBS] of `rows` given its values (key → value: tolerance,
    why, and the budget's allowance and errors), the observables changed, observable → why
    it was refused).  A key the table lacks is added after its tolerance line."""
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
                km = KEY_NAME.match(body)
                if km:
                    key = km.group(1)
                    one_line = WHY.match(body) if key == "why" else KEY.match(body)
                    found.setdefault(obs, {})[key if one_line else f"{key}_other"] = i
    changed, refused = [], {}
    inserts: dict[int, list[str]] = {}
    for obs, values in rows.items():
        at = found.get(obs, {})
        if not at:
            refused[obs] = f"no [{table}.{obs}] table with tolerance and why lines"
            continue
        if "why" not in at:
            refused[obs] = f"[{table}.{obs}] why is not a one-line basic string: edit it by hand"
            continue
        if "tolerance" not in at:
            refused[obs] = f"[{table}.{obs}] has no one-line tolerance"
            continue
        other = [k[:-6] for k in at if k.endswith("_other") and k[:-6] in values]
        if other:
            refused[obs] = f"[{table}.{obs}] {other[0]} is not on one line: edit it by hand"
            continue
        for key, value in values.items():
            if key not in at:  # a new key: after the tolerance, with its indentation
                indent = lines[at["tolerance"]][:len(lines[at["tolerance"]]) - len(lines[at["tolerance"]].lstrip())]
                inserts.setdefault(at["tolerance"], []).append(f"{indent}{key} = {toml_value(key, value)}\n")
                continue
            i = at[key]
            body = lines[i].rstrip("\r\n")
            m = WHY.match(body) if key == "why" else KEY.match(body)
            lines[i] = m.group("head") + toml_value(key, value) + m.group("tail") + lines[i][len(body):]
        changed.append(obs)
    for i in sorted(inserts, reverse=True):
        lines[i + 1:i + 1] = inserts[i]
    return "".join(lines), changed, refused


def apply_rows(case: Case, short: bool, rows: Mapping[str, Mapping[str, Any]]) -> Edit:
    """Give the rows of `case`'s variant (observable → key → value, `edit_text`) their new values
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
        for key, value in rows[obs].items():
            row[obs][key] = tomllib.loads(f"v = {toml_value(key, value)}")["v"]
    if tomllib.loads(new) != expected:
        raise InputError(str(path), table, "the edited file does not parse to the intended rows: not written")
    write_text(path, new)
    try:
        load_case(str(path))
    except InputError:
        write_text(path, old)  # put back what was there: the edit made it an invalid case
        raise
    return edit
