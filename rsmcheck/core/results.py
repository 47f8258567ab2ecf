"""Results files: one tool's run of one benchmark problem, as any tool can write it.

The format (docs/problems.md, "Write a results file"), version 1, CSV:

    # rsmcheck-results 1
    # case: free_drift
    # variant: short
    # units: SI
    # tool: MyCode
    # tool_version: 2.3
    # settings: {"step_s": 1e-4}
    # cpu_time_s: 12.5
    # machine: 2-core AMD EPYC
    # event: 5.0125, capture, arm=2
    time,base_pose_I[0],base_pose_I[1],base_pose_I[2],ee2_pos_B[0],ee2_pos_B[1]
    0,0,0,0,3.9,-0.6
    ...

Header lines start with "# KEY: value" (`case`, `tool` and `units` required, `units` must
be "SI": m, kg, s, rad, N); `event` may repeat (time, kind, detail), `settings` is one line
of JSON.  Then one header row of column names and one row per output sample: `time` first,
then any observables of docs/observables.md, a scalar as its name, a vector's components as
NAME[i] (every component of a named observable, in order).  HDF5 holds the same layout: the
header keys as root attributes (`event` as a dataset of rows), one dataset per column name.

`read_results` is the one reader: anything malformed is an InputError naming the file and
the field, so that the command line says it in one line.  `write_results` writes atomically.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import h5py
import numpy as np

from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import BY_NAME
from rsmcheck.core.store import EngineRun, Event, write_text

FORMAT = "rsmcheck-results"
VERSION = 1
#: header keys a file must have; the others are optional
REQUIRED = ("case", "tool", "units")
KNOWN = ("case", "variant", "units", "tool", "tool_version", "settings", "cpu_time_s", "machine", "event")
UNITS = "SI"


@dataclass
class Results:
    """One results file: its header and its columns (observable name → samples × components,
    `time` included as a vector)."""

    path: Path
    case: str
    tool: str
    variant: str = "short"
    tool_version: str = ""
    settings: dict[str, Any] = field(default_factory=dict)
    cpu_time_s: float | None = None
    machine: str = ""
    events: list[Event] = field(default_factory=list)
    observables: dict[str, np.ndarray] = field(default_factory=dict)

    def as_run(self, engine: str | None = None) -> EngineRun:
        """The file as an engine run (`engine`: the name its rows are judged under)."""
        return EngineRun(engine or self.tool, dict(self.observables), list(self.events),
                         solver={k: (v if isinstance(v, (int, float, str)) else json.dumps(v))
                                 for k, v in self.settings.items()},
                         versions={self.tool: self.tool_version} if self.tool_version else {})


def columns(name: str) -> list[str]:
    """The column names of observable `name`: NAME for a scalar, NAME[i] for each component."""
    size = BY_NAME[name].size
    return [name] if BY_NAME[name].shape == () else [f"{name}[{i}]" for i in range(size)]


def _fmt(x: float) -> str:
    return repr(float(x))


def results_text(results: Results) -> str:
    """The CSV text of `results` (full precision: repr of each float)."""
    head = [f"# {FORMAT} {VERSION}", f"# case: {results.case}", f"# variant: {results.variant}",
            f"# units: {UNITS}", f"# tool: {results.tool}"]
    if results.tool_version:
        head.append(f"# tool_version: {results.tool_version}")
    if results.settings:
        head.append(f"# settings: {json.dumps(results.settings, sort_keys=True)}")
    if results.cpu_time_s is not None:
        head.append(f"# cpu_time_s: {results.cpu_time_s:.6g}")
    if results.machine:
        head.append(f"# machine: {results.machine}")
    head += [f"# event: {_fmt(e.time)}, {e.kind}, {e.detail}" for e in results.events]
    names = ["time"] + [n for n in results.observables if n != "time"]
    cols = [c for n in names for c in columns(n)]
    n = len(results.observables["time"])
    blocks = [np.asarray(results.observables[k], float).reshape(n, -1) for k in names]
    data = np.hstack(blocks) if blocks else np.zeros((0, 0))
    rows = [",".join(_fmt(v) for v in row) for row in data]
    return "\n".join(head + [",".join(cols)] + rows) + "\n"


def write_results(path: str | Path, results: Results) -> Path:
    """Write `results` to `path` (.csv) atomically."""
    return write_text(path, results_text(results))


def _bad(path: Path, key: str, what: str) -> InputError:
    return InputError(str(path), key, what)


def _header(path: Path, lines: list[str]) -> tuple[dict[str, str], list[str]]:
    if not lines or lines[0].strip() != f"# {FORMAT} {VERSION}":
        got = lines[0].strip() if lines else "an empty file"
        raise _bad(path, "format", f"the first line must be '# {FORMAT} {VERSION}', not {got[:60]!r}")
    head: dict[str, str] = {}
    events: list[str] = []
    for line in lines[1:]:
        key, sep, value = line[1:].strip().partition(":")
        key, value = key.strip(), value.strip()
        if not sep or key not in KNOWN:
            raise _bad(path, key or "header", f"unknown header line {line.strip()[:60]!r} (known keys: "
                                              f"{', '.join(KNOWN)})")
        if key == "event":
            events.append(value)
        elif key in head:
            raise _bad(path, key, "given twice")
        else:
            head[key] = value
    for key in REQUIRED:
        if not head.get(key):
            raise _bad(path, key, "missing from the header")
    if head["units"] != UNITS:
        raise _bad(path, "units", f"must be {UNITS!r} (m, kg, s, rad, N), not {head['units']!r}")
    return head, events


def _events(path: Path, texts: list[str]) -> list[Event]:
    out = []
    for text in texts:
        parts = [p.strip() for p in text.split(",", 2)]
        try:
            t = float(parts[0])
        except ValueError:
            raise _bad(path, "event", f"{text!r}: must be 'time, kind, detail'") from None
        if len(parts) < 2 or not parts[1] or not math.isfinite(t):
            raise _bad(path, "event", f"{text!r}: must be 'time, kind, detail'")
        out.append(Event(t, parts[1], parts[2] if len(parts) > 2 else ""))
    return out


def _split_columns(path: Path, names: list[str]) -> dict[str, list[int]]:
    """observable → the indices of its columns, in component order; InputError for an
    unknown or malformed name, a repeated or a missing component."""
    if not names or names[0] != "time":
        raise _bad(path, "columns", f"the first column must be 'time', not {(names or [''])[0]!r}")
    found: dict[str, dict[int, int]] = {}
    for k, col in enumerate(names):
        base, _, rest = col.partition("[")
        if base not in BY_NAME:
            raise _bad(path, col, "not an observable of docs/observables.md")
        if BY_NAME[base].shape == ():
            if rest:
                raise _bad(path, col, f"{base} is a scalar: its column is {base!r}")
            i = 0
        else:
            try:
                i = int(rest.rstrip("]")) if rest.endswith("]") else -1
            except ValueError:
                i = -1
            if not 0 <= i < BY_NAME[base].size:
                raise _bad(path, col, f"{base} has components {base}[0] … {base}[{BY_NAME[base].size - 1}]")
        if i in found.setdefault(base, {}):
            raise _bad(path, col, "given twice")
        found[base][i] = k
    out = {}
    for base, comps in found.items():
        missing = [c for i, c in enumerate(columns(base)) if i not in comps]
        if missing:
            raise _bad(path, missing[0], f"missing (every component of {base} is needed)")
        out[base] = [comps[i] for i in range(len(comps))]
    return out


def read_results(path: str | Path) -> Results:
    """Read a results file (CSV, or HDF5 by its .h5 suffix); InputError naming the file
    and the field for anything malformed."""
    path = Path(path)
    if not path.is_file():
        raise _bad(path, "file", "no such file")
    if path.suffix in (".h5", ".hdf5"):
        return _read_h5(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise _bad(path, "file", f"cannot be read as UTF-8 text ({type(exc).__name__})") from None
    lines = text.splitlines()
    n_head = next((i for i, line in enumerate(lines) if not line.startswith("#")), len(lines))
    head, events = _header(path, lines[:n_head])
    if n_head >= len(lines):
        raise _bad(path, "columns", "no header row of column names")
    names = [c.strip() for c in lines[n_head].split(",")]
    index = _split_columns(path, names)
    rows = []
    for j, line in enumerate(lines[n_head + 1:], n_head + 2):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != len(names):
            raise _bad(path, f"line {j}", f"{len(cells)} values for {len(names)} columns")
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            bad = next(c for c in cells if not _is_float(c))
            raise _bad(path, f"line {j}", f"{bad.strip()[:30]!r} is not a number") from None
    return _results(path, head, events, index, np.array(rows, float).reshape(len(rows), len(names)), names)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _results(path: Path, head: Mapping[str, str], events: list[str], index: Mapping[str, list[int]],
             data: np.ndarray, names: list[str]) -> Results:
    if data.shape[0] < 2:
        raise _bad(path, "time", f"{data.shape[0]} sample(s): a run needs at least two")
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        i, k = bad[0]
        raise _bad(path, names[k], f"not finite ({data[i, k]}) at t = {data[i, 0]:.6g} s (sample {i})")
    t = data[:, 0]
    if np.any(np.diff(t) <= 0.0):
        i = int(np.flatnonzero(np.diff(t) <= 0.0)[0])
        raise _bad(path, "time", f"not increasing at sample {i + 1} (t = {t[i + 1]:.9g} s after {t[i]:.9g} s)")
    settings: dict[str, Any] = {}
    if head.get("settings"):
        try:
            settings = json.loads(head["settings"])
        except json.JSONDecodeError:
            raise _bad(path, "settings", "must be one line of JSON") from None
        if not isinstance(settings, dict):
            raise _bad(path, "settings", "must be a JSON object")
    cpu = None
    if head.get("cpu_time_s"):
        try:
            cpu = float(head["cpu_time_s"])
        except ValueError:
            cpu = float("nan")
        if not (math.isfinite(cpu) and cpu >= 0.0):
            raise _bad(path, "cpu_time_s", f"must be a number of seconds ≥ 0, not {head['cpu_time_s']!r}")
    obs = {name: data[:, cols].reshape((data.shape[0],) + BY_NAME[name].shape) for name, cols in index.items()}
    return Results(path, head["case"], head["tool"], head.get("variant", "short") or "short",
                   head.get("tool_version", ""), settings, cpu, head.get("machine", ""),
                   _events(path, events), obs)


def _read_h5(path: Path) -> Results:
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: (v.decode() if isinstance(v, bytes) else str(v)) for k, v in f.attrs.items()}
            if attrs.get("format") != f"{FORMAT} {VERSION}":
                raise _bad(path, "format", f"root attribute 'format' must be '{FORMAT} {VERSION}'")
            head = {k: v for k, v in attrs.items() if k in KNOWN}
            for key in REQUIRED:
                if not head.get(key):
                    raise _bad(path, key, "missing from the root attributes")
            if head["units"] != UNITS:
                raise _bad(path, "units", f"must be {UNITS!r} (m, kg, s, rad, N), not {head['units']!r}")
            events = [e.decode() if isinstance(e, bytes) else str(e) for e in f["event"][()]] if "event" in f else []
            names = [n.decode() if isinstance(n, bytes) else str(n) for n in f.attrs.get("columns", [])]
            index = _split_columns(path, names)
            data = np.column_stack([np.asarray(f[n][()], float) for n in names])
    except OSError:
        raise _bad(path, "file", "not an HDF5 file h5py can read") from None
    return _results(path, head, events, index, data, names)


def write_results_h5(path: str | Path, results: Results) -> Path:
    """The same layout in HDF5 (atomic: a temporary name, then renamed)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    names = ["time"] + [n for n in results.observables if n != "time"]
    n = len(results.observables["time"])
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs.update({"format": f"{FORMAT} {VERSION}", "case": results.case, "variant": results.variant,
                            "units": UNITS, "tool": results.tool, "tool_version": results.tool_version,
                            "settings": json.dumps(results.settings, sort_keys=True), "machine": results.machine})
            if results.cpu_time_s is not None:
                f.attrs["cpu_time_s"] = f"{results.cpu_time_s:.6g}"
            cols = []
            for name in names:
                block = np.asarray(results.observables[name], float).reshape(n, -1)
                for j, col in enumerate(columns(name)):
                    f[col] = block[:, j]
                    cols.append(col)
            f.attrs["columns"] = cols
            f["event"] = [f"{_fmt(e.time)}, {e.kind}, {e.detail}" for e in results.events]
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
