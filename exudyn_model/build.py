"""Building the Exudyn model: the mbs with its bodies, links, joints, connectors, the index
tables the engine reads coordinates by, and the solver settings.

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
  wrist bistop: `ObjectConnectorCoordinateSpringDamperExt` with limit stops between the
  terminal link's distal hub θ and θ_T;
* inputs held over the control period (zero-order hold, set once per period): τ_B
  (`LoadTorqueVector`), τ_m, thrust (`LoadForceVector`, body fixed), and, with an orbit or
  thrust, the field of docs/physics.md §5 as one generalised force vector on the mass
  coordinates (an `ObjectGenericODE2` without matrices), the propellant mass on the base,
  and the motion of O (RK4 in the engine, `exudyn_model.field`).

`BuildMixin` is the part of `exudyn_model.engine.ExudynEngine` that does this (called once,
from the constructor), with the basic access to the coordinates (`_qv`) and the base's
present mass.
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
    MarkerNodeRigid, MarkerObjectODE2Coordinates, NodeGenericData, NodeGenericODE2,
    NodePointGround, NodeRigidBody2D, ObjectConnectorCoordinateSpringDamperExt,
    ObjectConnectorCoordinateVector, ObjectGenericODE2, ObjectGround, ObjectJointPrismatic2D,
    ObjectJointRevolute2D, ObjectRigidBody2D)

from exudyn_model import links  # noqa: E402
from exudyn_model.field import N_GAUSS_FIELD, _ThrustInertia  # noqa: E402
from rsmcheck.core.geometry import rot  # noqa: E402

PP, PF = "PP", "PF"


def _perp(a) -> np.ndarray:
    return np.array([-a[1], a[0]])


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
    basis: str = PP


class BuildMixin:
    """`ExudynEngine`'s model: `_build` (the items), `_index` (ODE2 index tables and the
    mesh's matrices), `_init_solver` (settings and the implicit solver)."""

    def _build(self, init) -> None:
        p = self.params
        SC = exu.SystemContainer()
        mbs = SC.AddSystem()
        self.SC, self.mbs = SC, mbs
        self.ground = mbs.AddObject(ObjectGround())
        self.ground_coords = mbs.AddMarker(MarkerObjectODE2Coordinates(objectNumber=self.ground))
        gnode = mbs.AddNode(NodePointGround())
        self.ground_coord = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=gnode, coordinate=0))

        def rigid(pose, rate, mass, inertia):
            n = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=list(map(float, pose)),
                                            initialVelocities=list(map(float, rate))))
            return n, mbs.AddObject(ObjectRigidBody2D(nodeNumber=n, mass=mass, inertia=inertia))

        self.base_node, self.base = rigid(init.base_pose, init.base_rate, p.base.mass, p.base.inertia_z)
        self._base_mass = p.base.mass  # what the base and the solver's mass matrix carry (`_set_base_mass`)
        self.target_node, self.target = rigid(init.target_pose, init.target_rate, p.target.mass, p.target.inertia_z)

        # ---- links, arm by arm from the base outward (rigid kinematics, undeformed) ----
        self.links: list[LinkItems] = []
        L = p.link.length
        rB = np.asarray(init.base_pose[:2], float)
        vB = np.asarray(init.base_rate[:2], float)
        self.frame_ref = np.zeros(6)
        for k in range(2):
            th, om = float(init.base_pose[2]), float(init.base_rate[2])
            mount = np.asarray(p.geometry.mount_B(k + 1), float)
            pin = rB + rot(th) @ mount
            vel = vB + om * _perp(pin - rB)
            parent_marker = mbs.AddMarker(MarkerBodyPosition(bodyNumber=self.base, localPosition=[*mount, 0.0]))
            for s in range(3):
                i = 3 * k + s
                th += float(init.joint_angles[i])
                om += float(init.joint_rates[i])
                terminal = s == 2
                basis = PP if (not terminal or init.grasp[k]) else PF
                item = (self._rigid_link if self.rigid else self._flexible_link)(i, pin, th, vel, om, terminal, basis)
                mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[parent_marker, item.prox_marker]))
                self.links.append(item)
                self.frame_ref[i] = th
                d = L * np.array([math.cos(th), math.sin(th)])
                pin = pin + d
                vel = vel + om * _perp(d)
                parent_marker = item.dist_marker

        # ---- rotors: linear GenericODE2 over [parent θ, child θ, θ_m] (docs/exudyn.md §1) ----
        self.rotor_nodes = []
        self.motor_loads = []
        mo = p.motor
        # θ_m: at the joint angles (springs relaxed) unless the start state gives them
        th_m = init.joint_angles if init.motor_angles is None else init.motor_angles
        om_m = init.joint_rates if init.motor_rates is None else init.motor_rates
        for j in range(6):
            parent = self.base_node if j % 3 == 0 else self.links[j - 1].dist_hub
            child = self.links[j].prox_hub
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
            self.motor_loads.append(mbs.AddLoad(LoadCoordinate(markerNumber=mr, load=0.0)))
            self.rotor_nodes.append(nr)

        # ---- grasps and wrist bistops ----
        self.grasp_joints, self.grasp_markers, self.bistops = [], [], []
        w = p.wrist
        for k in range(2):
            link = self.links[3 * k + 2]
            mt = mbs.AddMarker(MarkerBodyPosition(bodyNumber=self.target, localPosition=[*self.rho_G[k], 0.0]))
            self.grasp_markers.append(mt)
            self.grasp_joints.append(mbs.AddObject(ObjectJointRevolute2D(
                markerNumbers=[mt, link.dist_marker], activeConnector=bool(init.grasp[k]))))
            psi_ref = float(init.target_pose[2]) - self.frame_ref[3 * k + 2]
            data = mbs.AddNode(NodeGenericData(initialCoordinates=[0.0, 0.0, 0.0], numberOfDataCoordinates=3))
            m0 = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=link.dist_hub, coordinate=2))
            m1 = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=self.target_node, coordinate=2))
            self.bistops.append(mbs.AddObject(ObjectConnectorCoordinateSpringDamperExt(
                markerNumbers=[m0, m1], nodeNumber=data, stiffness=0.0, damping=0.0,
                useLimitStops=True, limitStopsUpper=w.limit - psi_ref, limitStopsLower=-w.limit - psi_ref,
                limitStopsStiffness=w.stiffness, limitStopsDamping=w.damping,
                activeConnector=bool(init.grasp[k]))))

        # ---- base actuators ----
        mb = mbs.AddMarker(MarkerBodyRigid(bodyNumber=self.base, localPosition=[0.0, 0.0, 0.0]))
        self.base_torque_load = mbs.AddLoad(LoadTorqueVector(markerNumber=mb, loadVector=[0.0, 0.0, 0.0]))
        self.thrust_load = mbs.AddLoad(LoadForceVector(markerNumber=mb, loadVector=[0.0, 0.0, 0.0], bodyFixed=True))

        # ---- field carrier: generalised forces of the tidal/thrust-inertia field ----
        self.carrier = None
        if self.field:
            self.field_nodes = [self.base_node, self.target_node]
            for item in self.links:
                self.field_nodes += item.nodes if not item.rigid else [item.frame_node]
            self.carrier = mbs.AddObject(ObjectGenericODE2(nodeNumbers=self.field_nodes))
        mbs.Assemble()
        if self.field:
            # its pre-step function is registered while there is thrust (`_advance`)
            self._thrust_inertia = _ThrustInertia(self.carrier, self.base_node, float(init.base_pose[2]))
        self._pre_step_on = False

    def _rigid_link(self, i, pin, th, vel, om, terminal, basis) -> LinkItems:
        mbs, p = self.mbs, self.params
        L = p.link.length
        e = np.array([math.cos(th), math.sin(th)])
        com = pin + 0.5 * L * e
        v = vel + om * _perp(0.5 * L * e)
        n = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[*com, th], initialVelocities=[*v, om]))
        b = mbs.AddObject(ObjectRigidBody2D(nodeNumber=n, mass=p.link.mass, inertia=p.link.inertia_z))
        return LinkItems(i, True, n, b, n, n,
                         mbs.AddMarker(MarkerBodyPosition(bodyNumber=b, localPosition=[-0.5 * L, 0.0, 0.0])),
                         mbs.AddMarker(MarkerBodyPosition(bodyNumber=b, localPosition=[0.5 * L, 0.0, 0.0])),
                         basis=basis)

    def _flexible_link(self, i, pin, th, vel, om, terminal, basis) -> LinkItems:
        mbs, p = self.mbs, self.params
        L, m = p.link.length, p.link.mass
        nodes, elements = links.add_link(mbs, p.link, self.n_elements, pin, th, vel, om,
                                         axial_damping=self.axial_damping)
        # frame body: massless, J_extra, origin at the proximal pin
        nf = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[*pin, th], initialVelocities=[*vel, om]))
        bf = mbs.AddObject(ObjectRigidBody2D(nodeNumber=nf, mass=0.0, inertia=p.link.inertia_extra))
        prox = mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[0]))
        dist = mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[-1]))
        mf_pos = mbs.AddMarker(MarkerBodyPosition(bodyNumber=bf, localPosition=[0.0, 0.0, 0.0]))
        mf = mbs.AddMarker(MarkerBodyRigid(bodyNumber=bf, localPosition=[0.0, 0.0, 0.0]))
        mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[prox, mf_pos]))
        # PP: distal pin on the frame axis
        tip = mbs.AddMarker(MarkerBodyRigid(bodyNumber=elements[-1], localPosition=[self.mesh.le, 0.0, 0.0]))
        pp = mbs.AddObject(ObjectJointPrismatic2D(markerNumbers=[tip, mf], axisMarker0=[1.0, 0.0, 0.0],
                                                  normalMarker1=[0.0, 1.0, 0.0], constrainRotation=False,
                                                  activeConnector=basis == PP))
        item = LinkItems(i, False, nf, bf, links.add_hub(mbs, nodes[0], th), links.add_hub(mbs, nodes[-1], th),
                         prox, dist, nodes, elements, pp_joint=pp, basis=basis)
        if terminal:
            # PF: P = R + (L/I_0) ∫ρ ξ (r − R) dξ on the frame axis
            e = np.array([math.cos(th), math.sin(th)])
            pnode = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[*(pin + L * e), 0.0],
                                                initialVelocities=[*(vel + om * _perp(L * e)), 0.0]))
            holder = mbs.AddObject(ObjectGenericODE2(nodeNumbers=nodes + [pnode]))
            nq = self.mesh.nq
            X = np.zeros((2, nq + 3))
            X[:, :nq] = -L * self.mesh.moment_matrix()
            X[0, 0] += 0.5 * L * m * L - self.I0
            X[1, 1] += 0.5 * L * m * L - self.I0
            X[0, nq] = X[1, nq + 1] = self.I0
            mh = mbs.AddMarker(MarkerObjectODE2Coordinates(objectNumber=holder))
            # P is needed only while the link is PF: in PP the connector is off (its Jacobian,
            # evaluated at every Newton residual, was 3.7 % of an Exudyn run) and P is parked
            # at its reference position by two coordinate constraints (massless, it must be
            # held by something); `_switch_basis` swaps them (docs/exudyn.md §1)
            item.p_tie = mbs.AddObject(ObjectConnectorCoordinateVector(
                markerNumbers=[self.ground_coords, mh], scalingMarker0=np.zeros((2, 0)), scalingMarker1=X,
                activeConnector=basis == PF))
            item.p_park = [mbs.AddObject(CoordinateConstraint(
                markerNumbers=[self.ground_coord, mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=pnode, coordinate=c))],
                activeConnector=basis == PP)) for c in (0, 1)]
            mpr = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=pnode, coordinate=2))
            mbs.AddObject(CoordinateConstraint(markerNumbers=[self.ground_coord, mpr]))
            mp = mbs.AddMarker(MarkerNodeRigid(nodeNumber=pnode))
            item.pf_joint = mbs.AddObject(ObjectJointPrismatic2D(
                markerNumbers=[mp, mf], axisMarker0=[1.0, 0.0, 0.0], normalMarker1=[0.0, 1.0, 0.0],
                constrainRotation=False, activeConnector=basis == PF))
            item.p_node = pnode
        return item

    def _index(self) -> None:
        """Global ODE2 indices of the coordinates the engine reads."""
        mbs = self.mbs
        idx = mbs.GetNodeODE2Index
        self.i_base = idx(self.base_node) + np.arange(3)
        self.i_target = idx(self.target_node) + np.arange(3)
        self.i_frame = np.array([idx(it.frame_node) + 2 for it in self.links])
        self.i_hub_prox = np.array([idx(it.prox_hub) + 2 for it in self.links])
        self.i_hub_dist = np.array([idx(it.dist_hub) + 2 for it in self.links])
        self.i_rotor = np.array([idx(n) for n in self.rotor_nodes])
        for it in self.links:
            if it.rigid:
                it.coords = idx(it.frame_node) + np.arange(3)
            else:
                it.coords = np.concatenate([idx(n) + np.arange(4) for n in it.nodes])
            if it.p_node is not None:
                it.p_coords = idx(it.p_node) + np.arange(2)
        # the sensors' pairs (`ObserveMixin._sensors`): each joint's parent hub and parent frame
        # (the base's θ for the first joint of an arm), each wrist's terminal distal hub, the
        # end effectors' x, y (the tip nodes of flexible terminal links; rigid: None)
        i_thB = self.i_base[2]
        self._i_hub_parent = np.array([i_thB, *self.i_hub_dist[:2], i_thB, *self.i_hub_dist[3:5]])
        self._i_frame_parent = np.array([i_thB, *self.i_frame[:2], i_thB, *self.i_frame[3:5]])
        self._i_wrist_hub = self.i_hub_dist[[2, 5]]
        self._i_ee = None if self.rigid else np.array([self.links[2].coords[-4:-2], self.links[5].coords[-4:-2]])
        # all of them in one gather per sample (`_sensors`): `_sensor_rows`, and where each
        # group lies in it (`_sensor_at`, name → slice)
        groups = {"base": self.i_base, "target": self.i_target, "rotor": self.i_rotor,
                  "hub_prox": self.i_hub_prox, "hub_parent": self._i_hub_parent, "frame": self.i_frame,
                  "frame_parent": self._i_frame_parent, "wrist_hub": self._i_wrist_hub}
        if not self.rigid:
            groups["ee"] = self._i_ee.reshape(-1)
        ends = np.cumsum([len(g) for g in groups.values()])
        self._sensor_at = {name: slice(int(e) - len(g), int(e)) for (name, g), e in zip(groups.items(), ends)}
        self._sensor_rows = np.concatenate(list(groups.values())).astype(np.int64)
        self.q_ref = np.asarray(mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference))
        L = self.params.link.length
        self.first = self.mesh.first_matrix()
        self.moment = self.mesh.moment_matrix()
        self.mass_ancf = self.mesh.mass_matrix()
        self.pos_mid = self.mesh.pos_matrix(0.5 * L)
        self._rigid_gauss = links.gauss(8, -0.5 * L, 0.5 * L)  # a rigid link's field points
        # the tidal field's quadrature on the flexible links (field.tidal_carrier_forces)
        self._flex = [i for i, it in enumerate(self.links) if not it.rigid]
        self._flex_coords = np.array([self.links[i].coords for i in self._flex], dtype=np.int64).reshape(
            len(self._flex), self.mesh.nq)
        _, ws_flex, D = self.mesh.sample(N_GAUSS_FIELD)  # rows x_g, y_g of every Gauss point
        self._field_weights = self.params.link.rho_a * ws_flex  # ρA w_g [kg]
        # D by its non-zero entries per row (a point of an element: 4 of the link's coordinates)
        width = int(np.max(np.count_nonzero(D, axis=1)))
        cols = np.argsort(D == 0.0, axis=1, kind="stable")[:, :width]
        self._field_S = (np.ascontiguousarray(cols), np.ascontiguousarray(np.take_along_axis(D, cols, axis=1)))
        self._field_points = np.array([self.i_base[:2], self.i_target[:2]], dtype=np.int64)
        # places in the carrier's vector (base, target, then the links: `field_nodes`'s order)
        # of the base's and target's x, y, of each link's coordinates, of the flexible ones
        ends = 6 + np.cumsum([3 if it.rigid else len(it.coords) for it in self.links])
        self._n_carrier = int(ends[-1])
        self._carrier_points = np.array([[0, 1], [3, 4]], dtype=np.int64)
        self._carrier_links = [slice(int(e) - (3 if it.rigid else len(it.coords)), int(e))
                               for it, e in zip(self.links, ends)]
        self._carrier_flex = np.array([np.arange(self._n_carrier)[self._carrier_links[i]] for i in self._flex],
                                      dtype=np.int64).reshape(len(self._flex), self.mesh.nq)
        self._uniform: tuple[float, np.ndarray] | None = None  # (base mass, U) of the last build
        # ∫ρ r dξ of every link as one matrix on the stacked link coordinates
        self._link_coords = np.concatenate([it.coords for it in self.links])
        blocks = [np.hstack([self.params.link.mass * np.eye(2), np.zeros((2, 1))]) if it.rigid else self.first
                  for it in self.links]
        self._link_first = np.hstack(blocks)
        self.pos_tip = self.mesh.pos_matrix(L)

    def _settings(self) -> exu.SimulationSettings:
        s = exu.SimulationSettings()
        ti = s.timeIntegration
        ti.endTime = self.dt
        ti.numberOfSteps = self.substeps
        ti.generalizedAlpha.spectralRadius = self.spectral_radius
        ti.generalizedAlpha.computeInitialAccelerations = True
        if self.constraints == "index2":
            # Newmark (trapezoidal: β = 1/4, γ = 1/2, no numerical damping) with velocity-level
            # constraints: the multipliers scale as 1/h instead of 1/h² (docs/exudyn.md §6)
            ti.generalizedAlpha.useNewmark = True
            ti.generalizedAlpha.useIndex2Constraints = True
        ti.newton.relativeTolerance = self.newton_rtol
        ti.newton.absoluteTolerance = self.newton_atol
        ti.newton.useModifiedNewton = True
        ti.newton.modifiedNewtonJacUpdatePerStep = self.jacobian_per_step
        ti.adaptiveStep = True
        ti.verboseMode = 0
        # the mass matrix is computed once, not at every Newton residual (~6 % of the solver's
        # time); the one mass that changes, the base's under thrust, is set by `_set_base_mass`,
        # which recomputes it (docs/exudyn.md §4)
        ti.reuseConstantMassMatrix = True
        s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        s.solution.file.write = False
        s.solution.sensors.active = False
        s.solution.file.writeInitialValues = False
        return s

    def _init_solver(self) -> None:
        self.settings = self._settings()
        self.solver = exu.MainSolverImplicitSecondOrder()
        self.solver.InitializeSolver(self.mbs, self.settings)

    def _qv(self) -> tuple[np.ndarray, np.ndarray]:
        """Absolute ODE2 coordinates q and velocities q̇ (read-only: between the end of an
        `_advance` and the next change of the state, `_pause` or `_advance`, the same arrays
        of that sample are returned: the sensors, the observables and the next held inputs
        read them without three copies out of Exudyn)."""
        if self._qv_sample is not None:
            return self._qv_sample
        sd = self.mbs.systemData
        return np.asarray(sd.GetODE2Coordinates()) + self.q_ref, np.asarray(sd.GetODE2Coordinates_t())

    def _mass_base(self) -> float:
        return self.params.base.mass - self.m_used
