"""Phase chaining: end states, starting a case from another's end state, the mission.

Every run of a case stores its end state next to its HDF5 file, `DIR/CASE.end.json`
(`DIR/CASE.short.end.json` for the --short variant), one entry per engine:

* ``rigid`` — the common part every engine can start from: base pose and rates, joint
  angles and rates (both ψ_J between end sections and θ_J between link frames,
  docs/physics.md §3.3), motor angles and rates, target pose and rates, grasp state, held points (target
  frame about the COM), orbit state of the co-moving point O, propellant used, system
  COM position and velocity (relative to O), end time.  It is taken from the engine's
  `Sensors` and observables, so it means the same for every engine.
* ``exact`` — the engine's own full state, under the engine's name (the reference: its
  ODE state vector with the modal amplitudes, the link bases, grasp flags and held
  points; Exudyn: its absolute ODE2 coordinates and velocities with the beam deformation,
  bistop data, grasp flags, held points and bases).  An engine restores it when it can
  (same model size); otherwise it starts from the rigid part with undeformed links (a
  reference with another number of modes, Exudyn with another element count).  Engines
  give and take their exact state through `export_state() -> dict` and
  `import_state(dict) -> None` (rsmcheck.core.engine.Engine); this module never looks inside.

A case with `start_from = "P"` starts from the end state of P written by the same engine
(and the same variant: full or --short) — with --short not the first phase of the short
mission (p2: p1's short variant does not set it up), which runs from its own [initial].
When it enters an orbit the previous phase did not have (p3 → p4), O is placed on the
case's circular orbit at the system COM (`rsmcheck.driver.initial.place_on_orbit`), the same shift
for the rigid and the exact state.

The `mission` case runs its phases in sequence in memory, each phase starting from the
previous one's end state, and writes one run file with continuous time, every phase and
segment boundary in `phases`, and the events of all phases.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from rsmcheck.core.cases import Case, list_cases, load_case, phase_cases
from rsmcheck.core.engine import Inputs
from rsmcheck.core.errors import InputError
from rsmcheck.core.geometry import rot
from rsmcheck.driver.initial import StartState
from rsmcheck.core.observables import NAMES
from rsmcheck.core.plugins import make_engine
from rsmcheck.driver.runner import run
from rsmcheck.core.store import EngineRun, Event, Phase, write_run, write_text

FORMAT = "rsmcheck-endstate"
FORMAT_VERSION = 3
RIGID_KEYS = ("base_pose", "base_rate", "joint_angles", "joint_rates", "joint_frame_angles",
              "joint_frame_rates", "motor_angles", "motor_rates",
              "target_pose", "target_rate", "grasp", "held_points", "orbit_r", "orbit_v", "m_used",
              "com_I", "com_vel_I", "t_end")


# ---------------------------------------------------------------------------------------
# export
# ---------------------------------------------------------------------------------------
def rigid_state(engine, params) -> dict[str, Any]:
    """The common rigid part of the engine's current state (from its sensors)."""
    s = engine.sensors()
    obs = engine.observe(Inputs())
    held = np.zeros((2, 2))
    for k in range(2):
        # the held point: where the end effector is on the target (≡ ρ_G up to φ_T)
        held[k] = rot(s.target_pose_I[2]).T @ (s.ee_pos_I[k] - s.target_pose_I[:2])
    com_I = s.base_pose_I[:2] + rot(s.base_pose_I[2]) @ s.com_pos_B
    m_total0 = params.base.mass + params.target.mass + 6 * params.link.mass
    mass = float(s.system_mass)
    return {
        "base_pose": s.base_pose_I, "base_rate": s.base_rate_I, "joint_angles": s.joint_angles,
        "joint_rates": s.joint_rates, "joint_frame_angles": s.joint_frame_angles,
        "joint_frame_rates": s.joint_frame_rates, "motor_angles": s.motor_angles, "motor_rates": s.motor_rates,
        "target_pose": s.target_pose_I, "target_rate": s.target_rate_I,
        "grasp": [int(g) for g in s.grasp_state], "held_points": held,
        "orbit_r": s.orbit_r_I, "orbit_v": s.orbit_v_I, "m_used": m_total0 - mass,
        "com_I": com_I, "com_vel_I": np.asarray(obs["momentum_I"][:2], float) / mass,
        "t_end": float(s.time),
    }


def exact_state(engine) -> dict[str, Any] | None:
    """The engine's own full state (`export_state`), or None if it has no way to give it."""
    hook = getattr(engine, "export_state", None)
    return hook() if callable(hook) else None


def end_state(engine, params) -> dict[str, Any]:
    return {"rigid": rigid_state(engine, params), "exact": exact_state(engine)}


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, (np.floating, float)):
        return float(v)
    if isinstance(v, (np.integer, int)) and not isinstance(v, bool):
        return int(v)
    return v


