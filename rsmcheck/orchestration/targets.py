"""The suite's speed targets, read off one `rsmcheck bench` document.

The targets (README, "Speed"), each on the 2-core machine and from one run of the bench, so
that the engines and the right-hand sides are timed on the same machine at the same time:

* the reference flies the full mission (p1 → p5 chained) in ≤ 300 s of wall time;
* every phase of that flight runs at ≥ 20 × real time (the slowest phase is the reading);
* the reference runs the stand-alone cases at their short length in ≤ 30 s together;
* Exudyn flies the full mission in ≤ 20 min, with ≤ 15 % of it outside its solver;
* one compiled right-hand side of the rigid reference (closed chain) costs ≤ 3 Pinocchio ABA
  calls (`rhs_us`, rsmcheck.orchestration.bench).

`make test` ≤ 12 min on a fresh clone is the fifth; CI measures it, the bench does not.

A reading's margin is the suite's usual one, ≥ 1 when the target is met: bound / measured
for an upper bound, measured / bound for a lower one; 0.13 says "7.6 times too slow".

A wall-time reading also has a *floor*: the part of that wall the engine's own integrator
took (the reference's compiled DP5 and IMEX, Exudyn's `SolveSteps`; the runs' `split`,
rsmcheck.driver.runner).  Its margin, bound / floor, is the target's margin if the loop around
the engine (sensors, controller, held inputs, output samples) cost nothing: below 1, no
work on that loop can meet the target, only fewer or cheaper integration steps can.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from typing import Any, Callable, Sequence


@dataclass(frozen=True)
class SpeedTarget:
    """One target: `measured ≤ bound` (`upper`) or `measured ≥ bound`, in `unit`; `read`
    takes a bench document to (measured or None, which run it came from)."""

    key: str
    text: str
    bound: float
    unit: str
    upper: bool
    read: Callable[[dict], tuple[float | None, str]]
    floor: Callable[[dict], float | None] | None = None  # the integrator's share of `read`'s wall


@dataclass(frozen=True)
class TargetReading:
    """A target and what one bench document measured for it (None: no run measured it)."""

    target: SpeedTarget
    measured: float | None
    detail: str = ""
    floor: float | None = None  # the engine's integrator alone [the target's unit]

    @property
    def margin(self) -> float | None:
        """≥ 1 when met: bound / measured for an upper bound, measured / bound for a lower one."""
        return self._margin(self.measured)

    @property
    def floor_margin(self) -> float | None:
        """The margin of the integrator's share alone (module docstring): the most a free
        loop around the engine could make of the target."""
        return self._margin(self.floor)

    def _margin(self, value: float | None) -> float | None:
        if value is None:
            return None
        if self.target.upper:
            return self.target.bound / value if value > 0 else math.inf
        return value / self.target.bound

    @property
    def met(self) -> bool | None:
        return None if self.margin is None else self.margin >= 1.0


def _full_mission(doc: dict, engine: str) -> dict | None:
    """The document's full-length mission run of `engine`, if it has one that did not fail."""
    return next((r for r in doc.get("runs", []) if r.get("case") == "mission" and r.get("variant") == "full"
                 and r.get("engine") == engine and "error" not in r and r.get("wall_s")), None)


def _mission_wall(engine: str) -> Callable[[dict], tuple[float | None, str]]:
    def read(doc: dict) -> tuple[float | None, str]:
        run = _full_mission(doc, engine)
        if run is None:
            return None, ""
        return float(run["wall_s"]), f"{run['sim_s']:.0f} s of flight in {run['wall_s']:.1f} s"
    return read


def _mission_integrator(engine: str) -> Callable[[dict], float | None]:
    def floor(doc: dict) -> float | None:
        run = _full_mission(doc, engine)
        wall = ((run or {}).get("split") or {}).get("wall_integrator_s")
        return float(wall) if wall else None
    return floor


def _slowest_phase(engine: str) -> Callable[[dict], tuple[float | None, str]]:
    def read(doc: dict) -> tuple[float | None, str]:
        run = _full_mission(doc, engine)
        phases = [p for p in (run or {}).get("phases") or [] if p.get("wall_s")]
        if not phases:
            return None, ""
        speed = {p["phase"]: p["sim_s"] / p["wall_s"] for p in phases}
        slowest = min(speed, key=speed.get)
        return speed[slowest], "slowest " + slowest + "; " + ", ".join(f"{p} {s:.1f}" for p, s in speed.items())
    return read


