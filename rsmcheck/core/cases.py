"""Case files: declarative TOML in cases/ (and in a user's folders, `--cases-dir`,
$RSMCHECK_CASES_DIR), loaded into typed objects and validated.

A case names its initial state (or the stored end state of another case it starts from),
duration, controller and motion programme, scheduled events, solver settings, parameter
overrides, the observables engines are compared on with their tolerances, and a `short`
variant for CI.  Everything is checked before anything runs: an unknown key, a wrong type,
an out-of-range or inconsistent value raises `InputError(file, key, reason)`; the command
line turns it into one line and exit 2.

The format — every key, its type, unit and default — is described once, in docs/cases.md
§1; docs/cases.md §4 says what each case is for.
"""

from __future__ import annotations

import hashlib
import math
import os
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import NAMES as OBSERVABLE_NAMES  # what a [compare] table may name
from rsmcheck.core.params import Params
from rsmcheck.core.programme import Segment, check_programme, parse_segments
from rsmcheck.core.plugins import broken_plugins, owned_solver_keys, owned_tables, parse_engine_settings, plugins
from rsmcheck.core.schema import arm as _arm, choice as _choice, flag as _flag, grasp as _grasp
from rsmcheck.core.schema import number as _number, require as _require, table as _table
from rsmcheck.core.schema import text as _text, vector as _vector

#: environment variable naming folders of a user's own case files (os.pathsep-separated),
#: searched besides the packaged ones; `rsmcheck --cases-dir DIR` adds to it
CASES_ENV = "RSMCHECK_CASES_DIR"


def packaged_cases_dir() -> Path:
    """The project's case files: the data folder rsmcheck/case_files/ of an installed
    package (the repository's cases/, mapped there by pyproject's package-dir), read with
    importlib.resources; in a checkout (editable install, PYTHONPATH) cases/ itself."""
    packaged = resources.files("rsmcheck") / "case_files"
    if isinstance(packaged, Path) and packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parents[2] / "cases"


#: the packaged case files (see `packaged_cases_dir`)
CASES_DIR = packaged_cases_dir()

#: metrics a [compare] entry may ask for; rsmcheck.orchestration.compare.difference computes each
METRICS = ("max_abs", "rms", "final", "growth")
#: top-level keys a [short] table may replace
SHORT_KEYS = ("duration", "segment", "release", "capture", "controller", "solver", "compare")
#: besides SHORT_KEYS, [short] may replace any table an engine plug-in owns


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
    wrist_rate: float = 0.0
    held_points: tuple[tuple[float, float], tuple[float, float]] | None = None  # centre frame


@dataclass(frozen=True)
class OrbitSpec:
    enabled: bool = False
    altitude: float | None = None  # None: params.orbit.altitude_initial
    align: str = "fixed"
    centre_on_com: bool = True


@dataclass(frozen=True)
class BaseGains:
    kp: float = 0.0
    kd: float = 0.0


@dataclass(frozen=True)
class ArmGains:
    kp: tuple[float, float, float] = (0.0, 0.0, 0.0)
    kd: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ControllerSpec:
    kind: str = "none"
    motor_torques: tuple[float, ...] = (0.0,) * 6
    base_torque: float = 0.0
    ramp_time: float = 0.0  # "constant": smooth ramp-in time [s]; 0 = a step at t = 0
    sine_amplitude: tuple[float, ...] = (0.0,) * 6  # "constant": τ_m += A sin(2π f t) [N·m]
    sine_frequency_hz: float = 0.0  # "constant": f of that sine [Hz]
    feedback: str = "measured"
    rate_filter_hz: float = 0.0  # first-order low-pass on θ̇_J of eq. (14); 0 = none
    gains: str = ""
    base: BaseGains = BaseGains()
    arm1: ArmGains = ArmGains()
    arm2: ArmGains = ArmGains()


@dataclass(frozen=True)
class ReleaseSpec:
    time: float
    arm: int


