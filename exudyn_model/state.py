"""What changes during a run of the Exudyn model besides the mbs's own coordinates: the
time of the last control sample, the grasps and the grasp points on the target, the basis
(PP, PF) of each link's frame, the motion of the co-moving point O, the propellant used, the
inputs the mbs holds, the coordinates read at the last sample, and the solver's counters.

One `EngineState` per engine, shared by reference by its parts (`exudyn_model.engine`):
the stepper moves it forward, the switching functions change grasps and bases, the
observer and the exact-state functions read it.  The functions below read the state
together with the built model (`exudyn_model.build.ExudynModel`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def new_stats() -> dict:
    """The solver's counters, zero (reported by `ExudynEngine.solver_settings`)."""
    return {"steps": 0, "newton_iterations": 0, "jacobians": 0, "restarts": 0, "newton_retries": 0,
            "wall_integrator_s": 0.0}  # s waiting on Exudyn's solver (rsmcheck bench)


@dataclass
class EngineState:
    """The state of a run between control samples (SI; inertial axes relative to O)."""

    t: float  # time of the last control sample [s]
    grasp_on: np.ndarray  # (2,) int64, 1 where arm k holds the target
    rho_G: np.ndarray  # (2, 2) grasp point of arm k on the target, target frame [m]
    basis: list[str]  # (6,) the frame of each link: "PP" (chord) or "PF" (mass-orthogonal)
    r_O: np.ndarray  # position of O from Earth's centre [m]
    v_O: np.ndarray  # its velocity [m/s]
    m_used: float  # propellant burnt [kg]
    held: tuple | None = None  # the held inputs (τ_m, τ_B, T) the mbs carries, None: none yet
    # (q, v) read at the last sample, read-only, until the state changes (`coordinates`)
    sample: tuple[np.ndarray, np.ndarray] | None = None
    stats: dict = field(default_factory=new_stats)  # the solver's counters
    start_label: str = "initial"  # what the run started from (solver_settings' "start")


def coordinates(model, state: EngineState) -> tuple[np.ndarray, np.ndarray]:
    """Absolute ODE2 coordinates q and velocities q̇ of `model`'s mbs (read-only: between
    the end of an advance and the next change of the state, the stepper's `pause` or
    `advance`, the same arrays of that sample are returned: the sensors, the observables and
    the next held inputs read them without three copies out of Exudyn)."""
    if state.sample is not None:
        return state.sample
    sd = model.mbs.systemData
    q = np.asarray(sd.GetODE2Coordinates())  # a new array (pybind11 copies Exudyn's vector)
    q += model.index.q_ref
    return q, np.asarray(sd.GetODE2Coordinates_t())


def base_mass(params, state: EngineState) -> float:
    """The base's present mass [kg]: its mass at the start of the mission (params) less the
    propellant used."""
    return params.base.mass - state.m_used


def system_mass(params, state: EngineState) -> float:
    """m_B + m_T + 6 m_link [kg] (the base's present mass, `base_mass`)."""
    return base_mass(params, state) + params.target.mass + 6 * params.link.mass


def mass_flow(params, thrust: float) -> float:
    """Propellant flow ṁ = T/(I_sp g0) [kg/s] at thrust T [N] (physics.md §5)."""
    a = params.actuators
    return thrust / (a.isp * a.g0)
