"""Building the Exudyn model: the mbs with its bodies, links, joints and connectors
(`build_model`), and the `ExudynModel` that holds it with the numbers of its items.

Model (docs/exudyn.md has the reasons and the numbers):

* base, target: `ObjectRigidBody2D` at their COMs, positions relative to the co-moving
  reference point O (docs/physics.md §5);
* links: `ObjectANCFCable2D` chains (`exudyn_model.links`), or with `rigid=True`
  `ObjectRigidBody2D` (COM at mid-length, J_z about the COM);
* end sections (docs/physics.md §3.3): a massless *hub* (`NodeRigidBody2D` with an
  `ObjectRigidBody2D` of zero mass and inertia) at each end node of each beam, clamped to
  it by `ObjectJointGeneric(constrainedAxes=[1,1,0,0,0,1])` on `MarkerNodeRigid`s: its
  rotation is the rotation of the beam's end section (the ANCF slope direction);
* joints: `ObjectJointRevolute2D` between beam-end nodes (a hinge: no moment of its own);
  every torque the joint transmits acts on the two hubs;
* rotors (eq. 2): one linear `ObjectGenericODE2` per joint over [parent distal hub (the base
  for the first joint), child proximal hub, rotor θ_m (`NodeGenericODE2`)], mass B_m on θ_m,
  stiffness K_m v vᵀ, damping C_m v vᵀ, v = (+1, −1, +1): the spring acts on θ_m − ψ_J, ψ_J
  between the end sections; τ_m by `LoadCoordinate` on θ_m;
* link frames (docs/physics.md §2.1, §2.3): a massless rigid *frame body* per flexible link
  carrying J_extra (and nothing else), pinned at the proximal pin (`ObjectJointRevolute2D`)
  and aligned by an `ObjectJointPrismatic2D` (no rotation constraint) so that its x-axis
  passes through
    PP: the distal pin (chord frame), or
    PF: the point P = R + (L/I_0) ∫ρ ξ (r − R) dξ, a massless node tied to the beam
        coordinates by a linear `ObjectConnectorCoordinateVector`; its x-axis is then the
        mass-orthogonal frame, θ = atan2(∫ρ ξ (r − R) dξ), exactly;
  its inertial couple J_extra θ̈ reaches the beam as the generalised force of the frame
  rotation, as in the reference; θ_J (`joint_frame_angles`) is read from these bodies;
* grasps: `ObjectJointRevolute2D` end effector ↔ target point, switched by `activeConnector`;
  wrist bistop: `ObjectConnectorCoordinateSpringDamperExt` between the terminal link's
  distal hub θ and θ_T, its force the Hunt–Crossley stop of `bistop_law` (a symbolic
  `springForceUserFunction`, compiled by Exudyn);
* inputs held over the control period (zero-order hold, set once per period): τ_B
  (`LoadTorqueVector`), τ_m, thrust (`LoadForceVector`, body fixed), and, with an orbit or
  thrust, the field of docs/physics.md §5 as one generalised force vector on the mass
  coordinates (an `ObjectGenericODE2` without matrices), the propellant mass on the base,
  and the motion of O (RK4, `exudyn_model.field`).

`build_model` does this once, when an engine is made; the `ExudynModel` it returns does not
change during a run (connectors are switched on and off in its mbs, the base's mass is set
by the stepper: the items and their numbers stay).  `exudyn_model.indices` adds the tables
of ODE2 indices the engine reads coordinates by.
"""

from __future__ import annotations

import contextlib
import io
import math
import sys
from dataclasses import dataclass, field as dc_field

import numpy as np

sys.exudynFast = True  # the engine's build: import order must not matter
# exudyn announces the fast build on stdout: keep it out of `--json` output
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu  # noqa: E402
from exudyn.itemInterface import (  # noqa: E402
    CoordinateConstraint, LoadCoordinate, LoadForceVector, LoadTorqueVector,
    MarkerBodyPosition, MarkerBodyRigid, MarkerNodeCoordinate, MarkerNodePosition,
    MarkerNodeRigid, MarkerObjectODE2Coordinates, NodeGenericODE2,
    NodePointGround, NodeRigidBody2D, ObjectConnectorCoordinateSpringDamperExt,
    ObjectConnectorCoordinateVector, ObjectGenericODE2, ObjectGround, ObjectJointPrismatic2D,
    ObjectJointRevolute2D, ObjectRigidBody2D)

