"""Pinocchio models of the rigid space robot and their mapping to the reference coordinates.

The system (planar, every rotation about z, inertial axes, no gravity, no orbit)
-----------------------------------------------------------------------------------
* Base B: rigid, mass m_B, inertia I_B about its COM.  Base frame origin = base COM.
* Arms k = 1, 2: three rigid links each (mass m_l, length L, inertia I_l about the link
  COM, COM at (L/2, 0) of the link frame).  Link frame origin at the proximal joint,
  x-axis towards the distal joint at (L, 0).  Joint 1 of arm k sits at
  ``params.geometry.mount_B(k)`` in the base frame.  Joint angles are relative:
  θ_J1 = θ_l1 − θ_B, θ_J2 = θ_l2 − θ_l1, θ_J3 = θ_l3 − θ_l2.  End effector k = point
  (L, 0) of link 3.
* Target T: rigid, mass m_T, inertia I_T about its COM.  Grasp point k at
  ``params.geometry.grasp_T(k)`` (target frame, relative to the target COM).  A grasp is
  a revolute wrist between end effector k and grasp point k, wrist angle
  ψ_k = θ_T − θ_l3,k; its constraint is φ_k = r_EE,k − r_grasp,k = 0 (2 rows).

Reference coordinates (the paper's eq. 3, Sect. 2)
--------------------------------------------------
q = [x_B, y_B, θ_B, θ_J1..3 (arm 1), θ_J1..3 (arm 2)] (9) for the RSM and
X_T = [x_T, y_T, θ_T] (3) for the target, a Newtonian body held by Lagrange multipliers
R_cl (eq. 11).  R_cl = (R1, R2, R3, R4) is the force ON THE TARGET at grasp 1 and grasp 2,
inertial components; the end effector feels −R.  Joint torques u_J act between parent
and child (+u on the child, −u on the parent), the base torque τ_B on θ_B.  The rotors of
eq. (2) are not part of this model: the reduced model (docs/physics.md §3.4) writes each rotor on
its own angle θ_m relative to the parent with no gyroscopic coupling to the carrier, so
B_m never enters the arm's mass matrix or bias forces; a rotor acts on the arm only
through the spring/damper torque u_J of eq. (5), which is an input here.  The wrist
bistop is not modelled either (wrist torque 0).

Pinocchio models built here
---------------------------
``build_model(params, target=...)`` builds one of four trees, joints added depth-first
(base, arm 1 links, [wrist 1], arm 2 links, [wrist 2], [free target]) —
adding the wrist after the second arm gave a silently wrong ``crba``:

* ``target=None``    the RSM alone (9 dof): mass matrix, bias forces, end-effector kinematics;
* ``target="arm1"``/``"arm2"`` the target on a revolute wrist at end effector k (10 dof,
  minimal coordinates [q, ψ_k]): open-chain dynamics by ABA; with a 2-row loop-closure
  constraint at the other grasp, closed-chain dynamics by ``pin.forwardDynamics``;
* ``target="free"``  the target as a free planar body (12 dof, coordinates [q, X_T],
  exactly the reference's Y of eq. 3): system COM, its Jacobian w.r.t. [q, X_T], momentum.

Base joint.  Default ``base_joint="pxpyrz"``: three joints PX → PY → RZ with massless
intermediate bodies, so Pinocchio's configuration and velocity of the base ARE
(x_B, y_B, θ_B) and (ẋ_B, ẏ_B, θ̇_B) in inertial axes and no mapping can hide an error;
θ_B is an unbounded angle (no cos/sin normalisation).  These are three separate joints,
not a ``JointModelComposite`` (it gives wrong Coriolis terms for this chain).  The
alternative ``base_joint="planar"`` (``JointModelPlanar``: q = (x, y, cos θ, sin θ),
v = (R(θ)ᵀ ṙ, θ̇) in the LOCAL base frame) is kept as an internal cross-check of the
mapping below; tests/pinocchio_check show that both give the same reference quantities.

Mapping Pinocchio → reference coordinates (class `Chart`)
---------------------------------------------------------
Let y be the reference-ordered coordinates of a model (q, [q, ψ_k] or [q, X_T]) and
(q_pin, v_pin) Pinocchio's.  Every model has a linear velocity map

    v_pin = T(y) ẏ,   a_pin = T ÿ + Ṫ ẏ,

T = permutation (Pinocchio orders the wrist before arm 2) × blkdiag(R(θ)ᵀ, 1) on a planar
joint (identity block for PX-PY-RZ).  Power balance τ_pinᵀ v_pin = Q_yᵀ ẏ gives the
generalized forces Q_y = Tᵀ τ_pin.  Substituting into M a_pin + nle = τ_pin and
premultiplying by Tᵀ:

    M_y = Tᵀ M T,             h_y = Tᵀ (nle(q, v) + M Ṫ ẏ),
    J_y = J T,                J̇_y ẏ = J̇ v_pin + J Ṫ ẏ = (classical acceleration at a_pin = Ṫ ẏ),

(verified to 1e-11..1e-16 in tests/pinocchio_check).  h_y is the left-hand-side Coriolis /
centrifugal term, the reference's JᵀMJ̇q̇ of eq. (3) moved to the left.  Forward dynamics:
τ_pin = T⁻ᵀ Q_y, then ÿ = T⁻¹ (a_pin − Ṫ ẏ).

Units: m, rad, kg, s, N, N·m throughout.  Point quantities are taken in
``pin.LOCAL_WORLD_ALIGNED`` (origin at the point, inertial axes); only the x, y rows are
planar-relevant.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from rsmcheck.core.geometry import rot
from rsmcheck.core.params import Params

#: Reference-coordinate names of the RSM, in the order of q.
Q_NAMES = ("x_B", "y_B", "theta_B", "J1_1", "J2_1", "J3_1", "J1_2", "J2_2", "J3_2")
N_Q = len(Q_NAMES)
TARGET_NAMES = ("x_T", "y_T", "theta_T")
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

#: How far (m, m/s) a given reference state may be from satisfying an active grasp.
CONSISTENCY_TOL = 1e-8


def _xyz(p2) -> np.ndarray:
    return np.array([float(p2[0]), float(p2[1]), 0.0])


def _translation(p2) -> pin.SE3:
    return pin.SE3(np.eye(3), _xyz(p2))


def _planar_inertia(mass: float, com_xy, inertia_z: float) -> pin.Inertia:
    """Spatial inertia of a planar body: mass, COM (x, y) in the joint frame, I_z about the COM.

    Ixx and Iyy never enter planar motion about z; they are set equal to I_z only so that
    the 3-D inertia is physically valid (Ixx + Iyy ≥ Izz) for ``model.check``.
    """
    return pin.Inertia(float(mass), _xyz(com_xy), np.diag([inertia_z, inertia_z, inertia_z]))


# ---------------------------------------------------------------------------------------
# Chart: reference-ordered coordinates y  <->  Pinocchio (q_pin, v_pin)
# ---------------------------------------------------------------------------------------
@dataclass
class Chart:
    """Linear velocity map v_pin = T(y) ẏ between reference coordinates and Pinocchio's.

    ``scalar``: (i_y, idx_q, idx_v) of 1-dof joints (PX, PY, RZ): q_pin = y_i, v_pin = ẏ_i.
    ``planar``: (i_x, i_y, i_θ, idx_q, idx_v) of ``JointModelPlanar`` joints:
    q_pin = (x, y, cos θ, sin θ), v_pin = (R(θ)ᵀ (ẋ, ẏ), θ̇)  (velocity of the joint
    origin in the LOCAL joint frame).
    """

    n: int
    nq: int
    nv: int
    scalar: list[tuple[int, int, int]] = field(default_factory=list)
    planar: list[tuple[int, int, int, int, int]] = field(default_factory=list)

    def q_pin(self, y: np.ndarray) -> np.ndarray:
        """Pinocchio configuration for reference coordinates y."""
        q = np.zeros(self.nq)
        for i, iq, _ in self.scalar:
            q[iq] = y[i]
        for ix, iy, ith, iq, _ in self.planar:
            q[iq : iq + 4] = (y[ix], y[iy], np.cos(y[ith]), np.sin(y[ith]))
        return q

    def T(self, y: np.ndarray) -> np.ndarray:
        """T(y) (nv × n) with v_pin = T ẏ."""
        T = np.zeros((self.nv, self.n))
        for i, _, iv in self.scalar:
            T[iv, i] = 1.0
        for ix, iy, ith, _, iv in self.planar:
            Rt = rot(y[ith]).T
            T[iv : iv + 2, [ix, iy]] = Rt
            T[iv + 2, ith] = 1.0
        return T

    def Tdot_yd(self, y: np.ndarray, yd: np.ndarray) -> np.ndarray:
        """Ṫ ẏ (nv): the Pinocchio acceleration that corresponds to ÿ = 0.

        Only planar joints contribute: d/dt (R(θ)ᵀ) ṙ = θ̇ [[−s, c], [−c, −s]] ṙ.
        """
        out = np.zeros(self.nv)
        for ix, iy, ith, _, iv in self.planar:
            c, s = np.cos(y[ith]), np.sin(y[ith])
            dRt = np.array([[-s, c], [-c, -s]])
            out[iv : iv + 2] = yd[ith] * dRt @ np.array([yd[ix], yd[iy]])
        return out

    def v_pin(self, y: np.ndarray, yd: np.ndarray) -> np.ndarray:
        return self.T(y) @ yd


# ---------------------------------------------------------------------------------------
# Model construction
# ---------------------------------------------------------------------------------------
@dataclass
class PinModel:
    """One Pinocchio tree of the system with its chart and named frames/joints.

    ``names``: reference names of the coordinates y, in order.  ``frames``: name → frame
    id of the points used here ("ee1", "ee2", "target" (target COM), "grasp1", "grasp2",
    "com_<body>").  ``joints``: name → joint id ("wrist" when the target sits on a wrist).
    ``bodies``: (name, joint id) of every massive body, for hand checks.
    """

    model: pin.Model
    data: pin.Data
    chart: Chart
    names: tuple[str, ...]
    frames: dict[str, int]
    joints: dict[str, int]
    bodies: list[tuple[str, int]]
    target: str | None
    base_joint: str

    def state(self, y: np.ndarray, yd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q_pin, v_pin) for reference coordinates y and rates ẏ."""
        return self.chart.q_pin(y), self.chart.v_pin(y, yd)


