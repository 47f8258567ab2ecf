"""The condensed static shapes (reference_model/condense.py, docs/physics.md §2.4).

Condensed, each arm's static amplitudes are the equilibrium of its springs and its wrist
stop given the rest of the state (a_s = T y + g τ_w), and the force left on them goes to
y as Tᵀ f_s.  Checked here against the other formulation in the same package,
the explicit Ritz shapes of `system.assemble` (their rows of f are the shapes' own
equilibrium), and against the two invariants a massless slaved coordinate must keep:
its generalised forces derive from the condensed potential (test_end_couples.py) and its
damping dissipates exactly what the full model's damping would at ȧ_s = T ẏ.
"""

from __future__ import annotations

import numpy as np
import pytest

from reference_model.beam_modes import PP
from reference_model.build import Configuration, ReferenceModel, terminal_basis
from reference_model.kinematics import wrist_angles
from reference_model.model_arrays import N_INPUTS
from reference_model.system import _bistop
from rsmcheck.core.cases import load_case
from rsmcheck.core.params import Params
from rsmcheck.orchestration.compare import difference
from rsmcheck.orchestration.fuzz_scenarios import case_text, draw
from rsmcheck.orchestration.runs import run_engine

PARAMS = Params()


def loaded_state(model: ReferenceModel, wrist_over: float, seed: int = 11):
    """Arm 1 holding the target, links bent, every rotor off its section angle by 3e-4 rad,
    arm 1's wrist `wrist_over` rad beyond its upper stop (negative: inside the range)."""
    lay = model.layout
    rng = np.random.default_rng(seed)
    grasp = (1, 0)
    cfg = Configuration(grasp_on=np.array(grasp), rho_G=np.zeros((2, 2)), basis=terminal_basis(grasp))
    x = model.zero_state()
    x[3:9] = np.radians([60, -120, 60, -60, 120, -60])
    for i in range(6):
        x[lay.modes(i)][:model.n_eigen[i]] = 2e-5 * rng.normal(size=model.n_eigen[i])
    psi, _ = model.joint_section_angles(x[lay.q], x[lay.qd], cfg)
    x[lay.motors] = psi + 3e-4 * rng.choice([-1.0, 1.0], size=6)
    th3 = model.kinematics(x[lay.q], x[lay.qd], cfg).th[2]
    slope_L = model.bases[2][PP].slope_L[:model.n_eigen[2]] @ x[lay.q][lay.modes(2)][:model.n_eigen[2]]
    x[lay.target] = [5.0, 0.5, th3 + slope_L + PARAMS.wrist.limit + wrist_over]
    return x, cfg, rng


@pytest.mark.parametrize("wrist_over", [-0.1, 0.05])
def test_condensed_shapes_are_the_explicit_shapes_static_equilibrium(wrist_over):
    """The explicit model's own rows for the static shapes (−K a + the joint springs' and
    the stop's torques on the end slopes), at rest and at the condensed amplitudes: zero,
    while each of their terms is of the joint torques' size."""
    explicit = ReferenceModel(PARAMS, 2, static_modes="explicit")
    condensed = ReferenceModel(PARAMS, 2, static_modes="condensed")
    x, cfg, _ = loaded_state(condensed, wrist_over)
    xc = condensed.complete(x, cfg, settle=True)  # at rest: the stop's spring alone
    lay = condensed.layout
    static = np.setdiff1d(np.arange(lay.nq), condensed.coordinates)
    assert static.size == 12 and np.abs(xc[static]).min() > 0.0
    f = explicit.assemble(xc, np.zeros(N_INPUTS), cfg)[1]
    load = np.abs(explicit.assemble(xc, np.zeros(N_INPUTS), cfg)[7]).max()  # |u_J| [N·m]
    assert load > 1.0
    assert np.abs(f[static]).max() <= 1e-9 * load, f[static]
    # the slots of x are not read: any values there give the same completed state
    x[static] = 1.0
    assert np.array_equal(condensed.complete(x, cfg, settle=True), xc)


