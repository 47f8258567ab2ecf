"""One link as Exudyn finite elements: `ObjectANCFCable2D` on `NodePoint2DSlope1` nodes.

A link of length L is a chain of `n_elements` equal ANCF cable elements (cubic Hermite
interpolation of position; nodal coordinates x, y, ∂x/∂ξ, ∂y/∂ξ).  The material abscissa
ξ ∈ [0, L] is the arc length of the undeformed, unstretched link, from its proximal pin
(ξ = 0) to its distal pin (ξ = L).  Material data come from `rsmcheck.core.params.LinkParams`
only (docs/physics.md §2):

    massPerLength = ρA,  bendingStiffness = EI,  axialStiffness = EA = axial_to_bending·EI,
    bendingDamping = η·EI (Kelvin–Voigt, the damping law of docs/physics.md §2.2),
    axialDamping = η·EA (the reference is axially rigid; this damps the axial modes,
    2.3–4.6 kHz at the default EA = 1e5·EI, that have no counterpart there).

The cable element carries no rotary inertia of the cross-section (its mass matrix is the
consistent ρA ∫SᵀS, positive definite), so J_extra of docs/physics.md §2.3 is not in the
beam: the engine puts it on the frame body.

Besides the element factory this module holds the Hermite shape functions and the few
integrals over a link that the engine needs outside Exudyn (frame angle of a PF link,
mid-span deflection, kinetic energy, momentum, strain energy), all evaluated on exactly
the interpolation Exudyn uses, and `link_frequencies`, the eigenfrequencies of one link
pinned-pinned (PP) or pinned-free (PF) from Exudyn's own mass and stiffness matrices.
"""

from __future__ import annotations

import contextlib
import io
import math
import sys

import numpy as np

sys.exudynFast = True  # noqa: E402  (the fast build, no range checks)
# exudyn announces the fast build on stdout: keep it out of `--json` output
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu  # noqa: E402
from exudyn.itemInterface import (  # noqa: E402
    LoadTorqueVector, MarkerBodyPosition, MarkerNodePosition, MarkerNodeRigid,
    NodePoint2DSlope1, NodeRigidBody2D, ObjectANCFCable2D, ObjectGround, ObjectJointGeneric,
    ObjectJointRevolute2D, ObjectRigidBody2D)

from rsmcheck.core.params import LinkParams, Params  # noqa: E402

#: Elements per link chosen by the convergence study (docs/exudyn.md): PP and PF f1, f2
#: within 0.05 % of the Euler–Bernoulli values.
N_ELEMENTS_DEFAULT = 8
NODE_SIZE = 4  # x, y, x', y'


# --- Hermite interpolation of ObjectANCFCable2D ----------------------------------------
def shape(s: np.ndarray | float, le: float) -> np.ndarray:
    """The four cubic Hermite shape functions at element abscissa s ∈ [0, le], shape (..., 4):
    node-0 position, node-0 slope, node-1 position, node-1 slope (Exudyn's order)."""
    x = np.asarray(s, float) / le
    return np.stack([1 - 3 * x**2 + 2 * x**3, le * (x - 2 * x**2 + x**3), 3 * x**2 - 2 * x**3,
                     le * (-x**2 + x**3)], axis=-1)


def shape_x(s, le: float) -> np.ndarray:
    x = np.asarray(s, float) / le
    return np.stack([(-6 * x + 6 * x**2) / le, 1 - 4 * x + 3 * x**2, (6 * x - 6 * x**2) / le,
                     -2 * x + 3 * x**2], axis=-1)


def shape_xx(s, le: float) -> np.ndarray:
    x = np.asarray(s, float) / le
    return np.stack([(12 * x - 6) / le**2, (6 * x - 4) / le, (6 - 12 * x) / le**2, (6 * x - 2) / le],
                    axis=-1)


