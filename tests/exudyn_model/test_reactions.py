"""Index-1 constraint forces (exudyn_model.reactions) against analytic values and against
the integrator's own (index-3) multipliers.

* small systems built directly in Exudyn (a rigid pendulum, a two-body chain with a spring
  and a switched-off joint): λ against Newton–Euler by hand, ≤ 1e-9 relative;
* the engine: the evaluation leaves the running integrator bit for bit alone; at
  h = 0.5 ms the index-1 forces equal `GetObjectOutput(·, Force)` to ≤ 1e-5 (rigid,
  measured 6e-7) / 1e-4 (flexible, measured 5e-7) of their size; at h = 3.9 µs the native
  multipliers carry their round-off floor ε/(βh²) (measured 9.1e-3 of 21 N, ×5 from
  7.8 µs) while the index-1 forces converge with the state (7.8 → 3.9 µs: 1.4e-5);
* the inputs: evaluated with the inputs of the coming period (`held_inputs`, as advance()
  applies them; thrust_burn, thrust-inertia field), every parameter restored.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exudyn_model.build import exu
from exudyn_model.engine import ExudynEngine
from exudyn_model.reactions import ConstraintForces
from rsmcheck.core.cases import load_case
from rsmcheck.core.engine import Inputs
from rsmcheck.core.geometry import rot
from rsmcheck.driver.runner import run
from exudyn.itemInterface import (  # noqa: E402 — after the engine's import of exudyn
    CoordinateSpringDamper, LoadForceVector, LoadTorqueVector, MarkerBodyPosition, MarkerBodyRigid,
    MarkerNodeCoordinate, NodePointGround, NodeRigidBody2D, ObjectGround, ObjectJointRevolute2D,
    ObjectRigidBody2D)

FORCE = exu.OutputVariableType.Force


def _kz(r):  # e_z × r
    return np.array([-r[1], r[0]])


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _body(mbs, c, v, th, om, m, J):
    n = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[0.0, 0.0, 0.0], initialCoordinates=[*c, th],
                                    initialVelocities=[*v, om]))
    return n, mbs.AddObject(ObjectRigidBody2D(nodeNumber=n, mass=m, inertia=J))


# ---------------------------------------------------------------------------------------
# (a) analytic systems
# ---------------------------------------------------------------------------------------
def test_pendulum_tension_is_analytic():
    """Rigid body on a revolute joint at P0 (away from the origin), weight and a torque at
    φ = 0.4 rad, ω = 1.3 rad/s: the joint force is m a_c − F (tension m(g cos φ + Lω²));
    Exudyn's λ is its negative (the force on marker 0, the ground), the same as the
    integrator's own consistent initial multipliers."""
    m, J, L, g, tau = 2.0, 0.3, 0.7, 9.81, 0.8
    phi, om = 0.4, 1.3
    P0 = np.array([3.0, -2.0])
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    mg = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[*P0, 0.0]))
    er = np.array([math.sin(phi), -math.cos(phi)])  # pivot → COM
    _, b = _body(mbs, P0 + L * er, L * om * _kz(er), phi, om, m, J)
    joint = mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[mg, mbs.AddMarker(
        MarkerBodyPosition(bodyNumber=b, localPosition=[0.0, L, 0.0]))]))
    com = mbs.AddMarker(MarkerBodyPosition(bodyNumber=b, localPosition=[0.0, 0.0, 0.0]))
    mbs.AddLoad(LoadForceVector(markerNumber=com, loadVector=[0.0, -m * g, 0.0]))
    rigid = mbs.AddMarker(MarkerBodyRigid(bodyNumber=b, localPosition=[0.0, 0.0, 0.0]))
    mbs.AddLoad(LoadTorqueVector(markerNumber=rigid, loadVector=[0.0, 0.0, tau]))
    mbs.Assemble()

    alpha = (tau - m * g * L * math.sin(phi)) / (J + m * L * L)
    a_c = L * alpha * _kz(er) - L * om**2 * er
    R = m * a_c - np.array([0.0, -m * g])  # joint force on the body
    assert abs(-R @ er - m * (g * math.cos(phi) + L * om**2)) < 1e-12  # the tension

    cf = ConstraintForces(mbs)
    lam = cf.object_forces([joint])[0]
    assert np.abs(lam + R).max() < 1e-9 * np.abs(R).max(), (lam, -R)
    qdd, _ = cf.solve()
    assert abs(qdd[2] - alpha) < 1e-9 * abs(alpha)

    # the integrator's multipliers after its consistent initialisation: same sign, same value
    s = exu.SimulationSettings()
    s.solution.file.write = False
    s.solution.sensors.active = False
    s.timeIntegration.verboseMode = 0
    s.timeIntegration.endTime = 1e-3
    s.timeIntegration.numberOfSteps = 1
    exu.MainSolverImplicitSecondOrder().InitializeSolver(mbs, s)
    native = np.asarray(mbs.GetObjectOutput(joint, FORCE))[:2]
    assert np.abs(native - lam).max() < 1e-7 * np.abs(R).max(), (native, lam)