def _short_total(engine: str) -> Callable[[dict], tuple[float | None, str]]:
    """The wall of `engine`'s stand-alone cases at their short length, summed (the mission
    and failed runs aside)."""
    def read(doc: dict) -> tuple[float | None, str]:
        runs = [r for r in doc.get("runs", []) if r.get("engine") == engine and r.get("variant") == "short"
                and r.get("case") != "mission" and "error" not in r and r.get("wall_s")]
        if not runs:
            return None, ""
        slowest = max(runs, key=lambda r: r["wall_s"])
        return float(sum(r["wall_s"] for r in runs)), (f"{len(runs)} cases; slowest {slowest['case']} "
                                                        f"{slowest['wall_s']:.1f} s")
    return read


def _outside_share(engine: str) -> Callable[[dict], tuple[float | None, str]]:
    """The share of `engine`'s full mission spent outside its own integrator [%]: the loop
    around it (sensors, controller, held inputs, output samples)."""
    def read(doc: dict) -> tuple[float | None, str]:
        run = _full_mission(doc, engine)
        wall = ((run or {}).get("split") or {}).get("wall_integrator_s")
        if not wall:
            return None, ""
        return 100.0 * (1.0 - float(wall) / float(run["wall_s"])), f"{run['wall_s'] - wall:.0f} of {run['wall_s']:.0f} s"
    return read


def _rhs_ratio(numerator: str, denominator: str) -> Callable[[dict], tuple[float | None, str]]:
    def read(doc: dict) -> tuple[float | None, str]:
        rhs = doc.get("rhs_us") or {}
        num, den = rhs.get(numerator), rhs.get(denominator)
        if not (num and den and math.isfinite(num) and math.isfinite(den)):
            return None, ""
        return num / den, f"{num:.1f} µs against {den:.1f} µs"
    return read


def _target(t: dict[str, Any]) -> SpeedTarget:
    """One [[target]] of speed_targets.toml as a `SpeedTarget`."""
    kind = t["reading"]
    if kind == "mission_wall":
        read, floor = _mission_wall(t["engine"]), _mission_integrator(t["engine"])
    elif kind == "slowest_phase":
        read, floor = _slowest_phase(t["engine"]), None
    elif kind == "short_total":
        read, floor = _short_total(t["engine"]), None
    elif kind == "outside_share":
        read, floor = _outside_share(t["engine"]), None
    elif kind == "rhs_ratio":
        read, floor = _rhs_ratio(t["numerator"], t["denominator"]), None
    else:
        raise ValueError(f"speed_targets.toml: target {t['key']}: unknown reading {kind!r}")
    return SpeedTarget(t["key"], t["text"], float(t["bound"]), t["unit"], bool(t["upper"]), read, floor)


#: the targets, from the package's speed_targets.toml (data: it names the engines it times)
TARGETS = tuple(_target(t) for t in tomllib.loads(
    resources.files("rsmcheck.orchestration").joinpath("speed_targets.toml").read_text(encoding="utf-8"))["target"])


def read_targets(doc: dict[str, Any]) -> list[TargetReading]:
    """Each target with what `doc` (a bench document) measured for it, and the floor under
    it where the runs recorded their integrator's share."""
    readings = []
    for t in TARGETS:
        measured, detail = t.read(doc)
        floor = t.floor(doc) if t.floor is not None and measured is not None else None
        readings.append(TargetReading(t, measured, detail, floor))
    return readings


def targets_table(readings: Sequence[TargetReading]) -> str:
    """The readings that were measured, for people: target, measured, margin, met, and the
    margin of the engine's integrator alone ("engine alone", module docstring)."""
    rows = [r for r in readings if r.measured is not None]
    if not rows:
        return ""
    head = f"{'speed target':50s} {'measured':>12s} {'margin':>8s}  met {'engine alone':>12s}"
    lines = [head, "-" * len(head)]
    for r in rows:
        bound = f"{'≤' if r.target.upper else '≥'} {r.target.bound:g} {r.target.unit}"
        alone = "–" if r.floor_margin is None else f"{r.floor_margin:.3f}"
        floor = "" if r.floor is None else f"; integrator {r.floor:.4g} {r.target.unit}"
        lines.append(f"{r.target.text + ' ' + bound:50s} {r.measured:12.4g} {r.margin:8.3f}  "
                     f"{'yes' if r.met else 'no ':3s} {alone:>12s}  ({r.detail}{floor})")
    return "\n".join(lines)
