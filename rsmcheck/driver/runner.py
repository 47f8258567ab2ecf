"""The sampled-data loop that drives any engine through a case (docs/physics.md §6).

At every control sample t_k = k·Δt:
  1. scheduled releases due at t_k are applied;
  2. a programme case enters its next segment when the current one is over: the
     segment's releases are applied, its capture (arm and designated point) is armed, the
     controller takes its new references;
  3. if a capture is armed, the two IF conditions (Sect. 2: relative position and
     velocity of the end effector to the designated capture point below thresholds) are
     evaluated, and the grasp is switched on when both hold (a segment with
     until = "capture" then ends after its `settle` time);
  4. the wrist bistop contact state is logged (ψ beyond ±ψ_lim);
  5. the controller computes the inputs, held until t_{k+1};
  6. every `output_every` samples the observables are recorded;
  7. the engine integrates to t_{k+1}.
Every engine gets the same loop; only step 7 and the switching are engine code.

`capture_gap_B` is computed here from the engine's sensors, for the capture currently
armed (arm and designated point change from segment to segment, e.g. the regrasp of p2),
so both engines report the gap to the same point by the same formula.
"""

from __future__ import annotations

import math
import sys
import time as wallclock
from typing import Callable

import numpy as np

from rsmcheck.core.cases import Case
from rsmcheck.core.engine import Engine, Inputs, Sensors
from rsmcheck.core.errors import InputError, SimulationDiverged
from rsmcheck.core.observables import NAMES
from rsmcheck.core.store import EngineRun, Event, Phase
from rsmcheck.driver import control_kernels
from rsmcheck.driver.controllers import ProgrammeController, make_controller

Progress = Callable[[str, float, float], None]

#: the per-sample calls whose wall time a run reports (solver settings `wall_<part>_s`;
#: `advance` includes the engine's own `wall_integrator_s`, the compiled or C++ integrator)
SPLIT = ("sensors", "controller", "advance", "observe")