def test_two_body_chain_is_newton_euler():
    """Two rigid bodies: body 1 pinned to the ground, body 2 pinned to body 1; forces on
    both, a torque on body 1, a rotational spring-damper on θ_2 (an internal force: in f),
    and a third joint switched off (its rows are λ = 0).  Against the 6×6 Newton–Euler
    system written out here (α1, α2, R1, R2)."""
    m1, J1, a1, b1 = 3.0, 0.4, 0.5, 0.6  # COM at a1 from the pivot, distal pin b1 beyond
    m2, J2, a2, b2 = 1.5, 0.2, 0.4, 0.3
    th1, om1, th2, om2 = 0.7, -0.9, -0.5, 1.7
    F1, F2, tau1 = np.array([0.3, -29.4]), np.array([-1.1, -14.7]), 2.5
    k, d = 7.0, 0.6  # spring-damper on θ_2 (ground side 0)
    P0 = np.array([-1.0, 4.0])
    r1, s1 = rot(th1) @ [a1, 0.0], rot(th1) @ [b1, 0.0]
    r2 = rot(th2) @ [a2, 0.0]
    c1, v1 = P0 + r1, om1 * _kz(r1)
    vd1 = v1 + om1 * _kz(s1)
    c2, v2 = P0 + r1 + s1 + r2, vd1 + om2 * _kz(r2)

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    n1, B1 = _body(mbs, c1, v1, th1, om1, m1, J1)
    n2, B2 = _body(mbs, c2, v2, th2, om2, m2, J2)

    def pos(body, x):
        return mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[x, 0.0, 0.0]))

    j1 = mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[
        mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[*P0, 0.0])), pos(B1, -a1)]))
    j2 = mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[pos(B1, b1), pos(B2, -a2)]))
    j3 = mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[
        mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[0.0, 0.0, 0.0])), pos(B2, b2)],
        activeConnector=False))
    mbs.AddLoad(LoadForceVector(markerNumber=pos(B1, 0.0), loadVector=[*F1, 0.0]))
    mbs.AddLoad(LoadForceVector(markerNumber=pos(B2, 0.0), loadVector=[*F2, 0.0]))
    rigid1 = mbs.AddMarker(MarkerBodyRigid(bodyNumber=B1, localPosition=[0.0, 0.0, 0.0]))
    mbs.AddLoad(LoadTorqueVector(markerNumber=rigid1, loadVector=[0.0, 0.0, tau1]))
    g0 = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=mbs.AddNode(NodePointGround()), coordinate=0))
    th2_marker = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n2, coordinate=2))
    mbs.AddObject(CoordinateSpringDamper(markerNumbers=[g0, th2_marker], stiffness=k, damping=d))
    mbs.Assemble()

    # Newton–Euler: x = (α1, α2, R1x, R1y, R2x, R2y); R1 ground → body 1 at P0, R2 body 1 →
    # body 2 at the pin (−R2 on body 1); a_c1 = α1 k×r1 − ω1² r1, a_d1 = a_c1 + α1 k×s1 − ω1² s1,
    # a_c2 = a_d1 + α2 k×r2 − ω2² r2
    tau_s = -k * th2 - d * om2
    A = np.zeros((6, 6))
    rhs = np.zeros(6)
    A[0:2, 0] = m1 * _kz(r1)
    A[0:2, 2:4] = -np.eye(2)
    A[0:2, 4:6] = np.eye(2)
    rhs[0:2] = F1 + m1 * om1**2 * r1
    A[2, 0] = J1
    A[2, 2:4] = [-r1[1], r1[0]]  # −(−r1 × R1)
    A[2, 4:6] = [-s1[1], s1[0]]  # +(s1 × R2)
    rhs[2] = tau1
    A[3:5, 0] = m2 * (_kz(r1) + _kz(s1))
    A[3:5, 1] = m2 * _kz(r2)
    A[3:5, 4:6] = -np.eye(2)
    rhs[3:5] = F2 + m2 * (om1**2 * (r1 + s1) + om2**2 * r2)
    A[5, 1] = J2
    A[5, 4:6] = [-r2[1], r2[0]]  # −(−r2 × R2)
    rhs[5] = tau_s
    x = np.linalg.solve(A, rhs)
    R1, R2 = x[2:4], x[4:6]

    cf = ConstraintForces(mbs)
    qdd, lam = cf.solve()
    l1, l2, l3 = cf.object_forces([j1, j2, j3], lam)
    scale = max(np.abs(R1).max(), np.abs(R2).max())
    assert np.abs(l1 + R1).max() < 1e-9 * scale, (l1, -R1)
    assert np.abs(l2 + R2).max() < 1e-9 * scale, (l2, -R2)
    assert np.all(l3 == 0.0)
    i1, i2 = mbs.GetNodeODE2Index(n1), mbs.GetNodeODE2Index(n2)
    assert abs(qdd[i1 + 2] - x[0]) < 1e-9 * abs(x[0]) and abs(qdd[i2 + 2] - x[1]) < 1e-9 * abs(x[1])

    # switching the third joint on needs no new initialisation: same λ as a fresh object
    mbs.SetObjectParameter(j3, "activeConnector", True)
    l_kept, l_fresh = cf.multipliers(), ConstraintForces(mbs).multipliers()
    assert np.abs(l_kept[mbs.systemData.GetObjectLTGAE(j3)]).max() > 1.0  # now carries a load
    assert np.abs(l_kept - l_fresh).max() <= 1e-14 * np.abs(l_fresh).max()


