"""Case files: declarative TOML in cases/, loaded into typed objects and validated.

A case names its initial state, duration, controller, scheduled events, solver settings,
parameter overrides and a `short` duration for CI.  Everything is checked before
anything runs: an unknown key, a wrong type, an out-of-range or inconsistent value raises
`InputError(file, key, reason)`; the command line turns it into one line and exit 2.

Format (every key optional unless marked):

    name = "free_drift"              # required, equal to the file stem
    description = "..."              # required, one line
    duration = 20.0                  # required [s]
    short_duration = 5.0             # [s], the `--short` variant (default: duration)

    [initial]
    base_pose = [x, y, θ]            # [m, m, rad]
    base_rate = [ẋ, ẏ, θ̇]
    joint_angles_deg = [6 values]    # arm 1 then arm 2, base outward
    joint_rates = [6 values]         # [rad/s]
    grasp = [1, 0]                   # which arms hold the target at t = 0
    wrist_angle_deg = 0.0            # ψ of the first holding arm
    target_pose = [x, y, θ]          # only when no arm holds the target
    target_rate = [ẋ, ẏ, θ̇]

    [orbit]
    enabled = false                  # tidal gravity about the co-moving point O

    [controller]
    kind = "none" | "constant"
    motor_torques = [6 values]       # "constant": held τ_m [N·m]
    base_torque = 0.0

    [[release]]                      # scheduled releases
    time = 1.0
    arm = 1

    [capture]
    arm = 2                          # arm whose gap is reported and that may capture
    enabled = false                  # evaluate the IF conditions each sample

    [solver]
    control_period = 1e-3            # [s] controller sample, zero-order hold
    output_period = 1e-2             # [s] observable sampling, multiple of control_period
    rtol = 1e-9

    [reference]
    n_modes = 2                      # modes per link (0 = rigid), int or 6 ints

    [params]                         # overrides of rsmcheck.params.Params, by section
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from rsmcheck.errors import InputError
from rsmcheck.params import Params

CASES_DIR = Path(__file__).resolve().parent


@dataclass(frozen=True)
class InitialSpec:
    base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_rate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint_angles_deg: tuple[float, ...] = (60.0, -120.0, 60.0, -60.0, 120.0, -60.0)
    joint_rates: tuple[float, ...] = (0.0,) * 6
    grasp: tuple[int, int] = (1, 0)
    wrist_angle_deg: float = 0.0
    target_pose: tuple[float, float, float] | None = None
    target_rate: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ControllerSpec:
    kind: str = "none"
    motor_torques: tuple[float, ...] = (0.0,) * 6
    base_torque: float = 0.0


@dataclass(frozen=True)
class ReleaseSpec:
    time: float
    arm: int


@dataclass(frozen=True)
class CaptureSpec:
    arm: int = 2
    enabled: bool = False


@dataclass(frozen=True)
class SolverSpec:
    control_period: float = 1e-3
    output_period: float = 1e-2
    rtol: float = 1e-9

    @property
    def output_every(self) -> int:
        return int(round(self.output_period / self.control_period))


@dataclass(frozen=True)
class Case:
    name: str
    description: str
    duration: float
    short_duration: float
    initial: InitialSpec
    orbit: bool
    controller: ControllerSpec
    releases: tuple[ReleaseSpec, ...]
    capture: CaptureSpec
    solver: SolverSpec
    n_modes: tuple[int, ...]
    params: Params
    path: str
    file_hash: str
    raw: Mapping[str, Any] = field(repr=False, default_factory=dict)

    def run_duration(self, short: bool) -> float:
        return self.short_duration if short else self.duration


# ---------------------------------------------------------------------------------------
# Field checkers: each returns the converted value or raises InputError(where, key, why)
# ---------------------------------------------------------------------------------------
def _number(where: str, key: str, v: Any, lo: float | None = None, lo_open: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(where, key, f"must be a number, got {type(v).__name__}")
    v = float(v)
    if not math.isfinite(v):
        raise InputError(where, key, f"must be finite, got {v}")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise InputError(where, key, f"must be {'>' if lo_open else '>='} {lo}, got {v}")
    return v


def _vector(where: str, key: str, v: Any, n: int) -> tuple[float, ...]:
    if not isinstance(v, list) or len(v) != n:
        raise InputError(where, key, f"must be a list of {n} numbers")
    return tuple(_number(where, f"{key}[{i}]", x) for i, x in enumerate(v))


def _flag(where: str, key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise InputError(where, key, f"must be true or false, got {type(v).__name__}")
    return v


def _arm(where: str, key: str, v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v not in (1, 2):
        raise InputError(where, key, f"must be 1 or 2, got {v!r}")
    return v


def _text(where: str, key: str, v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise InputError(where, key, "must be a non-empty string")
    return v


def _table(where: str, key: str, v: Any, known: Mapping[str, Callable[[str, Any], Any]]) -> dict[str, Any]:
    if not isinstance(v, Mapping):
        raise InputError(where, key, "must be a table")
    out = {}
    for k, value in v.items():
        if k not in known:
            raise InputError(where, f"{key}.{k}", f"unknown key (known: {', '.join(sorted(known))})")
        out[k] = known[k](f"{key}.{k}", value)
    return out


# ---------------------------------------------------------------------------------------
def case_path(name_or_path: str | Path) -> Path:
    """cases/NAME.toml for a bare name, else the path as given."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.parent != Path("."):
        return p
    return CASES_DIR / f"{name_or_path}.toml"


