"""Initial conditions shared by the engines (rsmcheck.driver.initial): the target pose from the
holding arm and the wrist angle, arm 2 closed onto grasp point 2 (positions and rates),
the orbit start, and clear errors for an impossible closure.

The closure is checked twice: with the plane trigonometry of `rigid_arm`, and with the
reference model's own constraint φ_T of eq. (8) and its rate at the engine's first state.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.geometry import rigid_arm, rot
from rsmcheck.driver.initial import build_initial

CLOSED = """\
name = "{name}"
description = "closed chain, moving"
duration = 1.0
[initial]
base_pose = [0.2, -0.1, 0.3]
base_rate = [0.01, -0.02, 0.03]
joint_angles_deg = [60.0, -120.0, 60.0, -50.0, 110.0, -70.0]
joint_rates = [0.02, -0.01, 0.015, 0.0, 0.0, 0.0]
grasp = [1, 1]
wrist_angle_deg = 5.0
"""


def case_from(tmp_path: Path, text: str, stem: str = "c"):
    path = tmp_path / f"{stem}.toml"
    path.write_text(textwrap.dedent(text).replace("{name}", stem))
    return load_case(path)


def grasp_point(init, arm: int):
    """Inertial position and velocity of held point `arm` on the target."""
    lever = rot(init.target_pose[2]) @ init.rho_G[arm - 1]
    v = init.target_rate[:2] + init.target_rate[2] * np.array([-lever[1], lever[0]])
    return init.target_pose[:2] + lever, v


def test_single_grasp_places_the_target_on_arm_1():
    case = load_case("free_drift")
    init = build_initial(case)
    p, v, th3, om3, _ = rigid_arm(case.params, init.base_pose, init.base_rate, init.joint_angles[0:3],
                                  init.joint_rates[0:3], 1)
    g, gv = grasp_point(init, 1)
    assert np.abs(g - p).max() <= 1e-12 and np.abs(gv - v).max() <= 1e-12
    assert init.target_pose[2] - th3 == pytest.approx(math.radians(case.initial.wrist_angle_deg), abs=1e-15)
    assert init.target_rate[2] == pytest.approx(om3, abs=1e-15)
    assert list(init.grasp) == [1, 0]
    np.testing.assert_array_equal(init.joint_angles, np.radians(case.initial.joint_angles_deg))


def test_closed_chain_arm2_solved_onto_grasp_point_2(tmp_path):
    case = case_from(tmp_path, CLOSED)
    init = build_initial(case)
    prm = case.params
    # arm 1 carries the target with ψ = 5°
    _, _, th3, _, _ = rigid_arm(prm, init.base_pose, init.base_rate, init.joint_angles[0:3], init.joint_rates[0:3], 1)
    assert init.target_pose[2] - th3 == pytest.approx(math.radians(5.0), abs=1e-14)
    # arm 2's end effector sits on grasp point 2 and moves with it
    p2, v2, _, _, _ = rigid_arm(prm, init.base_pose, init.base_rate, init.joint_angles[3:6], init.joint_rates[3:6], 2)
    g2, gv2 = grasp_point(init, 2)
    assert np.linalg.norm(p2 - g2) <= 1e-12
    assert np.linalg.norm(v2 - gv2) <= 1e-12
    # the solve moved arm 2 from its first guess and gave it rates: the chain really moves
    assert np.abs(init.joint_angles[3:6] - np.radians([-50.0, 110.0, -70.0])).max() > 1e-3
    assert np.abs(init.joint_rates[3:6]).max() > 1e-3
    # arm 1 is left as given
    np.testing.assert_array_equal(init.joint_rates[0:3], case.initial.joint_rates[0:3])


def test_closed_chain_start_satisfies_the_reference_constraint(tmp_path):
    from reference_model.model_arrays import N_INPUTS
    from reference_model.engine import ReferenceEngine

    case = case_from(tmp_path, CLOSED)
    engine = ReferenceEngine(case)
    _, _, A, phi, phid, *_ = engine.model.assemble(engine.x, np.zeros(N_INPUTS), engine.cfg)
    assert A.shape[0] == 4
    assert np.abs(phi).max() <= 1e-12
    assert np.abs(phid).max() <= 1e-12
    lay = engine.model.layout
    # links start undeformed and at rest relative to their frames, rotors relaxed
    # undeformed: the eigen amplitudes zero, the slaved static shapes at the relaxed springs'
    # equilibrium (zero to round-off)
    assert np.abs(engine.x[9:lay.nq]).max() <= 1e-15 and np.abs(engine.x[lay.ns + 9:lay.ns + lay.nq]).max() <= 1e-15
    np.testing.assert_array_equal(engine.x[lay.motors], engine.x[3:9])


def test_closed_squeeze_case_closes():
    case = load_case("closed_squeeze")
    init = build_initial(case)
    p2 = rigid_arm(case.params, init.base_pose, init.base_rate, init.joint_angles[3:6], init.joint_rates[3:6], 2)[0]
    assert np.linalg.norm(p2 - grasp_point(init, 2)[0]) <= 1e-12


def test_no_grasp_takes_the_target_as_given(tmp_path):
    text = CLOSED.replace("grasp = [1, 1]", "grasp = [0, 0]\ntarget_pose = [6.0, 1.0, 0.2]\n"
                                            "target_rate = [0.01, 0.0, -0.02]")
    text = text.replace("wrist_angle_deg = 5.0\n", "")  # no wrist without a grasp
    init = build_initial(case_from(tmp_path, text))
    np.testing.assert_array_equal(init.target_pose, [6.0, 1.0, 0.2])
    np.testing.assert_array_equal(init.target_rate, [0.01, 0.0, -0.02])
    assert list(init.grasp) == [0, 0]


def test_unreachable_grasp_point_is_an_input_error(tmp_path):
    text = CLOSED + "[params.geometry]\ngrasp2_centre_T = [-1.5, -9.0]\n"
    case = case_from(tmp_path, text, "far")
    with pytest.raises(InputError) as info:
        build_initial(case)
    assert info.value.where == case.path
    assert info.value.field == "initial.joint_angles_deg"


def test_orbit_start_is_a_circular_orbit(tmp_path):
    text = CLOSED + "[orbit]\nenabled = true\n"
    case = case_from(tmp_path, text, "orb")
    init = build_initial(case)
    prm = case.params
    r0 = prm.orbit.earth_radius + prm.orbit.altitude_initial
    assert np.linalg.norm(init.orbit_r) == pytest.approx(r0, rel=1e-15)
    assert np.linalg.norm(init.orbit_v) == pytest.approx(math.sqrt(prm.orbit.mu / r0), rel=1e-15)
    assert abs(init.orbit_r @ init.orbit_v) <= 1e-9 * r0 * np.linalg.norm(init.orbit_v)
    # the closure is unaffected by where O is put
    p2, v2, _, _, _ = rigid_arm(prm, init.base_pose, init.base_rate, init.joint_angles[3:6], init.joint_rates[3:6], 2)
    g2, gv2 = grasp_point(init, 2)
    assert np.linalg.norm(p2 - g2) <= 1e-12 and np.linalg.norm(v2 - gv2) <= 1e-12