def gauss(n: int, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * x + 0.5 * (b + a), 0.5 * (b - a) * w


class LinkMesh:
    """Interpolation of one link: `n` elements of length `le`; a link's coordinate vector
    q (absolute: reference + displacement) has 4(n+1) entries, node by node (x, y, x', y').

    The matrices below map q to integrals over the link (ρ = ρA):
        pos(ξ)      r(ξ) = P(ξ) q                                         (2 × nq)
        first       ∫ρ r dξ = F q                                         (2 × nq)
        moment      ∫ρ ξ r dξ = C q                                       (2 × nq)
        mass        ∫ρ ṙ·ṙ dξ = q̇ᵀ M q̇                                    (nq × nq)
    and `sample(k)` maps q to r at k Gauss points per element (all elements stacked).
    """

    def __init__(self, n: int, length: float, rho_a: float):
        self.n = int(n)
        self.length = float(length)
        self.rho_a = float(rho_a)
        self._cache: dict = {}

    @property
    def le(self) -> float:
        return self.length / self.n

    @property
    def nq(self) -> int:
        return NODE_SIZE * (self.n + 1)

    def element_of(self, xi: float) -> tuple[int, float]:
        e = min(int(xi / self.le), self.n - 1)
        return e, xi - e * self.le

    def _interp(self, rows: list[tuple[int, np.ndarray]]) -> np.ndarray:
        """Stacked 2-row blocks, one per (element, 4 shape values): r = block @ q."""
        out = np.zeros((2 * len(rows), self.nq))
        for k, (e, sv) in enumerate(rows):
            base = NODE_SIZE * e
            for j, off in enumerate((0, 2, 4, 6)):
                out[2 * k, base + off] = sv[j]
                out[2 * k + 1, base + off + 1] = sv[j]
        return out

    def pos_matrix(self, xi: float) -> np.ndarray:
        """P(ξ): r(ξ) = P q."""
        e, s = self.element_of(xi)
        return self._interp([(e, shape(s, self.le))])

    def sample(self, k: int, deriv: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ξ_g, w_g, D): D @ q stacked as (x, y) pairs is r (deriv 0), r' (1) or r'' (2) at
        k Gauss points per element; ξ_g, w_g the material abscissae and weights."""
        key = ("sample", k, deriv)
        if key not in self._cache:
            s, w = gauss(k, 0.0, self.le)
            fn = (shape, shape_x, shape_xx)[deriv]
            sv = fn(s, self.le)
            rows = [(e, sv[g]) for e in range(self.n) for g in range(k)]
            xi = np.concatenate([e * self.le + s for e in range(self.n)])
            self._cache[key] = (xi, np.tile(w, self.n), self._interp(rows))
        return self._cache[key]

    def first_matrix(self) -> np.ndarray:
        _, w, D = self.sample(4)
        return self.rho_a * (np.repeat(w, 2)[:, None] * D).reshape(-1, 2, self.nq).sum(axis=0)

    def moment_matrix(self) -> np.ndarray:
        xi, w, D = self.sample(4)
        return self.rho_a * (np.repeat(w * xi, 2)[:, None] * D).reshape(-1, 2, self.nq).sum(axis=0)

    def mass_matrix(self) -> np.ndarray:
        _, w, D = self.sample(4)
        return self.rho_a * D.T @ (np.repeat(w, 2)[:, None] * D)

    def points(self, q: np.ndarray, n_gauss: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Material abscissae ξ_g, weights w_g and positions r(ξ_g) (n_gauss per element)
        of link coordinates q (or velocities q̇ for ṙ)."""
        xi, w, D = self.sample(n_gauss)
        return xi, w, (D @ q).reshape(-1, 2)

    def strain_energy(self, q: np.ndarray, ei: float, ea: float) -> float:
        """½∫(EA ε² + EI κ²) dξ with Exudyn's strain measures, ε = |r'| − 1,
        κ = (r' × r'')/|r'|², and its integration orders (axial 5, bending 3 Gauss points)."""
        _, w5, D5 = self.sample(5, 1)
        rx = (D5 @ q).reshape(-1, 2)
        u = 0.5 * ea * float(np.sum(w5 * (np.linalg.norm(rx, axis=1) - 1.0) ** 2))
        _, w3, D3 = self.sample(3, 1)
        _, _, D3xx = self.sample(3, 2)
        rx = (D3 @ q).reshape(-1, 2)
        rxx = (D3xx @ q).reshape(-1, 2)
        kappa = (rx[:, 0] * rxx[:, 1] - rx[:, 1] * rxx[:, 0]) / np.sum(rx**2, axis=1)
        return u + 0.5 * ei * float(np.sum(w3 * kappa**2))


# --- building a link in a system ---------------------------------------------------------
def material(link: LinkParams, axial_damping: float = 1.0) -> dict[str, float]:
    """ObjectANCFCable2D material parameters from the one parameter source.

    `axial_damping` scales the axial Kelvin–Voigt term η·EA (1: the same material law as
    in bending).  The axially rigid reference has neither the axial compliance nor this
    dissipation, P = η Ṅ² L / EA per link, which vanishes only as EA → ∞; it damps the rotor
    modes a little too (docs/exudyn.md §5 item 6).
    """
    ei = link.ei
    ea = link.axial_to_bending * ei
    eta = link.kelvin_voigt_eta
    return {"massPerLength": link.rho_a, "bendingStiffness": ei, "axialStiffness": ea,
            "bendingDamping": eta * ei, "axialDamping": axial_damping * eta * ea}


def add_link(mbs, link: LinkParams, n_elements: int, pin, theta: float, pin_vel=(0.0, 0.0),
             omega: float = 0.0, damping: bool = True, axial_damping: float = 1.0) -> tuple[list[int], list[int]]:
    """A straight, unstretched link from `pin` at angle `theta`, moving rigidly with the
    pin velocity and angular rate `omega`.  Returns (node numbers, element numbers)."""
    le = link.length / n_elements
    c, s = math.cos(theta), math.sin(theta)
    mat = material(link, axial_damping)
    if not damping:
        mat["bendingDamping"] = mat["axialDamping"] = 0.0
    nodes = []
    for k in range(n_elements + 1):
        d = np.array([c, s]) * (k * le)
        v = np.asarray(pin_vel, float) + omega * np.array([-d[1], d[0]])
        nodes.append(mbs.AddNode(NodePoint2DSlope1(
            referenceCoordinates=[pin[0] + d[0], pin[1] + d[1], c, s],
            initialVelocities=[v[0], v[1], -omega * s, omega * c])))
    elements = [mbs.AddObject(ObjectANCFCable2D(nodeNumbers=[nodes[k], nodes[k + 1]], length=le, **mat))
                for k in range(n_elements)]
    return nodes, elements


def add_hub(mbs, beam_node: int, theta: float) -> int:
    """A massless rigid hub clamped to an ANCF end node: its rotation coordinate (node
    coordinate 2) is the rotation of the beam's end section, where a joint's torques act
    (docs/physics.md §3.3).  `NodeRigidBody2D` with an `ObjectRigidBody2D` of zero mass and
    inertia, clamped by `ObjectJointGeneric` with x, y and the rotation about z constrained
    (`MarkerNodeRigid` on both: the ANCF node's orientation is its slope direction).
    `theta` is the section's angle in the reference configuration [rad]."""
    node = mbs.GetNode(beam_node)
    ref, vel = node["referenceCoordinates"], node["initialVelocities"]
    slope, slope_rate = np.asarray(ref[2:4], float), np.asarray(vel[2:4], float)
    omega = float(slope[0] * slope_rate[1] - slope[1] * slope_rate[0]) / float(slope @ slope)  # r'×ṙ'/|r'|²
    hub = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[ref[0], ref[1], float(theta)],
                                      initialVelocities=[float(vel[0]), float(vel[1]), omega]))
    mbs.AddObject(ObjectRigidBody2D(nodeNumber=hub, mass=0.0, inertia=0.0))
    mbs.AddObject(ObjectJointGeneric(markerNumbers=[mbs.AddMarker(MarkerNodeRigid(nodeNumber=beam_node)),
                                                    mbs.AddMarker(MarkerNodeRigid(nodeNumber=hub))],
                                     constrainedAxes=[1, 1, 0, 0, 0, 1]))
    return hub