from exudyn.advancedUtilities import CreateSymbolicUserFunction  # noqa: E402

from exudyn_model import links  # noqa: E402
from exudyn_model.indices import IndexTables, index_tables  # noqa: E402
from rsmcheck.core.geometry import rot  # noqa: E402

PP, PF = "PP", "PF"


def perp(a) -> np.ndarray:
    """a turned by +90° in the plane: ω × a = ω perp(a) for a rotation rate ω about z."""
    return np.array([-a[1], a[0]])


def bistop_law(limit: float):
    """The wrist bistop as the `springForceUserFunction` of a CoordinateSpringDamperExt
    (docs/physics.md §4.3), to be made symbolic by `CreateSymbolicUserFunction`.

    Exudyn passes q = q_T − q_hub (coordinates without their references), v = q̇, and the
    connector's stiffness k, damping d (here λ) and offset (−ψ at q = 0); its force f acts
    as −f on the target.  With ψ = q − offset, the penetration δ = max(|ψ| − ψ_lim, 0):

        f = sgn(ψ) max(0, k δ + λ δ sgn(ψ) v),

    zero at and inside the limit, never pulling the target into the stop.
    """
    sym = exu.symbolic

    def law(mbs, t, itemNumber, q, v, k, d, offset, velocityOffset, fDynamicFriction,
            fStaticFrictionOffset, exponentialDecayStatic, fViscousFriction, frictionProportionalZone):
        psi = q - offset
        s = sym.sign(psi)
        delta = sym.max(sym.abs(psi) - limit, 0.0)
        return s * sym.max(k * delta + d * delta * s * v, 0.0)

    return law


@dataclass
class LinkItems:
    """The Exudyn items of one link (index 0..5: arm 1 links 1–3, then arm 2)."""

    index: int
    rigid: bool
    frame_node: int  # coordinate 2 of this node is the link frame angle θ_i
    frame_body: int
    prox_hub: int  # node whose coordinate 2 is the rotation of the proximal end section
    dist_hub: int  # the same for the distal end section
    prox_marker: int  # position marker at the proximal pin
    dist_marker: int  # position marker at the distal pin (the end effector for link 3)
    nodes: list[int] = dc_field(default_factory=list)  # ANCF nodes (flexible)
    elements: list[int] = dc_field(default_factory=list)
    coords: np.ndarray | None = None  # global ODE2 indices of the beam (or rigid node) coordinates
    pp_joint: int | None = None  # chord prismatic (distal pin on the frame axis)
    pf_joint: int | None = None  # rigid-mode prismatic (P on the frame axis), terminal links
    p_node: int | None = None  # the massless point P of the PF axis, terminal links
    p_tie: int | None = None  # P tied to the beam (active in PF)
    p_park: list[int] = dc_field(default_factory=list)  # P's x, y held at their reference (active in PP)
    p_coords: np.ndarray | None = None  # global ODE2 indices of P's x, y


@dataclass
class ExudynModel:
    """The built robot: the Exudyn system and the numbers of its items (what does not change
    during a run), with the link mesh's matrices and the index tables (`indices.py`)."""

    params: object  # rsmcheck.core.params.Params
    rigid: bool  # links are ObjectRigidBody2D (else ANCF cables)
    n_elements: int  # ANCF elements per link
    mesh: links.LinkMesh  # one link's mesh (every link has the same)
    I0: float  # m L²/3, a link's inertia about its proximal pin [kg·m²]
    SC: object  # exu.SystemContainer
    mbs: object  # exu.MainSystem
    ground_coords: int  # marker: the ground's (empty) coordinate vector
    ground_coord: int  # marker: one ground coordinate
    base_node: int
    base: int
    target_node: int
    target: int
    links: list[LinkItems]  # index 0..5: arm 1 links 1–3, then arm 2
    frame_ref: np.ndarray  # (6,) each link's frame angle at build [rad]
    rotor_nodes: list[int]  # θ_m of each joint's rotor (NodeGenericODE2)
    motor_loads: list[int]  # τ_m (LoadCoordinate on θ_m)
    grasp_markers: list[int]  # arm k's grasp point on the target (moved at a capture)
    grasp_joints: list[int]  # arm k's grasp (ObjectJointRevolute2D, switched)
    bistops: list[int]  # arm k's wrist bistop (switched with the grasp)
    base_torque_load: int  # τ_B
    thrust_load: int  # thrust, body fixed
    carrier: int | None  # the field's generalised forces (ObjectGenericODE2), None without field
    field_nodes: list[int]  # the carrier's nodes: base, target, each link's mass nodes
    # the mesh's matrices on one link's coordinates (links.LinkMesh)
    first: np.ndarray  # ∫ρ r dξ
    moment: np.ndarray  # ∫ρ ξ r dξ
    mass_ancf: np.ndarray  # the consistent mass matrix
    pos_mid: np.ndarray  # r(L/2)
    pos_tip: np.ndarray  # r(L)
    index: IndexTables | None = None  # ODE2 index tables, set by `build_model` after Assemble
    # the bistops' symbolic spring-force functions (`bistop_law`): they must outlive the mbs
    bistop_laws: list = dc_field(default_factory=list)