@dataclass(frozen=True)
class CaptureSpec:
    arm: int = 2
    enabled: bool = False
    point_T: tuple[float, float] | None = None  # None: params.geometry.grasp_T(arm)


@dataclass(frozen=True)
class SolverSpec:
    """[solver]: the sampled-data loop's periods.  Its other keys belong to the engine
    plug-ins that declare them (`EnginePlugin.solver_keys`)."""

    control_period: float = 1e-3
    output_period: float = 1e-2

    @property
    def output_every(self) -> int:
        return int(round(self.output_period / self.control_period))

    def is_quiet(self, span: float) -> bool:
        """A control interval of `span` [s] longer than the case's control period belongs
        to a quiet segment (sampled at its own, longer control_period; docs/physics.md §7)."""
        return span > self.control_period * (1.0 + 1e-6)


def first_given(*values):
    """The first of `values` that is not None: an engine setting from its explicit option,
    the case's settings table and the engine's default, in that order."""
    return next(v for v in values if v is not None)


@dataclass(frozen=True)
class CompareSpec:
    observable: str
    tolerance: float
    why: str
    metric: str = "max_abs"
    #: the interval [s] the metric looks at: required by "growth" (the fit interval),
    #: optional for "max_abs" and "rms" (the samples t0 ≤ t ≤ t1 only), not with "final"
    window: tuple[float, float] | None = None
    #: the row's error budget in parts (docs/cases.md §1, rsmcheck.core.tolerances):
    #: `allowance`, what the paper's physics lets two faithful engines differ by on this row
    #: (the same for every pair); `errors`, engine → that engine's own integration error on
    #: this run, measured by its refinement.  `tolerance` is the row's tolerance for the pair
    #: `errors` names; any other pair's is scaled from its own parts.  None: a rule row (a
    #: flag, a bound by definition) whose tolerance is the same for every pair.
    allowance: float | None = None
    errors: Mapping[str, float] = field(default_factory=dict)
    #: engine → the own integration error of an engine outside the stated pair, recorded
    #: from its refined run (`rsmcheck budget`) so that a check need not run it again; it
    #: enters that engine's pairs only, as a measured one would
    engine_errors: Mapping[str, float] = field(default_factory=dict)


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
    params: Params
    path: str
    file_hash: str
    raw: Mapping[str, Any] = field(repr=False, default_factory=dict)
    orbit_spec: OrbitSpec = OrbitSpec()
    segments: tuple[Segment, ...] = ()
    compare: tuple[CompareSpec, ...] = ()
    start_from: str | None = None
    has_initial: bool = True
    is_short: bool = False
    short: "Case | None" = field(default=None, repr=False)
    #: a sequence case (the mission): the phase cases it runs in order, each chained
    phases: tuple[str, ...] = ()
    #: a sequence case: rows of a phase's [compare] table replaced for the chained flight
    #: (phase name → the replacing rows), from the sequence file's [compare.PHASE.OBSERVABLE]
    phase_compare: Mapping[str, tuple[CompareSpec, ...]] = field(default_factory=dict)
    #: each registered engine plug-in's settings of the case (name → the plug-in's own
    #: settings object), from the tables it owns (rsmcheck.core.plugins)
    engine_settings: Mapping[str, Any] = field(default_factory=dict)

    def run_duration(self, short: bool) -> float:
        return self.short_duration if short else self.duration

    def variant(self, short: bool) -> "Case":
        """The case to run: its `[short]` variant with `short`, else itself."""
        if short and self.short is not None:
            return self.short
        return self

    def capture_point_T(self, arm: int | None = None) -> tuple[float, float]:
        """Designated capture point of the case-level [capture] (target frame, about COM)."""
        arm = arm or self.capture.arm
        if self.capture.point_T is not None and arm == self.capture.arm:
            return self.capture.point_T
        return self.params.geometry.grasp_T(arm)


