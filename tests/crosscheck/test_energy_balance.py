"""Power of the motor torques = rate of the total energy, in both engines (docs/physics.md §3.3).

Without damping (link ζ = 0, C_m = 0), orbit or base torque, the only external work on the
system is the motors' on their rotors: with the torque τ_k held over each control period
(zero-order hold), the work over the period is exactly τ_k·(θ_m(t_{k+1}) − θ_m(t_k)), and

    E(t) − E(0) = Σ_k τ_k·Δθ_m,k,     E = kinetic + elastic (links, joint springs on ψ_J − θ_m).

Two configurations, torques ramped in over 0.2 s and held (5, −10, 5 / −5, 10, −5 N·m), 1 s:
the two free arms (no target), where every joint torque bends two links, and the closed
chain (both arms hold the target).  The balance checks that the generalised forces of the
joint springs (u_J on θ_J, the paper's u_e on the amplitudes) are the ones their potential
½K_m(ψ_J − θ_m)² implies, in each engine's own formulation.  Each engine's integrator
leaves its own residual.  Measured: the reference (DP5, rtol 1e-10) 2.8e-13 J of 4.16 J
(open) and 2.3e-12 J of 1.25 J (closed), tolerance 1e-11 of the work; Exudyn
(generalized-α, ρ∞ = 0.6) at 62.5 µs 1.5e-5 J of 4.16 J and 5.9e-6 J of 1.25 J (3.6e-6,
4.7e-6 of the work; first order in h: 8.8e-5 J at 0.5 ms, the held input's O(h) in
generalized-α, docs/exudyn.md §4), tolerance 1e-5 of the work.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.core.engine import Inputs

TORQUES = np.array([5.0, -10.0, 5.0, -5.0, 10.0, -5.0])
RAMP = 0.2
DURATION = 1.0

CASE = """
description = "energy balance: damping off, torques ramped in, no orbit"
duration = 1.0
[initial]
base_pose = [0.0, 0.0, 0.0]
joint_angles_deg = [60.0, -120.0, 60.0, -60.0, 120.0, -60.0]
{grasp}
[controller]
kind = "none"
[solver]
control_period = 1e-3
output_period = 1e-3
rtol = 1e-10
[params.link]
damping_ratio = 0.0
[params.motor]
damping = 0.0
"""
OPEN = 'grasp = [0, 0]\ntarget_pose = [20.0, 0.0, 0.0]'
CLOSED = 'grasp = [1, 1]\nwrist_angle_deg = 0.0'


def balance(engine, case) -> tuple[np.ndarray, np.ndarray]:
    """(E(t_k) − E(0), W(t_k)) at every control sample."""
    dt = case.solver.control_period
    n = int(round(DURATION / dt))
    e0 = float(np.sum(engine.observe(Inputs())["energy"]))
    de, work = [0.0], [0.0]
    w = 0.0
    for k in range(n):
        t = k * dt
        f = 0.5 * (1.0 - math.cos(math.pi * min(t, RAMP) / RAMP))
        u = Inputs(tau_m=f * TORQUES)
        before = engine.sensors().motor_angles
        engine.advance((k + 1) * dt, u)
        w += float(u.tau_m @ (engine.sensors().motor_angles - before))
        de.append(float(np.sum(engine.observe(u)["energy"])) - e0)
        work.append(w)
    return np.array(de), np.array(work)


@pytest.fixture(scope="module", params=["open", "closed"])
def configuration(request, tmp_path_factory):
    name = f"energy_balance_{request.param}"
    path = tmp_path_factory.mktemp("cases") / f"{name}.toml"
    path.write_text(f'name = "{name}"\n' + CASE.format(grasp=OPEN if request.param == "open" else CLOSED))
    return load_case(path)


@pytest.mark.crosscheck
def test_reference_motor_work_is_the_energy_change(configuration):
    from reference_model.engine import ReferenceEngine

    de, work = balance(ReferenceEngine(configuration), configuration)
    err = np.abs(de - work).max()
    assert np.abs(work).max() > 1.0  # the motors do work (J)
    assert err <= 1e-11 * np.abs(work).max(), f"reference: |ΔE − W| = {err:.2e} J of W = {np.abs(work).max():.3e} J"


@pytest.mark.crosscheck
def test_exudyn_motor_work_is_the_energy_change(configuration):
    from exudyn_model.engine import ExudynEngine

    de, work = balance(ExudynEngine(configuration, substeps=16), configuration)
    err = np.abs(de - work).max()
    assert np.abs(work).max() > 1.0
    assert err <= 1e-5 * np.abs(work).max(), f"Exudyn: |ΔE − W| = {err:.2e} J of W = {np.abs(work).max():.3e} J"