def test_condensed_damping_dissipates_what_the_full_model_does():
    """Power of the velocity-odd generalised forces on y (and the rotors) = −(dissipation of
    the full model at ȧ_s = T ẏ): Kelvin–Voigt η ȧᵀK_ff ȧ over every shape and the joint
    dampers C_m (ψ̇_J − θ̇_m)², the wrist inside its range.  The inertial forces are even in
    the velocities, so (F(v) − F(−v))/2 is the damping alone.  (Beyond the stop the
    damper's share goes through the stop deflection e: test_stop_torque_is_the_stop_law.)"""
    wrist_over = -0.1
    model = ReferenceModel(PARAMS, 2, static_modes="condensed")
    lay = model.layout
    x, cfg, rng = loaded_state(model, wrist_over)
    r = model.coordinates
    u = np.zeros(N_INPUTS)
    v = np.zeros(lay.nx)
    for c in r:  # every coordinate with mass, the target's too
        v[lay.ns + c] = (1e-5 if 9 <= c < lay.nq else 1e-3) * rng.normal()
    v[lay.motors_d] = 1e-3 * rng.normal(size=6)

    def forces(sign):
        xx = x.copy()
        xx[lay.ns:2 * lay.ns] = sign * v[lay.ns:2 * lay.ns]
        out = model.assemble(xx, u, cfg)
        return out[1][r], PARAMS.motor.inertia * out[6], out[8][0]

    fp, mp, tp = forces(1.0)
    fm, mm, tm = forces(-1.0)
    yd = v[lay.ns:lay.ns + lay.ny][r]
    power = 0.5 * (fp - fm) @ yd + 0.5 * (mp - mm) @ v[lay.motors_d]
    # the full model's dissipation at the condensed rates
    xc = model.complete(x.copy() + v, cfg)
    qd = xc[lay.qd]
    eta, cm = PARAMS.link.kelvin_voigt_eta, PARAMS.motor.damping
    dissipation = 0.0
    for i in range(6):
        ad = qd[lay.modes(i)]
        dissipation += eta * ad @ model.arrays.k_ff[i, cfg.basis[i], :len(ad), :len(ad)] @ ad
    _, psid = model.joint_section_angles(xc[lay.q], qd, cfg)
    dissipation += cm * np.sum((psid - xc[lay.motors_d]) ** 2)
    kin = model.kinematics(xc[lay.q], qd, cfg)
    wd = xc[lay.target_d][2] - kin.om[2] - model.bases[2][PP].slope_L @ qd[lay.modes(2)]
    stop_power = 0.5 * (tp - tm) * wd
    assert stop_power == 0.0
    assert dissipation > 0.0
    assert power == pytest.approx(-dissipation + stop_power, rel=1e-6), (power, dissipation, stop_power)


def test_slaved_shapes_keep_their_mass():
    """The kinetic energy of z = [Y, θ_m] in M_z (Guyan) equals that of the completed
    state in the full metric, ½ ẎᵀM_gẎ + ½ B_m Σθ̇_m², at ȧ_s = T ż; and M_z couples the
    rotors to their arm only through the shapes (zero without them)."""
    model = ReferenceModel(PARAMS, 2, static_modes="condensed")
    lay = model.layout
    x, cfg, rng = loaded_state(model, 0.05)
    x[lay.ns:2 * lay.ns] = 1e-3 * rng.normal(size=lay.ns)
    xc = model.complete(x, cfg)
    Mz = model.reduced(x, np.zeros(N_INPUTS), cfg)[0]
    Mg = model.assemble(x, np.zeros(N_INPUTS), cfg)[0]
    Z = np.concatenate([xc[lay.qd], xc[lay.target_d], xc[lay.motors_d]])
    static = np.setdiff1d(np.arange(lay.ny), model.coordinates)
    Z[static] = 0.0
    Yd = xc[lay.ns:lay.ns + lay.ny]
    full = 0.5 * Yd @ Mg @ Yd + 0.5 * PARAMS.motor.inertia * np.sum(xc[lay.motors_d] ** 2)
    assert 0.5 * Z @ Mz @ Z == pytest.approx(full, rel=1e-12)
    assert np.abs(Mz[static]).max() == 0.0 and np.abs(Mz[:, static]).max() == 0.0
    assert len(model.coordinates) == lay.ny - 12
    rotor_arm = Mz[lay.ny:lay.ny + 3, 3:6]  # arm 1's rotors with its joints
    assert np.abs(rotor_arm).max() > 0.0
    assert np.abs(Mz[lay.ny:lay.ny + 3, lay.ny + 3:]).max() == 0.0  # not with arm 2's rotors