# ---------------------------------------------------------------------------------------
# where the case files are: the packaged ones and a user's folders
# ---------------------------------------------------------------------------------------
def user_cases_dirs() -> list[Path]:
    """The folders of $RSMCHECK_CASES_DIR (os.pathsep-separated; empty entries skipped):
    InputError naming the variable if one is not a folder."""
    out = []
    for entry in os.environ.get(CASES_ENV, "").split(os.pathsep):
        if not entry:
            continue
        path = Path(entry)
        if not path.is_dir():
            raise InputError(CASES_ENV, entry, "no such folder of case files")
        out.append(path)
    return out


def cases_dirs() -> list[Path]:
    """Where case files are found: the packaged ones, then each user folder."""
    return [CASES_DIR] + user_cases_dirs()


def case_index() -> dict[str, Path]:
    """Case name → file, over every folder of `cases_dirs`: InputError naming both files
    when two folders hold a case of the same name (a user's case shadows nothing)."""
    index: dict[str, Path] = {}
    seen: set[Path] = set()
    for folder in cases_dirs():
        if folder.resolve() in seen:  # the same folder named twice
            continue
        seen.add(folder.resolve())
        for path in sorted(folder.glob("*.toml")):
            if path.stem in index:
                raise InputError(str(path), "case", f"'{path.stem}' is also {index[path.stem]} (rename one)")
            index[path.stem] = path
    return index


def case_path(name_or_path: str | Path) -> Path:
    """The case file of a bare name (in the packaged cases or a user's folder,
    `case_index`), else the path as given."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.parent != Path("."):
        return p
    return case_index().get(str(name_or_path), CASES_DIR / f"{name_or_path}.toml")


def sibling_case(name: str, path: Path) -> Path:
    """The case `name` referred to from the case file `path`: NAME.toml next to it, else
    the case of that name (`case_path`)."""
    near = Path(path).parent / f"{name}.toml"
    return near if near.is_file() else case_path(name)


def phase_cases(sequence: Case, short: bool) -> list[Case]:
    """The phases of `sequence` (a sequence case or its variant), each the variant to run:
    with `short`, each phase's short variant, in the order of the sequence's short phases."""
    return [load_case(sibling_case(p, Path(sequence.path))).variant(short) for p in sequence.variant(short).phases]


def list_cases() -> list[Path]:
    """Every case file (`case_index`), by name."""
    return [path for _, path in sorted(case_index().items())]


def load_case(name_or_path: str | Path) -> Case:
    """Load and validate one case file (a bare name: `case_path`)."""
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
    digest = hashlib.sha256(data).hexdigest()
    if "phases" in raw:
        return _parse_sequence(raw, where, path, digest)
    return _parse_with_short(raw, where, path, digest)


def _parse_sequence(raw: Mapping[str, Any], where: str, path: Path, digest: str) -> Case:
    """A case that runs other cases in sequence (`phases`), each from the previous end state.

    `short_phases` (default: `phases`) is the sequence run with --short: each phase's short
    variant, chained (a short phase need not end where the next one's short variant can
    start, e.g. p1's short variant does not bring the target into arm 2's reach)."""
    w = where
    for k in raw:
        if k not in ("name", "description", "phases", "short_phases", "compare", "short_compare"):
            raise InputError(w, k, "not allowed in a sequence case (known: compare, description, name, "
                             "phases, short_compare, short_phases)")
    for k in ("name", "description"):
        if k not in raw:
            raise InputError(w, k, "missing (required)")
    name = _text(w, "name", raw["name"])
    if name != path.stem:
        raise InputError(w, "name", f"'{name}' differs from the file name '{path.stem}'")
    full = _sequence(w, "phases", raw["phases"], name, path)
    short = _sequence(w, "short_phases", raw.get("short_phases", raw["phases"]), name, path)
    description = _text(w, "description", raw["description"])

    def build(cases: list[Case], key: str, is_short: bool) -> Case:
        first = cases[0]
        ckey = "short_compare" if is_short else "compare"
        return replace(first, name=name, description=description,
                       duration=sum(c.variant(is_short).duration for c in cases),
                       short_duration=sum(c.variant(True).duration for c in cases), path=w,
                       file_hash=digest, raw=raw, phases=tuple(c.name for c in cases), short=None,
                       segments=(), compare=(), start_from=None, is_short=is_short,
                       phase_compare=_phase_compare(w, ckey, raw.get(ckey, {}), cases, is_short))

    short_case = build(short, "short_phases", True)
    full_case = build(full, "phases", False)
    return replace(full_case, short_duration=short_case.duration, short=short_case)


def _phase_compare(w: str, key: str, v: Any, cases: list[Case], is_short: bool) -> dict[str, tuple[CompareSpec, ...]]:
    """[compare.PHASE.OBSERVABLE] of a sequence: rows that replace a phase's own for the
    chained flight; each phase and observable must exist in that variant's tables."""
    if not isinstance(v, Mapping):
        raise InputError(w, key, "must be a table of phase tables")
    by_name = {c.name: c.variant(is_short) for c in cases}
    out = {}
    for phase, table in v.items():
        if phase not in by_name:
            raise InputError(w, f"{key}.{phase}", f"not a phase of this variant (phases: {', '.join(by_name)})")
        rows = _compare(w, f"{key}.{phase}", table)
        own = {s.observable for s in by_name[phase].compare}
        for r in rows:
            if r.observable not in own:
                raise InputError(w, f"{key}.{phase}.{r.observable}", f"not compared in {phase}'s own table "
                                 f"(it compares {', '.join(sorted(own))}): only its rows can be replaced")
        out[phase] = rows
    return out


