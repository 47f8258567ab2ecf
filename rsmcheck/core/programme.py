"""The motion programme of a case file: its [[segment]] tables, each a span of time with
what every arm, the target and the base do (docs/cases.md §1), parsed into `Segment`s
and checked against the grasp they start from.  Errors are `InputError(file, key,
reason)`, one line on the command line (exit 2)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping

from rsmcheck.core.errors import InputError
from rsmcheck.core.schema import arm as _arm, arms as _arms, choice as _choice, flag as _flag
from rsmcheck.core.schema import number as _number, require as _require, table as _table, text as _text
from rsmcheck.core.schema import integer as _integer, vector as _vector

ARM_MODES = ("hold", "freeze", "move", "approach", "carry", "off", "torque")
TARGET_MODES = ("move", "push", "com_align")
BASE_MODES = ("hold", "freeze", "angle", "retrograde", "off")

@dataclass(frozen=True)
class ArmCommand:
    """What one arm does during a segment (see rsmcheck.driver.controllers)."""

    mode: str = "hold"
    to: tuple[float, float, float] | None = None  # move: x, y [m], φ [deg], base frame
    time: float | None = None  # duration of the move [s] (default: the segment's)
    point_T: tuple[float, float] | None = None  # approach: target frame about the COM
    phi_deg: float | None = None  # approach: final terminal-link attitude
    torques: tuple[float, float, float] = (0.0, 0.0, 0.0)  # torque: open loop [N·m]


@dataclass(frozen=True)
class TargetCommand:
    """A closed-chain (or single-arm) move of the target by the arms in mode "carry"."""

    mode: str = "move"
    to: tuple[float, float, float] | None = None  # move: x, y [m], θ [deg], base frame
    by: tuple[float, float] = (0.0, 0.0)  # push: displacement [m], base frame
    time: float | None = None
    tolerance: float = 1e-3  # com_align: |y_COM| goal [m]
    step_time: float = 20.0  # com_align: duration of one move [s]
    settle_time: float = 10.0  # com_align: wait after a move [s]
    max_iterations: int = 8


@dataclass(frozen=True)
class CaptureCommand:
    arm: int
    point_T: tuple[float, float]  # target frame about the COM


@dataclass(frozen=True)
class Segment:
    name: str
    duration: float
    until: str = ""
    settle: float = 0.0
    thrust: bool = False
    base: str = "hold"
    base_angle_deg: float = 0.0
    release: tuple[int, ...] = ()
    capture: CaptureCommand | None = None
    arm1: ArmCommand = ArmCommand()
    arm2: ArmCommand = ArmCommand()
    target: TargetCommand | None = None
    control_period: float | None = None  # None: the case's [solver] control_period



def parse_segments(w: str, key: str, v: Any, duration: float, point) -> tuple[Segment, ...]:
    if not isinstance(v, list):
        raise InputError(w, key, "must be an array of tables ([[segment]])")
    out = []
    names = set()
    planned = 0.0
    for n, item in enumerate(v):
        sk = f"{key}[{n}]"
        s = _table(w, sk, item, {
            "name": lambda k, x: _text(w, k, x),
            "duration": lambda k, x: _number(w, k, x, 0.0, lo_open=True),
            "until": lambda k, x: _choice(w, k, x, ("capture",)),
            "settle": lambda k, x: _number(w, k, x, 0.0),
            "thrust": lambda k, x: _flag(w, k, x),
            "base": lambda k, x: _choice(w, k, x, BASE_MODES),
            "base_angle_deg": lambda k, x: _number(w, k, x),
            "release": lambda k, x: _arms(w, k, x),
            "capture": lambda k, x: x,
            "arm1": lambda k, x: x,
            "arm2": lambda k, x: x,
            "target": lambda k, x: x,
            "control_period": lambda k, x: _number(w, k, x, 0.0, lo_open=True, hi=0.1),
        })
        _require(w, sk, s, ("name", "duration"))
        if "control_period" in s and s["control_period"] > s["duration"]:
            raise InputError(w, f"{sk}.control_period", f"{s['control_period']} s is longer than the "
                             f"segment ({s['duration']} s)")
        if s["name"] in names:
            raise InputError(w, f"{sk}.name", f"'{s['name']}' is used by an earlier segment")
        names.add(s["name"])
        if "base_angle_deg" in s and s.get("base") != "angle":
            raise InputError(w, f"{sk}.base_angle_deg", "only with base = \"angle\"")
        cap = None
        if "capture" in s:
            c = _table(w, f"{sk}.capture", s["capture"], {
                "arm": lambda k, x: _arm(w, k, x), "point": lambda k, x: x})
            _require(w, f"{sk}.capture", c, ("arm",))
            arm = c["arm"]
            pt = point(f"{sk}.capture.point", c["point"], arm) if "point" in c else point(
                f"{sk}.capture.point", f"grasp{arm}", arm)
            cap = CaptureCommand(arm=arm, point_T=pt)
        if s.get("until") == "capture" and cap is None:
            raise InputError(w, f"{sk}.until", "\"capture\" needs a capture in this segment")
        if "settle" in s and s.get("until") is None:
            raise InputError(w, f"{sk}.settle", "only with until")
        if s.get("settle", 0.0) >= s["duration"]:
            raise InputError(w, f"{sk}.settle", f"{s['settle']} s is not shorter than the segment "
                             f"({s['duration']} s)")
        arms = []
        for n_arm, a in enumerate(("arm1", "arm2")):
            cmd = _arm_command(w, f"{sk}.{a}", s.get(a, {"mode": "hold"}), s["duration"], point)
            if cmd.mode == "approach" and cmd.point_T is None:
                if cap is None or cap.arm != n_arm + 1:
                    raise InputError(w, f"{sk}.{a}.point", "missing (required for mode \"approach\" "
                                     "unless the segment captures with this arm)")
                cmd = replace(cmd, point_T=cap.point_T)
            arms.append(cmd)
        target = _target_command(w, f"{sk}.target", s["target"], s["duration"]) if "target" in s else None
        carrying = [a.mode == "carry" for a in arms]
        if target is not None and not any(carrying):
            raise InputError(w, f"{sk}.target", "no arm is in mode \"carry\" to move the target")
        if any(carrying) and target is None:
            a = "arm1" if carrying[0] else "arm2"
            raise InputError(w, f"{sk}.{a}.mode", "\"carry\" needs a target command in the segment")
        planned += s["duration"]
        seg = Segment(name=s["name"], duration=s["duration"], until=s.get("until", ""),
                      settle=s.get("settle", 0.0), thrust=s.get("thrust", False),
                      base=s.get("base", "hold"), base_angle_deg=s.get("base_angle_deg", 0.0),
                      release=s.get("release", ()), capture=cap, arm1=arms[0], arm2=arms[1],
                      target=target, control_period=s.get("control_period"))
        out.append(seg)
    if out and planned > duration * (1 + 1e-12):
        raise InputError(w, key, f"segments last {planned:g} s, longer than the case ({duration:g} s)")
    return tuple(out)


def _arm_command(w: str, key: str, v: Any, seg_duration: float, point) -> ArmCommand:
    c = _table(w, key, v, {
        "mode": lambda k, x: _choice(w, k, x, ARM_MODES),
        "to": lambda k, x: _vector(w, k, x, 3),
        "time": lambda k, x: _number(w, k, x, 0.0, lo_open=True),
        "point": lambda k, x: x,
        "phi_deg": lambda k, x: _number(w, k, x),
        "torques": lambda k, x: _vector(w, k, x, 3),
    })
    mode = _mode_keys(w, key, c, {"hold": (), "freeze": (), "off": (), "carry": (), "move": ("to", "time"),
                                  "approach": ("point", "phi_deg", "time"), "torque": ("torques",)},
                      {"move": "to", "torque": "torques"})
    if c.get("time", 0.0) > seg_duration * (1 + 1e-12):
        raise InputError(w, f"{key}.time", f"{c['time']} s exceeds the segment ({seg_duration} s)")
    return ArmCommand(mode=mode, to=c.get("to"), time=c.get("time"),
                      point_T=point(f"{key}.point", c["point"], None) if "point" in c else None,
                      phi_deg=c.get("phi_deg"), torques=c.get("torques", (0.0, 0.0, 0.0)))


def _mode_keys(w: str, key: str, c: Mapping[str, Any], allowed: Mapping[str, tuple[str, ...]],
               required: Mapping[str, str]) -> str:
    """The `mode` of a command table, after checking that every other key is used by that
    mode (`allowed`) and that the one key a mode cannot do without is there (`required`)."""
    _require(w, key, c, ("mode",))
    mode = c["mode"]
    for k in c:
        if k != "mode" and k not in allowed[mode]:
            raise InputError(w, f"{key}.{k}", f"not used by mode {mode!r}")
    need = required.get(mode)
    if need is not None and need not in c:
        raise InputError(w, f"{key}.{need}", f"missing (required for mode \"{mode}\")")
    return mode


def _target_command(w: str, key: str, v: Any, seg_duration: float) -> TargetCommand:
    c = _table(w, key, v, {
        "mode": lambda k, x: _choice(w, k, x, TARGET_MODES),
        "to": lambda k, x: _vector(w, k, x, 3),
        "by": lambda k, x: _vector(w, k, x, 2),
        "time": lambda k, x: _number(w, k, x, 0.0, lo_open=True),
        "tolerance": lambda k, x: _number(w, k, x, 0.0, lo_open=True),
        "step_time": lambda k, x: _number(w, k, x, 0.0, lo_open=True),
        "settle_time": lambda k, x: _number(w, k, x, 0.0),
        "max_iterations": lambda k, x: _integer(w, k, x, 1, 100),
    })
    mode = _mode_keys(w, key, c, {"move": ("to", "time"), "push": ("by", "time"),
                                  "com_align": ("tolerance", "step_time", "settle_time", "max_iterations")},
                      {"move": "to", "push": "by"})
    if mode != "push" and c.get("time", 0.0) > seg_duration * (1 + 1e-12):
        # (a push may outlast its segment: the target is released while it moves)
        raise InputError(w, f"{key}.time", f"{c['time']} s exceeds the segment ({seg_duration} s)")
    if mode == "com_align" and c.get("step_time", 20.0) + c.get("settle_time", 10.0) > seg_duration:
        raise InputError(w, f"{key}.step_time", "one iteration (step_time + settle_time) does not fit "
                         f"in the segment ({seg_duration} s)")
    c.pop("mode")
    return TargetCommand(mode=mode, **c)


def check_programme(w: str, key: str, segments: tuple[Segment, ...], grasp: tuple[int, int]) -> None:
    """Walk the planned grasp states through the segments (captures assumed to succeed)."""
    held = list(grasp)
    for n, seg in enumerate(segments):
        sk = f"{key}[{n}]"
        for arm in seg.release:
            if not held[arm - 1]:
                raise InputError(w, f"{sk}.release", f"arm {arm} does not hold the target at the "
                                 f"start of segment '{seg.name}'")
            held[arm - 1] = 0
        if seg.capture is not None:
            if held[seg.capture.arm - 1]:
                raise InputError(w, f"{sk}.capture.arm", f"arm {seg.capture.arm} already holds the "
                                 f"target in segment '{seg.name}'")
            if not any(held):
                raise InputError(w, f"{sk}.capture.arm", "nothing holds the target to capture it from "
                                 f"in segment '{seg.name}'")
        for a, cmd in ((1, seg.arm1), (2, seg.arm2)):
            if cmd.mode == "carry" and not held[a - 1]:
                raise InputError(w, f"{sk}.arm{a}.mode", f"arm {a} cannot carry the target: it does "
                                 f"not hold it in segment '{seg.name}'")
            if cmd.mode == "approach" and held[a - 1]:
                raise InputError(w, f"{sk}.arm{a}.mode", f"arm {a} already holds the target in "
                                 f"segment '{seg.name}'")
        if seg.target is not None:
            for a, cmd in ((1, seg.arm1), (2, seg.arm2)):
                if held[a - 1] and cmd.mode != "carry":
                    raise InputError(w, f"{sk}.arm{a}.mode", f"arm {a} holds the target while the "
                                     f"target moves: it must be \"carry\", got {cmd.mode!r}")
        if seg.capture is not None:
            held[seg.capture.arm - 1] = 1
