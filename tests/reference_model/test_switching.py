"""Basis switch, capture and release (docs/physics.md §4.2, §4.4).

Material points are evaluated here from the frame and the mode shapes, independently of
`switching`: r(ξ) = R + A(θ)(ξ, w(ξ)), ṙ(ξ) = Ṙ + θ̇ A S (ξ, w) + A e_y ẇ(ξ), at many ξ
along the switched link, before and after.  What must hold:

* the pins (ξ = 0 and ξ = L, the latter the end effector) are continuous up to the
  documented second-order axial term: ≤ 1e-9 m and m/s at a realistic deflection
  (≈1e-5 m tip deflection, slow elastic rates), and for a vibrating link the measured pin
  jump *is* that term (w_L ẇ_L/L-type, derived in the tests below);
* the field away from the pins jumps by the projection residual: the measured jump equals
  the `residual_m` / `residual_mps` the switch reports, and it shrinks as n_modes grows;
* the plastic impact of capture conserves linear and angular momentum (≤ 1e-9 relative)
  and dissipates the kinetic energy of the velocities it takes away (Carnot's theorem),
  no more, no less; capture → release returns to the open chain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference_model import switching
from reference_model.beam_modes import PF, PP
from reference_model.engine import ReferenceEngine
from reference_model.build import ReferenceModel
from reference_model.model_arrays import N_INPUTS
from reference_model.observe import energy_of_state, momentum_of_state

PIN_TOL = 1e-9  # m and m/s
MOMENTUM_REL_TOL = 1e-9
XI = np.linspace(0.0, 1.5, 1501)
ARM2_LINK = 5

OPEN_CHAIN = """
description = "arm 1 holds the target, arm 2 free with its end effector at grasp point 2"
duration = 1.0
[initial]
base_pose = [0.1, -0.05, 0.2]
base_rate = [0.003, -0.002, 0.004]
joint_angles_deg = [60.0, -120.0, 60.0, -60.0, 120.0, -60.0]
joint_rates = [0.002, -0.001, 0.001, -0.001, 0.0015, -0.0005]
grasp = [1, 0]
[reference]
n_modes = {n}
"""


def material_field(model: ReferenceModel, x: np.ndarray, cfg, link: int, xi: np.ndarray = XI):
    """Positions and velocities (len(xi)×2) of the material points of `link`."""
    lay = model.layout
    q, qd = x[lay.q], x[lay.qd]
    th, om, R, Rd = model.kinematics(q, qd, cfg)[:4]
    kind = int(cfg.basis[link])
    phi = model.bases[link][kind].shapes(xi)
    if kind == PP:
        phi[np.isclose(xi, model.params.link.length), :] = 0.0  # sin(jπ) = 0
    w = phi @ q[lay.modes(link)]
    wd = phi @ qd[lay.modes(link)]
    c, s = math.cos(th[link]), math.sin(th[link])
    r = np.stack([R[link, 0] + c * xi - s * w, R[link, 1] + s * xi + c * w], axis=1)
    v = np.stack([Rd[link, 0] + om[link] * (-c * w - s * xi) - s * wd,
                  Rd[link, 1] + om[link] * (-s * w + c * xi) + c * wd], axis=1)
    return r, v


def tip_values(model, x, cfg, link):
    """w(L), ẇ(L) of `link` in its current basis (0 for PP) and its frame rate."""
    lay = model.layout
    L = model.params.link.length
    if cfg.basis[link] == PP:
        return 0.0, 0.0
    phi = model.bases[link][int(cfg.basis[link])].shapes(np.array([L]))[0]
    return float(phi @ x[lay.q][lay.modes(link)]), float(phi @ x[lay.qd][lay.modes(link)])


def open_chain_engine(make_case, n: int, amp: float, rate: float, seed: int = 0,
                      static_modes: str = "explicit") -> ReferenceEngine:
    """Open chain (arm 1 holds the target), every link deflected: amplitudes ~amp/j² [m],
    amplitude rates ~rate [m/s].  The static shapes explicit: the switch's projection of
    every shape is what these tests examine (slaved, they follow: `test_condense.py`)."""
    case = make_case(f"open_chain_n{n}", OPEN_CHAIN.format(n=n))
    engine = ReferenceEngine(case, static_modes=static_modes)
    lay = engine.model.layout
    rng = np.random.default_rng(seed)
    for i in range(6):
        sl = lay.modes(i)
        j = np.arange(1, lay.n_modes[i] + 1)
        engine.x[lay.q][sl] = amp * rng.uniform(0.5, 1.0, size=j.size) * rng.choice([-1, 1], size=j.size) / j**2
        engine.x[lay.qd][sl] = rate * rng.uniform(-1.0, 1.0, size=j.size) / j
    return engine


def _jumps(before, after):
    dr = np.linalg.norm(after[0] - before[0], axis=1)
    dv = np.linalg.norm(after[1] - before[1], axis=1)
    return dr, dv


# ---------------------------------------------------------------------------------------
# pins and end effector
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 4])
def test_pins_and_end_effector_continuous_at_realistic_deflection(make_case, n):
    """Capture (PF → PP) then release (PP → PF) of arm 2's terminal link with ≈1e-5 m tip
    deflection and slow elastic rates: pins, end effector ≤ 1e-9 m, m/s."""
    engine = open_chain_engine(make_case, n, amp=1e-5, rate=1e-5, seed=n)
    model, x, cfg = engine.model, engine.x, engine.cfg
    lay = model.layout
    assert cfg.basis[ARM2_LINK] == PF
    w_L = tip_values(model, x, cfg, ARM2_LINK)[0]
    assert 5e-6 < abs(w_L) < 2e-5  # realistic: ~1e-5 m tip deflection
    for new in (PP, PF):
        before = material_field(model, x, cfg, ARM2_LINK)
        ee_before = model.kinematics(x[lay.q], x[lay.qd], cfg)[7:9]
        others_before = x.copy()
        switching.switch_basis(model, x, cfg, ARM2_LINK, new)
        assert cfg.basis[ARM2_LINK] == new
        after = material_field(model, x, cfg, ARM2_LINK)
        dr, dv = _jumps(before, after)
        assert dr[0] == 0.0 and dv[0] == 0.0  # proximal pin: untouched
        assert dr[-1] <= PIN_TOL and dv[-1] <= PIN_TOL, (new, dr[-1], dv[-1])
        ee_after = model.kinematics(x[lay.q], x[lay.qd], cfg)[7:9]
        assert np.abs(ee_after[0] - ee_before[0]).max() <= PIN_TOL
        assert np.abs(ee_after[1] - ee_before[1]).max() <= PIN_TOL
        # only θ_J6 (and its rate) and link 6's amplitudes change
        changed = np.flatnonzero(x != others_before)
        allowed = {3 + ARM2_LINK, lay.ns + 3 + ARM2_LINK}
        allowed |= set(range(lay.modes(ARM2_LINK).start, lay.modes(ARM2_LINK).stop))
        allowed |= {lay.ns + i for i in range(lay.modes(ARM2_LINK).start, lay.modes(ARM2_LINK).stop)}
        assert set(changed.tolist()) <= allowed
        # the rotor angle is a physical angle: it does not jump
        assert np.array_equal(x[lay.motors], others_before[lay.motors])


@pytest.mark.parametrize("new", [PP, PF], ids=["capture", "release"])
def test_pin_jump_is_exactly_the_second_order_axial_term(make_case, new):
    """A vibrating link (ẇ ~ 3 mm/s): the distal pin moves by the documented second-order
    term only.  Capture: the PP chord has length L while the PF tip sits at √(L² + w_L²);
    tangential velocity jump ẇ_L sin δ.  Release: |Δr| = L(1 − cos δ), tangential velocity
    jump (θ̇' − θ̇) L sin δ.  Both are ∝ deflection × (deflection or its rate)."""
    engine = open_chain_engine(make_case, 2, amp=1e-5, rate=3e-3, seed=11)
    model, x, cfg = engine.model, engine.x, engine.cfg
    L = model.params.link.length
    if new == PF:
        switching.switch_basis(model, x, cfg, ARM2_LINK, PP)
    w_L, wd_L = tip_values(model, x, cfg, ARM2_LINK)
    om_old = model.kinematics(x[model.layout.q], x[model.layout.qd], cfg)[1][ARM2_LINK]
    before = material_field(model, x, cfg, ARM2_LINK)
    rep = switching.switch_basis(model, x, cfg, ARM2_LINK, new)
    after = material_field(model, x, cfg, ARM2_LINK)
    om_new = model.kinematics(x[model.layout.q], x[model.layout.qd], cfg)[1][ARM2_LINK]
    dr, dv = _jumps(before, after)
    d = rep.delta_rad
    if new == PP:
        want_r = math.hypot(L, w_L) - L
        want_v = abs(wd_L * math.sin(d))
    else:
        want_r = L * (1.0 - math.cos(d))
        want_v = abs((om_new - om_old) * L * math.sin(d))
    print(f"\n{'capture' if new == PP else 'release'}: pin jump {dr[-1]:.3e} m (predicted {want_r:.3e}), "
          f"{dv[-1]:.3e} m/s (predicted {want_v:.3e}); δ = {d:.3e} rad")
    assert want_v > 1e-9  # this state is one where the second-order term is visible
    assert dr[-1] == pytest.approx(want_r, rel=1e-2, abs=2e-14)
    assert dv[-1] == pytest.approx(want_v, rel=1e-3, abs=1e-14)


# ---------------------------------------------------------------------------------------
# field: the projection residual, honestly reported, shrinking with n
# ---------------------------------------------------------------------------------------
def _single_mode_switch(make_case, n: int, new: int):
    """The same physical field for every n: only mode 1 of the old basis is excited
    (1e-5 m, 1e-5 m/s), so the n-mode truncation of the new basis is all that varies."""
    engine = open_chain_engine(make_case, n, amp=0.0, rate=0.0)
    model, x, cfg = engine.model, engine.x, engine.cfg
    lay = model.layout
    if new == PF:
        switching.switch_basis(model, x, cfg, ARM2_LINK, PP)
    sl = lay.modes(ARM2_LINK)
    x[lay.q][sl] = 0.0
    x[lay.qd][sl] = 0.0
    x[lay.q][sl.start] = 1e-5
    x[lay.qd][sl.start] = 1e-5
    before = material_field(model, x, cfg, ARM2_LINK)
    rep = switching.switch_basis(model, x, cfg, ARM2_LINK, new)
    after = material_field(model, x, cfg, ARM2_LINK)
    dr, dv = _jumps(before, after)
    return rep, dr, dv


@pytest.mark.parametrize("new", [PP, PF], ids=["capture", "release"])
def test_field_jump_equals_reported_residual_and_shrinks_with_modes(make_case, new):
    measured = {}
    for n in (1, 2, 4):
        rep, dr, dv = _single_mode_switch(make_case, n, new)
        measured[n] = (dr.max(), dv.max(), rep.residual_m, rep.residual_mps)
        # the report is honest: the largest material jump is the reported residual (the
        # switch samples 64 Gauss points, we sample 1501 points; 2 % covers the sampling)
        assert dr.max() == pytest.approx(rep.residual_m, rel=2e-2, abs=1e-10), n
        assert dv.max() == pytest.approx(rep.residual_mps, rel=2e-2, abs=1e-10), n
        assert dr[-1] <= PIN_TOL and dv[-1] <= PIN_TOL  # pins continuous all the same
    print("\n" + ("capture" if new == PP else "release") + " residual (measured m, m/s | reported m, m/s):")
    for n, (a, b, c, d) in measured.items():
        print(f"  n = {n}: {a:.3e} {b:.3e} | {c:.3e} {d:.3e}")
    for lo, hi in ((1, 2), (2, 4)):
        assert measured[hi][0] < 0.5 * measured[lo][0], (lo, hi, measured)
        assert measured[hi][1] < 0.5 * measured[lo][1], (lo, hi, measured)


def test_undeformed_link_switches_exactly(make_case):
    """No deflection, no elastic rate: nothing to project, the switch is an identity of the
    material state (δ = 0, residual 0)."""
    engine = open_chain_engine(make_case, 2, amp=0.0, rate=0.0)
    model, x, cfg = engine.model, engine.x, engine.cfg
    before = material_field(model, x, cfg, ARM2_LINK)
    x0 = x.copy()
    rep = switching.switch_basis(model, x, cfg, ARM2_LINK, PP)
    assert rep.delta_rad == 0.0 and rep.residual_m == 0.0 and rep.residual_mps == 0.0
    after = material_field(model, x, cfg, ARM2_LINK)
    assert np.abs(after[0] - before[0]).max() <= 1e-15 and np.abs(after[1] - before[1]).max() <= 1e-15
    assert np.array_equal(x, x0)


# ---------------------------------------------------------------------------------------
# capture (plastic impact) and release
# ---------------------------------------------------------------------------------------
def _momentum_energy(model, x, cfg):
    Mg = model.assemble(x, np.zeros(N_INPUTS), cfg)[0]
    return momentum_of_state(model, x, cfg), energy_of_state(model, x, np.zeros(N_INPUTS), cfg, Mg)


@pytest.mark.parametrize("static_modes", ["explicit", "condensed"])
def test_plastic_impact_conserves_momentum_and_dissipates(make_case, static_modes):
    """Arm 2's terminal link undeformed (so the basis switch is exact), every other link
    deflected; relative end-effector speed of a few mm/s.  With the static shapes slaved
    (the default) the impact is in the metric of z = [Y, θ_m] and the terminal link keeps
    the slaved part of its bending, which the switch re-solves in the new basis."""
    engine = open_chain_engine(make_case, 2, amp=1e-5, rate=1e-3, seed=4, static_modes=static_modes)
    model, x, cfg = engine.model, engine.x, engine.cfg
    lay = model.layout
    sl = lay.modes(ARM2_LINK)
    x[lay.q][sl] = 0.0
    x[lay.qd][sl] = 0.0
    s = engine.sensors()
    lever = np.array(model.params.geometry.grasp_T(2))
    c, sn = math.cos(s.target_pose_I[2]), math.sin(s.target_pose_I[2])
    lev = np.array([c * lever[0] - sn * lever[1], sn * lever[0] + c * lever[1]])
    v_point = s.target_rate_I[:2] + s.target_rate_I[2] * np.array([-lev[1], lev[0]])
    v_rel = np.linalg.norm(s.ee_vel_I[1] - v_point)
    assert 1e-4 < v_rel < 1e-2

    p0, e0 = _momentum_energy(model, x, cfg)
    before = x.copy()
    info = switching.capture(model, x, cfg, 2)
    p1, e1 = _momentum_energy(model, x, cfg)
    assert list(cfg.grasp_on) == [1, 1] and cfg.basis[ARM2_LINK] == PP
    dp = np.linalg.norm(p1[:2] - p0[:2]) / np.linalg.norm(p0[:2])
    dL = abs(p1[2] - p0[2]) / abs(p0[2])
    loss = e0[0] - e1[0]
    print(f"\nplastic impact at {v_rel * 1e3:.2f} mm/s: |Δp|/|p| = {dp:.1e}, |ΔL|/|L| = {dL:.1e}, "
          f"loss {loss:.3e} J (reported {info['impact_loss_J']:.3e} J)")
    assert dp <= MOMENTUM_REL_TOL and dL <= MOMENTUM_REL_TOL
    assert loss >= 0.0 and info["impact_loss_J"] >= 0.0
    assert loss == pytest.approx(info["impact_loss_J"], rel=1e-6, abs=1e-15)
    prm = model.params
    m_total = prm.base.mass + prm.target.mass + 6 * prm.link.mass
    assert loss <= 0.5 * m_total * v_rel**2  # ≤ ½ m_eff v², m_eff ≤ the total mass
    # Carnot's theorem for a perfectly plastic impact: the energy lost is the kinetic energy
    # of the velocities lost, T(ẏ⁻) − T(ẏ⁺) = T(ẏ⁻ − ẏ⁺) (the jump is orthogonal to ẏ⁺ in
    # the kinetic metric; a projection in any other metric breaks it).  With explicit shapes
    # the switched link, undeformed and at rest in its modes, reads the same in the new
    # basis and the switch drops nothing: the identity holds for ẏ⁻ itself.  With slaved
    # shapes the switch first re-solves the terminal link's static rates with the PP tables
    # and gives back the momentum that drops, inside `project_velocities`: the identity
    # holds for the velocities after that step, which this test does not see (here
    # T(ẏ⁻) in the new basis is 6.0e-7 J, 0.27 % of the loss, below T(ẏ⁻) in the old one).
    jump = x.copy()
    v = slice(lay.ns, 2 * lay.ns)
    jump[v] = before[v] - x[v]
    lost = _momentum_energy(model, jump, cfg)[1][0]
    print(f"Carnot: T(ẏ⁻ − ẏ⁺) = {lost:.6e} J")
    if static_modes == "explicit":
        assert loss == pytest.approx(lost, rel=1e-9, abs=1e-15)
    if static_modes == "explicit":
        assert e1[1] == e0[1]  # positions did not move: same elastic energy
    else:
        print(f"elastic energy {e0[1]:.6e} → {e1[1]:.6e} J")
    # on the manifold: φ = 0 (held point = coincident point), φ̇ = 0 after the impact
    _, _, A, phi, phid, *_ = model.assemble(x, np.zeros(N_INPUTS), cfg)
    assert np.abs(phi).max() <= 1e-14
    assert np.abs(phid).max() <= 1e-12 * v_rel


def test_capture_release_round_trip(make_case):
    """Capture then release of arm 2 with a deflected, vibrating terminal link: grasp and
    basis back to the open chain, pins continuous through both switches, the field back to
    within the two reported residuals, momentum conserved by both (the rates the new basis
    cannot carry go back to the system as internal impulses), energy never created."""
    engine = open_chain_engine(make_case, 2, amp=1e-5, rate=1e-5, seed=9)
    model, x, cfg = engine.model, engine.x, engine.cfg
    m_link = model.params.link.mass
    start = material_field(model, x, cfg, ARM2_LINK)
    p0, e0 = _momentum_energy(model, x, cfg)
    info_c = switching.capture(model, x, cfg, 2)
    mid = material_field(model, x, cfg, ARM2_LINK)
    p1, _ = _momentum_energy(model, x, cfg)
    info_r = switching.release(model, x, cfg, 2)
    end = material_field(model, x, cfg, ARM2_LINK)
    p2, e2 = _momentum_energy(model, x, cfg)
    assert list(cfg.grasp_on) == [1, 0] and cfg.basis[ARM2_LINK] == PF
    assert info_c["impact_loss_J"] >= 0.0
    for a, b in ((start, mid), (mid, end)):
        dr, dv = _jumps(a, b)
        assert dr[0] <= PIN_TOL and dr[-1] <= PIN_TOL
    # at the release (no impact) the pins' velocities move only by the system's response to
    # the dropped momentum, of the size of the rate residual (measured 0.15× and 1.02× of it)
    assert max(dv[0], dv[-1]) <= 2.0 * info_r["residual_mps"]
    # positions: the impact moves nothing, so only the two projections act
    dr = np.linalg.norm(end[0] - start[0], axis=1)
    assert dr.max() <= 1.02 * (info_c["residual_m"] + info_r["residual_m"]) + 1e-10
    # momentum: every velocity jump is an internal impulse (the field's dropped residual,
    # J_extra's coupling to the new frame, the grasp), so linear and angular momentum are
    # conserved through both switches (docs/physics.md §4.4)
    for a, b in ((p0, p1), (p1, p2)):
        assert np.linalg.norm(b[:2] - a[:2]) <= MOMENTUM_REL_TOL * np.linalg.norm(p0[:2])
        assert abs(b[2] - a[2]) <= MOMENTUM_REL_TOL * abs(p0[2])
    print(f"\nround trip: |Δp| = {np.linalg.norm(p1[:2] - p0[:2]):.1e}, {np.linalg.norm(p2[:2] - p1[:2]):.1e} "
          f"of {np.linalg.norm(p0[:2]):.1e} kg·m/s; |ΔL| = {abs(p1[2] - p0[2]):.1e}, {abs(p2[2] - p1[2]):.1e} "
          f"of {abs(p0[2]):.1e} kg·m²/s; residual_mps {info_c['residual_mps']:.1e}, {info_r['residual_mps']:.1e}")
    # the elastic energy after the round trip is that of the projected field: no more
    # than a residual's worth away from the start (½ k (A ± res)² − ½ k A²)
    assert e2[1] == pytest.approx(e0[1], rel=0.05)