def _sequence(w: str, key: str, names: Any, name: str, path: Path) -> list[Case]:
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise InputError(w, key, "must be a non-empty list of case names")
    cases = []
    for i, n in enumerate(names):
        if n == name or not sibling_case(n, path).is_file():
            raise InputError(w, f"{key}[{i}]", f"no case '{n}' to run as a phase")
        try:
            c = load_case(sibling_case(n, path))
        except InputError as exc:
            raise InputError(w, f"{key}[{i}]", f"case '{n}' is invalid: {exc}") from None
        if c.phases:
            raise InputError(w, f"{key}[{i}]", f"'{n}' is itself a sequence")
        if i == 0 and not c.has_initial:
            raise InputError(w, f"{key}[0]", f"'{n}' has no [initial] to start the sequence from")
        if i > 0 and c.start_from != names[i - 1]:
            raise InputError(w, f"{key}[{i}]", f"'{n}' starts from {c.start_from!r}, not from the "
                             f"previous phase '{names[i - 1]}'")
        cases.append(c)
    return cases


def _parse_with_short(raw: Mapping[str, Any], where: str, path: Path, digest: str) -> Case:
    w = where
    short_raw = raw.get("short")
    if short_raw is not None and not isinstance(short_raw, Mapping):
        raise InputError(w, "short", "must be a table")
    short_raw = dict(short_raw or {})
    allowed = (*SHORT_KEYS, *owned_tables())
    for k in short_raw:
        if k not in allowed:
            raise InputError(w, f"short.{k}", f"cannot be changed by the short variant "
                             f"(allowed: {', '.join(allowed)})")
    if "short_duration" in raw:
        if "duration" in short_raw:
            raise InputError(w, "short_duration", "given twice (also as short.duration)")
        short_raw["duration"] = raw["short_duration"]
    base = {k: v for k, v in raw.items() if k not in ("short", "short_duration")}
    full = _parse(base, w, path, digest)
    if not short_raw:
        return full
    merged = dict(base)
    merged.update(short_raw)
    keys = {k: f"short.{k}" for k in short_raw}
    if "short_duration" in raw:
        keys["duration"] = "short_duration"
    short = _parse(merged, w, path, digest, short_keys=keys)
    if short.duration > full.duration:
        key = "short_duration" if "short_duration" in raw else "short.duration"
        raise InputError(w, key, f"{short.duration} s exceeds duration {full.duration} s")
    return replace(full, short_duration=short.duration, short=short, raw=raw)


