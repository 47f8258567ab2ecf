"""The scenarios of `rsmcheck fuzz`: drawn from declared ranges, written as case files.

A scenario is an ordinary case file: `rsmcheck check PATH` runs it as it runs any case.
It is drawn from the ranges of fuzz_ranges.toml (each with its reason) by a generator
seeded with (seed, index), so scenario `index` of campaign `seed` is the same whatever
the number of scenarios or the machine:

* the chain: free (nothing held; the target floats 11 m away), open (one arm holds the
  target) or closed (both arms: arm 2's joint angles and rates are solved by the
  initial-state solver, rsmcheck.driver.initial, from the drawn ones as first guess);
* the initial joint angles around the elbow-bent pose, the wrist, base and joint rates;
* the torque history of the six motors and the base: a step, a smooth ramp, or a sine on
  a ramp (`[controller] kind = "constant"` with `ramp_time`, `sine_amplitude`,
  `sine_frequency_hz`);
* the link mass and bending stiffness, each within ±20 % (`[params.link]`);
* with or without the orbit.

`case_text` writes the scenario; a failing scenario's file gets the `[compare]` rows that
failed (fuzz.py), each tolerance the allowance the criterion gave, so that `rsmcheck
check` on it fails the same rows.
"""

from __future__ import annotations

import math
import tempfile
import tomllib
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.params import Params
from rsmcheck.driver.initial import build_initial

#: the free target's pose: far outside both arms' reach, at rest (flex_arm_step's)
FREE_TARGET_POSE = (9.0, 6.0, 0.0)
#: the sampled-data loop of every scenario: the mission's control period; output every 5 ms
CONTROL_PERIOD = 1e-3
OUTPUT_PERIOD = 5e-3
RTOL = 1e-9
#: observables the criterion judges from `reaction_skip_s` on (fuzz_ranges.toml)
WINDOWED = ("reaction_forces_I",)
#: Exudyn's step and Newton for a scenario, with the reason the case file states
EXUDYN_SUBSTEPS = 4
EXUDYN_WHY = ("4 generalized-α steps per 1 ms sample (h = 250 µs): a random torque step rings the 75–89 Hz rotor "
              "modes, whose phase error ω(ωh)²/12 is 3.6 rad/s at the default h = 0.5 ms and 0.91 rad/s here "
              "(docs/exudyn.md §4); the half-step rerun measures what is left, at a quarter of the cost of 8 steps.  A Jacobian per step: modified "
              "Newton's residual acts as a force the free arm integrates, and does not shrink with h "
              "(flex_arm_step's [exudyn]).")


@lru_cache(maxsize=1)
def declared() -> dict[str, Any]:
    """fuzz_ranges.toml: the ranges and the criterion."""
    return tomllib.loads(resources.files("rsmcheck.orchestration").joinpath("fuzz_ranges.toml").read_text("utf-8"))


@dataclass(frozen=True)
class Scenario:
    """One drawn scenario (module doc); `name` is its case name, fuzz_SEED_INDEX."""

    seed: int
    index: int
    duration: float
    chain: str  # "free" | "open" | "closed"
    holding_arm: int  # the arm that holds the target in an open chain (0 otherwise)
    joint_angles_deg: tuple[float, ...]
    wrist_angle_deg: float
    base_rate: tuple[float, float, float]
    joint_rates: tuple[float, ...]
    torque_form: str  # "step" | "ramp" | "sine"
    motor_torques: tuple[float, ...]
    base_torque: float
    ramp_time: float
    sine_amplitude: tuple[float, ...]
    sine_frequency_hz: float
    link_mass_factor: float
    link_stiffness_factor: float
    orbit: bool
    compare: Mapping[str, tuple[float, str]] = field(default_factory=dict)  # observable → (tolerance, why)

    @property
    def name(self) -> str:
        return f"fuzz_{self.seed}_{self.index}"

    @property
    def grasp(self) -> tuple[int, int]:
        return {"free": (0, 0), "closed": (1, 1)}.get(self.chain, (int(self.holding_arm == 1), int(self.holding_arm == 2)))

    def describe(self) -> str:
        """One line: what was drawn."""
        held = {"free": "free target", "open": f"arm {self.holding_arm} holds the target",
                "closed": "closed chain"}[self.chain]
        return (f"{held}, torque {self.torque_form}, {'in orbit' if self.orbit else 'free space'}, "
                f"link mass x{self.link_mass_factor:.3f}, EI x{self.link_stiffness_factor:.3f}, {self.duration:.2f} s")