def initial_basis(grasp) -> list[str]:
    """Each link's basis at the start: PP, except a terminal link whose arm does not hold
    the target (PF: docs/physics.md §4.4)."""
    return [PP if (s != 2 or grasp[k]) else PF for k in range(2) for s in range(3)]


def build_model(p, init, rho_G: np.ndarray, basis: list[str], rigid: bool, n_elements: int,
                axial_damping: float, field: bool) -> ExudynModel:
    """The mbs of the robot at the start state `init` (rsmcheck.driver.initial), params `p`,
    grasp points `rho_G` on the target, link bases `basis`; `field`: with the carrier of the
    field's generalised forces.  Assembled, its index tables made."""
    mesh = links.LinkMesh(n_elements, p.link.length, p.link.rho_a)
    I0 = p.link.mass * p.link.length**2 / 3.0
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    ground_coords = mbs.AddMarker(MarkerObjectODE2Coordinates(objectNumber=ground))
    gnode = mbs.AddNode(NodePointGround())
    ground_coord = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=gnode, coordinate=0))

    def rigid_body(pose, rate, mass, inertia):
        n = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=list(map(float, pose)),
                                        initialVelocities=list(map(float, rate))))
        return n, mbs.AddObject(ObjectRigidBody2D(nodeNumber=n, mass=mass, inertia=inertia))

    base_node, base = rigid_body(init.base_pose, init.base_rate, p.base.mass, p.base.inertia_z)
    target_node, target = rigid_body(init.target_pose, init.target_rate, p.target.mass, p.target.inertia_z)

    # ---- links, arm by arm from the base outward (rigid kinematics, undeformed) ----
    items: list[LinkItems] = []
    L = p.link.length
    rB = np.asarray(init.base_pose[:2], float)
    vB = np.asarray(init.base_rate[:2], float)
    frame_ref = np.zeros(6)
    for k in range(2):
        th, om = float(init.base_pose[2]), float(init.base_rate[2])
        mount = np.asarray(p.geometry.mount_B(k + 1), float)
        pin = rB + rot(th) @ mount
        vel = vB + om * perp(pin - rB)
        parent_marker = mbs.AddMarker(MarkerBodyPosition(bodyNumber=base, localPosition=[*mount, 0.0]))
        for s in range(3):
            i = 3 * k + s
            th += float(init.joint_angles[i])
            om += float(init.joint_rates[i])
            terminal = s == 2
            if rigid:
                item = _rigid_link(mbs, p, i, pin, th, vel, om)
            else:
                item = _flexible_link(mbs, p, mesh, I0, (ground_coords, ground_coord), n_elements, axial_damping,
                                      i, pin, th, vel, om, terminal, basis[i])
            mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[parent_marker, item.prox_marker]))
            items.append(item)
            frame_ref[i] = th
            d = L * np.array([math.cos(th), math.sin(th)])
            pin = pin + d
            vel = vel + om * perp(d)
            parent_marker = item.dist_marker

    # ---- rotors: linear GenericODE2 over [parent θ, child θ, θ_m] (docs/exudyn.md §1) ----
    rotor_nodes = []
    motor_loads = []
    mo = p.motor
    # θ_m: at the joint angles (springs relaxed) unless the start state gives them
    th_m = init.joint_angles if init.motor_angles is None else init.motor_angles
    om_m = init.joint_rates if init.motor_rates is None else init.motor_rates
    for j in range(6):
        parent = base_node if j % 3 == 0 else items[j - 1].dist_hub
        child = items[j].prox_hub
        nr = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[float(init.joint_angles[j])],
                                         initialCoordinates=[float(th_m[j] - init.joint_angles[j])],
                                         initialCoordinates_t=[float(om_m[j])],
                                         numberOfODE2Coordinates=1))
        v = np.zeros(7)
        v[2], v[5], v[6] = 1.0, -1.0, 1.0
        M = np.zeros((7, 7))
        M[6, 6] = mo.inertia
        mbs.AddObject(ObjectGenericODE2(nodeNumbers=[parent, child, nr], massMatrix=M,
                                        stiffnessMatrix=mo.stiffness * np.outer(v, v),
                                        dampingMatrix=mo.damping * np.outer(v, v)))
        mr = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nr, coordinate=0))
        motor_loads.append(mbs.AddLoad(LoadCoordinate(markerNumber=mr, load=0.0)))
        rotor_nodes.append(nr)

    # ---- grasps and wrist bistops ----
    grasp_joints, grasp_markers, bistops, bistop_laws = [], [], [], []
    w = p.wrist
    for k in range(2):
        link = items[3 * k + 2]
        mt = mbs.AddMarker(MarkerBodyPosition(bodyNumber=target, localPosition=[*rho_G[k], 0.0]))
        grasp_markers.append(mt)
        grasp_joints.append(mbs.AddObject(ObjectJointRevolute2D(
            markerNumbers=[mt, link.dist_marker], activeConnector=bool(init.grasp[k]))))
        # the markers' coordinates exclude the reference ones: ψ = q_T − q_hub + psi_ref
        psi_ref = float(init.target_pose[2]) - frame_ref[3 * k + 2]
        m0 = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=link.dist_hub, coordinate=2))
        m1 = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=target_node, coordinate=2))
        law = CreateSymbolicUserFunction(mbs, bistop_law(w.limit), "springForceUserFunction",
                                         itemTypeName="ObjectConnectorCoordinateSpringDamperExt")
        bistop_laws.append(law)
        bistops.append(mbs.AddObject(ObjectConnectorCoordinateSpringDamperExt(
            markerNumbers=[m0, m1], stiffness=w.stiffness, damping=w.contact_damping,
            offset=-psi_ref, useLimitStops=False, springForceUserFunction=law,
            activeConnector=bool(init.grasp[k]))))

    # ---- base actuators ----
    mb = mbs.AddMarker(MarkerBodyRigid(bodyNumber=base, localPosition=[0.0, 0.0, 0.0]))
    base_torque_load = mbs.AddLoad(LoadTorqueVector(markerNumber=mb, loadVector=[0.0, 0.0, 0.0]))
    thrust_load = mbs.AddLoad(LoadForceVector(markerNumber=mb, loadVector=[0.0, 0.0, 0.0], bodyFixed=True))

    # ---- field carrier: generalised forces of the tidal/thrust-inertia field ----
    carrier = None
    field_nodes: list[int] = []
    if field:
        field_nodes = [base_node, target_node]
        for item in items:
            field_nodes += item.nodes if not item.rigid else [item.frame_node]
        carrier = mbs.AddObject(ObjectGenericODE2(nodeNumbers=field_nodes))
    mbs.Assemble()
    model = ExudynModel(
        params=p, rigid=rigid, n_elements=n_elements, mesh=mesh, I0=I0, SC=SC, mbs=mbs,
        ground_coords=ground_coords, ground_coord=ground_coord, base_node=base_node, base=base,
        target_node=target_node, target=target, links=items, frame_ref=frame_ref, rotor_nodes=rotor_nodes,
        motor_loads=motor_loads, grasp_markers=grasp_markers, grasp_joints=grasp_joints, bistops=bistops,
        bistop_laws=bistop_laws,
        base_torque_load=base_torque_load, thrust_load=thrust_load, carrier=carrier, field_nodes=field_nodes,
        first=mesh.first_matrix(), moment=mesh.moment_matrix(), mass_ancf=mesh.mass_matrix(),
        pos_mid=mesh.pos_matrix(0.5 * L), pos_tip=mesh.pos_matrix(L))
    model.index = index_tables(model)
    return model


