"""What an engine offers the shared driver, and what the driver hands to controllers.

Both engines (reference, Exudyn) implement `Engine`; `rsmcheck.driver.runner.run` drives either
through the same sampled-data loop (docs/physics.md §6), so the controller, the capture
logic and the output sampling are the same code for both.  Nothing here knows how an
engine computes anything.

Beyond the `Engine` object, each engine package (`reference_model`, `exudyn_model`) offers
the orchestration (rsmcheck.orchestration.modes, closed_loop, bench) the same functions
with the same signatures, so that shared code never reads an engine's internals;
`engine_options` go to the package's engine class (e.g. `n_modes` for the reference,
`n_elements` for Exudyn):

* `modes.linear_plant(case, outputs, n_inputs=7, eps=1e-7, **engine_options)` → (A, B, C):
  the engine linearised at the initial state of `case`, damping kept: ẋ = A x + B u,
  y = C x, with u = (τ_m1..6, τ_B) and y = `outputs(Sensors)`;
* `modes.coupled_frequencies(case, n=6, f_min=1.0, **engine_options)` → the first `n`
  eigenfrequencies [Hz] above `f_min` of the robot at rest in the initial configuration
  of `case`, undamped;
* `stepping.rhs_timing(case, n=2000, **engine_options)` → {"call_us", "compiled_us",
  "states"}: µs per evaluation of the engine's right-hand side at the initial state of
  `case`, from Python and inside a compiled loop (NaN where there is none), and the size
  of its first-order state.

The engine packages are heavy optional imports (numba, exudyn): shared code imports them
inside the functions that use them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class Sensors:
    """What a controller or supervisor may measure at a sample (SI, rad; `_I` inertial axes
    relative to the co-moving point O, `_B` base frame about the base COM).

    ee_pos_I / ee_vel_I: end effector of arm k in row k, relative to O, inertial axes.
    joint_angles / joint_rates: ψ_J, ψ̇_J, between end sections (docs/physics.md §3.3): what
    link-side joint encoders read; joint_frame_angles / _rates: θ_J, θ̇_J, between link frames.
    wrist_angles: ψ_w of each arm, θ_T relative to the terminal link's distal section.
    """

    time: float
    base_pose_I: np.ndarray  # x, y, θ_B
    base_rate_I: np.ndarray  # ẋ, ẏ, θ̇_B
    joint_angles: np.ndarray  # 6, ψ_J
    joint_rates: np.ndarray  # 6, ψ̇_J
    joint_frame_angles: np.ndarray  # 6, θ_J
    joint_frame_rates: np.ndarray  # 6, θ̇_J
    motor_angles: np.ndarray  # 6
    motor_rates: np.ndarray  # 6
    ee_pos_I: np.ndarray  # (2, 2)
    ee_vel_I: np.ndarray  # (2, 2)
    target_pose_I: np.ndarray  # x_T, y_T, θ_T
    target_rate_I: np.ndarray  # 3
    com_pos_B: np.ndarray  # system COM, 2
    wrist_angles: np.ndarray  # 2, ψ_w
    grasp_state: np.ndarray  # 2, 1 where arm k holds the target
    system_mass: float
    orbit_r_I: np.ndarray  # position of O from Earth's centre (zeros when no orbit)
    orbit_v_I: np.ndarray


@dataclass
class Inputs:
    """Held over one control period: motor torques τ_m (6), base torque τ_B, thrust T."""

    tau_m: np.ndarray = field(default_factory=lambda: np.zeros(6))
    tau_B: float = 0.0
    thrust: float = 0.0


class Engine(Protocol):
    """One simulator of the paper's system, stepping in control periods."""

    name: str

    def time(self) -> float: ...

    def sensors(self) -> Sensors: ...

    def observe(self, inputs: Inputs) -> dict[str, np.ndarray | float]:
        """Every observable (docs/observables.md) at the current instant."""
        ...

    def advance(self, t_next: float, inputs: Inputs) -> None:
        """Integrate to t_next with `inputs` held; raise SimulationDiverged on blow-up."""
        ...

    def capture(self, arm: int) -> dict[str, float]:
        """Switch grasp `arm` (1, 2) on at the current instant (docs/physics.md §4.2);
        returns figures for the event log (e.g. the basis-switch residual)."""
        ...

    def release(self, arm: int) -> dict[str, float]:
        """Switch grasp `arm` off (docs/physics.md §4.2)."""
        ...

    def solver_settings(self) -> dict[str, float | int | str]: ...

    def versions(self) -> dict[str, str]: ...

    def export_state(self) -> dict:
        """The engine's own full state (with the link deformation), JSON-able arrays and
        scalars, enough for a new engine of the same model to continue (rsmcheck.orchestration.chain)."""
        ...

    def import_state(self, exact: dict) -> None:
        """Continue from `export_state()` of an engine of the same model size; another
        size (or another engine's state) leaves the rigid start the case built."""
        ...