def _parse(raw: Mapping[str, Any], where: str, path: Path, digest: str,
           short_keys: Mapping[str, str] | None = None) -> Case:
    """One variant.  `short_keys`: for the short variant, the keys it replaced and the name
    under which an error in them is reported (short.X, or short_duration)."""
    w = where
    is_short = short_keys is not None
    short_keys = short_keys or {}

    def kname(k: str) -> str:
        return short_keys.get(k, k)

    top = {"name", "description", "duration", "short_duration", "initial", "orbit", "controller",
           "release", "capture", "solver", "params", "segment", "compare",
           "start_from", "short", *owned_tables()}
    for k in raw:
        if k not in top:
            raise InputError(w, k, f"unknown key (known: {', '.join(sorted(top))})")
    for k in ("name", "description", "duration"):
        if k not in raw:
            raise InputError(w, k, "missing (required)")
    name = _text(w, "name", raw["name"])
    if name != path.stem:
        raise InputError(w, "name", f"'{name}' differs from the file name '{path.stem}'")
    duration = _number(w, kname("duration"), raw["duration"], 0.0, lo_open=True)

    start_from = None
    if "start_from" in raw:
        start_from = _text(w, "start_from", raw["start_from"])
        if start_from == name:
            raise InputError(w, "start_from", "a case cannot start from its own end state")
        if not sibling_case(start_from, path).is_file():
            known = ", ".join(p.stem for p in list_cases())
            raise InputError(w, "start_from", f"no case '{start_from}' (known cases: {known})")
    has_initial = "initial" in raw or start_from is None

    params = Params.from_overrides(raw.get("params", {}), w)
    geo = params.geometry

    def point(key: str, v: Any, arm: int | None) -> tuple[float, float]:
        """A point of the target: "grasp1"/"grasp2" or [x, y] about the geometric centre;
        returned in the target frame about the COM."""
        if isinstance(v, str):
            if v not in ("grasp1", "grasp2"):
                raise InputError(w, key, f"must be \"grasp1\", \"grasp2\" or [x, y], got {v!r}")
            return geo.grasp_T(1 if v == "grasp1" else 2)
        x, y = _vector(w, key, v, 2)
        half = 0.5 * params.target.side
        if max(abs(x), abs(y)) > half * (1 + 1e-9):
            raise InputError(w, key, f"({x}, {y}) lies outside the target (half side {half} m)")
        o = geo.target_com_offset_T
        return (x - o[0], y - o[1])

    ini = _table(w, "initial", raw.get("initial", {}), {
        "base_pose": lambda k, v: _vector(w, k, v, 3),
        "base_rate": lambda k, v: _vector(w, k, v, 3),
        "joint_angles_deg": lambda k, v: _vector(w, k, v, 6),
        "joint_rates": lambda k, v: _vector(w, k, v, 6),
        "grasp": lambda k, v: _grasp(w, k, v),
        "wrist_angle_deg": lambda k, v: _number(w, k, v),
        "wrist_rate": lambda k, v: _number(w, k, v),
        "held_points": lambda k, v: _held_points(w, k, v, point),
        "target_pose": lambda k, v: _vector(w, k, v, 3),
        "target_rate": lambda k, v: _vector(w, k, v, 3),
    })
    initial = InitialSpec(**ini)
    if any(initial.grasp) and initial.target_pose is not None:
        raise InputError(w, "initial.target_pose", "given although an arm holds the target "
                         "(the grasp fixes the target pose)")
    if not any(initial.grasp) and initial.target_pose is None and has_initial:
        raise InputError(w, "initial.target_pose", "required when no arm holds the target")
    if not any(initial.grasp) and (initial.wrist_rate or initial.wrist_angle_deg):
        raise InputError(w, "initial.wrist_rate" if initial.wrist_rate else "initial.wrist_angle_deg",
                         "given although no arm holds the target")

    orb = _table(w, "orbit", raw.get("orbit", {}), {
        "enabled": lambda k, v: _flag(w, k, v),
        "altitude": lambda k, v: _number(w, k, v, 100e3, hi=50000e3),
        "align": lambda k, v: _choice(w, k, v, ("fixed", "retrograde")),
        "centre_on_com": lambda k, v: _flag(w, k, v),
    })
    orbit_spec = OrbitSpec(**orb)
    if not orbit_spec.enabled and len(orb) > ("enabled" in orb):
        extra = sorted(set(orb) - {"enabled"})[0]
        raise InputError(w, f"orbit.{extra}", "given although the orbit is not enabled")

    controller = _controller(w, kname("controller"), raw.get("controller", {}))

    rel_raw = raw.get("release", [])
    if not isinstance(rel_raw, list):
        raise InputError(w, kname("release"), "must be an array of tables ([[release]])")
    releases = []
    for n, item in enumerate(rel_raw):
        key = f"{kname('release')}[{n}]"
        r = _table(w, key, item, {
            "time": lambda k, v: _number(w, k, v, 0.0),
            "arm": lambda k, v: _arm(w, k, v),
        })
        _require(w, key, r, ("time", "arm"))
        if r["time"] >= duration:
            raise InputError(w, f"{key}.time", f"{r['time']} s is not before the end ({duration} s)")
        if not initial.grasp[r["arm"] - 1] and has_initial and start_from is None:
            raise InputError(w, f"{key}.arm", f"arm {r['arm']} does not hold the target at t = 0")
        releases.append(ReleaseSpec(**r))

    cap_raw = _table(w, kname("capture"), raw.get("capture", {}), {
        "arm": lambda k, v: _arm(w, k, v),
        "enabled": lambda k, v: _flag(w, k, v),
        "point": lambda k, v: v,
    })
    cap_arm = cap_raw.get("arm", 2)
    cap_point = point(f"{kname('capture')}.point", cap_raw["point"], cap_arm) if "point" in cap_raw else None
    cap = CaptureSpec(arm=cap_arm, enabled=cap_raw.get("enabled", False), point_T=cap_point)
    if cap.enabled and initial.grasp[cap.arm - 1] and has_initial and start_from is None:
        raise InputError(w, f"{kname('capture')}.enabled", f"arm {cap.arm} already holds the target at t = 0")

    solver_raw = raw.get("solver", {})
    engine_keys = owned_solver_keys()
    solver = SolverSpec(**_table(w, kname("solver"), {k: x for k, x in solver_raw.items() if k not in engine_keys}
                                if isinstance(solver_raw, Mapping) else solver_raw, {
        "control_period": lambda k, v: _number(w, k, v, 0.0, lo_open=True, hi=0.1),
        "output_period": lambda k, v: _number(w, k, v, 0.0, lo_open=True),
        **{k: None for k in engine_keys},  # named in the error for an unknown key
    }))
    ratio = solver.output_period / solver.control_period
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise InputError(w, kname("solver") + ".output_period", "must be a whole multiple of solver.control_period")
    steps = duration / solver.control_period
    if abs(steps - round(steps)) > 1e-6 * max(1.0, steps):
        raise InputError(w, kname("duration"), f"{duration} s is not a whole number of control periods "
                         f"({solver.control_period} s)")

    engines = parse_engine_settings(raw, {k: x for k, x in solver_raw.items() if k in engine_keys}, w, kname)

    # a short variant that keeps the full programme is the full run cut at its duration
    cut = is_short and "segment" not in short_keys
    segments = parse_segments(w, kname("segment"), raw.get("segment", []), math.inf if cut else duration, point)
    if segments and controller.kind != "programme":
        raise InputError(w, kname("controller") + ".kind", f"must be \"programme\" for a case with segments, "
                         f"got {controller.kind!r}")
    if controller.kind == "programme" and not segments:
        raise InputError(w, kname("segment"), "a \"programme\" controller needs at least one [[segment]]")
    if segments and has_initial and start_from is None:
        check_programme(w, kname("segment"), segments, initial.grasp)

    compare = _compare(w, kname("compare"), raw.get("compare", {}))
    for c in compare:
        if c.window is not None and c.window[1] > duration + 1e-9:
            raise InputError(w, f"{kname('compare')}.{c.observable}.window",
                             f"ends at {c.window[1]} s, after the run ({duration} s)")

    return Case(
        name=name, description=_text(w, "description", raw["description"]), duration=duration,
        short_duration=duration, initial=initial, orbit=orbit_spec.enabled,
        controller=controller, releases=tuple(sorted(releases, key=lambda r: r.time)),
        capture=cap, solver=solver, params=params, path=where,
        file_hash=digest, raw=raw, orbit_spec=orbit_spec, segments=segments, compare=compare,
        start_from=start_from, has_initial=has_initial, is_short=is_short, engine_settings=engines,
    )