class _Builder:
    """Accumulates joints, bodies, frames and the chart of one model."""

    def __init__(self, base_joint: str, names: tuple[str, ...]):
        self.model = pin.Model()
        self.model.gravity = pin.Motion.Zero()
        self.base_joint = base_joint
        self.names = names  # reference order of y; Pinocchio's order may differ
        self.scalar: list[tuple[int, int, int]] = []
        self.planar: list[tuple[int, int, int, int, int]] = []
        self.frames: dict[str, int] = {}
        self.joints: dict[str, int] = {}
        self.bodies: list[tuple[str, int]] = []

    def _coordinate(self, name: str) -> int:
        """Index of coordinate `name` in y (reference order, not Pinocchio's order)."""
        return self.names.index(name)

    def revolute(self, parent: int, placement: pin.SE3, name: str) -> int:
        jid = self._add_joint(parent, pin.JointModelRZ(), placement, name)
        j = self.model.joints[jid]
        self.scalar.append((self._coordinate(name), j.idx_q, j.idx_v))
        self.joints[name] = jid
        return jid

    def floating_planar(self, parent: int, placement: pin.SE3, prefix: str, names) -> int:
        """A free planar body attached to `parent`; coordinates (x, y, θ) named `names`.

        "pxpyrz": PX → PY → RZ, the first two with no body (zero inertia);
        "planar": one ``JointModelPlanar``.  Returns the joint that carries the body.
        """
        if self.base_joint == "pxpyrz":
            jx = self._add_joint(parent, pin.JointModelPX(), placement, prefix + "_px")
            jy = self._add_joint(jx, pin.JointModelPY(), pin.SE3.Identity(), prefix + "_py")
            jz = self._add_joint(jy, pin.JointModelRZ(), pin.SE3.Identity(), prefix + "_rz")
            for jid, name in zip((jx, jy, jz), names):
                j = self.model.joints[jid]
                self.scalar.append((self._coordinate(name), j.idx_q, j.idx_v))
            self.joints[prefix] = jz
            return jz
        if self.base_joint == "planar":
            jid = self._add_joint(parent, pin.JointModelPlanar(), placement, prefix + "_planar")
            j = self.model.joints[jid]
            ix, iy, ith = (self._coordinate(n) for n in names)
            self.planar.append((ix, iy, ith, j.idx_q, j.idx_v))
            self.joints[prefix] = jid
            return jid
        raise ValueError(f"base_joint must be 'pxpyrz' or 'planar', got {self.base_joint!r}")

    def body(self, jid: int, name: str, inertia: pin.Inertia) -> None:
        """Rigid body on joint `jid` plus an OP frame "com_<name>" at its COM."""
        self.model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        self.frame("com_" + name, jid, inertia.lever[:2])
        self.bodies.append((name, jid))

    def _add_joint(self, parent: int, joint_model, placement: pin.SE3, name: str) -> int:
        """``addJoint`` plus its JOINT frame (the parent frame of OP frames on it)."""
        jid = self.model.addJoint(parent, joint_model, placement, name)
        self.model.addJointFrame(jid, -1)
        return jid

    def frame(self, name: str, jid: int, p_xy) -> None:
        parent_frame = self.model.getFrameId(self.model.names[jid], pin.FrameType.JOINT)
        self.frames[name] = self.model.addFrame(
            pin.Frame(name, jid, parent_frame, _translation(p_xy), pin.FrameType.OP_FRAME)
        )

    def finish(self, target: str | None) -> PinModel:
        model = self.model
        data = model.createData()
        if not model.check(data):
            raise RuntimeError("pinocchio model.check(data) failed for the RSM model")
        chart = Chart(n=len(self.names), nq=model.nq, nv=model.nv, scalar=self.scalar, planar=self.planar)
        used = sorted([s[0] for s in self.scalar] + [i for p in self.planar for i in p[:3]])
        if used != list(range(len(self.names))) or chart.n != model.nv:
            raise RuntimeError(f"chart does not cover the coordinates {self.names}")
        return PinModel(model, data, chart, self.names, self.frames, self.joints,
                        self.bodies, target, self.base_joint)