# ---------------------------------------------------------------------------------------
# (b, c) the engine
# ---------------------------------------------------------------------------------------
def _squeeze_inputs(case):
    return Inputs(tau_m=np.array(case.controller.motor_torques, float))


def _native(eng):
    return np.concatenate([np.asarray(eng.mbs.GetObjectOutput(j, FORCE))[:2] * eng.state.grasp_on[k]
                           for k, j in enumerate(eng.model.grasp_joints)])


def _series(case, periods, **options):
    """Native and index-1 grasp forces at every control sample 1 … periods (constant inputs)."""
    eng = ExudynEngine(case, **options)
    u = _squeeze_inputs(case)
    nat, idx = [], []
    for k in range(1, periods + 1):
        eng.advance(k * case.solver.control_period, u)
        nat.append(_native(eng))
        idx.append(eng.observer.grasp_forces(u))
    return np.array(nat), np.array(idx)


@pytest.fixture(scope="module")
def squeeze():
    return load_case("closed_squeeze")


def _states(mbs):
    sd = mbs.systemData
    C = exu.ConfigurationType
    out = []
    for c in (C.Current, C.StartOfStep, C.Initial):
        d = sd.GetSystemStateDict(configuration=c)
        out += [np.array(d[key], copy=True) for key in sorted(d)] + [sd.GetTime(c)]
    return out


