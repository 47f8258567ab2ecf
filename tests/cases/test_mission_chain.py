"""Phase chaining (rsmcheck.orchestration.chain): a case starts from the stored end state of another,
the end-state file, entering the orbit, and a sequence case with continuous time."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.orchestration.chain import end_state_path, load_end_state, run_case, start_of
from rsmcheck.core.plugins import make_engine
from rsmcheck.core.errors import InputError
from rsmcheck.driver.initial import build_initial
from rsmcheck.core.store import read_run

GAINS = """
[controller]
kind = "programme"
rate_filter_hz = 1.0
gains = "The flexibility-aware set of p1_transport."
base = { kp = 100.0, kd = 1000.0 }
arm1 = { kp = [1000.0, 1000.0, 1000.0], kd = [100.0, 100.0, 50.0] }
arm2 = { kp = [1000.0, 1000.0, 1000.0], kd = [100.0, 100.0, 50.0] }
"""

A = """
name = "a"
description = "closed chain squeezed off its rest pose, no orbit"
duration = 0.3
[initial]
joint_angles_deg = [37.2624, -69.8644, 32.602, -36.2139, 69.9134, -35.459]
joint_rates = [0.01, -0.02, 0.0, 0.0, 0.0, 0.0]
grasp = [1, 1]
held_points = [[-1.5, 0.8], [-1.5, -0.6]]
""" + GAINS + """
[[segment]]
name = "hold"
duration = 0.3
[solver]
output_period = 0.01
"""

B = """
name = "b"
description = "continues a on orbit with the motor on"
duration = 0.2
start_from = "a"
[orbit]
enabled = true
align = "retrograde"
""" + GAINS + """
[[segment]]
name = "burn"
duration = 0.2
thrust = true
base = "retrograde"
arm1 = { mode = "freeze" }
arm2 = { mode = "freeze" }
[solver]
output_period = 0.01
"""

M = """
name = "m"
description = "a then b"
phases = ["a", "b"]
"""


@pytest.fixture(scope="module")
def chain_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("chain")
    for name, text in (("a", A), ("b", B), ("m", M)):
        (d / f"{name}.toml").write_text(textwrap.dedent(text))
    out = d / "out"
    run_case(load_case(d / "a.toml"), ["reference"], short=False, out_dir=out)
    run_case(load_case(d / "b.toml"), ["reference"], short=False, out_dir=out)
    return d, out


def test_end_state_file(chain_dir):
    d, out = chain_dir
    path = end_state_path(out, "a", short=False)
    doc = json.loads(path.read_text())
    assert doc["format"] == "rsmcheck-endstate" and doc["case"] == "a" and doc["short"] is False
    st = doc["engines"]["reference"]
    assert st["rigid"]["grasp"] == [1, 1]
    assert st["rigid"]["t_end"] == pytest.approx(0.3)
    # the exact state: 2 eigenmodes + 2 static correction shapes per link
    assert len(st["exact"]["x"]) > 40 and st["exact"]["n_modes"] == [4] * 6
    with pytest.raises(InputError, match="full"):
        load_end_state(path, "reference", short=True, where="x")
    with pytest.raises(InputError, match="no end state of engine 'exudyn'"):
        load_end_state(path, "exudyn", short=False, where="x")
    with pytest.raises(InputError, match="run that case first"):
        load_end_state(out / "nothing.end.json", "reference", short=False, where="x")


def test_chained_run_starts_where_the_previous_ended(chain_dir):
    d, out = chain_dir
    ra, _ = read_run(out / "a.h5")
    rb, attrs = read_run(out / "b.h5")
    assert attrs["start_from"] == "a"
    a, b = ra["reference"].observables, rb["reference"].observables
    # relative quantities are continuous through the re-centring on the orbit
    for key in ("joint_angles", "motor_angles", "target_pose_B", "ee1_pos_B", "ee2_pos_B", "link_deflection",
                "grasp_state", "com_pos_B"):
        assert b[key][0] == pytest.approx(a[key][-1], abs=1e-12), key
    assert b["base_pose_I"][0, 2] == pytest.approx(a["base_pose_I"][-1, 2], abs=1e-15)
    assert np.max(np.abs(a["link_deflection"][-1])) > 0  # the exact (modal) state was restored
    # O is at the system COM, on the 700 km circle
    com_I = b["base_pose_I"][0, :2] + np.array(
        [[np.cos(b["base_pose_I"][0, 2]), -np.sin(b["base_pose_I"][0, 2])],
         [np.sin(b["base_pose_I"][0, 2]), np.cos(b["base_pose_I"][0, 2])]]) @ b["com_pos_B"][0]
    assert np.max(np.abs(com_I)) < 1e-9
    assert b["altitude"][0] == pytest.approx(700e3, abs=1e-6)
    assert b["system_mass"][-1] < b["system_mass"][0]


def test_rigid_part_is_what_other_engines_start_from(chain_dir):
    d, out = chain_dir
    st, _ = load_end_state(end_state_path(out, "a", False), "reference", False, "x")
    case = load_case(d / "b.toml")
    start = start_of(st)
    init = build_initial(case, start=start)
    rigid = st["rigid"]
    # undeformed links placed by the frame angles; each spring keeps its twist θ_m − ψ_J
    assert init.joint_angles == pytest.approx(rigid["joint_frame_angles"], abs=0)
    twist = np.asarray(rigid["motor_angles"]) - np.asarray(rigid["joint_angles"])
    assert init.motor_angles - init.joint_angles == pytest.approx(twist, abs=1e-15)
    assert np.max(np.abs(np.asarray(rigid["joint_angles"]) - rigid["joint_frame_angles"])) > 1e-7  # bent links
    assert init.rho_G == pytest.approx(np.array(rigid["held_points"]), abs=0)
    assert init.m_used == pytest.approx(rigid["m_used"])
    assert np.linalg.norm(init.orbit_r) == pytest.approx(6378137.0 + 700e3)
    # the exact reference restore and the rigid start agree on the rigid coordinates
    engine = make_engine("reference", case, start)
    s = engine.sensors()
    assert s.joint_frame_angles == pytest.approx(init.joint_angles, abs=1e-12)
    assert s.joint_angles == pytest.approx(rigid["joint_angles"], abs=1e-12)  # the bent links restored
    assert s.base_pose_I == pytest.approx(init.base_pose, abs=1e-12)
    assert s.orbit_r_I == pytest.approx(init.orbit_r, abs=1e-6)


def test_a_case_that_only_chains_needs_its_predecessor(tmp_path):
    (tmp_path / "a.toml").write_text(textwrap.dedent(A))
    (tmp_path / "b.toml").write_text(textwrap.dedent(B))
    with pytest.raises(InputError, match="run that case first"):
        run_case(load_case(tmp_path / "b.toml"), ["reference"], short=False, out_dir=tmp_path / "out")
    with pytest.raises(InputError, match="run it chained"):
        build_initial(load_case(tmp_path / "b.toml"))


def test_sequence_case_runs_the_phases_with_continuous_time(chain_dir):
    d, out = chain_dir
    path = run_case(load_case(d / "m.toml"), ["reference"], short=False, out_dir=out / "m")
    runs, attrs = read_run(path)
    r = runs["reference"]
    t = r.observables["time"]
    assert t[0] == 0.0 and t[-1] == pytest.approx(0.5)
    assert np.all(np.diff(t) >= 0)
    names = [p.name for p in r.phases]
    assert names[:2] == ["a", "a:hold"] and "b" in names and "b:burn" in names
    b = [p for p in r.phases if p.name == "b"][0]
    assert b.t_start == pytest.approx(0.3) and b.t_end == pytest.approx(0.5)
    assert attrs["mission_phases"] == "a,b"
    # the same as running the phases one by one
    rb, _ = read_run(out / "b.h5")
    assert r.observables["joint_angles"][-1] == pytest.approx(rb["reference"].observables["joint_angles"][-1], abs=1e-12)


def test_orbit_start_puts_o_at_the_com_with_the_thrust_retrograde():
    from rsmcheck.driver.initial import rigid_com

    case = load_case("thrust_burn")
    init = build_initial(case)
    com, vcom = rigid_com(case.params, init)
    assert np.max(np.abs(com)) < 1e-12 and np.max(np.abs(vcom)) < 1e-12
    r = np.linalg.norm(init.orbit_r)
    assert r == pytest.approx(case.params.orbit.earth_radius + case.params.orbit.altitude_initial)
    v_hat = init.orbit_v / np.linalg.norm(init.orbit_v)
    x_B = np.array([np.cos(init.base_pose[2]), np.sin(init.base_pose[2])])
    assert v_hat == pytest.approx(-x_B, abs=1e-15)  # thrust along +x_B is retrograde
    assert init.orbit_r @ init.orbit_v == pytest.approx(0.0, abs=1e-3)  # circular
    assert np.linalg.norm(init.orbit_v) == pytest.approx(np.sqrt(case.params.orbit.mu / r))
    p5 = build_initial(load_case("p5_release"))
    assert np.linalg.norm(p5.orbit_r) == pytest.approx(case.params.orbit.earth_radius + 300e3)


def test_short_runs_start_p2_from_its_own_initial(tmp_path):
    """The short mission starts at p2 (p1's short variant does not bring the target into arm
    2's reach): with --short, p2 ignores a stored p1 end state; p3 still chains from p2, and
    full-length runs chain as usual."""
    from rsmcheck.orchestration.chain import starts_short_sequence, use_stored_start

    assert starts_short_sequence("p2_capture_regrasp")
    assert not starts_short_sequence("p3_com_alignment")
    assert not starts_short_sequence("p1_transport")
    stored = tmp_path / "p1_transport.short.end.json"
    stored.write_text("{}")
    p2 = load_case("p2_capture_regrasp")
    assert not use_stored_start(p2.variant(True), stored, short=True)
    assert use_stored_start(p2, stored, short=False)
    assert use_stored_start(load_case("p3_com_alignment").variant(True), stored, short=True)
    assert not use_stored_start(p2, tmp_path / "missing.json", short=False)