def build_model(params: Params, target: str | None = None, base_joint: str = "pxpyrz") -> PinModel:
    """Pinocchio tree of the rigid RSM built from `params` only (see module docstring).

    target: None (RSM alone), "arm1"/"arm2" (target on the wrist of that arm, extra
    coordinate ψ_k = θ_T − θ_l3,k appended to y), or "free" (target as a free planar
    body, X_T appended to y).
    """
    if target not in (None, "arm1", "arm2", "free"):
        raise ValueError(f"target must be None, 'arm1', 'arm2' or 'free', got {target!r}")
    g = params.geometry
    L = params.link.length
    extra = {None: (), "arm1": ("psi_1",), "arm2": ("psi_2",), "free": TARGET_NAMES}[target]
    b = _Builder(base_joint, Q_NAMES + extra)

    # Base: joint origin = base COM, so the base COM is at the joint origin.
    j_base = b.floating_planar(0, pin.SE3.Identity(), "base", Q_NAMES[:3])
    b.body(j_base, "base", _planar_inertia(params.base.mass, (0.0, 0.0), params.base.inertia_z))

    link_inertia = _planar_inertia(params.link.mass, (L / 2.0, 0.0), params.link.inertia_z)
    target_on = {"arm1": 1, "arm2": 2}.get(target)
    for arm in (1, 2):
        parent, placement = j_base, _translation(g.mount_B(arm))
        for i in (1, 2, 3):
            jid = b.revolute(parent, placement, f"J{i}_{arm}")
            b.body(jid, f"link{i}_{arm}", link_inertia)
            parent, placement = jid, _translation((L, 0.0))
        b.frame(f"ee{arm}", parent, (L, 0.0))
        if target_on == arm:
            # Wrist joint at the end effector; its frame has the target's axes
            # (θ_l3 + ψ = θ_T) and its origin at grasp point `arm`, so the target COM
            # is at −grasp_T(arm) and grasp j at grasp_T(j) − grasp_T(arm).
            jw = b.revolute(parent, _translation((L, 0.0)), f"psi_{arm}")
            b.joints["wrist"] = jw
            g_k = np.array(g.grasp_T(arm))
            b.body(jw, "target", _planar_inertia(params.target.mass, -g_k, params.target.inertia_z))
            b.frames["target"] = b.frames["com_target"]
            for j in (1, 2):
                b.frame(f"grasp{j}", jw, np.array(g.grasp_T(j)) - g_k)
    if target == "free":
        jt = b.floating_planar(0, pin.SE3.Identity(), "target", TARGET_NAMES)
        b.body(jt, "target", _planar_inertia(params.target.mass, (0.0, 0.0), params.target.inertia_z))
        b.frames["target"] = b.frames["com_target"]
        for j in (1, 2):
            b.frame(f"grasp{j}", jt, g.grasp_T(j))
    return b.finish(target)