def test_evaluation_leaves_the_integrator_alone(squeeze):
    """Evaluated at every control sample while the solver's greenlet is suspended (the first call
    initialises the static solver): every system state (current, start of step, initial,
    accelerations included) is unchanged bit for bit, and so is the trajectory."""
    u = _squeeze_inputs(squeeze)
    a = ExudynEngine(squeeze, rigid=True, substeps=2)
    b = ExudynEngine(squeeze, rigid=True, substeps=2)
    for k in range(1, 31):
        a.advance(k * 1e-3, u)
        b.advance(k * 1e-3, u)
        before = _states(b.mbs)
        loads = [b.mbs.GetLoadParameter(ld, "loadVector") for ld in (b.model.base_torque_load, b.model.thrust_load)]
        b.observer.grasp_forces(Inputs(tau_m=u.tau_m, tau_B=3.0))  # a different held input
        after = _states(b.mbs)
        assert all(np.array_equal(x, y) for x, y in zip(before, after)), k
        assert all(np.array_equal(x, b.mbs.GetLoadParameter(ld, "loadVector"))
                   for x, ld in zip(loads, (b.model.base_torque_load, b.model.thrust_load)))
    assert np.array_equal(np.concatenate(a.coordinates()), np.concatenate(b.coordinates()))


def test_rigid_matches_native_at_the_default_step(squeeze):
    """h = 0.5 ms, both grasps on: the index-1 forces are the integrator's multipliers to
    ≤ 1e-5 of their size (measured 5.8e-7 over 0.1 s; docs/exudyn.md §6 floor ε/(βh²) is
    negligible at this step)."""
    nat, idx = _series(squeeze, 100, rigid=True, substeps=2)
    scale = np.abs(idx).max()
    assert scale > 15.0  # the ~20 N squeeze
    assert np.abs(nat - idx).max() < 1e-5 * scale, np.abs(nat - idx).max() / scale


def test_small_steps_index1_converges_native_does_not(squeeze):
    """h = 7.8 µs and 3.9 µs (substeps 128, 256): the index-1 forces of the two runs agree to
    ≤ 5e-5 of 21 N (the state's O(h²) difference over 30 ms; measured 1.4e-5), while the
    native multipliers carry the round-off floor ε/(βh²): ≥ 1e-3 from the index-1 forces at
    3.9 µs (measured 9.1e-3, 640 × the index-1 difference), growing as the step halves
    (measured 1.8e-3 → 9.1e-3; 1/h² → ×4)."""
    nat1, idx1 = _series(squeeze, 30, rigid=True, substeps=128)
    nat2, idx2 = _series(squeeze, 30, rigid=True, substeps=256)
    scale = np.abs(idx2).max()
    conv = np.abs(idx2 - idx1).max() / scale
    noise1 = np.abs(nat1 - idx1).max() / scale
    noise2 = np.abs(nat2 - idx2).max() / scale
    assert conv < 5e-5, conv
    assert noise2 > 1e-3 and noise2 > 2.0 * noise1, (noise1, noise2)
    assert noise2 > 30.0 * conv, (conv, noise2)


def test_release_rigid():
    """Case release through the runner (h = 0.5 ms): both grasps before t = 1 s, grasp 1
    after; the released grasp's multipliers are exactly 0 (its rows are λ = 0), and the
    static solver initialised before the release needs no new initialisation."""
    case = load_case("release")

    class Probe(ExudynEngine):
        def observe(self, inputs):
            out = super().observe(inputs)
            cf = self.constraint_forces
            lam = cf.multipliers()
            rows = [lam[self.mbs.systemData.GetObjectLTGAE(j)] for j in self.model.grasp_joints]
            self.rec.append((self.state.t, self.state.grasp_on.copy(), _native(self), self.observer.grasp_forces(inputs), rows))
            return out

    eng = Probe(case, rigid=True, substeps=2)
    eng.rec = []
    run(eng, case, 1.02)
    t = np.array([r[0] for r in eng.rec])
    on = np.array([r[1] for r in eng.rec])
    nat = np.array([r[2] for r in eng.rec])
    idx = np.array([r[3] for r in eng.rec])
    assert np.all(on[t < 1.0] == [1, 1]) and np.all(on[t >= 1.0] == [1, 0])
    scale = np.abs(idx).max()
    late = t > 0.0  # t = 0: nothing integrated yet (both zero at rest)
    assert np.abs(nat - idx)[late].max() < 1e-5 * scale, np.abs(nat - idx)[late].max() / scale
    after = t >= 1.0
    assert np.all(idx[after, 2:] == 0.0) and all(np.all(r[4][1] == 0.0) for r, a in zip(eng.rec, after) if a)
    assert np.abs(idx[after, :2]).max() > 1.0  # grasp 1 still loaded
    fresh = ConstraintForces(eng.mbs).multipliers()
    kept = eng.constraint_forces.multipliers()
    assert np.abs(kept - fresh).max() <= 1e-13 * np.abs(fresh).max()


