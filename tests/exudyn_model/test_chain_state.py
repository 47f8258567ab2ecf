"""Phase chaining with the Exudyn engine: `export_state` / `import_state` (rsmcheck.orchestration.chain).

A phase started from a stored end state must continue the same motion: the new engine is
built from the rigid part of the end state and then takes Exudyn's own exact state (link
deformation, rotor twist, bistop data), so every observable is continuous across the
phase boundary.  When the next phase places O on an orbit at the system COM, every
position moves by the same shift and the relative geometry is unchanged.
"""

from __future__ import annotations

import numpy as np
import pytest

from rsmcheck.orchestration import chain
from rsmcheck.core.cases import load_case
from rsmcheck.core.engine import Inputs
from rsmcheck.core.plugins import make_engine
from rsmcheck.driver.runner import run

RELATIVE = ("target_pose_B", "ee1_pos_B", "ee2_pos_B", "capture_gap_B", "com_pos_B", "joint_angles",
            "motor_angles", "link_deflection", "grasp_state", "constraint_residual")


def _continued(case_name: str, duration: float, edit=None):
    case = load_case(case_name).variant(True)
    first = make_engine("exudyn", case)
    run(first, case, duration)
    state = chain.end_state(first, case.params)
    if edit:
        edit(state)
    second = make_engine("exudyn", case, chain.start_of(state))
    return first, second


def test_import_continues_the_deformed_state():
    first, second = _continued("closed_squeeze", 0.05)  # squeezed closed chain: twisted rotors, bent links
    a, b = first.observe(Inputs()), second.observe(Inputs())
    assert second.solver_settings()["start"] == "exact end state"
    assert np.max(np.abs(a["link_deflection"])) > 1e-7  # there is a deformation to carry over
    assert np.max(np.abs(a["motor_angles"] - a["joint_angles"])) > 1e-5  # and a rotor twist
    for name in RELATIVE + ("base_pose_I", "momentum_I", "energy"):
        assert np.allclose(a[name], b[name], rtol=1e-12, atol=1e-12), name


def test_rigid_start_takes_spring_twists_and_propellant():
    """From the rigid part alone the links start undeformed at the frame angles θ_J and each
    joint spring keeps its twist θ_m − ψ_J (and its rate), so the joints carry on with their
    torques (rsmcheck.driver.initial: the rotors are shifted by the bend θ_J − ψ_J)."""
    def drop_exact(state):
        state["exact"] = None
        state["rigid"]["m_used"] = 2.5

    first, second = _continued("closed_squeeze", 0.05, drop_exact)
    s1, s2 = first.sensors(), second.sensors()
    assert second.solver_settings()["start"] == "rigid end state"
    assert np.allclose(s2.joint_frame_angles, s1.joint_frame_angles, atol=1e-12)
    assert np.allclose(s2.joint_angles, s2.joint_frame_angles, atol=1e-12)  # undeformed
    assert np.allclose(s2.motor_angles - s2.joint_angles, s1.motor_angles - s1.joint_angles, atol=1e-13)
    assert np.allclose(s2.motor_rates - s2.joint_rates, s1.motor_rates - s1.joint_rates, atol=1e-12)
    assert np.max(np.abs(s1.joint_angles - s1.joint_frame_angles)) > 1e-7  # the bend was real
    assert second.state.m_used == 2.5
    assert s2.system_mass == pytest.approx(s1.system_mass - 2.5, abs=1e-12)


def test_orbit_placement_shifts_every_position_alike():
    def off_orbit(state):  # as a phase without orbit would have stored it (p3 → p4)
        state["rigid"]["orbit_r"] = [0.0, 0.0]
        state["rigid"]["orbit_v"] = [0.0, 0.0]

    first, second = _continued("thrust_burn", 0.02, off_orbit)
    a, b = first.observe(Inputs()), second.observe(Inputs())
    assert second.solver_settings()["start"] == "exact end state"
    for name in RELATIVE:
        assert np.allclose(a[name], b[name], rtol=1e-9, atol=1e-11), name
    # O is now at the system COM (thrust_burn centres O on it) and moves with it
    th = b["base_pose_I"][2]
    A = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    assert np.linalg.norm(b["base_pose_I"][:2] + A @ b["com_pos_B"]) < 1e-12
    assert np.linalg.norm(b["momentum_I"][:2]) < 1e-12 * np.linalg.norm(a["momentum_I"][:2]) + 1e-12
    # the COM left O during the first 20 ms of the burn (5 µm): the shift is real
    assert np.linalg.norm(a["base_pose_I"][:2] + A @ a["com_pos_B"]) > 1e-6
    # a PP terminal link's P is not shifted with the rest: it stays parked at the new
    # model's reference, where its two coordinate constraints hold (exudyn_model/build.py)
    q, v = second.coordinates()
    for it in [it for it in second.model.links if it.p_node is not None]:
        assert second.state.basis[it.index] == "PP"
        ip = second.mbs.GetNodeODE2Index(it.p_node) + np.arange(2)
        assert np.array_equal(q[ip], second.model.index.q_ref[ip]) and not np.any(v[ip]), it.index