def static_end_couples(params: Params | LinkParams, couple_0: float, couple_L: float,
                       n_elements: int = N_ELEMENTS_DEFAULT) -> dict[str, float]:
    """One link pinned at both ends (x, y of both end nodes on the ground), couples
    `couple_0` and `couple_L` [N·m, counter-clockwise] on the hubs of its end sections,
    Exudyn's static solver.  Returns the transverse deflection at mid-span [m] and the
    rotations of the two end sections [rad] (hub angles), for the beam-formula tests."""
    link = params.link if isinstance(params, Params) else params
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    nodes, _ = add_link(mbs, link, n_elements, (0.0, 0.0), 0.0, damping=False)
    hubs = [add_hub(mbs, nodes[0], 0.0), add_hub(mbs, nodes[-1], 0.0)]
    for node, x in ((nodes[0], 0.0), (nodes[-1], link.length)):
        mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[
            mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[x, 0.0, 0.0])),
            mbs.AddMarker(MarkerNodePosition(nodeNumber=node))]))
    for hub, couple in zip(hubs, (couple_0, couple_L)):
        marker = mbs.AddMarker(MarkerNodeRigid(nodeNumber=hub))
        mbs.AddLoad(LoadTorqueVector(markerNumber=marker, loadVector=[0.0, 0.0, float(couple)]))
    mbs.Assemble()
    s = exu.SimulationSettings()
    s.solution.file.write = False
    s.solution.sensors.active = False
    s.staticSolver.verboseMode = 0
    # the axial force's round-off floor (∝ ε·EA, docs/exudyn.md §4) sets the absolute tolerance
    s.staticSolver.newton.absoluteTolerance = 1e-2
    s.staticSolver.newton.relativeTolerance = 1e-10
    s.linearSolver.solverType = exu.LinearSolverType.EXUdense
    with contextlib.redirect_stdout(io.StringIO()):
        mbs.SolveStatic(s)
    mesh = LinkMesh(n_elements, link.length, link.rho_a)
    q = np.concatenate([np.asarray(mbs.GetNodeOutput(n, exu.OutputVariableType.Coordinates), float)
                        + np.asarray(mbs.GetNode(n)["referenceCoordinates"], float) for n in nodes])
    rot = [float(mbs.GetNodeOutput(h, exu.OutputVariableType.Coordinates)[2]) for h in hubs]
    return {"mid_m": float((mesh.pos_matrix(0.5 * link.length) @ q)[1]), "slope_0": rot[0], "slope_L": rot[1]}


