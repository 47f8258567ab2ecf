"""The wrist bistop only pushes, and turns on without a step, in both engines
(docs/physics.md §4.3).

The law, with δ = |ψ| − ψ_lim the penetration and δ̇ = sgn(ψ) ψ̇ its rate:

    τ_w = −sgn(ψ) max(0, k δ + λ δ δ̇)   for δ > 0,     τ_w = 0   for δ ≤ 0,

τ_w on the target (−τ_w on the terminal link's distal section).  Checked

* at chosen (ψ, ψ̇) against numbers worked out by hand (k = 5000, λ = 1.2e5): the
  reference's `system._bistop`, Exudyn's symbolic spring-force function (`build.bistop_law`,
  evaluated as Exudyn compiled it) and that function in a connector (the generalised force
  it puts on the target);
* over the whole short wrist_bistop run (6 s, contact 1.971–4.81 s), the torque each engine
  applies after every control period (1 ms): the reference's τ_w from `assemble`, Exudyn's
  connector force f (−f on the target).  Never pulling: τ_w sgn(ψ) ≤ 0 in contact, τ_w = 0
  outside; no step: |Δτ_w| per period ≤ 5 % of the peak push, the step at first contact
  included.  Measured (both engines): peak push 27.00 N·m, largest change 0.53 N·m per
  period (1.95 %, the ramp just after first contact), first contact sample 0.02 N·m;
  smallest push in contact a few 1e-3 N·m (the clamp does not act here: the target leaves
  at ψ̇ ≈ −1e-3 rad/s, far above −k/λ = −0.042 rad/s).  The paper's linear spring-damper fails
  both: it pulled by up to 0.52 N·m during the rebound (c |ψ̇| > k δ) and stepped by
  c ψ̇ = 14.5 / 25.1 N·m (51 / 88 % of the peak) at the first contact sample.

The runs are looser than the check's (reference rtol 1e-6, Exudyn 1 ms steps, one output
sample: 2–4 s each instead of 7 and 4.4 s): the law's sign and continuity do not depend on
the integration error, and the figures above are the same at the check's settings to the
digits shown.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsmcheck.core.cases import load_case
from rsmcheck.core.plugins import make_engine
from rsmcheck.driver.runner import run

LIM, K, LAM = 0.5, 5000.0, 1.2e5

#: (ψ, ψ̇) → τ_w on the target, worked out by hand:  δ = 0.01: k δ = 50, λ δ = 1200 per rad/s
POINTS = [
    (0.51, 0.05, -110.0),      # entering: 50 + 1200·0.05 = 110, pushes −
    (-0.51, -0.05, 110.0),     # the lower stop, mirrored
    (0.51, 0.0, -50.0),        # at rest in the stop: the spring alone
    (0.51, -0.03, -14.0),      # leaving slowly: 50 − 1200·0.03 = 14, still pushes
    (-0.51, 0.03, 14.0),
    (0.51, -0.05, 0.0),        # leaving fast: 50 − 60 < 0, clamped, no pull
    (-0.51, 0.05, 0.0),
    (0.5, 1.0, 0.0),           # at the limit (δ = 0): zero whatever the rate
    (0.5 + 1e-6, 0.05, -0.011),  # just in: 1e-6·(5000 + 6000), continuous at δ = 0
    (0.3, 1.0, 0.0),           # inside the range
    (-0.3, -1.0, 0.0),
]


@pytest.mark.parametrize("psi,psid,tau", POINTS)
def test_reference_bistop_law(psi, psid, tau):
    from reference_model.system import _bistop

    assert _bistop(psi, psid, LIM, K, LAM) == pytest.approx(tau, rel=1e-12, abs=1e-12)


@pytest.fixture(scope="module")
def exudyn_law():
    import exudyn as exu
    from exudyn.advancedUtilities import CreateSymbolicUserFunction

    from exudyn_model.build import bistop_law

    mbs = exu.SystemContainer().AddSystem()
    law = CreateSymbolicUserFunction(mbs, bistop_law(LIM), "springForceUserFunction",
                                     itemTypeName="ObjectConnectorCoordinateSpringDamperExt")
    return mbs, law


@pytest.mark.parametrize("psi,psid,tau", POINTS)
def test_exudyn_bistop_law(psi, psid, tau, exudyn_law):
    """The compiled expression: f(q, v; k, d = λ, offset) with ψ = q − offset, −f on the target."""
    mbs, law = exudyn_law
    offset = -0.3  # as in the model: q excludes the reference angle ψ(q = 0) = −offset
    f = law.Evaluate(mbs, 0.0, 0, psi + offset, psid, K, LAM, offset, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert -f == pytest.approx(tau, rel=1e-12, abs=1e-12)


def test_exudyn_bistop_connector_pushes_the_target_back():
    """The law in a CoordinateSpringDamperExt between a hub and a target coordinate, as in
    the model: the generalised forces it applies are +τ_w on the target, −τ_w on the hub."""
    import exudyn as exu
    from exudyn.advancedUtilities import CreateSymbolicUserFunction
    from exudyn.itemInterface import (MarkerNodeCoordinate, NodeGenericODE2, ObjectConnectorCoordinateSpringDamperExt,
                                      ObjectGenericODE2)

    from exudyn_model.build import bistop_law
    from exudyn_model.reactions import ConstraintForces

    psi_ref = 0.3
    for psi, psid, tau in POINTS:
        mbs = exu.SystemContainer().AddSystem()
        node = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.0, psi_ref], numberOfODE2Coordinates=2,
                                           initialCoordinates=[0.2, 0.2 + psi - psi_ref],
                                           initialCoordinates_t=[-0.1, -0.1 + psid]))
        mbs.AddObject(ObjectGenericODE2(nodeNumbers=[node], massMatrix=np.diag([3000.0, 600.0])))
        law = CreateSymbolicUserFunction(mbs, bistop_law(LIM), "springForceUserFunction",
                                         itemTypeName="ObjectConnectorCoordinateSpringDamperExt")
        mbs.AddObject(ObjectConnectorCoordinateSpringDamperExt(
            markerNumbers=[mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=node, coordinate=c)) for c in (0, 1)],
            stiffness=K, damping=LAM, offset=-psi_ref, useLimitStops=False, springForceUserFunction=law))
        mbs.Assemble()
        hub, target = ConstraintForces(mbs).rhs()
        assert target == pytest.approx(tau, rel=1e-9, abs=1e-9), (psi, psid)
        assert hub == pytest.approx(-tau, rel=1e-9, abs=1e-9), (psi, psid)


# ---- over a whole run -----------------------------------------------------------------
#: looser settings than the check's (module docstring)
RUN_OPTIONS = {"reference": {"rtol": 1e-6}, "exudyn": {"substeps": 1}}


def torque_history(engine_name: str, case_name: str = "wrist_bistop"
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(t, ψ, τ_w) of arm 1 after every control period of a case's short run, and ψ_lim:
    ψ the engine's wrist-angle sensor, τ_w the torque it applies to the target there."""
    case = load_case(case_name).variant(True)
    case = dataclasses.replace(case, solver=dataclasses.replace(case.solver, output_period=case.duration))
    engine = make_engine(engine_name, case, **RUN_OPTIONS[engine_name])
    sensors = engine.sensors
    rows = []
    if engine_name == "reference":
        from reference_model.model_arrays import N_INPUTS

        u0 = np.zeros(N_INPUTS)  # τ_w does not depend on the inputs

        def torque() -> float:
            return float(engine.model.assemble(engine.x, u0, engine.cfg)[8][0])
    else:
        import exudyn as exu

        mbs, bistop = engine.model.mbs, engine.model.bistops[0]

        def torque() -> float:  # Exudyn's connector force f acts as −f on marker 1, the target
            return -float(mbs.GetObjectOutput(bistop, exu.OutputVariableType.Force))

    def recording():
        s = sensors()
        rows.append((s.time, s.wrist_angles[0], torque()))
        return s

    engine.sensors = recording
    run(engine, case, case.duration)
    t, psi, tau = np.array(rows).T
    return t, psi, tau, case.params.wrist.limit