def test_flexible_matches_native(squeeze):
    """Flexible links (6 × 8 ANCF elements, 252 ODE2 coordinates, 50 multipliers), h = 0.5 ms:
    finite and equal to the integrator's multipliers to ≤ 1e-4 of their size (measured
    4.7e-7; the flexible Newton absolute tolerance is 1e-4 N)."""
    nat, idx = _series(squeeze, 20, rigid=False, substeps=2)
    assert np.all(np.isfinite(idx))
    scale = np.abs(idx).max()
    assert scale > 15.0
    assert np.abs(nat - idx).max() < 1e-4 * scale, np.abs(nat - idx).max() / scale


def test_held_inputs_apply_the_coming_period():
    """thrust_burn (orbit, thrust-inertia field; rigid): at a control sample the index-1
    forces with the inputs of the coming period equal those that advance() itself leaves
    in the mbs for the same inputs (≤ 2e-6; measured 2.3e-7: advance() holds the base mass
    of the period's start, 2.3e-7 heavier), every parameter is put back bit for bit, and
    switching the thrust off changes them by its whole inertial load (measured 1.25)."""
    case = load_case("thrust_burn")
    eng = ExudynEngine(case, rigid=True, substeps=2)
    assert eng.field
    on = Inputs(thrust=case.params.actuators.thrust)
    off = Inputs()
    for k in range(1, 6):
        eng.advance(k * 1e-3, on)
    mbs = eng.mbs

    def params():
        return ([mbs.GetLoadParameter(ld, "loadVector") for ld in (eng.model.base_torque_load, eng.model.thrust_load)]
                + [mbs.GetObjectParameter(eng.model.carrier, "forceVector"), mbs.GetObjectParameter(eng.model.base, "mass")])

    before, states = params(), _states(mbs)
    left = eng.observer.grasp_forces()  # the loads advance() set for `on`
    right_on = eng.observer.grasp_forces(on)
    right_off = eng.observer.grasp_forces(off)
    assert all(np.array_equal(x, y) for x, y in zip(before, params()))
    assert all(np.array_equal(x, y) for x, y in zip(states, _states(mbs)))
    scale = np.abs(left).max()
    assert scale > 0.5  # 0.84 N five periods into the burn
    assert np.abs(right_on - left).max() < 2e-6 * scale, np.abs(right_on - left).max() / scale
    assert np.abs(right_off - left).max() > 0.1 * scale, np.abs(right_off - left).max() / scale


def test_the_mbs_carries_the_held_thrust_when_advance_skips_an_unchanged_one():
    """advance() sets the thrust load only when the thrust differs from the held one, to
    the sign of zero (`Stepper.set_inputs`' previous): across an evaluation with other inputs
    (`held_inputs` sets and restores the loads) and across ±0, the mbs carries the held
    thrust bit for bit at every period."""
    case = load_case("thrust_burn")
    eng = ExudynEngine(case, rigid=True, substeps=2)
    thrust = case.params.actuators.thrust
    mbs = eng.mbs
    for k, value in enumerate([thrust, thrust, thrust, 0.0, -0.0, -0.0, 0.0, thrust], start=1):
        eng.observer.grasp_forces(Inputs(thrust=0.5 * thrust))
        eng.advance(k * 1e-3, Inputs(thrust=value))
        load = mbs.GetLoadParameter(eng.model.thrust_load, "loadVector")
        assert np.asarray(load).tobytes() == np.array([value, 0.0, 0.0]).tobytes(), (k, value, load)