def aba_timing(params: Params, n: int = 2000) -> dict[str, float]:
    """µs per Pinocchio ABA call from Python on the rigid open chain of the base and arm 1
    at its neutral configuration (best of 3; `rsmcheck bench`: the scale of a compiled
    rigid-body step), and `nv`, its number of coordinates."""
    import timeit

    model = build_model(params, target="arm1").model
    data = model.createData()
    q, v, tau = pin.neutral(model), np.zeros(model.nv), np.zeros(model.nv)
    pin.aba(model, data, q, v, tau)
    return {"call_us": min(timeit.repeat(lambda: pin.aba(model, data, q, v, tau), number=n, repeat=3)) / n * 1e6,
            "nv": int(model.nv)}


# ---------------------------------------------------------------------------------------
# Quantities of one model in reference coordinates
# ---------------------------------------------------------------------------------------
def mass_matrix_y(pm: PinModel, y: np.ndarray) -> np.ndarray:
    """M_y = Tᵀ M T from ``pin.crba`` (Python's crba returns the full symmetric matrix)."""
    T = pm.chart.T(y)
    M = pin.crba(pm.model, pm.data, pm.chart.q_pin(y))
    return T.T @ M @ T


def bias_y(pm: PinModel, y: np.ndarray, yd: np.ndarray) -> np.ndarray:
    """h_y = Tᵀ (nle(q, v) + M Ṫ ẏ): Coriolis/centrifugal generalized force, LHS sign.

    Gravity is zero in every model built here, so ``nonLinearEffects`` is C(q, v) v.
    """
    q, v = pm.state(y, yd)
    T = pm.chart.T(y)
    nle = pin.nonLinearEffects(pm.model, pm.data, q, v)
    M = pin.crba(pm.model, pm.data, q)
    return T.T @ (nle + M @ pm.chart.Tdot_yd(y, yd))