def list_cases() -> list[Path]:
    return sorted(CASES_DIR.glob("*.toml"))


def load_case(name_or_path: str | Path) -> Case:
    """Load and validate one case file (a bare name looks in cases/)."""
    path = case_path(name_or_path)
    where = str(path)
    if not path.is_file():
        known = ", ".join(p.stem for p in list_cases())
        raise InputError(where, "case", f"no such case file (known cases: {known})")
    data = path.read_bytes()
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(where, "toml", str(exc)) from None
    return _parse(raw, where, path, hashlib.sha256(data).hexdigest())


def _parse(raw: Mapping[str, Any], where: str, path: Path, digest: str) -> Case:
    w = where
    top = {"name", "description", "duration", "short_duration", "initial", "orbit", "controller",
           "release", "capture", "solver", "reference", "params"}
    for k in raw:
        if k not in top:
            raise InputError(w, k, f"unknown key (known: {', '.join(sorted(top))})")
    for k in ("name", "description", "duration"):
        if k not in raw:
            raise InputError(w, k, "missing (required)")
    name = _text(w, "name", raw["name"])
    if name != path.stem:
        raise InputError(w, "name", f"'{name}' differs from the file name '{path.stem}'")
    duration = _number(w, "duration", raw["duration"], 0.0, lo_open=True)
    short = _number(w, "short_duration", raw.get("short_duration", duration), 0.0, lo_open=True)
    if short > duration:
        raise InputError(w, "short_duration", f"{short} s exceeds duration {duration} s")

    ini = _table(w, "initial", raw.get("initial", {}), {
        "base_pose": lambda k, v: _vector(w, k, v, 3),
        "base_rate": lambda k, v: _vector(w, k, v, 3),
        "joint_angles_deg": lambda k, v: _vector(w, k, v, 6),
        "joint_rates": lambda k, v: _vector(w, k, v, 6),
        "grasp": lambda k, v: _grasp(w, k, v),
        "wrist_angle_deg": lambda k, v: _number(w, k, v),
        "target_pose": lambda k, v: _vector(w, k, v, 3),
        "target_rate": lambda k, v: _vector(w, k, v, 3),
    })
    initial = InitialSpec(**ini)
    if any(initial.grasp) and initial.target_pose is not None:
        raise InputError(w, "initial.target_pose", "given although an arm holds the target "
                         "(the grasp fixes the target pose)")
    if not any(initial.grasp) and initial.target_pose is None:
        raise InputError(w, "initial.target_pose", "required when no arm holds the target")

    orbit = _table(w, "orbit", raw.get("orbit", {}), {"enabled": lambda k, v: _flag(w, k, v)})
    ctrl = _table(w, "controller", raw.get("controller", {}), {
        "kind": lambda k, v: _choice(w, k, v, ("none", "constant")),
        "motor_torques": lambda k, v: _vector(w, k, v, 6),
        "base_torque": lambda k, v: _number(w, k, v),
    })
    controller = ControllerSpec(**ctrl)

    rel_raw = raw.get("release", [])
    if not isinstance(rel_raw, list):
        raise InputError(w, "release", "must be an array of tables ([[release]])")
    releases = []
    for n, item in enumerate(rel_raw):
        r = _table(w, f"release[{n}]", item, {
            "time": lambda k, v: _number(w, k, v, 0.0),
            "arm": lambda k, v: _arm(w, k, v),
        })
        for k in ("time", "arm"):
            if k not in r:
                raise InputError(w, f"release[{n}].{k}", "missing (required)")
        if r["time"] >= duration:
            raise InputError(w, f"release[{n}].time", f"{r['time']} s is not before the end ({duration} s)")
        if not initial.grasp[r["arm"] - 1]:
            raise InputError(w, f"release[{n}].arm", f"arm {r['arm']} does not hold the target at t = 0")
        releases.append(ReleaseSpec(**r))

    cap = CaptureSpec(**_table(w, "capture", raw.get("capture", {}), {
        "arm": lambda k, v: _arm(w, k, v),
        "enabled": lambda k, v: _flag(w, k, v),
    }))
    solver = SolverSpec(**_table(w, "solver", raw.get("solver", {}), {
        "control_period": lambda k, v: _number(w, k, v, 0.0, lo_open=True),
        "output_period": lambda k, v: _number(w, k, v, 0.0, lo_open=True),
        "rtol": lambda k, v: _number(w, k, v, 0.0, lo_open=True),
    }))
    ratio = solver.output_period / solver.control_period
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise InputError(w, "solver.output_period", "must be a whole multiple of solver.control_period")
    if solver.rtol >= 1e-2:
        raise InputError(w, "solver.rtol", f"{solver.rtol} is too loose to mean anything (< 1e-2)")

    ref = _table(w, "reference", raw.get("reference", {}), {"n_modes": lambda k, v: _modes(w, k, v)})
    n_modes = ref.get("n_modes", (2,) * 6)
    params = Params.from_overrides(raw.get("params", {}), w)
    return Case(
        name=name, description=_text(w, "description", raw["description"]), duration=duration,
        short_duration=short, initial=initial, orbit=orbit.get("enabled", False),
        controller=controller, releases=tuple(sorted(releases, key=lambda r: r.time)),
        capture=cap, solver=solver, n_modes=n_modes, params=params, path=where,
        file_hash=digest, raw=raw,
    )


def _grasp(where: str, key: str, v: Any) -> tuple[int, int]:
    if not isinstance(v, list) or len(v) != 2 or any(isinstance(x, bool) or x not in (0, 1) for x in v):
        raise InputError(where, key, "must be a list of two 0/1 values")
    return (int(v[0]), int(v[1]))


def _choice(where: str, key: str, v: Any, options: tuple[str, ...]) -> str:
    if v not in options:
        raise InputError(where, key, f"must be one of {', '.join(options)}, got {v!r}")
    return v


def _modes(where: str, key: str, v: Any) -> tuple[int, ...]:
    items = [v] * 6 if not isinstance(v, list) else v
    if len(items) != 6 or any(isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= 6 for x in items):
        raise InputError(where, key, "must be an integer 0..6 or a list of six")
    return tuple(items)
