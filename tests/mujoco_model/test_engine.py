"""The MuJoCo engine's conservation laws and switched forces: momentum in free flight, the
wrist stop's sign, a capture's plastic impact."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")

from mujoco_model.engine import MujocoEngine  # noqa: E402
from rsmcheck.core.cases import load_case  # noqa: E402
from rsmcheck.core.engine import Inputs  # noqa: E402
from rsmcheck.core.plugins import plugin  # noqa: E402


def test_momentum_kept_in_free_flight():
    """Internal motor torques keep the momentum of base, links and target
    (docs/physics.md §3.4): 0.1 s of flex_arm_step's shoulder step from a drifting start."""
    case = load_case("flex_arm_step")
    e = MujocoEngine(case)
    e.d.qvel[e.mm.index.base] = [0.01, -0.02, 0.03]
    e._fresh = False
    u = Inputs(tau_m=np.array([0.0, 0.0, 0.0, 10.0, 0.0, 0.0]))
    e.refresh()
    p0 = e.observer.momentum()
    for j in range(100):
        e.advance((j + 1) * 1e-3, u)
    e.refresh()
    p1 = e.observer.momentum()
    assert np.max(np.abs(p1 - p0)) < 1e-10, p1 - p0
    assert e.sensors().joint_angles[3] > case.initial.joint_angles_deg[3] * np.pi / 180  # it moved


def test_wrist_stop_pushes_back():
    """Beyond +ψ_lim the stop's torque on the target is negative, on the terminal link's
    distal piece positive, and zero inside the range (docs/physics.md §4.3)."""
    e = MujocoEngine(load_case("wrist_tumble"))
    m, d, ix = e.mm.model, e.d, e.mm.index
    lim = e.params.wrist.limit
    for psi_over, sign in ((0.01, -1.0), (-0.01, 1.0), (-0.3, 0.0)):
        d.qpos[ix.target[2]] = ix.wrist[0] @ d.qpos + np.copysign(lim, psi_over) + psi_over \
            if sign else ix.wrist[0] @ d.qpos + psi_over
        d.qvel[:] = 0.0
        d.qfrc_passive[:] = 0.0
        e._passive(m, d)
        tau = d.qfrc_passive[ix.target[2]]
        if sign == 0.0:
            assert tau == 0.0
        else:
            assert np.sign(tau) == sign
            assert abs(tau) == pytest.approx(e.params.wrist.stiffness * 0.01, rel=1e-9)
            assert d.qfrc_passive[ix.base[2]] == pytest.approx(-tau)


def test_capture_is_a_plastic_impact():
    """A capture with the end effector moving relative to the target: the held point is
    the coincident one, the momentum is kept to round-off, the velocities meet, energy is
    lost (docs/physics.md §4.2)."""
    case = load_case("capture")
    e = MujocoEngine(case)
    ix = e.mm.index
    e.d.qvel[ix.rotor[1]] += [0.002, -0.001, 0.001]
    e.d.qvel[ix.target] += [0.001, 0.0005, 0.0002]
    e._fresh = False
    e.refresh()
    p0 = e.observer.momentum()
    info = e.capture(2)
    e.refresh()
    p1 = e.observer.momentum()
    assert np.max(np.abs(p1 - p0)) < 1e-11, p1 - p0
    assert info["impact_loss_J"] > 0.0
    s = e.sensors()
    assert s.grasp_state[1] == 1
    obs = e.observe(Inputs())
    assert np.max(np.abs(obs["constraint_residual"][2:])) < 1e-12
    from rsmcheck.core.geometry import rot

    tgt = s.target_pose_I
    lever = rot(tgt[2]) @ e.state.rho_G[1]
    v_point = s.target_rate_I[:2] + s.target_rate_I[2] * np.array([-lever[1], lever[0]])
    assert np.allclose(s.ee_vel_I[1], v_point, atol=1e-12)