def point_kinematics_y(pm: PinModel, y: np.ndarray, yd: np.ndarray, frame: str):
    """(r_I (2,), J_y (2, n), J̇_y ẏ (2,)) of the origin of `frame`, inertial axes.

    r_I and J from ``updateFramePlacements`` / ``getFrameJacobian(LOCAL_WORLD_ALIGNED)``
    (linear rows x, y); J̇_y ẏ = classical acceleration of the point for ÿ = 0, i.e. for
    a_pin = Ṫ ẏ (``getFrameClassicalAcceleration``, LOCAL_WORLD_ALIGNED).
    """
    model, data = pm.model, pm.data
    q, v = pm.state(y, yd)
    fid = pm.frames[frame]
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    r_I = data.oMf[fid].translation[:2].copy()
    J = pin.getFrameJacobian(model, data, fid, LWA)[:2] @ pm.chart.T(y)
    pin.forwardKinematics(model, data, q, v, pm.chart.Tdot_yd(y, yd))
    jdot_yd = pin.getFrameClassicalAcceleration(model, data, fid, LWA).linear[:2].copy()
    return r_I, J, jdot_yd


def frame_pose_velocity_y(pm: PinModel, y: np.ndarray, yd: np.ndarray, frame: str):
    """Pose (x, y, θ) and its rate (ẋ, ẏ, θ̇) of `frame`, inertial (LOCAL_WORLD_ALIGNED).

    θ is recovered from the rotation matrix with atan2 (principal value).
    """
    model, data = pm.model, pm.data
    q, v = pm.state(y, yd)
    fid = pm.frames[frame]
    pin.forwardKinematics(model, data, q, v)
    oMf = pin.updateFramePlacement(model, data, fid)
    R = oMf.rotation
    pose = np.array([oMf.translation[0], oMf.translation[1], np.arctan2(R[1, 0], R[0, 0])])
    vel = pin.getFrameVelocity(model, data, fid, LWA)
    rate = np.array([vel.linear[0], vel.linear[1], vel.angular[2]])
    return pose, rate


def tau_pin(pm: PinModel, y: np.ndarray, Q_y: np.ndarray) -> np.ndarray:
    """Pinocchio joint torques whose generalized force on y is Q_y: τ_pin = T⁻ᵀ Q_y."""
    return np.linalg.solve(pm.chart.T(y).T, Q_y)


def yddot_from_apin(pm: PinModel, y: np.ndarray, yd: np.ndarray, a_pin: np.ndarray) -> np.ndarray:
    """ÿ = T⁻¹ (a_pin − Ṫ ẏ)."""
    return np.linalg.solve(pm.chart.T(y), a_pin - pm.chart.Tdot_yd(y, yd))


def generalized_inputs(pm: PinModel, u_J, tau_B: float) -> np.ndarray:
    """Q_y of the inputs: τ_B on θ_B, u_J on the six joint angles, nothing elsewhere.

    A torque u of joint i acts +u on the child and −u on the parent, so its virtual
    power is u δθ_J: its generalized force is u on θ_J (and 0 on θ_B).  The base torque
    acts on the base alone, whose angle is θ_B: generalized force τ_B on θ_B.  The wrist
    (ψ) and the free target carry no applied load.
    """
    Q = np.zeros(pm.chart.n)
    Q[2] = float(tau_B)
    Q[3:9] = np.asarray(u_J, dtype=float)
    return Q


