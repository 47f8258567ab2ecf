"""The engine's settings of a case: its own table [twomode] (also in [short]).

Pure data and validation with rsmcheck.core.schema: reading a case file imports no numba.
An error is one `InputError(file, key, reason)`: the command line prints one line, exit 2.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

from rsmcheck.core.errors import InputError
from rsmcheck.core.schema import engine_table, number

#: the paper's two eigenmodes on each of the six links
N_MODES_DEFAULT = (2,) * 6
RTOL_DEFAULT = 1e-9


@dataclass(frozen=True)
class TwomodeSettings:
    """A case's settings of the engine.

    The engine is the reference model's class under another name, and that class reads its
    settings by its name (`rsmcheck.core.plugins.settings_of(case, name)`): so these carry
    every field it reads (n_modes, static_modes, h_max, quiet_integrator, rtol, integrator),
    the fixed ones at their values here."""

    n_modes: tuple[int, ...] = N_MODES_DEFAULT
    rtol: float = RTOL_DEFAULT
    why: str = ""
    #: fixed: no static correction shapes, one integrator, its default largest step
    static_modes: bool = False
    integrator: str = "dopri5"
    quiet_integrator: str | None = None
    h_max: float | None = None

    def given(self) -> dict[str, Any]:
        return {"n_modes": ",".join(str(n) for n in self.n_modes), "rtol": self.rtol,
                "static_modes": self.static_modes, "integrator": self.integrator}


def parse(tables: Mapping[str, Mapping[str, Any]], where: str, key: Callable[[str], str]) -> TwomodeSettings:
    """[twomode]: `n_modes` (an integer 1..6, or a list of six), `rtol` (0 < rtol < 1e-2);
    either needs `why`, the study behind it."""
    t = engine_table(where, key("twomode"), tables.get("twomode", {}), {
        "n_modes": lambda k, x: _modes(where, k, x),
        "rtol": lambda k, x: _rtol(where, k, x),
    }, needs_why=("n_modes", "rtol"))
    return TwomodeSettings(**t)


def _modes(where: str, key: str, v: Any) -> tuple[int, ...]:
    items = [v] * 6 if not isinstance(v, list) else v
    if len(items) != 6 or any(isinstance(x, bool) or not isinstance(x, int) or not 1 <= x <= 6 for x in items):
        raise InputError(where, key, f"must be an integer 1..6 or a list of six, got {v!r}")
    return tuple(items)


def _rtol(where: str, key: str, v: Any) -> float:
    x = number(where, key, v, 0.0, lo_open=True)
    if x >= 1e-2:
        raise InputError(where, key, f"{x} is too loose to mean anything (< 1e-2)")
    return x