def end_state_path(out_dir: str | Path, case_name: str, short: bool) -> Path:
    return Path(out_dir) / f"{case_name}{'.short' if short else ''}.end.json"


def save_end_states(path: str | Path, case: Case, short: bool, states: Mapping[str, dict]) -> Path:
    """Write the end states of one run (engine name → end_state) atomically."""
    path = Path(path)
    doc = {"format": FORMAT, "format_version": FORMAT_VERSION, "case": case.name,
           "case_hash": case.file_hash, "param_hash": case.params.digest(), "short": bool(short),
           "engines": _jsonable(dict(states))}
    return write_text(path, json.dumps(doc, indent=1))


def load_end_state(path: str | Path, engine: str, short: bool, where: str) -> tuple[dict, str]:
    """(end state of `engine`, file hash) from a stored end-state file; InputError if the
    file is missing, malformed, of the other variant or without that engine."""
    path = Path(path)
    if not path.is_file():
        raise InputError(where, "start_from", f"no stored end state {path} (run that case first "
                         f"with the same --out directory{' and --short' if short else ''})")
    data = path.read_bytes()
    try:
        doc = json.loads(data)
    except json.JSONDecodeError as exc:
        raise InputError(str(path), "json", str(exc)) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("format_version") != FORMAT_VERSION:
        raise InputError(str(path), "format", "not an rsmcheck end-state file of this version")
    if bool(doc.get("short")) != bool(short):
        raise InputError(str(path), "short", f"stored by a {'--short' if doc.get('short') else 'full'} run; "
                         f"this run is {'--short' if short else 'full'}")
    engines = doc.get("engines", {})
    if engine not in engines:
        raise InputError(str(path), "engines", f"no end state of engine '{engine}' "
                         f"(has: {', '.join(engines) or 'none'})")
    st = engines[engine]
    missing = [k for k in RIGID_KEYS if k not in st.get("rigid", {})]
    if missing:
        raise InputError(str(path), f"engines.{engine}.rigid", f"missing {', '.join(missing)}")
    return st, hashlib.sha256(data).hexdigest()


# ---------------------------------------------------------------------------------------
# starting a case from an end state
# ---------------------------------------------------------------------------------------
def start_of(state: Mapping[str, Any]) -> StartState:
    """The `StartState` a run continues from, out of an `end_state` (stored or in memory)."""
    return StartState(rigid=state["rigid"], exact=state.get("exact"))


# ---------------------------------------------------------------------------------------
# running cases
# ---------------------------------------------------------------------------------------
ProgressFactory = Callable[[str, str], Any]
#: a phase's variant → the engine options of that phase
PhaseOptions = Callable[[Case], Mapping[str, Any]]


def run_case(name_or_case: str | Case, engines: Sequence[str], short: bool, out_dir: str | Path,
             from_dir: str | Path | None = None, progress: ProgressFactory | None = None,
             chain: bool | None = None, options: Mapping[str, Mapping[str, Any]] | None = None) -> Path:
    """Run a case (or the mission) with each engine; write DIR/CASE.h5 and its end states.

    A case with `start_from` starts from the stored end state of that case in `from_dir`
    (default: `out_dir`) when `chain` is True, or when `chain` is None and that file
    exists; otherwise from its own [initial] (InputError if it has none).  `options`:
    engine name → keyword options of its constructor.
    """
    case = name_or_case if isinstance(name_or_case, Case) else load_case(name_or_case)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    options = options or {}
    if case.phases:
        return run_mission(case.variant(short), engines, short, out, progress, options)
    variant = case.variant(short)
    runs: dict[str, EngineRun] = {}
    states: dict[str, dict] = {}
    extra: dict[str, Any] = {"short": bool(short)}
    for name in engines:
        start = None
        if variant.start_from is not None:
            src = end_state_path(from_dir or out, variant.start_from, short)
            use = chain if chain is not None else use_stored_start(variant, src, short)
            if use:
                st, digest = load_end_state(src, name, short, variant.path)
                start = start_of(st)
                extra.update(start_from=variant.start_from, start_state_file=str(src),
                             start_state_hash=digest)
            else:
                extra.update(start_from="[initial] (stand-alone)")
        engine = make_engine(name, variant, start, **dict(options.get(name, {})))
        runs[name] = run(engine, variant, variant.duration, progress(name, case.name) if progress else None)
        states[name] = end_state(engine, variant.params)
    path = out / f"{case.name}.h5"
    write_run(path, runs, case_name=case.name, case_hash=case.file_hash, param_hash=case.params.digest(),
              extra_attrs=extra)
    save_end_states(end_state_path(out, case.name, short), case, short, states)
    return path