# ---------------------------------------------------------------------------------------
# The facade: reference-model-shaped API answered by Pinocchio
# ---------------------------------------------------------------------------------------
class PinocchioRSM:
    """Pinocchio's answers, in reference coordinates, to the reference model's questions.

    Method names and signatures mirror ``reference_model.build.ReferenceModel`` so that
    `compare` can put the two side by side.  States (q, qd, X_T, XT_d) follow the
    reference convention (module docstring); a state with an active grasp must satisfy
    the grasp constraint to ``CONSISTENCY_TOL`` (else ValueError).
    """

    def __init__(self, params: Params, base_joint: str = "pxpyrz"):
        self.params = params
        self.base_joint = base_joint
        self.rsm = build_model(params, None, base_joint)
        self.held = {1: build_model(params, "arm1", base_joint), 2: build_model(params, "arm2", base_joint)}
        self.free = build_model(params, "free", base_joint)

    # ---- RSM alone -------------------------------------------------------------------
    def mass_matrix(self, q) -> np.ndarray:
        """JᵀMJ of the RSM (9×9): ``crba`` mapped by M_y = Tᵀ M T."""
        return mass_matrix_y(self.rsm, np.asarray(q, float))

    def bias_forces(self, q, qd) -> np.ndarray:
        """JᵀMJ̇q̇ of the RSM (9): ``nonLinearEffects`` mapped by h_y = Tᵀ(nle + M Ṫ ẏ)."""
        return bias_y(self.rsm, np.asarray(q, float), np.asarray(qd, float))

    def point_kinematics(self, q, qd, point: str):
        """(r_I, J (2×9), J̇q̇) of "ee1" or "ee2" (point (L, 0) of link 3 of that arm)."""
        if point not in ("ee1", "ee2"):
            raise ValueError(f"point must be 'ee1' or 'ee2', got {point!r}")
        return point_kinematics_y(self.rsm, np.asarray(q, float), np.asarray(qd, float), point)

    # ---- target and system -----------------------------------------------------------
    def grasp_point(self, X_T, arm: int) -> np.ndarray:
        """Inertial position of grasp point `arm` for target pose X_T (free-target model)."""
        y = np.concatenate([np.zeros(N_Q), np.asarray(X_T, float)])
        r, _, _ = point_kinematics_y(self.free, y, np.zeros_like(y), f"grasp{arm}")
        return r

    def com(self, q, X_T):
        """System COM (RSM + target) and its Jacobian (2 × 12) w.r.t. [q, X_T].

        ``centerOfMass`` and ``jacobianCenterOfMass`` on the free-target model, whose
        coordinates are exactly [q, X_T]; J_y = J_com T.
        """
        pm = self.free
        y = np.concatenate([np.asarray(q, float), np.asarray(X_T, float)])
        qp = pm.chart.q_pin(y)
        c = pin.centerOfMass(pm.model, pm.data, qp)[:2].copy()
        Jc = pin.jacobianCenterOfMass(pm.model, pm.data, qp)[:2] @ pm.chart.T(y)
        return c, Jc

    def momentum(self, q, qd, X_T, XT_d) -> np.ndarray:
        """(p_x, p_y, L_z) of RSM + target; L_z about the inertial origin.

        ``computeCentroidalMomentum`` gives h_G = (p, L_G) about the system COM c in
        inertial axes; L_O = L_G + (c × p)_z = L_G + c_x p_y − c_y p_x.
        """
        pm = self.free
        y = np.concatenate([np.asarray(q, float), np.asarray(X_T, float)])
        yd = np.concatenate([np.asarray(qd, float), np.asarray(XT_d, float)])
        qp, vp = pm.state(y, yd)
        c = pin.centerOfMass(pm.model, pm.data, qp)
        hg = pin.computeCentroidalMomentum(pm.model, pm.data, qp, vp)
        p = hg.linear
        return np.array([p[0], p[1], hg.angular[2] + c[0] * p[1] - c[1] * p[0]])

    # ---- conversion between reference states and wrist-tree states -------------------
    def tree_coordinates(self, arm: int, q, qd, X_T, XT_d):
        """Minimal coordinates y = [q, ψ_k] and rates of the tree held by `arm`.

        ψ_k = θ_T − θ_l3,k = θ_T − θ_B − Σ_i θ_Ji,k; ψ̇_k likewise.  The remaining target
        coordinates follow from the tree; `check_grasp` verifies they equal X_T.
        """
        q, qd, X_T, XT_d = (np.asarray(a, float) for a in (q, qd, X_T, XT_d))
        cols = slice(3, 6) if arm == 1 else slice(6, 9)
        psi = X_T[2] - q[2] - q[cols].sum()
        psid = XT_d[2] - qd[2] - qd[cols].sum()
        return np.append(q, psi), np.append(qd, psid)

    def reference_state(self, arm: int, y: np.ndarray, yd: np.ndarray):
        """(q, qd, X_T, XT_d) of a state of the tree held by `arm` (y = [q, ψ_k]).

        X_T, Ẋ_T: pose and LOCAL_WORLD_ALIGNED velocity of the target COM frame; θ_T is
        taken as the unwrapped sum θ_B + Σ θ_J,k + ψ_k (the rotation matrix gives the same
        angle modulo 2π, tested).
        """
        pm = self.held[arm]
        pose, rate = frame_pose_velocity_y(pm, y, yd, "target")
        cols = slice(3, 6) if arm == 1 else slice(6, 9)
        pose[2] = y[2] + y[cols].sum() + y[9]
        return y[:N_Q].copy(), yd[:N_Q].copy(), pose, rate

    def grasp_residual(self, arm: int, q, qd, X_T, XT_d) -> tuple[np.ndarray, np.ndarray]:
        """(φ_k, φ̇_k): r_EE,k − r_grasp,k and its rate, EE from the RSM model, grasp
        from the free-target model (independent of the wrist tree)."""
        r_ee, J_ee, _ = self.point_kinematics(q, qd, f"ee{arm}")
        y = np.concatenate([np.asarray(q, float), np.asarray(X_T, float)])
        yd = np.concatenate([np.asarray(qd, float), np.asarray(XT_d, float)])
        r_g, J_g, _ = point_kinematics_y(self.free, y, yd, f"grasp{arm}")
        return r_ee - r_g, J_ee @ np.asarray(qd, float) - J_g @ yd

    def check_grasp(self, arm: int, q, qd, X_T, XT_d, tol: float = CONSISTENCY_TOL) -> None:
        phi, phid = self.grasp_residual(arm, q, qd, X_T, XT_d)
        if np.max(np.abs(phi)) > tol or np.max(np.abs(phid)) > tol:
            raise ValueError(
                f"state does not satisfy grasp {arm}: |φ| = {np.max(np.abs(phi)):.3g} m, "
                f"|φ̇| = {np.max(np.abs(phid)):.3g} m/s (tolerance {tol:g})"
            )

    # ---- constrained forward dynamics --------------------------------------------------
    def constrained_accelerations(self, q, qd, X_T, XT_d, grasp=(True, False),
                                  u_J=None, tau_B: float = 0.0):
        """(q̈ (9), Ẍ_T (3), R_cl (4)) of eq. (11), Baumgarte off, by Pinocchio.

        One grasp (arm k): the target rides on wrist k (tree `held[k]`), ``pin.aba``.
        Both grasps: tree `held[1]` plus the loop closure φ_2 = r_EE2 − r_grasp2 = 0 by
        ``pin.forwardDynamics`` (see `_closed_chain`).  No grasp: ABA of the RSM, the
        target drifts (Ẍ_T = 0).  R_cl: force on the target at grasp 1 (R1, R2) and
        grasp 2 (R3, R4), inertial; zero for an inactive grasp.  u_J = None means zero.
        """
        u_J = np.zeros(6) if u_J is None else np.asarray(u_J, float)
        g1, g2 = bool(grasp[0]), bool(grasp[1])
        for arm, on in ((1, g1), (2, g2)):
            if on:
                self.check_grasp(arm, q, qd, X_T, XT_d)
        if g1 and g2:
            return self._closed_chain(q, qd, X_T, XT_d, u_J, tau_B)
        if g1 or g2:
            return self._open_chain(1 if g1 else 2, q, qd, X_T, XT_d, u_J, tau_B)
        pm = self.rsm
        y, yd = np.asarray(q, float), np.asarray(qd, float)
        qp, vp = pm.state(y, yd)
        a = pin.aba(pm.model, pm.data, qp, vp, tau_pin(pm, y, generalized_inputs(pm, u_J, tau_B)))
        return yddot_from_apin(pm, y, yd, a), np.zeros(3), np.zeros(4)

    def _target_acceleration(self, pm: PinModel, qp, vp, a) -> np.ndarray:
        """Ẍ_T: classical acceleration of the target COM frame (LOCAL_WORLD_ALIGNED),
        linear x, y and angular z (= θ̈_T)."""
        pin.forwardKinematics(pm.model, pm.data, qp, vp, a)
        acc = pin.getFrameClassicalAcceleration(pm.model, pm.data, pm.frames["target"], LWA)
        return np.array([acc.linear[0], acc.linear[1], acc.angular[2]])

    def _wrist_force_I(self, pm: PinModel, qp, vp, a, fext=None) -> tuple[np.ndarray, float]:
        """Force on the target through the wrist joint, inertial (2,), and the wrist torque.

        ``pin.rnea`` leaves in data.f[i] the spatial force that joint i transmits from
        its parent to the subtree of body i (= f_i = I a + v ×* I v − f_ext, summed over
        the subtree), in the LOCAL frame of joint i.  The wrist's subtree is the target
        alone, so its linear part rotated to inertial axes is the force of end effector k
        on the target at grasp point k (the joint origin).  Its z-moment about the joint
        is the wrist torque, zero for an unactuated wrist (returned for checking).
        """
        jw = pm.joints["wrist"]
        if fext is None:
            pin.rnea(pm.model, pm.data, qp, vp, a)
        else:
            pin.rnea(pm.model, pm.data, qp, vp, a, fext)
        f = pm.data.f[jw]
        R = pm.data.oMi[jw].rotation
        return (R @ f.linear)[:2].copy(), float(f.angular[2])

    def _open_chain(self, arm, q, qd, X_T, XT_d, u_J, tau_B):
        """Target on wrist `arm`: ABA on y = [q, ψ_k]; R from the wrist joint force."""
        pm = self.held[arm]
        y, yd = self.tree_coordinates(arm, q, qd, X_T, XT_d)
        qp, vp = pm.state(y, yd)
        tau = tau_pin(pm, y, generalized_inputs(pm, u_J, tau_B))
        a = pin.aba(pm.model, pm.data, qp, vp, tau)
        ydd = yddot_from_apin(pm, y, yd, a)
        XT_dd = self._target_acceleration(pm, qp, vp, a)
        R_k, _ = self._wrist_force_I(pm, qp, vp, a)
        R_cl = np.zeros(4)
        R_cl[2 * (arm - 1) : 2 * arm] = R_k
        return ydd[:N_Q], XT_dd, R_cl

    def closure_constraint(self, pm: PinModel, y, yd):
        """Loop closure at grasp 2 of the tree held by arm 1, in Pinocchio velocities.

        φ = r_EE2 − r_grasp2 (x, y rows).  J_c = (J_EE2 − J_grasp2)[:2] in
        LOCAL_WORLD_ALIGNED (∂φ̇/∂v_pin); γ = J̇_c v_pin = (classical acceleration of EE2
        − of grasp 2) at a_pin = 0, so that φ̈ = J_c a_pin + γ.  Returns (φ, J_c, γ).
        """
        model, data = pm.model, pm.data
        qp, vp = pm.state(y, yd)
        f_ee, f_g = pm.frames["ee2"], pm.frames["grasp2"]
        pin.computeJointJacobians(model, data, qp)
        pin.updateFramePlacements(model, data)
        phi = (data.oMf[f_ee].translation - data.oMf[f_g].translation)[:2]
        Jc = (pin.getFrameJacobian(model, data, f_ee, LWA) - pin.getFrameJacobian(model, data, f_g, LWA))[:2]
        pin.forwardKinematics(model, data, qp, vp, np.zeros(model.nv))
        gamma = (pin.getFrameClassicalAcceleration(model, data, f_ee, LWA).linear
                 - pin.getFrameClassicalAcceleration(model, data, f_g, LWA).linear)[:2]
        return phi, Jc, gamma

    def _closed_chain(self, q, qd, X_T, XT_d, u_J, tau_B):
        """Both grasps: tree held by arm 1 + loop closure at grasp 2, Baumgarte off.

        ``pin.forwardDynamics(model, data, q, v, τ, J_c, γ, 0)`` solves
            M a + nle = τ + J_cᵀ λ,   J_c a + γ = 0
        (sign of λ verified in tests/pinocchio_check against M a + nle − τ = J_cᵀ λ).
        J_cᵀ λ = J_EE2ᵀ λ − J_grasp2ᵀ λ: λ acts on end effector 2 and −λ on the target at
        grasp 2, hence (R3, R4) = −λ.  (R1, R2): wrist-1 joint force from ``rnea`` with the
        external forces +λ at EE2 (on link 3 of arm 2) and −λ at grasp 2 (on the target).
        """
        pm = self.held[1]
        y, yd = self.tree_coordinates(1, q, qd, X_T, XT_d)
        qp, vp = pm.state(y, yd)
        tau = tau_pin(pm, y, generalized_inputs(pm, u_J, tau_B))
        _, Jc, gamma = self.closure_constraint(pm, y, yd)
        a = pin.forwardDynamics(pm.model, pm.data, qp, vp, tau, Jc, gamma, 0.0).copy()
        lam = pm.data.lambda_c.copy()
        ydd = yddot_from_apin(pm, y, yd, a)
        XT_dd = self._target_acceleration(pm, qp, vp, a)
        fext = self.point_forces(pm, qp, {"ee2": lam, "grasp2": -lam})
        R1, _ = self._wrist_force_I(pm, qp, vp, a, fext)
        return ydd[:N_Q], XT_dd, np.concatenate([R1, -lam])

    @staticmethod
    def point_forces(pm: PinModel, qp, forces_I: dict[str, np.ndarray]):
        """External forces for ``rnea``: inertial planar force F at the origin of each
        named frame, as a spatial force at the parent joint in its LOCAL frame:
        f = R_iᵀ F, n = p × f with p the frame origin in the joint frame."""
        model, data = pm.model, pm.data
        pin.forwardKinematics(model, data, qp)
        fext = pin.StdVec_Force()
        for _ in range(model.njoints):
            fext.append(pin.Force.Zero())
        for name, F in forces_I.items():
            frame = model.frames[pm.frames[name]]
            jid = frame.parentJoint
            f_loc = data.oMi[jid].rotation.T @ _xyz(F)
            p_loc = frame.placement.translation
            fext[jid] = fext[jid] + pin.Force(f_loc, np.cross(p_loc, f_loc))
        return fext
