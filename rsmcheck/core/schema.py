"""Readers of case-file values: each returns the converted value or raises
`InputError(where, key, reason)`, which the command line prints as one line (exit 2).
Shared by the case loader (rsmcheck.core.cases) and the engine plug-ins' settings tables."""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping

from rsmcheck.core.errors import InputError


def number(where: str, key: str, v: Any, lo: float | None = None, lo_open: bool = False,
            hi: float | None = None) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(where, key, f"must be a number, got {type(v).__name__}")
    v = float(v)
    if not math.isfinite(v):
        raise InputError(where, key, f"must be finite, got {v}")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise InputError(where, key, f"must be {'>' if lo_open else '>='} {lo}, got {v}")
    if hi is not None and v > hi:
        raise InputError(where, key, f"must be <= {hi}, got {v}")
    return v


def integer(where: str, key: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise InputError(where, key, f"must be an integer {lo}..{hi}, got {v!r}")
    return v


def vector(where: str, key: str, v: Any, n: int, lo: float | None = None, lo_open: bool = False) -> tuple[float, ...]:
    if not isinstance(v, list) or len(v) != n:
        raise InputError(where, key, f"must be a list of {n} numbers")
    return tuple(number(where, f"{key}[{i}]", x, lo, lo_open) for i, x in enumerate(v))


def flag(where: str, key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise InputError(where, key, f"must be true or false, got {type(v).__name__}")
    return v


def arm(where: str, key: str, v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v not in (1, 2):
        raise InputError(where, key, f"must be 1 or 2, got {v!r}")
    return v


def text(where: str, key: str, v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise InputError(where, key, "must be a non-empty string")
    return v


def table(where: str, key: str, v: Any, known: Mapping[str, Callable[[str, Any], Any]]) -> dict[str, Any]:
    if not isinstance(v, Mapping):
        raise InputError(where, key, "must be a table")
    out = {}
    for k, value in v.items():
        if k not in known:
            raise InputError(where, f"{key}.{k}", f"unknown key (known: {', '.join(sorted(known))})")
        out[k] = known[k](f"{key}.{k}", value)
    return out


def require(where: str, key: str, table: Mapping[str, Any], names: tuple[str, ...]) -> None:
    for k in names:
        if k not in table:
            raise InputError(where, f"{key}.{k}", "missing (required)")


# ---------------------------------------------------------------------------------------
def grasp(where: str, key: str, v: Any) -> tuple[int, int]:
    if not isinstance(v, list) or len(v) != 2 or any(isinstance(x, bool) or x not in (0, 1) for x in v):
        raise InputError(where, key, "must be a list of two 0/1 values")
    return (int(v[0]), int(v[1]))


def arms(where: str, key: str, v: Any) -> tuple[int, ...]:
    if not isinstance(v, list) or not v or len(set(map(repr, v))) != len(v):
        raise InputError(where, key, "must be a non-empty list of distinct arms (1, 2)")
    return tuple(arm(where, f"{key}[{i}]", x) for i, x in enumerate(v))


def choice(where: str, key: str, v: Any, options: tuple[str, ...]) -> str:
    if v not in options:
        raise InputError(where, key, f"must be one of {', '.join(options)}, got {v!r}")
    return v


def engine_table(w: str, key: str, v: Any, known: Mapping[str, Callable[[str, Any], Any]],
                     needs_why: tuple[str, ...]) -> dict[str, Any]:
    """An engine's settings table; a numerical setting in `needs_why` requires `why`."""
    t = table(w, key, v, {**known, "why": lambda k, x: text(w, k, x)})
    if any(k in t for k in needs_why) and "why" not in t:
        raise InputError(w, f"{key}.why", "missing (required with any setting: the study behind it)")
    return t