def _controller(w: str, key: str, v: Any) -> ControllerSpec:
    ctrl = _table(w, key, v, {
        "kind": lambda k, x: _choice(w, k, x, ("none", "constant", "programme")),
        "motor_torques": lambda k, x: _vector(w, k, x, 6),
        "base_torque": lambda k, x: _number(w, k, x),
        "ramp_time": lambda k, x: _number(w, k, x, 0.0),
        "sine_amplitude": lambda k, x: _vector(w, k, x, 6),
        "sine_frequency_hz": lambda k, x: _number(w, k, x, 0.0),
        "feedback": lambda k, x: _choice(w, k, x, ("measured", "kinematic")),
        "rate_filter_hz": lambda k, x: _number(w, k, x, 0.0),
        "gains": lambda k, x: _text(w, k, x),
        "base": lambda k, x: BaseGains(**_table(w, k, x, {
            "kp": lambda kk, y: _number(w, kk, y, 0.0),
            "kd": lambda kk, y: _number(w, kk, y, 0.0)})),
        "arm1": lambda k, x: _arm_gains(w, k, x),
        "arm2": lambda k, x: _arm_gains(w, k, x),
    })
    spec = ControllerSpec(**ctrl)
    kind = spec.kind
    if kind != "constant":
        for k in ("motor_torques", "base_torque", "ramp_time", "sine_amplitude", "sine_frequency_hz"):
            if k in ctrl:
                raise InputError(w, f"{key}.{k}", f"only for kind = \"constant\" (kind is {kind!r})")
    if kind != "programme":
        for k in ("feedback", "rate_filter_hz", "gains", "base", "arm1", "arm2"):
            if k in ctrl:
                raise InputError(w, f"{key}.{k}", f"only for kind = \"programme\" (kind is {kind!r})")
    else:
        for k in ("gains", "base", "arm1", "arm2"):
            if k not in ctrl:
                raise InputError(w, f"{key}.{k}", "missing (required for kind = \"programme\")")
    return spec


