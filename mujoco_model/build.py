"""The robot as an MJCF model of MuJoCo's own elements, built from `Params` alone.

Bodies, all in the orbit plane (x, y; hinges about z):

* base: slides x, y and a hinge at its COM (the root of the robot's tree);
* each link: a chain of N + 1 rigid pieces (finite-segment method).  Hinges sit at
  ξ = (p + ½)ℓ, ℓ = L/N, p = 0 … N − 1, each with stiffness EI/ℓ and Kelvin–Voigt damping
  η·EI/ℓ; the pieces between them have length ℓ (the two end pieces ℓ/2), uniform mass
  ρA per metre and their own rotary inertia.  The end pieces are the link's end sections
  (docs/physics.md §3.3);
* each joint: two hinges in series at the pin, on the child link's first piece: the rotor
  hinge θ_m (armature B_m, the motor torque) relative to the parent's end section, then the
  spring hinge s = ψ_J − θ_m (stiffness K_m, damping C_m).  The two together are eq. (2)
  exactly (docs/mujoco.md §1);
* J_extra: a fixed tendon per link and basis (PP, PF) whose length is the link frame's
  angle to first order in the bending; its `armature` is J_extra in the link's current
  basis and 0 in the other;
* target: slides x, y and a hinge at its COM; one site per grasp point;
* grasps: a site-to-site `connect` equality per arm (end-effector site ↔ target site),
  inactive until a capture.

Nothing here solves an equation: MuJoCo builds the mass matrix, the passive forces and
the constraints from these elements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rsmcheck.core.params import Params

N_SEGMENTS_DEFAULT = 8
#: the grasp's soft-constraint impedance: as close to rigid as MuJoCo allows
SOLIMP = "0.9999 0.9999 0.001 0.5 2"
#: the grasp's time constant, in steps (MuJoCo's own stability floor is 2 steps)
SOLREF_STEPS = 2.0


def hinge_positions(L: float, n: int) -> np.ndarray:
    """ξ of the N hinges of one link: the middle of each of its N segments."""
    return (np.arange(n) + 0.5) * (L / n)


def piece_bounds(L: float, n: int) -> np.ndarray:
    """(N + 1, 2): material start and end [m] of each piece of one link."""
    h = hinge_positions(L, n)
    edges = np.concatenate([[0.0], h, [L]])
    return np.stack([edges[:-1], edges[1:]], axis=1)


def frame_weights(L: float, n: int, basis: str) -> np.ndarray:
    """∂θ_frame/∂φ_p of the link frame's angle (docs/physics.md §2.1) with respect to the N
    hinge angles φ_p, at the straight link.  PP (chord): the share of the length beyond
    hinge p, (L − ξ_p)/L.  PF (rigid-mode frame, ∫ρ ξ w dξ = 0): ∫_{ξ_p}^{L} ξ(ξ − ξ_p) dξ
    over ∫_0^L ξ² dξ."""
    xi = hinge_positions(L, n)
    if basis == "PP":
        return (L - xi) / L
    integral = (L**3 - xi**3) / 3.0 - xi * (L**2 - xi**2) / 2.0
    return integral / (L**3 / 3.0)


@dataclass(frozen=True)
class Index:
    """Where the model's degrees of freedom sit (qpos ≡ qvel indices: hinges and slides
    only) and the linear maps the engine reads.

    base, target: (x, y, θ) dofs.  rotor, spring: (2, 3) dofs of θ_m and s per arm and
    joint.  bend: (2, 3, N) hinge dofs.  piece_body: (2, 3, N + 1) MuJoCo body ids.
    angle: (2, 3, N + 1, nv) the absolute angle of each piece as a row on qpos (exact:
    planar rotations add).  frame_tendon: (2, 3, 2) tendon ids, basis PP then PF.
    wrist: (2, nv) ∂(θ of the terminal link's distal piece)/∂q.
    frame_row: (2, 3, 2, nv) the frame tendons' coefficients (PP, PF).  tip_site, hold_site:
    site ids of the end effectors and the target's held points; grasp_eq: equality ids.
    """

    nv: int
    n: int
    base: np.ndarray
    target: np.ndarray
    rotor: np.ndarray
    spring: np.ndarray
    bend: np.ndarray
    piece_body: np.ndarray
    base_body: int
    target_body: int
    angle: np.ndarray
    frame_tendon: np.ndarray
    wrist: np.ndarray
    frame_row: np.ndarray
    tip_site: np.ndarray
    hold_site: np.ndarray
    grasp_eq: np.ndarray


@dataclass
class MujocoModel:
    """The compiled model, its index and the numbers the engine reuses."""

    model: object  # mujoco.MjModel
    index: Index
    params: Params
    n: int
    bounds: np.ndarray  # (N + 1, 2) piece material bounds
    timestep: float
    integrator: str


def piece_rotary_inertia(mass: float, length: float) -> float:
    """A piece's rotary inertia about its centre: the uniform rod's, m ℓ_p²/12.  With it
    the chain's link frequencies converge at fourth order in 1/N (PP f1 −1.7e-5 at N = 8);
    with none or twice as much the leading error is second order (±5e-3)."""
    return mass * length**2 / 12.0


def frame_inertia(p: Params, n: int) -> float:
    """The frame tendon's armature: J_extra (docs/physics.md §2.3)."""
    return p.link.inertia_extra


def _inertial(mass: float, length: float, start: float) -> str:
    """A rod piece from `start` to `start + length` along x (body frame): its mass at its
    centre, its rotary inertia `piece_rotary_inertia`."""
    j = piece_rotary_inertia(mass, length)
    # ixx, iyy never act in the plane; they only have to satisfy MuJoCo's triangle rule
    return (f'<inertial pos="{start + 0.5 * length!r} 0 0" mass="{mass!r}" '
            f'diaginertia="{j / 2!r} {j / 2!r} {j!r}"/>')


def _square(mass: float, inertia: float) -> str:
    return f'<inertial pos="0 0 0" mass="{mass!r}" diaginertia="{0.5 * inertia!r} {0.5 * inertia!r} {inertia!r}"/>'


def model_xml(p: Params, n: int, timestep: float, integrator: str, rho_G: np.ndarray,
              base_mass: float) -> str:
    """The MJCF text of the robot (module doc)."""
    lk, mo = p.link, p.motor
    L, ell = lk.length, lk.length / n
    k_bend = lk.ei / ell
    c_bend = lk.kelvin_voigt_eta * k_bend
    bounds = piece_bounds(L, n)
    out = ['<mujoco model="rsmcheck-dual-arm">',
           '<compiler angle="radian" autolimits="true"/>',
           f'<option timestep="{timestep!r}" integrator="{integrator}" gravity="0 0 0" '
           'tolerance="1e-15" iterations="200" ls_iterations="100">',
           '<flag contact="disable" energy="disable"/></option>',
           '<worldbody>', '<body name="base" pos="0 0 0">',
           '<joint name="base_x" type="slide" axis="1 0 0"/>',
           '<joint name="base_y" type="slide" axis="0 1 0"/>',
           '<joint name="base_th" type="hinge" axis="0 0 1"/>',
           _square(base_mass, p.base.inertia_z)]
    for k in range(2):
        mx, my = p.geometry.mount_B(k + 1)
        closers = 0
        for i in range(3):
            for q in range(n + 1):
                a, b = bounds[q]
                if q == 0:
                    pos = f"{mx!r} {my!r} 0" if i == 0 else f"{ell / 2!r} 0 0"
                    out.append(f'<body name="l{k}{i}p0" pos="{pos}">')
                    out.append(f'<joint name="rotor{k}{i}" type="hinge" axis="0 0 1" armature="{mo.inertia!r}"/>')
                    out.append(f'<joint name="spring{k}{i}" type="hinge" axis="0 0 1" '
                               f'stiffness="{mo.stiffness!r}" damping="{mo.damping!r}"/>')
                else:
                    step = ell / 2 if q == 1 else ell
                    out.append(f'<body name="l{k}{i}p{q}" pos="{step!r} 0 0">')
                    out.append(f'<joint name="bend{k}{i}_{q - 1}" type="hinge" axis="0 0 1" '
                               f'stiffness="{k_bend!r}" damping="{c_bend!r}"/>')
                out.append(_inertial(float(lk.rho_a * (b - a)), float(b - a), 0.0))
                closers += 1
            # the distal pin: the end of the last piece (ℓ/2 beyond its hinge)
            if i == 2:
                out.append(f'<site name="tip{k}" pos="{ell / 2!r} 0 0"/>')
        out.append("</body>" * closers)
    out.append("</body>")
    out += ['<body name="target" pos="0 0 0">',
            '<joint name="target_x" type="slide" axis="1 0 0"/>',
            '<joint name="target_y" type="slide" axis="0 1 0"/>',
            '<joint name="target_th" type="hinge" axis="0 0 1"/>',
            _square(p.target.mass, p.target.inertia_z)]
    for k in range(2):
        out.append(f'<site name="hold{k}" pos="{float(rho_G[k][0])!r} {float(rho_G[k][1])!r} 0"/>')
    out += ["</body>", "</worldbody>", "<tendon>"]
    for k in range(2):
        for i in range(3):
            for basis in ("PP", "PF"):
                w = frame_weights(L, n, basis)
                parts = ['<joint joint="base_th" coef="1"/>']
                for j in range(i + 1):
                    parts += [f'<joint joint="rotor{k}{j}" coef="1"/>', f'<joint joint="spring{k}{j}" coef="1"/>']
                    ws = np.ones(n) if j < i else w
                    parts += [f'<joint joint="bend{k}{j}_{q}" coef="{float(ws[q])!r}"/>' for q in range(n)]
                out.append(f'<fixed name="frame{k}{i}{basis}" armature="0">' + "".join(parts) + "</fixed>")
    out += ["</tendon>", "<equality>"]
    tc = SOLREF_STEPS * timestep
    for k in range(2):
        out.append(f'<connect name="grasp{k}" site1="tip{k}" site2="hold{k}" active="false" '
                   f'solref="{tc!r} 1" solimp="{SOLIMP}"/>')
    out += ["</equality>", "</mujoco>"]
    return "\n".join(out)


def build_model(p: Params, n: int, timestep: float, integrator: str, rho_G: np.ndarray,
                base_mass: float, basis: list[str]) -> MujocoModel:
    """The compiled model and its index; `basis` the six links' bases (arm 1 then arm 2,
    base outward) that decide which frame tendon carries J_extra."""
    import mujoco

    m = mujoco.MjModel.from_xml_string(model_xml(p, n, timestep, integrator, rho_G, base_mass))
    jid = lambda name: int(m.joint(name).dofadr[0])  # noqa: E731
    nv = m.nv
    rotor = np.array([[jid(f"rotor{k}{i}") for i in range(3)] for k in range(2)])
    spring = np.array([[jid(f"spring{k}{i}") for i in range(3)] for k in range(2)])
    bend = np.array([[[jid(f"bend{k}{i}_{q}") for q in range(n)] for i in range(3)] for k in range(2)])
    base = np.array([jid("base_x"), jid("base_y"), jid("base_th")])
    target = np.array([jid("target_x"), jid("target_y"), jid("target_th")])
    piece_body = np.array([[[m.body(f"l{k}{i}p{q}").id for q in range(n + 1)] for i in range(3)] for k in range(2)])
    angle = np.zeros((2, 3, n + 1, nv))
    wrist = np.zeros((2, nv))
    for k in range(2):
        row = np.zeros(nv)
        row[base[2]] = 1.0
        for i in range(3):
            row[rotor[k, i]] = row[spring[k, i]] = 1.0
            angle[k, i, 0] = row
            for q in range(n):
                row[bend[k, i, q]] = 1.0
                angle[k, i, q + 1] = row
        wrist[k] = angle[k, 2, n]
    frame_row = np.zeros((2, 3, 2, nv))
    for k in range(2):
        for i in range(3):
            for j, basis_name in enumerate(("PP", "PF")):
                frame_row[k, i, j] = angle[k, i, 0]
                frame_row[k, i, j, bend[k, i]] = frame_weights(p.link.length, n, basis_name)
    frame_tendon = np.array([[[m.tendon(f"frame{k}{i}{b}").id for b in ("PP", "PF")] for i in range(3)]
                             for k in range(2)])
    index = Index(nv=nv, n=n, base=base, target=target, rotor=rotor, spring=spring, bend=bend,
                  piece_body=piece_body, base_body=m.body("base").id, target_body=m.body("target").id,
                  angle=angle, frame_tendon=frame_tendon, wrist=wrist, frame_row=frame_row,
                  tip_site=np.array([m.site(f"tip{k}").id for k in range(2)]),
                  hold_site=np.array([m.site(f"hold{k}").id for k in range(2)]),
                  grasp_eq=np.array([m.equality(f"grasp{k}").id for k in range(2)]))
    mm = MujocoModel(model=m, index=index, params=p, n=n, bounds=piece_bounds(p.link.length, n),
                     timestep=timestep, integrator=integrator)
    set_basis(mm, basis)
    return mm


def set_basis(mm: MujocoModel, basis: list[str]) -> None:
    """J_extra on the frame tendon of each link's basis, 0 on the other."""
    m, ix = mm.model, mm.index
    j = frame_inertia(mm.params, mm.n)
    for c, b in enumerate(basis):
        k, i = divmod(c, 3)
        m.tendon_armature[ix.frame_tendon[k, i, 0]] = j if b == "PP" else 0.0
        m.tendon_armature[ix.frame_tendon[k, i, 1]] = j if b == "PF" else 0.0


def initial_basis(grasp) -> list[str]:
    """PP for the inner links and a holding arm's terminal link, PF for a free terminal link
    (docs/physics.md §2.1)."""
    return ["PP", "PP", "PP" if grasp[0] else "PF", "PP", "PP", "PP" if grasp[1] else "PF"]


def perp(d: np.ndarray) -> np.ndarray:
    return np.array([-d[1], d[0]])


def hypot2(v) -> float:
    return math.hypot(float(v[0]), float(v[1]))