def draw(seed: int, index: int) -> Scenario:
    """Scenario `index` of the campaign `seed` (module doc): the same on every machine."""
    r = declared()["ranges"]
    rng = np.random.default_rng([seed, index])

    def uniform(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    def sym(half: float, n: int) -> tuple[float, ...]:
        return tuple(round(uniform(-half, half), 4) for _ in range(n))

    duration = round(uniform(*r["duration_s"]), 2)
    chain = str(rng.choice(r["chains"]))
    holding_arm = int(rng.integers(1, 3)) if chain == "open" else 0
    nominal, spread = r["joint_angles_deg"]
    angles = tuple(round(a + uniform(-spread, spread), 3) for a in nominal)
    wrist = round(uniform(-r["wrist_angle_deg"], r["wrist_angle_deg"]), 3)
    form = str(rng.choice(["step", "ramp", "sine"]))
    ramp = 0.0 if form == "step" else round(uniform(*r["ramp_time_s"]), 3)
    amplitude = sym(r["sine_amplitude"], 6) if form == "sine" else (0.0,) * 6
    frequency = round(uniform(*r["sine_frequency_hz"]), 3) if form == "sine" else 0.0
    if chain == "closed":  # angles of arm 1 and the wrist whose closed arm 2 stays in the ranges too
        angles, wrist = closable_pose(seed, index)
    return Scenario(
        seed=seed, index=index, duration=duration, chain=chain, holding_arm=holding_arm,
        joint_angles_deg=angles, wrist_angle_deg=wrist,
        base_rate=tuple(round(uniform(-h, h), 5) for h in r["base_rate"]),
        joint_rates=tuple(round(uniform(-r["joint_rate"], r["joint_rate"]), 5) for _ in range(6)),
        torque_form=form, motor_torques=sym(r["held_torque"], 6), base_torque=round(uniform(-r["base_torque"],
                                                                                             r["base_torque"]), 4),
        ramp_time=ramp, sine_amplitude=amplitude, sine_frequency_hz=frequency,
        link_mass_factor=round(uniform(*r["link_mass_factor"]), 4),
        link_stiffness_factor=round(uniform(*r["link_stiffness_factor"]), 4),
        orbit=bool(rng.random() < r["orbit_probability"]),
    )


#: how many poses `closable_pose` tries before it gives up (about one in four closes in range)
CLOSURE_ATTEMPTS = 200


def closable_pose(seed: int, index: int) -> tuple[tuple[float, ...], float]:
    """(joint angles [deg], wrist angle [deg]) of a closed-chain scenario: drawn as an open
    chain's (a generator of their own, seeded with (seed, index, 1)) until the arm 2 that
    closes the chain on the target — the initial-state solver's (rsmcheck.driver.initial),
    from the drawn arm-2 angles — lies within the joint ranges too.  Without it arm 2's
    elbow closed anywhere from 45° to 183° (folded back on itself, a singular arm)."""
    r = declared()["ranges"]
    nominal, spread = r["joint_angles_deg"]
    rng = np.random.default_rng([seed, index, 1])
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(CLOSURE_ATTEMPTS):
            angles = tuple(round(a + float(rng.uniform(-spread, spread)), 3) for a in nominal)
            wrist = round(float(rng.uniform(-r["wrist_angle_deg"], r["wrist_angle_deg"])), 3)
            probe = _probe(angles, wrist)
            path = Path(folder) / f"{probe.name}.toml"
            path.write_text(case_text(probe))
            try:
                closed = np.degrees(build_initial(load_case(path)).joint_angles[3:])
            except InputError:
                continue
            if np.all(np.abs(closed - np.array(nominal[3:])) <= spread):
                return tuple(round(float(a), 3) for a in (*angles[:3], *closed)), wrist
    raise RuntimeError(f"fuzz scenario {index} of seed {seed}: no closable pose in {CLOSURE_ATTEMPTS} attempts")


def _probe(angles: tuple[float, ...], wrist: float) -> "Scenario":
    """A closed-chain scenario at rest with these angles: only its initial state is used."""
    return Scenario(seed=0, index=0, duration=1.0, chain="closed", holding_arm=0, joint_angles_deg=angles,
                    wrist_angle_deg=wrist, base_rate=(0.0,) * 3, joint_rates=(0.0,) * 6, torque_form="step",
                    motor_torques=(0.0,) * 6, base_torque=0.0, ramp_time=0.0, sine_amplitude=(0.0,) * 6,
                    sine_frequency_hz=0.0, link_mass_factor=1.0, link_stiffness_factor=1.0, orbit=False)


def _list(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def _string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + escaped + '"'


def link_overrides(s: Scenario, params: Params | None = None) -> dict[str, float]:
    """[params.link] of the scenario: mass and rotary inertia scaled by the mass factor (so
    the inertia beyond the slender beam's mL²/12 keeps its sign), f1 so that EI scales by
    the stiffness factor: EI = ρA (2 f1 L²/π)², ρA ∝ mass, hence f1 ∝ sqrt(k_EI / k_m)."""
    link = (params or Params()).link
    return {"mass": link.mass * s.link_mass_factor, "inertia_z": link.inertia_z * s.link_mass_factor,
            "f1_pp_hz": link.f1_pp_hz * math.sqrt(s.link_stiffness_factor / s.link_mass_factor)}


def case_text(s: Scenario) -> str:
    """The scenario as a case file (module doc)."""
    lines = [
        f"# Drawn by `rsmcheck fuzz --seed {s.seed}` (scenario {s.index}) from the ranges of",
        "# rsmcheck/orchestration/fuzz_ranges.toml: an ordinary case, `rsmcheck check` runs it.",
        f"name = {_string(s.name)}",
        f"description = {_string('Randomized: ' + s.describe())}",
        f"duration = {s.duration!r}",
        "",
        "[initial]",
        "base_pose = [0.0, 0.0, 0.0]",
        f"base_rate = {_list(s.base_rate)}",
        f"joint_angles_deg = {_list(s.joint_angles_deg)}",
        f"joint_rates = {_list(s.joint_rates)}",
        f"grasp = [{s.grasp[0]}, {s.grasp[1]}]",
    ]
    lines.append(f"target_pose = {_list(FREE_TARGET_POSE)}" if s.chain == "free"
                 else f"wrist_angle_deg = {s.wrist_angle_deg!r}")
    if s.orbit:
        lines += ["", "[orbit]", "enabled = true"]
    lines += ["", "[controller]", 'kind = "constant"', f"motor_torques = {_list(s.motor_torques)}",
              f"base_torque = {s.base_torque!r}", f"ramp_time = {s.ramp_time!r}"]
    if s.torque_form == "sine":
        lines += [f"sine_amplitude = {_list(s.sine_amplitude)}", f"sine_frequency_hz = {s.sine_frequency_hz!r}"]
    lines += ["", "[params.link]"] + [f"{k} = {v!r}" for k, v in link_overrides(s).items()]
    lines += ["", "[exudyn]", f"substeps = {EXUDYN_SUBSTEPS}", "jacobian_per_step = true", f"why = {_string(EXUDYN_WHY)}"]
    lines += ["", "[solver]", f"control_period = {CONTROL_PERIOD!r}", f"output_period = {OUTPUT_PERIOD!r}",
              f"rtol = {RTOL!r}"]
    for obs, (tolerance, why) in s.compare.items():
        lines += ["", f"[compare.{obs}]", f"tolerance = {tolerance:.3g}", f"why = {_string(why)}"]
        if obs in WINDOWED:  # the samples the criterion judged (fuzz_ranges.toml, reaction_skip_s)
            lines.append(f"window = [{declared()['criterion']['reaction_skip_s']!r}, {s.duration!r}]")
    return "\n".join(lines) + "\n"
