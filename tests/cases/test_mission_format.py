"""The case-format extensions for controllers, programmes, chaining, comparisons and short
variants: every kind of bad input stops with the file, the key and a reason (exit 2)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.cli import main
from rsmcheck.core.errors import InputError

PROGRAMME = """
name = "{name}"
description = "test"
duration = 10.0
{top}
[initial]
joint_angles_deg = [60.0, -120.0, 60.0, -60.0, 120.0, -60.0]
grasp = [1, 0]
{initial}
[controller]
kind = "programme"
gains = "Test gains."
base = {{ kp = 100.0, kd = 1000.0 }}
arm1 = {{ kp = [1000.0, 1000.0, 1000.0], kd = [100.0, 100.0, 50.0] }}
arm2 = {{ kp = [1000.0, 1000.0, 1000.0], kd = [100.0, 100.0, 50.0] }}
{controller}
[[segment]]
name = "approach"
duration = 6.0
{segment}
[[segment]]
name = "hold"
duration = 4.0
{rest}
"""


def write(tmp_path: Path, name: str = "t", top: str = "", initial: str = "", controller: str = "",
          segment: str = 'until = "capture"\ncapture = { arm = 2 }\narm2 = { mode = "approach" }',
          rest: str = "") -> Path:
    text = PROGRAMME.format(name=name, top=top, initial=initial, controller=controller, segment=segment,
                            rest=rest)
    path = tmp_path / f"{name}.toml"
    path.write_text(textwrap.dedent(text))
    return path


def bad(path: Path, key: str, reason: str) -> InputError:
    with pytest.raises(InputError) as info:
        load_case(path)
    assert info.value.field == key, str(info.value)
    assert reason in info.value.reason, str(info.value)
    assert info.value.where == str(path)
    return info.value


def test_a_good_programme_loads(tmp_path):
    case = load_case(write(tmp_path))
    assert [s.name for s in case.segments] == ["approach", "hold"]
    seg = case.segments[0]
    assert seg.until == "capture" and seg.capture.arm == 2
    assert seg.arm2.mode == "approach"
    assert seg.arm2.point_T == case.params.geometry.grasp_T(2)  # defaults to the capture point
    assert case.controller.arm1.kp == (1000.0, 1000.0, 1000.0)


# ---- unknown keys ---------------------------------------------------------------------
@pytest.mark.parametrize("where, text, key", [
    ("controller", "damping = 1.0", "controller.damping"),
    ("segment", 'speed = 2.0\ncapture = { arm = 2 }', "segment[0].speed"),
    ("segment", 'arm1 = { mode = "hold", gain = 1 }', "segment[0].arm1.gain"),
    ("segment", 'capture = { arm = 2, where = "x" }', "segment[0].capture.where"),
    ("rest", '[compare.ee2_speed]\ntolerance = 1.0\nwhy = "x."\nunit = "m"', "compare.ee2_speed.unit"),
    ("rest", '[orbit]\nenabled = true\nphase = 1.0', "orbit.phase"),
    ("rest", '[short]\nduration = 5.0\n[short.controller]\nkind = "none"\nfoo = 1', "short.controller.foo"),
])
def test_unknown_keys(tmp_path, where, text, key):
    bad(write(tmp_path, **{where: text}), key, "unknown key")


# ---- wrong types ----------------------------------------------------------------------
@pytest.mark.parametrize("where, text, key, reason", [
    ("controller", "rate_filter_hz = \"fast\"", "controller.rate_filter_hz", "must be a number"),
    ("controller", "feedback = 3", "controller.feedback", "must be one of"),
    ("segment", "thrust = 1\ncapture = { arm = 2 }", "segment[0].thrust", "must be true or false"),
    ("segment", "release = 1\ncapture = { arm = 2 }", "segment[0].release", "list of distinct arms"),
    ("segment", 'arm1 = { mode = "move", to = [1.0, 2.0] }', "segment[0].arm1.to", "list of 3 numbers"),
    ("segment", 'capture = { arm = "two" }', "segment[0].capture.arm", "must be 1 or 2"),
    ("rest", '[compare.ee2_speed]\ntolerance = "small"\nwhy = "x."', "compare.ee2_speed.tolerance", "must be a number"),
    ("top", 'start_from = 3', "start_from", "non-empty string"),
    ("rest", '[solver]\nintegrator = "euler"', "solver.integrator", "must be one of"),
    ("segment", 'control_period = "fast"\ncapture = { arm = 2 }', "segment[0].control_period", "must be a number"),
    ("initial", "wrist_rate = \"slow\"", "initial.wrist_rate", "must be a number"),
    ("initial", "held_points = [1.0, 2.0, 3.0]", "initial.held_points", "two points"),
])
def test_wrong_types(tmp_path, where, text, key, reason):
    bad(write(tmp_path, **{where: text}), key, reason)


def test_controller_gain_vectors_are_typed(tmp_path):
    p = write(tmp_path, controller="")
    text = p.read_text().replace("kd = [100.0, 100.0, 50.0] }\narm2", "kd = [100.0, 100.0] }\narm2")
    p.write_text(text)
    bad(p, "controller.arm1.kd", "list of 3 numbers")


# ---- out of range ---------------------------------------------------------------------
@pytest.mark.parametrize("where, text, key, reason", [
    ("controller", "rate_filter_hz = -1.0", "controller.rate_filter_hz", ">= 0.0"),
    ("segment", 'settle = -1.0\nuntil = "capture"\ncapture = { arm = 2 }', "segment[0].settle", ">= 0.0"),
    ("segment", 'arm1 = { mode = "move", to = [4.0, 0.6, 0.0], time = 0.0 }', "segment[0].arm1.time", "> 0.0"),
    ("segment", 'capture = { arm = 2, point = [-2.0, 0.0] }', "segment[0].capture.point", "outside the target"),
    ("rest", '[compare.ee2_speed]\ntolerance = 0.0\nwhy = "x."', "compare.ee2_speed.tolerance", "> 0.0"),
    ("rest", '[orbit]\nenabled = true\naltitude = 10.0', "orbit.altitude", ">= 100000.0"),
    ("rest", '[solver]\ncontrol_period = 0.5', "solver.control_period", "<= 0.1"),
    ("segment", 'control_period = 0.0\ncapture = { arm = 2 }', "segment[0].control_period", "> 0.0"),
    ("segment", 'control_period = 0.2\ncapture = { arm = 2 }', "segment[0].control_period", "<= 0.1"),
])
def test_out_of_range(tmp_path, where, text, key, reason):
    bad(write(tmp_path, **{where: text}), key, reason)


def test_segment_duration_must_be_positive(tmp_path):
    p = write(tmp_path)
    p.write_text(p.read_text().replace("duration = 4.0", "duration = -4.0"))
    bad(p, "segment[1].duration", "> 0.0")


def test_com_align_iterations_are_bounded(tmp_path):
    rest = ('[[segment]]\nname = "align"\nduration = 100.0\narm1 = { mode = "carry" }\n'
            'target = { mode = "com_align", max_iterations = 0 }')
    p = write(tmp_path, rest="")
    p.write_text(p.read_text().replace("duration = 10.0", "duration = 110.0", 1) + rest)
    bad(p, "segment[2].target.max_iterations", "integer 1..100")


# ---- inconsistent values --------------------------------------------------------------
@pytest.mark.parametrize("where, text, key, reason", [
    ("segment", 'capture = { arm = 1 }', "segment[0].capture.arm", "already holds"),
    ("segment", 'until = "capture"', "segment[0].until", "needs a capture"),
    ("segment", 'settle = 1.0\ncapture = { arm = 2 }', "segment[0].settle", "only with until"),
    ("segment", 'release = [2]\ncapture = { arm = 2 }', "segment[0].release", "does not hold"),
    ("segment", 'release = [1]\ncapture = { arm = 2 }', "segment[0].capture.arm", "nothing holds"),
    ("segment", 'arm2 = { mode = "carry" }\ncapture = { arm = 2 }', "segment[0].arm2.mode", "needs a target command"),
    ("segment", 'arm1 = { mode = "carry" }\ntarget = { mode = "move", to = [6.0, 0.0, 0.0] }\narm2 = { mode = "approach" }\ncapture = { arm = 2 }', None, None),
    ("segment", 'target = { mode = "move", to = [6.0, 0.0, 0.0] }', "segment[0].target", "no arm is in mode"),
    ("segment", 'arm1 = { mode = "approach", point = "grasp1" }', "segment[0].arm1.mode", "already holds"),
    ("segment", 'arm1 = { mode = "hold", to = [1.0, 1.0, 0.0] }', "segment[0].arm1.to", "not used by mode"),
    ("segment", 'arm2 = { mode = "approach" }', "segment[0].arm2.point", "missing"),
    ("segment", 'arm1 = { mode = "move", to = [4.0, 0.6, 0.0], time = 7.0 }', "segment[0].arm1.time", "exceeds the segment"),
    ("segment", 'base = "hold"\nbase_angle_deg = 10.0', "segment[0].base_angle_deg", "only with base"),
    ("top", 'start_from = "t"', "start_from", "its own end state"),
    ("top", 'start_from = "no_such_case"', "start_from", "no case"),
    ("rest", '[compare.not_an_observable]\ntolerance = 1.0\nwhy = "x."', "compare.not_an_observable", "not an observable"),
    ("rest", '[compare.ee2_speed]\ntolerance = 1.0', "compare.ee2_speed.why", "missing"),
    ("rest", '[orbit]\nalign = "retrograde"', "orbit.align", "not enabled"),
    ("rest", '[short]\nduration = 20.0', "short.duration", "exceeds duration"),
    ("rest", '[short]\n[short.initial]\ngrasp = [1, 1]', "short.initial", "cannot be changed"),
    ("rest", '[short]\nduration = 4.0\n[[short.segment]]\nname = "a"\nduration = 5.0', "short.segment", "longer than the case"),
    ("initial", "wrist_rate = 0.1\ngrasp = [0, 0]\ntarget_pose = [8.0, 0.0, 0.0]", None, None),
])
def test_inconsistent_values(tmp_path, where, text, key, reason):
    path = write(tmp_path, **{where: text})
    if key is None:  # a consistent variant of its neighbour: loads
        if "grasp = [0, 0]" in text:
            # (the TOML above repeats the grasp key: a TOML error, still exit 2)
            with pytest.raises(InputError):
                load_case(path)
            return
        load_case(path)
        return
    bad(path, key, reason)


def test_wrist_rate_without_a_grasp(tmp_path):
    p = write(tmp_path)
    p.write_text(p.read_text().replace("grasp = [1, 0]", 'grasp = [0, 0]\ntarget_pose = [8.0, 0.0, 0.0]\nwrist_rate = 0.1')
                 .replace('until = "capture"\ncapture = { arm = 2 }\narm2 = { mode = "approach" }', ""))
    bad(p, "initial.wrist_rate", "no arm holds")


def test_segments_need_a_programme_and_vice_versa(tmp_path):
    p = write(tmp_path)
    p.write_text(p.read_text().replace('kind = "programme"\ngains = "Test gains."\nbase = { kp = 100.0, kd = 1000.0 }\n'
                                       'arm1 = { kp = [1000.0, 1000.0, 1000.0], kd = [100.0, 100.0, 50.0] }\n'
                                       'arm2 = { kp = [1000.0, 1000.0, 1000.0], kd = [100.0, 100.0, 50.0] }',
                                       'kind = "none"'))
    bad(p, "controller.kind", "must be \"programme\"")
    q = tmp_path / "q.toml"
    q.write_text('name = "q"\ndescription = "x"\nduration = 1.0\n[controller]\nkind = "programme"\n'
                 'gains = "x."\nbase = { kp = 1.0, kd = 1.0 }\narm1 = { kp = [1.0, 1.0, 1.0], kd = [1.0, 1.0, 1.0] }\n'
                 'arm2 = { kp = [1.0, 1.0, 1.0], kd = [1.0, 1.0, 1.0] }\n')
    bad(q, "segment", "at least one")
    r = tmp_path / "r.toml"
    r.write_text('name = "r"\ndescription = "x"\nduration = 1.0\n[controller]\nkind = "none"\n'
                 'base = { kp = 1.0, kd = 1.0 }\n')
    bad(r, "controller.base", "only for kind")
    s = tmp_path / "s.toml"
    s.write_text('name = "s"\ndescription = "x"\nduration = 1.0\n[controller]\nkind = "programme"\n'
                 'base = { kp = 1.0, kd = 1.0 }\narm1 = { kp = [1.0, 1.0, 1.0], kd = [1.0, 1.0, 1.0] }\n'
                 'arm2 = { kp = [1.0, 1.0, 1.0], kd = [1.0, 1.0, 1.0] }\n')
    bad(s, "controller.gains", "missing")


def test_duplicate_segment_names_and_too_long_programmes(tmp_path):
    p = write(tmp_path)
    p.write_text(p.read_text().replace('name = "hold"', 'name = "approach"'))
    bad(p, "segment[1].name", "earlier segment")
    p = write(tmp_path)
    p.write_text(p.read_text().replace("duration = 4.0", "duration = 5.0"))
    bad(p, "segment", "longer than the case")


def test_segment_control_period_not_longer_than_the_segment(tmp_path):
    p = write(tmp_path, rest="control_period = 0.1")
    p.write_text(p.read_text().replace("duration = 4.0", "duration = 0.05"))
    bad(p, "segment[1].control_period", "longer than the segment")


def test_runner_follows_segment_control_periods(tmp_path):
    """A quiet segment may sample more slowly; the boundaries are hit exactly."""
    from reference_model.engine import ReferenceEngine
    from rsmcheck.driver.runner import run

    text = PROGRAMME.format(name="cp", top="", initial="", controller="",
                            segment="", rest="control_period = 0.015")
    text = (text.replace("duration = 10.0", "duration = 0.2", 1).replace("duration = 6.0", "duration = 0.05")
            .replace("duration = 4.0", "duration = 0.15"))
    path = tmp_path / "cp.toml"
    path.write_text(text + "[solver]\ncontrol_period = 0.001\noutput_period = 0.001\n")
    case = load_case(path)
    r = run(ReferenceEngine(case), case)
    t = r.observables["time"]
    first = t[t <= 0.05 + 1e-12]
    assert np.allclose(np.diff(first), 0.001)
    rest = t[t >= 0.05 - 1e-12]
    assert rest[0] == pytest.approx(0.05, abs=1e-15)
    steps = np.diff(rest)
    assert np.allclose(steps[:-1], 0.015) and 0 < steps[-1] <= 0.015 + 1e-12
    assert t[-1] == pytest.approx(0.2, abs=1e-12)
    assert [p.t_start for p in r.phases if p.name == "cp:hold"] == [pytest.approx(0.05)]


def test_duration_must_be_whole_control_periods(tmp_path):
    p = write(tmp_path)
    p.write_text(p.read_text().replace("duration = 10.0", "duration = 10.0005", 1))
    bad(p, "duration", "whole number of control periods")


def test_short_duration_given_twice(tmp_path):
    p = write(tmp_path, top="short_duration = 5.0", rest="[short]\nduration = 4.0")
    bad(p, "short_duration", "given twice")


def test_short_variant_replaces_the_programme(tmp_path):
    rest = ('[short]\nduration = 3.0\n[[short.segment]]\nname = "quick"\nduration = 3.0\n'
            'capture = { arm = 2 }\narm2 = { mode = "approach", time = 2.0 }')
    case = load_case(write(tmp_path, rest=rest))
    assert case.short_duration == 3.0
    short = case.variant(True)
    assert short.is_short and [s.name for s in short.segments] == ["quick"]
    assert case.variant(False) is case
    assert short.initial == case.initial and short.params == case.params


def test_short_errors_name_the_short_table(tmp_path):
    rest = '[short]\nduration = 3.0\n[[short.segment]]\nname = "quick"\nduration = 3.0\nthrust = "yes"'
    bad(write(tmp_path, rest=rest), "short.segment[0].thrust", "true or false")


# ---- sequence cases -------------------------------------------------------------------
def test_sequence_case_rules(tmp_path):
    m = tmp_path / "m.toml"
    m.write_text('name = "m"\ndescription = "x"\nphases = ["p1_transport", "p3_com_alignment"]\n')
    bad(m, "phases[1]", "not from the previous phase")
    m.write_text('name = "m"\ndescription = "x"\nphases = []\n')
    bad(m, "phases", "non-empty list")
    m.write_text('name = "m"\ndescription = "x"\nphases = ["p1_transport"]\nduration = 3.0\n')
    bad(m, "duration", "not allowed in a sequence")
    m.write_text('name = "m"\ndescription = "x"\nphases = ["nope"]\n')
    bad(m, "phases[0]", "no case")


def test_mission_case_runs_the_phases_in_order():
    case = load_case("mission")
    assert case.phases == ("p1_transport", "p2_capture_regrasp", "p3_com_alignment", "p4_hohmann", "p5_release")
    assert case.duration == pytest.approx(sum(load_case(p).duration for p in case.phases))
    short = case.variant(True)
    assert short.phases == case.phases[1:] and short.is_short
    assert case.short_duration == short.duration == pytest.approx(
        sum(load_case(p).short_duration for p in short.phases))


def test_short_phases_must_chain_too(tmp_path):
    m = tmp_path / "m.toml"
    m.write_text('name = "m"\ndescription = "x"\nphases = ["p1_transport", "p2_capture_regrasp"]\n'
                 'short_phases = ["p2_capture_regrasp", "p4_hohmann"]\n')
    bad(m, "short_phases[1]", "not from the previous phase")
    m.write_text('name = "m"\ndescription = "x"\nphases = ["p1_transport"]\nshort_phases = "p1"\n')
    bad(m, "short_phases", "non-empty list")


# ---- the command line turns each into exit 2 -----------------------------------------
def test_bad_case_file_exits_2_with_one_line(tmp_path, capsys):
    p = write(tmp_path, segment='capture = { arm = 1 }')
    assert main(["run", str(p), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "segment[0].capture.arm" in err[0] and str(p) in err[0]
