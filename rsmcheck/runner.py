"""The sampled-data loop that drives any engine through a case (docs/physics.md §6).

At every control sample t_k = k·Δt:
  1. scheduled releases due at t_k are applied;
  2. if capture is enabled, the two IF conditions (Sect. 2: relative position and velocity
     of the end effector to the designated capture point below thresholds) are evaluated,
     and the grasp is switched on when both hold;
  3. the wrist bistop contact state is logged (ψ beyond ±ψ_lim);
  4. the controller computes the inputs, held until t_{k+1};
  5. every `output_every` samples the observables are recorded;
  6. the engine integrates to t_{k+1}.
Every engine gets the same loop; only step 6 and the switching are engine code.
"""

from __future__ import annotations

import math
import sys
import time as wallclock
from typing import Callable

import numpy as np

from cases.loader import Case
from rsmcheck.controllers import make_controller
from rsmcheck.engine import Engine, Inputs, Sensors
from rsmcheck.errors import SimulationDiverged
from rsmcheck.observables import NAMES
from rsmcheck.store import EngineRun, Event, Phase

Progress = Callable[[str, float, float], None]


def _rot(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def capture_point(s: Sensors, rho_T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inertial position and velocity of the target point ρ_T (target frame, about the COM)."""
    lever = _rot(s.target_pose_I[2]) @ rho_T
    v = s.target_rate_I[:2] + s.target_rate_I[2] * np.array([-lever[1], lever[0]])
    return s.target_pose_I[:2] + lever, v


def if_conditions(s: Sensors, arm: int, rho_T: np.ndarray, distance: float, speed: float) -> tuple[bool, float, float]:
    """Both IF conditions of capture for `arm`, with the measured gap and relative speed."""
    p, v = capture_point(s, rho_T)
    gap = float(np.linalg.norm(s.ee_pos_I[arm - 1] - p))
    rel = float(np.linalg.norm(s.ee_vel_I[arm - 1] - v))
    return gap < distance and rel < speed, gap, rel


def wrist_angle(s: Sensors, arm: int) -> float:
    """ψ = θ_T − θ_3 of `arm`; joint angles are between link frames, so θ_3 = θ_B + Σθ_J."""
    return float(s.target_pose_I[2] - s.base_pose_I[2] - np.sum(s.joint_angles[3 * (arm - 1):3 * arm]))


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


def run(engine: Engine, case: Case, duration: float, progress: Progress | None = None) -> EngineRun:
    """Drive `engine` through `case` for `duration` seconds and collect an `EngineRun`."""
    params = case.params
    dt = case.solver.control_period
    n_steps = int(round(duration / dt))
    every = case.solver.output_every
    controller = make_controller(case.controller, params)
    releases = list(case.releases)
    events: list[Event] = []
    samples: list[dict] = []
    contact = [False, False]
    phase = case.name
    arm_c = case.capture.arm
    rho_c = np.asarray(params.geometry.grasp_T(arm_c), float)
    started = wallclock.monotonic()
    for k in range(n_steps + 1):
        t = k * dt
        s = engine.sensors()
        while releases and releases[0].time <= t + 0.5 * dt:
            rel = releases.pop(0)
            info = engine.release(rel.arm)
            events.append(Event(t, "release", _detail(rel.arm, info)))
            s = engine.sensors()
        if case.capture.enabled and not s.grasp_state[arm_c - 1]:
            ok, gap, speed = if_conditions(s, arm_c, rho_c, params.grasp.capture_distance, params.grasp.capture_speed)
            if ok:
                info = engine.capture(arm_c)
                info.update(gap_m=gap, rel_speed_mps=speed)
                events.append(Event(t, "capture", _detail(arm_c, info)))
                s = engine.sensors()
        for arm in (1, 2):
            touching = bool(s.grasp_state[arm - 1]) and abs(wrist_angle(s, arm)) > params.wrist.limit
            if touching != contact[arm - 1]:
                contact[arm - 1] = touching
                events.append(Event(t, "bistop_contact" if touching else "bistop_free",
                                    f"arm={arm} psi={wrist_angle(s, arm):.6f}"))
        u: Inputs = controller(s)
        if k % every == 0:
            samples.append(engine.observe(u))
        if k == n_steps:
            break
        try:
            engine.advance((k + 1) * dt, u)
        except SimulationDiverged as exc:
            raise SimulationDiverged(exc.engine, exc.time, phase, exc.quantity, exc.value) from None
        if progress is not None:
            progress(phase, (k + 1) * dt, n_steps * dt)
    observables = {name: np.array([smp[name] for smp in samples]) for name in NAMES}
    solver = dict(engine.solver_settings())
    solver["wall_s"] = wallclock.monotonic() - started
    return EngineRun(engine=engine.name, observables=observables, events=events,
                     phases=[Phase(phase, 0.0, n_steps * dt)], solver=solver, versions=engine.versions())


def _detail(arm: int, info: dict[str, float]) -> str:
    return " ".join([f"arm={arm}"] + [f"{k}={v:.6g}" for k, v in info.items()])