# A held target swinging fast into its wrist stop (randomized cross-check, docs/fuzz.md):
# scenario 1 of seed 2026, arm 2 holds the target, a torque step, in orbit, 1.98 s; the
# stop engages at 1.55 s and lets go at 1.76 s.  The explicit shapes' own distance to
# Exudyn is 2.3e-5 rad; the slaved ones differ from them by 1.6e-4 rad with 2 eigenmodes
# per link and 2.3e-5 with 4 (the stop's impact excites the band above the second
# eigenmode, which the explicit shapes carry with their inertia).  With the stop's damper
# left out of the shapes' balance the difference was 2.3e-2 rad at 2 eigenmodes.
@pytest.mark.parametrize("n_modes, bound", [(2, 3e-4), (4, 4e-5)])
def test_slaved_shapes_follow_the_explicit_ones_with_a_held_target_swinging(tmp_path, n_modes, bound):
    s = draw(2026, 1)
    path = tmp_path / f"{s.name}.toml"
    path.write_text(case_text(s).replace("[solver]", f"[reference]\nn_modes = {n_modes}\n\n[solver]"))
    case = load_case(path)
    slaved = run_engine("reference", case, {"static_modes": "condensed"})
    explicit = run_engine("reference", case, {"static_modes": "explicit"})
    assert [e.kind for e in slaved.events] == ["bistop_contact", "bistop_free"]
    assert difference(slaved, explicit, "joint_angles")[0] < bound


@pytest.mark.parametrize("fraction", [0.0, 0.5, 1.0, 40.0])
@pytest.mark.parametrize("toward", [1.0, -1.0])
def test_stop_torque_is_the_stop_law_at_the_slaved_wrist(fraction, toward):
    """Beyond the stop the terminal link's deflection under it, e, is a state (condense.py):
    whatever its value, the torque on the target is the Hunt–Crossley law of the explicit
    model (system._bistop) at the wrist angle of the completed state, which carries e, and
    its rate with ė added (the completed rates leave it out: massless, it carries no
    momentum): ψ_w = ψ_free − s e, ψ̇_w = ψ̇_free − s ė.  That is the stop's equation the
    state obeys, clamp included (e = 40× its value at rest, the target moving away: the
    stop lets go).  And the torque only pushes, τ_w ψ_w ≤ 0."""
    model = ReferenceModel(PARAMS, 2, static_modes="condensed")
    lay = model.layout
    x, cfg, rng = loaded_state(model, 0.05)
    x[lay.ns:2 * lay.ns] = 1e-3 * rng.normal(size=lay.ns)
    x[lay.ns + lay.nq + 2] = toward * 0.3  # the target turning into the stop (+) or away
    rest = x.copy()
    rest[lay.ns:2 * lay.ns] = 0.0
    x[lay.stop_deflection] = fraction * model.complete(rest, cfg, settle=True)[lay.stop_deflection]
    assert 0.0 < x[lay.stop_deflection][0] or fraction == 0.0
    xc = model.complete(x, cfg)
    u = np.zeros(N_INPUTS)
    tau = model.assemble(x, u, cfg)[8][0]
    edot = model.rhs(x, u, cfg)[lay.stop_deflection][0]
    kin = model.kinematics(xc[lay.q], xc[lay.qd], cfg)
    psi, psid = wrist_angles(xc[lay.q], xc[lay.qd], xc[lay.target], xc[lay.target_d], kin.th, kin.om,
                             model.arrays, cfg.basis)
    w = PARAMS.wrist
    law = _bistop(psi[0], psid[0] - np.sign(psi[0]) * edot, w.limit, w.stiffness, w.contact_damping)
    # the law's terms reach 1e4 N·m here: 1e-3 N·m is their round-off, not a tolerance of the model
    assert tau == pytest.approx(law, rel=1e-9, abs=1e-3)
    assert tau * psi[0] <= 0.0
    if toward > 0:
        assert tau < 0.0  # pressing on the upper stop: pushed back