def starts_short_sequence(name: str) -> bool:
    """True when the --short variant of a sequence case (the mission) starts at phase `name`
    although its full sequence does not: the short predecessor does not end where this phase
    begins (p1's short variant does not bring the target into arm 2's reach), so with --short
    this phase runs from its own [initial], as in the short mission."""
    for path in list_cases():
        seq = load_case(path)
        if seq.phases and seq.variant(True).phases[:1] == (name,) and seq.phases[0] != name:
            return True
    return False


def use_stored_start(variant: Case, src: Path, short: bool) -> bool:
    """Default of `run_case(chain=None)`: start from the stored end state `src` of the
    predecessor when it exists — except a phase that starts a short sequence, with --short —
    and always when the case has no [initial] of its own."""
    if not variant.has_initial:
        return True
    return src.is_file() and not (short and starts_short_sequence(variant.name))


def run_mission(mission: Case, engines: Sequence[str], short: bool, out: Path,
                progress: ProgressFactory | None = None,
                options: Mapping[str, Mapping[str, Any]] | None = None,
                phase_runs: dict[str, dict[str, EngineRun]] | None = None,
                phase_options: Mapping[str, PhaseOptions] | None = None) -> Path:
    """All phases of `mission` (the variant to run) in sequence, each from the previous
    one's end state (each phase's short variant with `short`); one run file.  With
    `phase_runs`, each phase's own run is also put there (phase name → engine → run);
    `options` and `phase_options`: engine → what `fly` takes."""
    runs: dict[str, EngineRun] = {}
    states: dict[str, dict] = {}
    for name in engines:
        pieces, states[name] = fly(mission, name, short, progress, (options or {}).get(name, {}),
                                   (phase_options or {}).get(name))
        runs[name] = _concatenate(name, pieces)
        if phase_runs is not None:
            for (_, r), phase in zip(pieces, mission.phases):
                phase_runs.setdefault(phase, {})[name] = r
    path = out / f"{mission.name}.h5"
    write_run(path, runs, case_name=mission.name, case_hash=mission.file_hash,
              param_hash=mission.params.digest(),
              extra_attrs={"short": bool(short), "mission_phases": ",".join(mission.phases)})
    save_end_states(end_state_path(out, mission.name, short), mission, short, states)
    return path


def fly(mission: Case, engine_name: str, short: bool, progress: ProgressFactory | None = None,
        options: Mapping[str, Any] | None = None,
        phase_options: PhaseOptions | None = None) -> tuple[list[tuple[float, EngineRun]], dict]:
    """One engine through the phases of `mission` (the variant to run): [(start time in the
    mission, the phase's run)], and the end state of the last phase.  The engine of every
    phase takes `options`, and those `phase_options(phase variant)` gives for that phase
    (e.g. a finer run of each phase at its own settings: `rsmcheck budget`)."""
    pieces: list[tuple[float, EngineRun]] = []
    state = None
    offset = 0.0
    for ph in phase_cases(mission, short):
        opts = {**dict(options or {}), **(dict(phase_options(ph)) if phase_options is not None else {})}
        engine = make_engine(engine_name, ph, None if state is None else start_of(state), **opts)
        r = run(engine, ph, ph.duration, progress(engine_name, ph.name) if progress else None)
        pieces.append((offset, r))
        state = end_state(engine, ph.params)
        offset += ph.duration
    return pieces, state


#: the solver entries that count (each phase's engine counts from zero): summed over the
#: phases of a chained run, as are the wall times; the other entries are settings, the first
#: phase's
COUNTS = ("steps", "rejected_steps", "quiet_steps", "samples", "newton_iterations", "newton_retries", "jacobians",
          "restarts")


def _concatenate(engine: str, pieces: list[tuple[float, EngineRun]]) -> EngineRun:
    obs = {}
    for key in NAMES:
        parts = []
        for off, r in pieces:
            a = np.asarray(r.observables[key], float)
            parts.append(a + off if key == "time" else a)
        obs[key] = np.concatenate(parts)
    events = [Event(e.time + off, e.kind, e.detail) for off, r in pieces for e in r.events]
    phases = [Phase(p.name, p.t_start + off, p.t_end + off) for off, r in pieces for p in r.phases]
    solver: dict[str, Any] = {}
    for off, r in pieces:
        for k, v in r.solver.items():
            if (k in COUNTS or k.startswith("wall_")) and k in solver:
                solver[k] += v
            else:
                solver.setdefault(k, v)
    return EngineRun(engine=engine, observables=obs, events=events, phases=phases, solver=solver,
                     versions=pieces[0][1].versions)