def capture_point(s: Sensors, rho_T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inertial position and velocity of the target point ρ_T (target frame, about the COM):
    p = r_T + A(θ_T) ρ_T, v = ṙ_T + θ̇_T e_z × A(θ_T) ρ_T (`control_kernels.capture_point`)."""
    rho = np.asarray(rho_T, float)
    px, py, vx, vy = control_kernels.capture_point(s.target_pose_I, s.target_rate_I, float(rho[0]), float(rho[1]))
    return np.array([px, py]), np.array([vx, vy])


def if_conditions(s: Sensors, arm: int, rho_T: np.ndarray, distance: float, speed: float) -> tuple[bool, float, float]:
    """Both IF conditions of capture for `arm` (Sect. 2): |r_EE − p| < `distance` and
    |ṙ_EE − v| < `speed` at the target point ρ_T (`capture_point`), with the measured gap
    and relative speed (`control_kernels.supervise`)."""
    out = np.empty(4)
    control_kernels.supervise(s.target_pose_I, s.target_rate_I, s.ee_pos_I, s.ee_vel_I, s.wrist_angles,
                              s.grasp_state, arm, np.asarray(rho_T, float), math.inf, out)
    gap, rel = float(out[2]), float(out[3])
    return gap < distance and rel < speed, gap, rel


def capture_gap_B(s: Sensors, arm: int, rho_T: np.ndarray) -> np.ndarray:
    """End effector `arm` minus the target point ρ_T, base axes (the observable of Fig. 10):
    A(θ_B)ᵀ (r_EE − p) (`control_kernels.capture_gap`)."""
    out = np.empty(2)
    control_kernels.capture_gap(s.base_pose_I, s.target_pose_I, s.ee_pos_I, arm, np.asarray(rho_T, float), out)
    return out


def terminal_progress(engine: str, case: str) -> Progress | None:
    """A progress line on stderr when it is a terminal (about once a second)."""
    if not sys.stderr.isatty():
        return None
    last = [0.0]

    def report(phase: str, t: float, t_end: float) -> None:
        now = wallclock.monotonic()
        if now - last[0] >= 1.0 or t >= t_end:
            last[0] = now
            sys.stderr.write(f"\r{engine} {case} [{phase}]: t = {t:8.2f} / {t_end:.2f} s ({100 * t / t_end:5.1f} %)")
            if t >= t_end:
                sys.stderr.write("\n")
            sys.stderr.flush()

    return report


def run(engine: Engine, case: Case, duration: float | None = None, progress: Progress | None = None) -> EngineRun:
    """Drive `engine` through `case` for `duration` seconds (default: the case's) and collect
    an `EngineRun`.

    A `duration` equal to the short variant's selects the short variant's programme (the
    command line passes `case.run_duration(short)`; the short variant differs only in
    durations, programme, events, solver and comparison, never in the initial state).
    """
    if case.phases:
        raise InputError(case.path, "phases",
                         "a sequence case runs through rsmcheck.orchestration.chain.run_case")
    if duration is None:
        duration = case.duration
    elif case.short is not None and not case.is_short and duration != case.duration \
            and math.isclose(duration, case.short.duration):
        case = case.short
    params = case.params
    dt_case = case.solver.control_period
    t_end = duration
    eps = 1e-9 * max(1.0, duration)
    out_period = case.solver.output_period
    controller = make_controller(case.controller, params, dt_case)
    programme = controller if isinstance(controller, ProgrammeController) else None
    segments = list(case.segments)
    releases = list(case.releases)
    events: list[Event] = []
    samples: list[dict] = []
    phases: list[Phase] = []
    contact = [False, False]
    phase = case.name
    # the capture armed now: case-level [capture] (feature cases) or the segment's
    armed: tuple[int, np.ndarray] | None = None
    report_arm = case.capture.arm
    report_point = np.asarray(case.capture_point_T(), float)
    if case.capture.enabled:
        armed = (case.capture.arm, report_point)
    seg_index = -1
    seg_end = 0.0
    seg_start = 0.0
    dt = dt_case
    t = 0.0
    k = 0
    next_out = 0.0
    started = wallclock.monotonic()
    # where the wall time goes (rsmcheck bench): the per-sample calls, timed here for every engine
    clock = wallclock.perf_counter
    spent = dict.fromkeys(SPLIT, 0.0)
    supervise, capture_gap = control_kernels.supervise, control_kernels.capture_gap
    seen = np.zeros(4)  # the supervisor's measurements (control_kernels.supervise)
    no_point = np.zeros(2)
    wrist_limit = params.wrist.limit
    capture_distance, capture_speed = params.grasp.capture_distance, params.grasp.capture_speed
    while True:
        tic = clock()
        s = engine.sensors()
        spent["sensors"] += clock() - tic
        if programme is not None and k == 0:
            programme.start(s)
        while releases and releases[0].time <= t + 0.5 * dt_case:
            rel = releases.pop(0)
            if s.grasp_state[rel.arm - 1]:
                info = engine.release(rel.arm)
                events.append(Event(t, "release", _detail(rel.arm, info)))
                s = engine.sensors()
        if programme is not None and seg_index + 1 < len(segments) and (seg_index < 0 or t >= seg_end - eps):
            if seg_index >= 0:
                phases.append(Phase(f"{case.name}:{segments[seg_index].name}", seg_start, t))
                if armed is not None and segments[seg_index].capture is not None:
                    events.append(Event(t, "capture_missed", f"arm={armed[0]} segment={segments[seg_index].name}"))
            seg_index += 1
            seg = segments[seg_index]
            seg_start = t
            seg_end = t + seg.duration
            dt = seg.control_period or dt_case
            events.append(Event(t, "segment", seg.name))
            for arm in seg.release:
                if s.grasp_state[arm - 1]:
                    info = engine.release(arm)
                    events.append(Event(t, "release", _detail(arm, info)))
                else:
                    events.append(Event(t, "release_skipped", f"arm={arm} does not hold the target"))
            s = engine.sensors()
            if seg.capture is not None:
                armed = (seg.capture.arm, np.asarray(seg.capture.point_T, float))
                report_arm, report_point = armed
            else:
                armed = None
            programme.enter(seg, s)
        # the supervisor's measurements in one compiled call: the bistop contacts and, for
        # an armed capture whose arm does not hold the target yet, the IF conditions' gap
        # and relative speed
        arm_c = armed[0] if armed is not None and not s.grasp_state[armed[0] - 1] else 0
        supervise(s.target_pose_I, s.target_rate_I, s.ee_pos_I, s.ee_vel_I, s.wrist_angles, s.grasp_state,
                  arm_c, armed[1] if arm_c else no_point, wrist_limit, seen)
        if arm_c and seen[2] < capture_distance and seen[3] < capture_speed:
            info = engine.capture(arm_c)
            info.update(gap_m=float(seen[2]), rel_speed_mps=float(seen[3]))
            events.append(Event(t, "capture", _detail(arm_c, info)))
            s = engine.sensors()
            armed = None
            if programme is not None:
                programme.captured(arm_c, s)
                seg = segments[seg_index]
                if seg.until == "capture":
                    seg_end = min(seg_end, t + seg.settle)
            supervise(s.target_pose_I, s.target_rate_I, s.ee_pos_I, s.ee_vel_I, s.wrist_angles, s.grasp_state,
                      0, no_point, wrist_limit, seen)
        if seen[0] != contact[0] or seen[1] != contact[1]:
            for arm in (1, 2):
                touching = bool(seen[arm - 1])
                if touching != contact[arm - 1]:
                    contact[arm - 1] = touching
                    events.append(Event(t, "bistop_contact" if touching else "bistop_free",
                                        f"arm={arm} psi={float(s.wrist_angles[arm - 1]):.6f}"))
        tic = clock()
        u: Inputs = controller(s)
        spent["controller"] += clock() - tic
        if programme is not None and programme.log:
            events.extend(Event(te, kind, detail) for te, kind, detail in programme.log)
            programme.log.clear()
        done = t >= t_end - eps
        if t >= next_out - eps or done:
            tic = clock()
            sample = engine.observe(u)
            gap = np.empty(2)
            capture_gap(s.base_pose_I, s.target_pose_I, s.ee_pos_I, report_arm, report_point, gap)
            sample["capture_gap_B"] = gap
            samples.append(sample)
            spent["observe"] += clock() - tic
            while next_out <= t + eps:
                next_out += out_period
        if done:
            break
        # the next sample: one control period on, clipped to the next segment boundary
        # and to the end (durations need not be whole numbers of a long period)
        t_next = t + dt
        if programme is not None and seg_index + 1 < len(segments) and t_next > seg_end - eps:
            t_next = seg_end
        t_next = min(t_next, t_end)
        if dt == dt_case:  # on the case's grid: no drift of round-off over long runs
            t_next = min(round(t_next / dt_case) * dt_case, t_end) if abs(t_next / dt_case - round(
                t_next / dt_case)) < 1e-6 else t_next
        try:
            tic = clock()
            engine.advance(t_next, u)
            spent["advance"] += clock() - tic
        except SimulationDiverged as exc:
            raise SimulationDiverged(exc.engine, exc.time, phase, exc.quantity, exc.value) from None
        t = t_next
        k += 1
        if progress is not None:
            progress(phase, t, t_end)
    t_final = t
    if programme is not None and seg_index >= 0:
        phases.append(Phase(f"{case.name}:{segments[seg_index].name}", seg_start, t_final))
        if seg_index + 1 < len(segments):
            events.append(Event(t_final, "programme_incomplete",
                                f"ended in segment '{segments[seg_index].name}'"))
    if armed is not None and programme is not None and segments[seg_index].capture is not None:
        events.append(Event(t_final, "capture_missed", f"arm={armed[0]} segment={segments[seg_index].name}"))
    observables = {name: np.array([smp[name] for smp in samples]) for name in NAMES}
    solver = dict(engine.solver_settings())
    solver["wall_s"] = wallclock.monotonic() - started
    solver["samples"] = k
    solver.update({f"wall_{part}_s": spent[part] for part in SPLIT})
    return EngineRun(engine=engine.name, observables=observables, events=events,
                     phases=[Phase(phase, 0.0, t_final), *phases], solver=solver,
                     versions=engine.versions())


def _detail(arm: int, info: dict[str, float]) -> str:
    """'arm=2 gap_m=0.00139949 residual_m=0.00000 …': the arm identifies the event, the
    measured values are written as real numbers ('#': always with a decimal point, so that an
    exact 0 does not read as an identifying integer, `Event.identity`)."""
    return " ".join([f"arm={arm}"] + [f"{k}={v:#.6g}" for k, v in info.items()])
