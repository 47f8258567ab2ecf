"""Case files: every kind of bad input is refused with an `InputError` that names the file
and the field, before anything runs; good files load into the values they say.

Each bad case is a minimal valid case with exactly one thing wrong, so the test shows that
this one thing, and nothing else, is what the loader objects to.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from exudyn_model.settings import ExudynSettings
from reference_model.settings import ReferenceSettings
from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError

VALID = """\
name = "{name}"
description = "a valid case"
duration = 2.0
short_duration = 1.0

[initial]
base_pose = [0.0, 0.0, 0.0]
base_rate = [0.0, 0.0, 0.01]
joint_angles_deg = [60.0, -120.0, 60.0, -60.0, 120.0, -60.0]
joint_rates = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
grasp = [1, 0]
wrist_angle_deg = 0.0

[controller]
kind = "constant"
motor_torques = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
base_torque = 0.0

[solver]
control_period = 1e-3
output_period = 1e-2
rtol = 1e-9

[reference]
n_modes = 2

[params.link]
damping_ratio = 0.02
"""


def write(tmp_path: Path, text: str, stem: str = "bad") -> Path:
    path = tmp_path / f"{stem}.toml"
    path.write_text(text.replace("{name}", stem))
    return path


def edit(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def test_valid_case_loads(tmp_path):
    path = write(tmp_path, VALID, "good")
    case = load_case(path)
    assert case.name == "good"
    assert case.duration == 2.0 and case.short_duration == 1.0
    assert case.initial.grasp == (1, 0)
    assert case.initial.base_rate == (0.0, 0.0, 0.01)
    assert case.controller.kind == "constant" and case.controller.motor_torques[0] == 1.0
    assert case.solver.output_every == 10
    assert case.engine_settings["reference"].n_modes == (2,) * 6
    assert case.params.link.damping_ratio == 0.02
    assert case.params.link.mass == 36.49  # untouched defaults stay
    assert case.path == str(path)
    assert len(case.file_hash) == 64
    assert case.run_duration(True) == 1.0 and case.run_duration(False) == 2.0
    assert case.engine_settings["exudyn"] == ExudynSettings() and case.engine_settings["exudyn"].given() == {}


def test_exudyn_table_sets_the_engine_discretisation(tmp_path):
    text = VALID + '[exudyn]\nsubsteps = 32\nn_elements = 4\nwhy = "the step study"\n'
    case = load_case(write(tmp_path, text, "good"))
    assert case.engine_settings["exudyn"].given() == {"substeps": 32, "n_elements": 4}
    assert case.engine_settings["exudyn"].why == "the step study"
    assert case.variant(True).engine_settings["exudyn"].given() == {"substeps": 32, "n_elements": 4}


def test_exudyn_table_sets_the_integrator(tmp_path):
    text = (VALID + '[exudyn]\nconstraints = "index2"\nrestart_threshold = 0.0\nnewton_atol = 1e-3\n'
            'why = "the ZOH study"\n')
    case = load_case(write(tmp_path, text, "good"))
    assert case.engine_settings["exudyn"].given() == {"constraints": "index2", "restart_threshold": 0.0, "newton_atol": 1e-3}
    assert (case.engine_settings["exudyn"].constraints, case.engine_settings["exudyn"].substeps) == ("index2", None)


def test_growth_metric_takes_a_window(tmp_path):
    text = VALID + '[compare.motor_torques]\ntolerance = 0.02\nwhy = "w."\nmetric = "growth"\nwindow = [0.2, 0.9]\n'
    case = load_case(write(tmp_path, text, "good"))
    (spec,) = case.compare
    assert (spec.metric, spec.window) == ("growth", (0.2, 0.9))


def test_max_abs_takes_an_optional_window(tmp_path):
    text = VALID + '[compare.motor_torques]\ntolerance = 0.02\nwhy = "w."\nwindow = [0.2, 0.9]\n'
    (spec,) = load_case(write(tmp_path, text, "good")).compare
    assert (spec.metric, spec.window) == ("max_abs", (0.2, 0.9))


def test_reference_table_sets_the_largest_step(tmp_path):
    text = edit(VALID, "n_modes = 2", 'n_modes = 2\nh_max = 2e-4\nwhy = "the ripple study"')
    case = load_case(write(tmp_path, text, "good"))
    assert case.engine_settings["reference"] == ReferenceSettings(h_max=2e-4, why="the ripple study") and case.engine_settings["reference"].n_modes == (2,) * 6
    assert case.variant(True).engine_settings["reference"].given() == {"integrator": "dopri5", "rtol": 1e-9, "h_max": 2e-4}


def test_reference_table_names_the_quiet_segments_integrator(tmp_path):
    text = edit(VALID, "n_modes = 2", 'n_modes = 2\nquiet_integrator = "imex"\nwhy = "the coast study"')
    case = load_case(write(tmp_path, text, "good"))
    assert case.engine_settings["reference"].quiet_integrator == "imex" and case.engine_settings["reference"].integrator == "dopri5"


GROWTH = '[compare.motor_torques]\ntolerance = 0.02\nwhy = "w."\nmetric = "growth"\n'

# (id, edit of VALID, field the error must name)
BAD = [
    ("unknown_top_key", lambda t: edit(t, "duration = 2.0\n", 'duration = 2.0\ncolour = "red"\n'), "colour"),
    ("unknown_initial_key", lambda t: edit(t, "[initial]\n", "[initial]\nspeed = 1.0\n"), "initial.speed"),
    ("unknown_param_section", lambda t: t + "[params.gearbox]\nratio = 100.0\n", "params.gearbox"),
    ("unknown_param_key", lambda t: edit(t, "damping_ratio = 0.02", "damping_ratio = 0.02\nstiffness = 1.0"),
     "params.link.stiffness"),
    ("wrong_type_duration", lambda t: edit(t, "duration = 2.0", 'duration = "long"'), "duration"),
    ("wrong_type_bool_number", lambda t: edit(t, "wrist_angle_deg = 0.0", "wrist_angle_deg = true"),
     "initial.wrist_angle_deg"),
    ("wrong_length_vector", lambda t: edit(t, "base_pose = [0.0, 0.0, 0.0]", "base_pose = [0.0, 0.0]"),
     "initial.base_pose"),
    ("wrong_type_param", lambda t: edit(t, "damping_ratio = 0.02", 'damping_ratio = "low"'),
     "params.link.damping_ratio"),
    ("wrong_grasp_values", lambda t: edit(t, "grasp = [1, 0]", "grasp = [1, 2]"), "initial.grasp"),
    ("unknown_controller_kind", lambda t: edit(t, 'kind = "constant"', 'kind = "magic"'), "controller.kind"),
    ("negative_mass", lambda t: t + "[params.base]\nmass = -300.0\n", "params.base.mass"),
    ("zero_length", lambda t: edit(t, "damping_ratio = 0.02", "damping_ratio = 0.02\nlength = 0.0"),
     "params.link.length"),
    ("negative_damping", lambda t: edit(t, "damping_ratio = 0.02", "damping_ratio = -0.01"),
     "params.link.damping_ratio"),
    ("negative_duration", lambda t: edit(t, "duration = 2.0", "duration = -2.0"), "duration"),
    ("nan_param", lambda t: edit(t, "damping_ratio = 0.02", "damping_ratio = nan"), "params.link.damping_ratio"),
    ("inf_duration", lambda t: edit(t, "duration = 2.0", "duration = inf"), "duration"),
    ("nan_in_vector", lambda t: edit(t, "base_rate = [0.0, 0.0, 0.01]", "base_rate = [0.0, nan, 0.01]"),
     "initial.base_rate"),
    ("inf_rtol", lambda t: edit(t, "rtol = 1e-9", "rtol = inf"), "solver.rtol"),
    ("missing_description", lambda t: edit(t, 'description = "a valid case"\n', ""), "description"),
    ("missing_duration", lambda t: edit(t, "duration = 2.0\n", ""), "duration"),
    ("missing_name", lambda t: edit(t, 'name = "{name}"\n', ""), "name"),
    ("name_not_stem", lambda t: edit(t, 'name = "{name}"', 'name = "other_name"'), "name"),
    ("target_pose_with_grasp",
     lambda t: edit(t, "wrist_angle_deg = 0.0", "wrist_angle_deg = 0.0\ntarget_pose = [5.0, 0.0, 0.0]"),
     "initial.target_pose"),
    ("no_grasp_no_target_pose", lambda t: edit(t, "grasp = [1, 0]", "grasp = [0, 0]"), "initial.target_pose"),
    ("output_period_not_multiple", lambda t: edit(t, "output_period = 1e-2", "output_period = 2.5e-3"),
     "solver.output_period"),
    ("output_period_below_control", lambda t: edit(t, "output_period = 1e-2", "output_period = 5e-4"),
     "solver.output_period"),
    ("short_longer_than_case", lambda t: edit(t, "short_duration = 1.0", "short_duration = 3.0"),
     "short_duration"),
    ("release_of_free_arm", lambda t: t + "[[release]]\ntime = 0.5\narm = 2\n", "release[0].arm"),
    ("release_after_end", lambda t: t + "[[release]]\ntime = 5.0\narm = 1\n", "release[0].time"),
    ("release_without_time", lambda t: t + "[[release]]\narm = 1\n", "release[0].time"),
    ("bad_n_modes", lambda t: edit(t, "n_modes = 2", "n_modes = 9"), "reference.n_modes"),
    ("link_inertia_below_slender_beam",
     lambda t: edit(t, "damping_ratio = 0.02", "damping_ratio = 0.02\ninertia_z = 5.0"), "params.link.inertia_z"),
    ("exudyn_unknown_key", lambda t: t + '[exudyn]\nstep = 1e-5\nwhy = "a study"\n', "exudyn.step"),
    ("exudyn_substeps_not_integer", lambda t: t + '[exudyn]\nsubsteps = 2.5\nwhy = "a study"\n', "exudyn.substeps"),
    ("exudyn_substeps_zero", lambda t: t + '[exudyn]\nsubsteps = 0\nwhy = "a study"\n', "exudyn.substeps"),
    ("exudyn_without_why", lambda t: t + "[exudyn]\nsubsteps = 32\n", "exudyn.why"),
    ("reference_h_max_negative", lambda t: edit(t, "n_modes = 2", 'n_modes = 2\nh_max = -1e-4\nwhy = "a study"'),
     "reference.h_max"),
    ("reference_h_max_text", lambda t: edit(t, "n_modes = 2", 'n_modes = 2\nh_max = "small"\nwhy = "a study"'),
     "reference.h_max"),
    ("reference_h_max_without_why", lambda t: edit(t, "n_modes = 2", "n_modes = 2\nh_max = 2e-4"), "reference.why"),
    ("reference_quiet_integrator_unknown",
     lambda t: edit(t, "n_modes = 2", 'n_modes = 2\nquiet_integrator = "rk4"\nwhy = "a study"'),
     "reference.quiet_integrator"),
    ("reference_quiet_integrator_without_why",
     lambda t: edit(t, "n_modes = 2", 'n_modes = 2\nquiet_integrator = "imex"'), "reference.why"),
    ("reference_unknown_key", lambda t: edit(t, "n_modes = 2", "n_modes = 2\nrtol = 1e-9"), "reference.rtol"),
    ("exudyn_constraints_unknown", lambda t: t + '[exudyn]\nconstraints = "index1"\nwhy = "a study"\n',
     "exudyn.constraints"),
    ("exudyn_restart_negative", lambda t: t + '[exudyn]\nrestart_threshold = -0.1\nwhy = "a study"\n',
     "exudyn.restart_threshold"),
    ("exudyn_newton_atol_zero", lambda t: t + '[exudyn]\nnewton_atol = 0.0\nwhy = "a study"\n',
     "exudyn.newton_atol"),
    ("exudyn_newton_atol_without_why", lambda t: t + '[exudyn]\nnewton_atol = 1e-3\n', "exudyn.why"),
    ("exudyn_jacobian_per_step_text", lambda t: t + '[exudyn]\njacobian_per_step = "yes"\nwhy = "a study"\n',
     "exudyn.jacobian_per_step"),
    ("exudyn_jacobian_per_step_without_why", lambda t: t + '[exudyn]\njacobian_per_step = true\n', "exudyn.why"),
    ("exudyn_constraints_without_why", lambda t: t + '[exudyn]\nconstraints = "index2"\n', "exudyn.why"),
    ("growth_without_window", lambda t: t + GROWTH, "compare.motor_torques.window"),
    ("window_with_final",
     lambda t: t + '[compare.motor_torques]\ntolerance = 0.02\nwhy = "w."\nmetric = "final"\nwindow = [0.5, 1.0]\n',
     "compare.motor_torques.window"),
    ("window_reversed", lambda t: t + GROWTH + "window = [1.5, 0.5]\n", "compare.motor_torques.window"),
    ("window_not_a_pair", lambda t: t + GROWTH + "window = [0.5]\n", "compare.motor_torques.window"),
    ("window_text", lambda t: t + GROWTH + 'window = [0.5, "end"]\n', "compare.motor_torques.window"),
    ("window_after_the_run", lambda t: t + GROWTH + "window = [0.5, 3.0]\n", "compare.motor_torques.window"),
    ("ramp_time_without_torques",
     lambda t: edit(t, 'kind = "constant"\nmotor_torques = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nbase_torque = 0.0',
                    'kind = "none"\nramp_time = 0.5'), "controller.ramp_time"),
    *((f"ramp_time_{name}", lambda t, v=value: edit(t, "base_torque = 0.0", f"base_torque = 0.0\nramp_time = {v}"),
       "controller.ramp_time") for name, value in (("negative", "-0.5"), ("text", '"slow"'), ("not_finite", "inf"))),
    ("sine_without_torques",
     lambda t: edit(t, 'kind = "constant"\nmotor_torques = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nbase_torque = 0.0',
                    'kind = "none"\nsine_frequency_hz = 2.0'), "controller.sine_frequency_hz"),
    ("sine_amplitude_of_five", lambda t: edit(t, "base_torque = 0.0", "base_torque = 0.0\nsine_amplitude = [1, 2, 3, 4, 5]"),
     "controller.sine_amplitude"),
    ("sine_frequency_negative", lambda t: edit(t, "base_torque = 0.0", "base_torque = 0.0\nsine_frequency_hz = -1.0"),
     "controller.sine_frequency_hz"),
    ("toml_syntax", lambda t: t + "this is not toml\n", "toml"),
]


@pytest.mark.parametrize("mutate, field", [(m, f) for _, m, f in BAD], ids=[i for i, _, _ in BAD])
def test_bad_case_file_names_file_and_field(tmp_path, mutate, field):
    path = write(tmp_path, mutate(VALID))
    with pytest.raises(InputError) as info:
        load_case(path)
    err = info.value
    assert err.where == str(path)
    assert err.field == field or err.field.startswith(field + "[") or err.field.startswith(field + "."), (
        err.field, field)
    message = str(err)
    assert message.startswith(str(path)) and field in message
    assert "\n" not in message and err.reason.strip()


def test_missing_case_file_lists_the_known_cases(tmp_path):
    with pytest.raises(InputError) as info:
        load_case(tmp_path / "nowhere.toml")
    assert info.value.where.endswith("nowhere.toml")
    with pytest.raises(InputError) as info:
        load_case("no_such_case")
    assert "free_drift" in info.value.reason and "closed_squeeze" in info.value.reason


def test_non_utf8_file_is_an_input_error(tmp_path):
    path = tmp_path / "binary.toml"
    path.write_bytes(b'name = "binary"\n\xff\xfe\n')
    with pytest.raises(InputError) as info:
        load_case(path)
    assert info.value.where == str(path)


@pytest.mark.parametrize("name", ["free_drift", "closed_squeeze"])
def test_shipped_cases_load(name):
    case = load_case(name)
    assert case.name == name
    assert case.description.strip()
    assert math.isfinite(case.duration) and case.duration > 0
    assert case.solver.output_every >= 1