def test_plugin_settings_and_refinement():
    p = plugin("mujoco")
    case = load_case("flex_arm_step")
    s = p.parse_settings({"mujoco": {}}, {}, "x.toml", lambda k: k)
    assert p.step_perturbed(s, 10.0) is s
    opts = p.refined_options(case)
    assert set(opts) <= set(p.engine_options)
    assert opts["n_segments"] == 16 and opts["timestep"] < 1.4e-5
    from rsmcheck.core.errors import InputError

    with pytest.raises(InputError):
        p.parse_settings({"mujoco": {"n_segments": 12}}, {}, "x.toml", lambda k: k)  # no why


def _into_the_stop(delta: float) -> MujocoEngine:
    """wrist_tumble's robot at rest with the held target turned about its held point to
    ψ = ψ_lim + δ: the grasp's constraint met, the stop loaded."""
    from rsmcheck.core.geometry import rot

    e = MujocoEngine(load_case("wrist_tumble"))
    m, d, ix = e.mm.model, e.d, e.mm.index
    d.qvel[:] = 0.0
    e.refresh()
    held = d.site_xpos[ix.hold_site[0], :2].copy()
    th = ix.wrist[0] @ d.qpos + e.params.wrist.limit + delta
    d.qpos[ix.target[2]] = th
    d.qpos[ix.target[:2]] = held - rot(th) @ e.state.rho_G[0]
    import mujoco

    mujoco.mj_forward(m, d)
    e._fresh = True
    return e


def _energy(e: MujocoEngine) -> float:
    e.refresh()
    return float(np.sum(e.observer.energy(e.sensors())))


def test_stop_contact_dissipates_with_its_substeps():
    """The stop's damping λδ on the distal end piece (inertia ρA(ℓ/2)³/3) is 18 times RK4's
    bound at the case's 0.1 ms step (δ = 0.02 rad); cut by `_contact_steps` to λδh/I ≤ 2, the
    released stop only dissipates: no force but the springs, the Kelvin–Voigt and the stop's
    damping acts, so the energy cannot grow (docs/physics.md §4.3)."""
    e = _into_the_stop(0.02)
    assert abs(e.d.qpos[e.mm.index.target[2]] - e.mm.index.wrist[0] @ e.d.qpos - 0.52) < 1e-12
    E = [_energy(e)]
    assert E[0] == pytest.approx(0.5 * e.params.wrist.stiffness * 0.02**2, rel=1e-6)
    for j in range(20):
        e.advance((j + 1) * 1e-3, Inputs())
        E.append(_energy(e))
    assert e.state.stats["stop_substeps"] > 0
    assert np.all(np.diff(E) < 1e-9 * E[0]), np.diff(E)
    assert E[-1] < E[0]


def test_stop_contact_needs_its_substeps(monkeypatch):
    """The same start at the case's step alone: RK4 is unstable on the end piece and the
    energy grows (the contact chatters)."""
    from rsmcheck.core.errors import SimulationDiverged

    e = _into_the_stop(0.02)
    monkeypatch.setattr(e, "_contact_steps", lambda span: 1)
    E0, top = _energy(e), 0.0
    try:
        for j in range(10):
            e.advance((j + 1) * 1e-3, Inputs())
            top = max(top, _energy(e))
    except SimulationDiverged:
        top = np.inf
    assert top > 5.0 * E0  # 1 J → 16 J in 6 ms


def test_departures_only_where_measured():
    """motor_step's end-section departure is ε/3 of MuJoCo's own error the short rows record
    (Richardson at order 2, docs/mujoco.md §5); the full run, not measured, declares none."""
    p = plugin("mujoco")
    case = load_case("motor_step")
    short = p.departures(case.variant(True))
    assert set(short) == {"motor_angles", "joint_angles"}
    recorded = {s.observable: s.engine_errors["mujoco"] for s in case.variant(True).compare}
    for obs, (size, why) in short.items():
        assert size == pytest.approx(recorded[obs] / 3, rel=0.05) and "ε/3" in why, (obs, size, recorded[obs])
    assert p.departures(case.variant(False)) == {}
    assert p.departures(load_case("flex_arm_step").variant(True)) == {}