def _arm_gains(w: str, key: str, v: Any) -> ArmGains:
    g = _table(w, key, v, {"kp": lambda k, x: _vector(w, k, x, 3, 0.0),
                           "kd": lambda k, x: _vector(w, k, x, 3, 0.0)})
    _require(w, key, g, ("kp", "kd"))
    return ArmGains(**g)


def _compare(w: str, key: str, v: Any) -> tuple[CompareSpec, ...]:
    if not isinstance(v, Mapping):
        raise InputError(w, key, "must be a table of observable tables")
    out = []
    for obs, item in v.items():
        k = f"{key}.{obs}"
        if obs not in OBSERVABLE_NAMES or obs == "time":
            raise InputError(w, k, "not an observable (docs/observables.md, rsmcheck.core.observables)")
        c = _table(w, k, item, {
            "tolerance": lambda kk, x: _number(w, kk, x, 0.0, lo_open=True),
            "why": lambda kk, x: _text(w, kk, x),
            "metric": lambda kk, x: _choice(w, kk, x, METRICS),
            "window": lambda kk, x: _window(w, kk, x),
            "allowance": lambda kk, x: _number(w, kk, x, 0.0),
            "errors": lambda kk, x: _errors(w, kk, x),
            "engine_errors": lambda kk, x: _errors(w, kk, x, pair=False),
        })
        _require(w, k, c, ("tolerance", "why"))
        if "engine_errors" in c and "errors" not in c:
            raise InputError(w, f"{k}.engine_errors", "only with a budget (allowance and errors)")
        for e in set(c.get("engine_errors", {})) & set(c.get("errors", {})):
            raise InputError(w, f"{k}.engine_errors.{e}", "is in errors already: the stated pair's own errors")
        if ("allowance" in c) != ("errors" in c):
            given, other = ("allowance", "errors") if "allowance" in c else ("errors", "allowance")
            raise InputError(w, f"{k}.{other}", f"missing (required with {given}: a budget has both parts)")
        metric = c.get("metric", "max_abs")
        if metric == "growth" and "window" not in c:
            raise InputError(w, f"{k}.window", "required with metric \"growth\" (the fit interval)")
        if metric == "final" and "window" in c:
            raise InputError(w, f"{k}.window", "not with metric \"final\" (the last sample)")
        out.append(CompareSpec(observable=obs, **c))
    return tuple(out)