def _rigid_link(mbs, p, i, pin, th, vel, om) -> LinkItems:
    L = p.link.length
    e = np.array([math.cos(th), math.sin(th)])
    com = pin + 0.5 * L * e
    v = vel + om * perp(0.5 * L * e)
    n = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[*com, th], initialVelocities=[*v, om]))
    b = mbs.AddObject(ObjectRigidBody2D(nodeNumber=n, mass=p.link.mass, inertia=p.link.inertia_z))
    return LinkItems(i, True, n, b, n, n,
                     mbs.AddMarker(MarkerBodyPosition(bodyNumber=b, localPosition=[-0.5 * L, 0.0, 0.0])),
                     mbs.AddMarker(MarkerBodyPosition(bodyNumber=b, localPosition=[0.5 * L, 0.0, 0.0])))


def _flexible_link(mbs, p, mesh, I0, ground, n_elements, axial_damping, i, pin, th, vel, om, terminal,
                   basis) -> LinkItems:
    """ANCF link i with its frame body, hubs and PP joint; a terminal link also with the
    point P of its PF axis.  `ground`: the ground's coordinate-vector and coordinate markers."""
    ground_coords, ground_coord = ground
    L, m = p.link.length, p.link.mass
    nodes, elements = links.add_link(mbs, p.link, n_elements, pin, th, vel, om,
                                     axial_damping=axial_damping)
    # frame body: massless, J_extra, origin at the proximal pin
    nf = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[*pin, th], initialVelocities=[*vel, om]))
    bf = mbs.AddObject(ObjectRigidBody2D(nodeNumber=nf, mass=0.0, inertia=p.link.inertia_extra))
    prox = mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[0]))
    dist = mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[-1]))
    mf_pos = mbs.AddMarker(MarkerBodyPosition(bodyNumber=bf, localPosition=[0.0, 0.0, 0.0]))
    mf = mbs.AddMarker(MarkerBodyRigid(bodyNumber=bf, localPosition=[0.0, 0.0, 0.0]))
    mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[prox, mf_pos]))
    # PP: distal pin on the frame axis
    tip = mbs.AddMarker(MarkerBodyRigid(bodyNumber=elements[-1], localPosition=[mesh.le, 0.0, 0.0]))
    pp = mbs.AddObject(ObjectJointPrismatic2D(markerNumbers=[tip, mf], axisMarker0=[1.0, 0.0, 0.0],
                                              normalMarker1=[0.0, 1.0, 0.0], constrainRotation=False,
                                              activeConnector=basis == PP))
    item = LinkItems(i, False, nf, bf, links.add_hub(mbs, nodes[0], th), links.add_hub(mbs, nodes[-1], th),
                     prox, dist, nodes, elements, pp_joint=pp)
    if terminal:
        # PF: P = R + (L/I_0) ∫ρ ξ (r − R) dξ on the frame axis
        e = np.array([math.cos(th), math.sin(th)])
        pnode = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[*(pin + L * e), 0.0],
                                            initialVelocities=[*(vel + om * perp(L * e)), 0.0]))
        holder = mbs.AddObject(ObjectGenericODE2(nodeNumbers=nodes + [pnode]))
        nq = mesh.nq
        X = np.zeros((2, nq + 3))
        X[:, :nq] = -L * mesh.moment_matrix()
        X[0, 0] += 0.5 * L * m * L - I0
        X[1, 1] += 0.5 * L * m * L - I0
        X[0, nq] = X[1, nq + 1] = I0
        mh = mbs.AddMarker(MarkerObjectODE2Coordinates(objectNumber=holder))
        # P is needed only while the link is PF: in PP the connector is off (its Jacobian,
        # evaluated at every Newton residual, was 3.7 % of an Exudyn run) and P is parked
        # at its reference position by two coordinate constraints (massless, it must be
        # held by something); `switching.switch_basis` swaps them (docs/exudyn.md §1)
        item.p_tie = mbs.AddObject(ObjectConnectorCoordinateVector(
            markerNumbers=[ground_coords, mh], scalingMarker0=np.zeros((2, 0)), scalingMarker1=X,
            activeConnector=basis == PF))
        item.p_park = [mbs.AddObject(CoordinateConstraint(
            markerNumbers=[ground_coord, mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=pnode, coordinate=c))],
            activeConnector=basis == PP)) for c in (0, 1)]
        mpr = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=pnode, coordinate=2))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[ground_coord, mpr]))
        mp = mbs.AddMarker(MarkerNodeRigid(nodeNumber=pnode))
        item.pf_joint = mbs.AddObject(ObjectJointPrismatic2D(
            markerNumbers=[mp, mf], axisMarker0=[1.0, 0.0, 0.0], normalMarker1=[0.0, 1.0, 0.0],
            constrainRotation=False, activeConnector=basis == PF))
        item.p_node = pnode
    return item