def test_a_start_on_the_stop_settles_where_the_deflection_rests():
    """A start in contact (`complete(…, settle=True)`) puts e where the stop's law holds with
    ė = 0, the slaved shapes' Kelvin–Voigt force x_kv included: the state then starts with
    ė = 0 also when the links move (x_kv ≠ 0), not only at rest.  Without x_kv the settled e
    is off by s x_kv h / (1 + h stiff), and ė starts at x_kv / (λδ + c_e)."""
    model = ReferenceModel(PARAMS, 2, static_modes="condensed")
    lay = model.layout
    x, cfg, rng = loaded_state(model, 0.02)
    x[lay.ns:2 * lay.ns] = 1e-3 * rng.normal(size=lay.ns)  # every rate (ψ̇ stays under k/λ)
    x[lay.ns + lay.nq + 2] = 0.0
    settled = model.complete(x, cfg, settle=True)
    e = settled[lay.stop_deflection][0]
    edot = model.rhs(settled, np.zeros(N_INPUTS), cfg)[lay.stop_deflection][0]
    assert e > 0.0
    assert abs(edot) <= 1e-9 * e, (edot, e)


def test_a_deflection_left_off_the_stop_relaxes_in_place():
    """Off the stop (the wrist back inside its range) the terminal link's deflection under the
    stop, e, relaxes through its own damping, e/h + c_e ė = 0, and stays in the shapes while
    it does: the completed wrist angle is the free one less s e (continuous with the contact),
    the stop pushes nothing, and ė = −e/(h c_e)."""
    model = ReferenceModel(PARAMS, 2, static_modes="condensed")
    lay = model.layout
    x, cfg, _ = loaded_state(model, -0.01)  # 0.01 rad inside the upper stop
    u = np.zeros(N_INPUTS)

    def wrist(state):
        xc = model.complete(state, cfg)
        kin = model.kinematics(xc[lay.q], xc[lay.qd], cfg)
        return wrist_angles(xc[lay.q], xc[lay.qd], xc[lay.target], xc[lay.target_d], kin.th, kin.om,
                            model.arrays, cfg.basis)[0][0]

    free = wrist(x)
    e = 1e-3
    x[lay.stop_deflection] = [e, 0.0]
    assert wrist(x) == pytest.approx(free - e, abs=1e-12)  # s = +1: the upper stop's side
    assert model.assemble(x, u, cfg)[8][0] == 0.0
    edot = model.rhs(x, u, cfg)[lay.stop_deflection][0]
    h, ce = model.arrays.sl_h[0, PP], model.arrays.sl_ce[0, PP]
    assert edot == pytest.approx(-e / (h * ce), rel=1e-12) and edot < 0.0


def test_linear_plant_refuses_a_start_on_a_stop(monkeypatch):
    """`modes.linear_plant` holds the stop deflections e: off the stops (e = 0, every case's
    start) that is exact, on a stop it would leave out the stop's relaxation, so such a
    start is refused with the deflections named (off the stop: tests/crosscheck/test_closed_loop.py)."""
    from reference_model import modes
    from reference_model.engine import ReferenceEngine

    class OnTheStop(ReferenceEngine):
        def __init__(self, case, **options):
            super().__init__(case, **options)
            self.x[self.model.layout.stop_deflection] = (2e-6, 0.0)

    case = load_case("p2_capture_regrasp").short
    monkeypatch.setattr(modes, "ReferenceEngine", OnTheStop)
    with pytest.raises(ValueError, match=r"on a wrist stop \(stop deflections e = 2e-06, 0 rad\)"):
        modes.linear_plant(case, lambda s: np.zeros(0))