# --- eigenfrequencies of one link ------------------------------------------------------
def link_frequencies(params: Params | LinkParams, basis: str, n_elements: int = N_ELEMENTS_DEFAULT,
                     n_modes: int = 2) -> np.ndarray:
    """First `n_modes` bending eigenfrequencies [Hz] of one link, pinned at ξ = 0 and, for
    basis "PP", also at ξ = L ("PF": free there), from Exudyn's mass and stiffness matrices
    (`ComputeODE2Eigenvalues`, pinned coordinates removed).  The rigid rotation (PF, 0 Hz)
    and the axial modes are skipped: a mode counts as bending when most of its eigenvector
    is in the transverse coordinates (y, y') of the straight link."""
    link = params.link if isinstance(params, Params) else params
    if basis not in ("PP", "PF"):
        raise ValueError(f"basis must be 'PP' or 'PF', got {basis!r}")
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    nodes, _ = add_link(mbs, link, n_elements, (0.0, 0.0), 0.0, damping=False)
    mbs.Assemble()
    nq = NODE_SIZE * len(nodes)
    fixed = [0, 1] + ([nq - 4, nq - 3] if basis == "PP" else [])
    freqs, vecs = mbs.ComputeODE2Eigenvalues(constrainedCoordinates=fixed, convert2Frequencies=True,
                                             numberOfEigenvalues=nq - len(fixed))
    transverse = np.array([i % 2 == 1 for i in range(nq)])
    out = []
    for j, f in enumerate(freqs):
        v = vecs[:, j]
        if f > 1.0 and np.sum(v[transverse] ** 2) > 0.5 * np.sum(v**2):
            out.append(f)
        if len(out) == n_modes:
            break
    return np.array(out)


def convergence_table(params: Params | None = None, counts=(2, 4, 6, 8, 12, 16)) -> list[dict]:
    """Relative errors of the first two PP and PF frequencies against Euler–Bernoulli and
    against Table 2 as printed, per element count (the study recorded in docs/exudyn.md)."""
    from rsmcheck.core.beams import analytic_frequencies
    from rsmcheck.core.params import TABLE2_HZ

    params = params or Params()
    rows = []
    for n in counts:
        for basis in ("PP", "PF"):
            f = link_frequencies(params, basis, n)
            fa = analytic_frequencies(params.link, basis)
            for j in range(2):
                rows.append({"n_elements": n, "basis": basis, "mode": j + 1, "exudyn_hz": float(f[j]),
                             "analytic_hz": float(fa[j]), "table2_hz": TABLE2_HZ[basis][j],
                             "error_analytic": float(f[j] / fa[j] - 1.0),
                             "error_table2": float(f[j] / TABLE2_HZ[basis][j] - 1.0)})
    return rows