def _errors(w: str, key: str, v: Any, pair: bool = True) -> dict[str, float]:
    """{engine: integration error ≥ 0} of registered engines: of a row's budget, the two it
    was measured on (`pair`: a misspelt name would silently change which pair the row
    states); else (`engine_errors`) any others."""
    if not isinstance(v, Mapping) or (len(v) != 2 if pair else not v):
        raise InputError(w, key, "must be a table of the two engines the budget was measured on, "
                         "e.g. { reference = 7.0e-10, exudyn = 1.8e-09 }" if pair else
                         "must be a table of engines and their own errors, e.g. { mujoco = 1.0e-06 }")
    known = set(plugins()) | set(broken_plugins())
    for e in v:
        if e not in known:
            raise InputError(w, f"{key}.{e}", f"not a registered engine (registered: {', '.join(sorted(known))})")
    return {str(e): _number(w, f"{key}.{e}", x, 0.0) for e, x in v.items()}


def _window(w: str, key: str, v: Any) -> tuple[float, float]:
    """[t0, t1] with 0 ≤ t0 < t1 [s] (checked against the duration where the case is built)."""
    if not isinstance(v, list) or len(v) != 2:
        raise InputError(w, key, "must be a list [t0, t1] of two times in s")
    t0 = _number(w, f"{key}[0]", v[0], 0.0)
    t1 = _number(w, f"{key}[1]", v[1], 0.0)
    if not t1 > t0:
        raise InputError(w, key, f"must have t0 < t1, got [{t0}, {t1}]")
    return (t0, t1)


def _held_points(where: str, key: str, v: Any, point) -> tuple[tuple[float, float], tuple[float, float]]:
    if not isinstance(v, list) or len(v) != 2:
        raise InputError(where, key, "must be a list of two points [[x, y], [x, y]]")
    return (point(f"{key}[0]", v[0], 1), point(f"{key}[1]", v[1], 2))


# ---------------------------------------------------------------------------------------
# a case's configuration, held still: what the linearisations of both engines start from
# ---------------------------------------------------------------------------------------
def at_rest(case: Case) -> Case:
    """`case` in its initial configuration with zero base and joint rates."""
    ini = replace(case.initial, base_rate=(0.0, 0.0, 0.0), joint_rates=(0.0,) * 6)
    return replace(case, initial=ini)


def undamped(case: Case, params: Params | None = None) -> Case:
    """`case` (with `params` instead of its own, if given) without link damping (ζ = 0) and
    motor damping (C_m = 0): the undamped frequencies both engines are compared on."""
    params = params or case.params
    params = replace(params, link=replace(params.link, damping_ratio=0.0),
                     motor=replace(params.motor, damping=0.0))
    return replace(case, params=params)


def without_orbit(case: Case) -> Case:
    """`case` with the orbit (field, co-moving frame) switched off."""
    return replace(case, orbit=False, orbit_spec=OrbitSpec())
