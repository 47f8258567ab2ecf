"""Controllers: one implementation, used by every engine (docs/physics.md §6).

A controller maps the `Sensors` of one sample to the `Inputs` held until the next one and
applies the saturations of Tables 3–4 (|τ_B| ≤ 12 N·m, |τ_m| ≤ 80 N·m).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from cases.loader import ControllerSpec
from rsmcheck.engine import Inputs, Sensors
from rsmcheck.params import Params

Controller = Callable[[Sensors], Inputs]


def saturate(inputs: Inputs, params: Params) -> Inputs:
    """Clip τ_m to ±τ_m,max (Table 4) and τ_B to ±τ_B,max (Table 3)."""
    tm = params.motor.torque_max
    tb = params.actuators.torque_max
    return Inputs(tau_m=np.clip(inputs.tau_m, -tm, tm), tau_B=float(np.clip(inputs.tau_B, -tb, tb)),
                  thrust=inputs.thrust)


def make_controller(spec: ControllerSpec, params: Params) -> Controller:
    """The controller a case names."""
    if spec.kind == "none":
        return lambda s: Inputs()
    if spec.kind == "constant":
        held = saturate(Inputs(tau_m=np.array(spec.motor_torques, float), tau_B=spec.base_torque), params)
        return lambda s: Inputs(tau_m=held.tau_m.copy(), tau_B=held.tau_B, thrust=0.0)
    raise ValueError(f"unknown controller kind {spec.kind!r}")