@pytest.fixture(scope="module", params=["reference", "exudyn"])
def history(request):
    return request.param, torque_history(request.param)


@pytest.mark.crosscheck
def test_bistop_only_pushes(history):
    name, (t, psi, tau, lim) = history
    engaged = np.abs(psi) > lim
    push = -tau * np.sign(psi)  # > 0: out of the stop
    assert engaged.sum() > 1000 and push.max() > 10.0, f"{name}: no contact ({engaged.sum()} samples)"
    worst = int(np.argmin(np.where(engaged, push, np.inf)))
    assert push[worst] >= 0.0, (f"{name} pulls the target into its stop by {-push[worst]:.3e} N·m at "
                                f"t = {t[worst]:.3f} s (ψ − ψ_lim = {abs(psi[worst]) - lim:.3e} rad)")
    assert np.abs(tau[~engaged]).max() <= 1e-9, f"{name}: torque outside the stop"


@pytest.mark.crosscheck
def test_bistop_torque_has_no_step(history):
    name, (t, psi, tau, lim) = history
    engaged = np.abs(psi) > lim
    peak = np.abs(tau).max()
    first = int(np.argmax(engaged))
    jump = np.abs(np.diff(tau))
    i = int(np.argmax(jump))
    assert jump[i] <= 0.05 * peak, (f"{name}: τ_w changes by {jump[i]:.3f} N·m in one control period at "
                                    f"t = {t[i + 1]:.3f} s, {jump[i] / peak:.1%} of the peak {peak:.2f} N·m "
                                    f"(first contact at {t[first]:.3f} s: {tau[first]:.3f} N·m)")


# ---- the clamp, on both sides, with the shapes slaved: wrist_kick ----------------------
@pytest.fixture(scope="module", params=["reference", "exudyn"])
def kick(request):
    return request.param, torque_history(request.param, "wrist_kick")


@pytest.mark.crosscheck
def test_the_clamp_acts_on_both_stops_and_never_pulls(kick):
    """wrist_kick (short, 5 s; the reference's static shapes slaved, so that its stop acts
    through the terminal link's deflection state, docs/physics.md §2.4): the target leans on
    the + stop, is kicked off it and strikes the − stop.  On each side the wrist leaves
    faster than k/λ while still inside, where the unclamped law kδ + λδδ̇ would pull: there
    the torque is held at exactly zero (the clamp, max(0, ·): inside the stop the unclamped
    law is zero only where kδ + λδδ̇ = 0 to the bit); everywhere in contact it pushes."""
    name, (t, psi, tau, lim) = kick
    side = np.sign(psi)
    delta = np.abs(psi) - lim
    push = -tau * side
    for s in (1.0, -1.0):
        engaged = (side == s) & (delta > 0.0)
        assert engaged.sum() > 50, f"{name}: no contact with the {s:+.0f} stop"
        assert push[engaged].min() >= 0.0, f"{name} pulls the target into its {s:+.0f} stop"
        clamped = engaged & (delta > 1e-4) & (tau == 0.0)
        assert clamped.sum() >= 5, f"{name}: the clamp never acts at the {s:+.0f} stop"
        # and there the wrist is leaving: δ falls over the periods around those samples
        i = np.flatnonzero(clamped)
        assert np.all(delta[i + 1] < delta[i - 1]), f"{name}: zero torque in the {s:+.0f} stop while not leaving"
