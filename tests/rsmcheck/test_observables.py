"""The observable schema against a hand-written oracle, and what check_observables rejects.

The table of docs/observables.md is a generated block rendered from the schema
(rsmcheck.orchestration.doc_tables; tests/docs/test_doc_tables.py checks the page)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.core.observables import (
    BY_NAME,
    NAMES,
    OBSERVABLES,
    ObservableSpec,
    allocate,
    check_observables,
)

# The observable names and shapes, copied by hand: the test oracle for the schema in code
# (θ_J beside ψ_J, and the wrist angles of the bistop, included).
HAND_TABLE = {
    "joint_frame_angles": (6,),
    "wrist_angles": (2,),
    "time": (),
    "base_pose_I": (3,),
    "target_pose_B": (3,),
    "ee1_pos_B": (2,),
    "ee2_pos_B": (2,),
    "ee2_speed": (),
    "capture_gap_B": (2,),
    "com_pos_B": (2,),
    "joint_angles": (6,),
    "motor_angles": (6,),
    "motor_torques": (6,),
    "base_torque": (),
    "link_deflection": (6,),
    "target_attitude": (),
    "reaction_forces_I": (4,),
    "constraint_residual": (4,),
    "grasp_state": (2,),
    "energy": (3,),
    "momentum_I": (3,),
    "altitude": (),
    "target_rel_lvlh": (2,),
    "system_mass": (),
}


def valid(n: int = 5) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    data = {spec.name: rng.normal(size=(n, *spec.shape)) for spec in OBSERVABLES}
    data["time"] = np.linspace(0.0, 1.0, n)
    data["grasp_state"] = rng.integers(0, 2, size=(n, 2)).astype(float)
    return data


def test_schema_matches_the_table_by_hand():
    assert {s.name: s.shape for s in OBSERVABLES} == HAND_TABLE
    assert len(NAMES) == len(set(NAMES)) == len(HAND_TABLE)
    assert NAMES[0] == "time"
    assert set(BY_NAME) == set(HAND_TABLE)


def test_every_row_has_unit_and_meaning():
    for spec in OBSERVABLES:
        assert isinstance(spec.shape, tuple) and all(isinstance(d, int) for d in spec.shape)
        assert spec.unit.strip(), spec.name
        assert spec.meaning.strip(), spec.name
    assert BY_NAME["time"].unit == "s"
    assert BY_NAME["joint_angles"].unit == "rad"
    assert BY_NAME["system_mass"].unit == "kg"
    assert BY_NAME["energy"].unit == "J"


def test_spec_is_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        BY_NAME["time"].unit = "ms"  # type: ignore[misc]
    assert ObservableSpec("x", (2, 3), "m", "").size == 6
    assert BY_NAME["time"].size == 1


def test_valid_data_returns_sample_count():
    assert check_observables(valid(7), "run") == 7
    assert check_observables(valid(1), "run") == 1


def test_allocate_has_every_observable_and_passes():
    data = allocate(4)
    assert set(data) == set(NAMES)
    assert data["joint_angles"].shape == (4, 6)
    assert data["time"].shape == (4,)
    assert check_observables(data, "alloc") == 4
    with pytest.raises(ValueError):
        allocate(0)


@pytest.mark.parametrize("name", sorted(HAND_TABLE))
def test_missing_observable_is_named(name):
    data = valid()
    del data[name]
    with pytest.raises(ValueError, match=rf"^somewhere: observable '{name}': missing"):
        check_observables(data, "somewhere")


def test_all_missing_are_listed():
    data = valid()
    del data["energy"], data["altitude"]
    with pytest.raises(ValueError, match=r"2 missing: energy, altitude"):
        check_observables(data, "w")


def test_unknown_name_rejected():
    data = valid()
    data["base_pose"] = data["base_pose_I"]
    with pytest.raises(ValueError, match=r"observable 'base_pose': unknown name"):
        check_observables(data, "w")


@pytest.mark.parametrize(
    "name, shape",
    [("joint_angles", (5, 5)), ("base_pose_I", (5, 2)), ("altitude", (5, 1)),
     ("energy", (5,)), ("time", (5, 1)), ("reaction_forces_I", (5, 2, 2))],
)
def test_wrong_shape_is_named(name, shape):
    data = valid(5)
    data[name] = np.zeros(shape)
    with pytest.raises(ValueError, match=rf"observable '{name}': expected"):
        check_observables(data, "w")


def test_sample_count_mismatch_is_named():
    data = valid(5)
    data["motor_torques"] = np.zeros((4, 6))
    with pytest.raises(ValueError, match=r"'motor_torques': has 4 samples, 'time' has 5"):
        check_observables(data, "w")


def test_zero_samples_rejected():
    data = {spec.name: np.zeros((0, *spec.shape)) for spec in OBSERVABLES}
    with pytest.raises(ValueError, match=r"'time': has no samples"):
        check_observables(data, "w")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_is_named_with_index(bad):
    data = valid(5)
    data["link_deflection"][3, 2] = bad
    with pytest.raises(ValueError, match=r"'link_deflection': non-finite value .* at index \(3, 2\)"):
        check_observables(data, "w")


def test_non_numeric_rejected():
    data = valid(2)
    data["altitude"] = np.array(["a", "b"])
    with pytest.raises(ValueError, match=r"'altitude': must be numeric"):
        check_observables(data, "w")


def test_time_must_not_decrease_but_may_repeat():
    data = valid(4)
    data["time"] = np.array([0.0, 1.0, 1.0, 2.0])  # state before and after an event
    assert check_observables(data, "w") == 4
    data["time"] = np.array([0.0, 1.0, 0.5, 2.0])
    with pytest.raises(ValueError, match=r"'time': decreases at sample 2"):
        check_observables(data, "w")


def test_grasp_state_is_zero_or_one():
    data = valid(3)
    data["grasp_state"][1, 0] = 0.5
    with pytest.raises(ValueError, match=r"'grasp_state': must be 0 or 1"):
        check_observables(data, "w")


def test_lists_and_int_arrays_accepted():
    data = {k: v.tolist() for k, v in valid(3).items()}
    data["grasp_state"] = np.ones((3, 2), dtype=np.int8)
    assert check_observables(data, "w") == 3
