"""Constraint forces of an Exudyn system from an index-1 (acceleration-level) solve.

The generalized-α integrator (index 3) returns Lagrange multipliers with a round-off floor
≈ ε·M·|q| / (β h²) that grows as the step shrinks (docs/exudyn.md §6).  Here the
multipliers are computed instead from the state (q, q̇) alone, which is as accurate as the
integrator's positions and velocities:

    [ M   Gᵀ ] [ q̈ ]   [ f(q, q̇, t) ]
    [ G   0  ] [ λ  ] = [ γ(q, q̇)    ],     γ = −(∂(G q̇)/∂q) q̇ ,

every matrix and vector from Exudyn's own functions for the model, evaluated by a separate
`exu.MainSolverStatic` on the mbs at its current configuration (never the reference
model's equations):

* M   `ComputeMassMatrix` → `GetSystemMassMatrix()` (ODE2 × ODE2);
* G   `ComputeJacobianAE(scalarFactor_ODE2=1, scalarFactor_ODE2_t=0, scalarFactor_ODE1=0)`
      into a zeroed system Jacobian (it *adds*); the call fills the whole saddle-point
      pattern [[0, Gᵀ], [G, J_λλ]]: active constraints give their rows of G (and the
      columns of Gᵀ), a switched-off connector (`activeConnector = False`) gives the rows
      "λ = 0" (G row zero, J_λλ = 1, also the unused second row of a prismatic joint
      without rotation constraint).  The system solved is exactly that Jacobian with M
      added in the ODE2 block, so inactive multipliers come out as 0 and no row selection
      is needed;
* f   `ComputeODE2RHS` → `GetSystemResidual()[:nODE2]`: applied loads minus the internal,
      elastic, damping and connector (spring-damper, bistop) forces, *without* Gᵀλ;
      Exudyn's equations of motion are M q̈ + Gᵀλ = f, so λ has the sign of
      `GetObjectOutput(·, OutputVariableType.Force)` (= the object's AE coordinates,
      `systemData.GetObjectLTGAE(object)` gives their places);
* γ   central difference (4 points, O(ε⁴)) of Exudyn's velocity-level algebraic equations
      g_v(q, q̇) = G(q) q̇ (`ComputeAlgebraicEquations(velocityLevel=True)`) along q̇, q̇ held:
      (∂(G q̇)/∂q) q̇ = d/ds g_v(q + s q̇, q̇) at s = 0.  For a λ = 0 row g_v is λ itself,
      unchanged by the perturbation, so its γ is exactly 0.

Units: SI; λ of a position constraint (revolute joint) is a force in N.  All constraints of
the model are scleronomic (no explicit time dependence), which the formula assumes.

The static solver is initialised once (lazily).  Its `InitializeSolver` copies the
system's initial state onto the current and start-of-step states and sets the times, so
those three states (accelerations included: `GetSystemState` has none) are saved and
restored around it; it also resets the system-wide solver flags to their defaults (load
factor 1), which the time integration uses unchanged.  Later evaluations only read the
current state; the perturbed coordinates for γ are restored bit for bit.  The running
integrator, paused in its post-step function, keeps its own solver object, factorised
Jacobian and algorithmic accelerations: its trajectory is bit for bit the same with and
without these evaluations (tests/exudyn_model/test_reactions.py).  Switching a connector
on or off needs no re-initialisation: the evaluation reads `activeConnector` at every
call and the system sizes do not change (same λ as a fresh object, tested; the capture
projection is bit for bit the one of a freshly initialised solver).

Cost per evaluation (p3's flexible model: 6 links × 8 ANCF elements, hubs and frame bodies,
288 ODE2 and 122 AE coordinates; one core, the other busy): 3.3 ms, of which the dense
system Jacobian zeroed and read back ~1.8 ms (the Python interface offers no sparse
access), SuperLU 0.5 ms, γ 0.26 ms, gathering the nonzeros 0.6 ms; 3.6 ms before the
Jacobian was filled in sparse storage and the nonzeros gathered block by block (the same
λ bit for bit).  Rigid model (30 + 16, dense solve): 0.19 ms.  Since then (wrist_bistop's
flexible model, 288 + 126; medians of one process, another busy): the nonzeros gathered
by one compiled kernel straight into canonical CSC (`saddle_csc`, 0.35 → 0.11 ms), and the
heap kept mapped between the Jacobian's 1.4 MB temporaries (`keep_heap_top_pad`: its
read-back 1.07 → 0.18 ms); an evaluation 1.9 → 0.6 ms alone, 3.3 → 2.1 ms between the
integrator's steps in a run (cold caches), λ bit for bit the same.
"""

from __future__ import annotations

import contextlib
import copy
import ctypes
import io
import sys

import numpy as np
from numba import njit
from scipy import sparse
from scipy.sparse import linalg as spla

sys.exudynFast = True  # the engine's build (exudyn_model.engine): import order must not matter
with contextlib.redirect_stdout(io.StringIO()):
    import exudyn as exu

#: Step s [s] of the difference along q̇ for γ (q ± s q̇, q ± 2s q̇: the configurations a
#: time s, 2s ahead and back on the tangent).  Truncation of the 4-point stencil ≈ (s ω)⁴/30
#: of γ for rotation rates ω (3e-14 at ω = 10 rad/s; free_drift turns at ≤ 0.05 rad/s);
#: round-off ≈ ε_mach (|q̇| + ω|q|)/s in γ, i.e. ∝ 1/s.  Measured (free_drift, rigid,
#: 0.18 N reaction): λ moves by ≤ 6e-13 N for s = 3e-3 … 1e-4 s, 2e-11 N at 1e-5 s,
#: 6e-10 N at 1e-7 s; rigid pendulum (ω = 1.3 rad/s): 9e-15 from the analytic λ.
EPS_DEFAULT = 1e-4

#: Solve the saddle-point system with SuperLU above this size (flexible model: 410 unknowns,
#: 1788 non-zeros, 0.5 ms; dense LAPACK at 302 unknowns 0.8 ms median but up to 0.15 s
#: when the threaded BLAS competes for the 2 cores), dense below (rigid model: 46
#: unknowns, 16 µs).
SPARSE_ABOVE = 100

_STATES = (exu.ConfigurationType.Current, exu.ConfigurationType.StartOfStep, exu.ConfigurationType.Initial)

#: Heap kept at the top by glibc's allocator when it grows or trims (M_TOP_PAD) [bytes]
HEAP_TOP_PAD = 8 << 20


def keep_heap_top_pad(pad: int = HEAP_TOP_PAD) -> bool:
    """Let glibc's malloc keep `pad` bytes at the top of the heap (mallopt M_TOP_PAD; the
    process's allocator, glibc only: elsewhere nothing is done, False).

    Why: every evaluation reads Exudyn's dense system Jacobian (`GetSystemJacobian`, 1.4 MB
    on the flexible model) through a temporary of the same size on each side of the
    binding; with the default pad (128 kB) the heap is trimmed after each and grown again,
    and the fresh pages are faulted in at every output sample: 1.07 ms of the Jacobian's
    1.1 ms.  Kept mapped, the Jacobian costs 0.18 ms and an evaluation 0.7 ms instead of
    1.7 ms (wrist_bistop, same process).  Results are unchanged (where memory comes from)."""
    try:
        mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    except OSError:  # pragma: no cover - no C library to ask
        return False
    if mallopt is None:  # pragma: no cover - not glibc
        return False
    M_TOP_PAD = -2  # malloc.h
    return bool(mallopt(M_TOP_PAD, int(pad)))


@njit(cache=True)
def saddle_csc(K, M, indptr, indices, data):  # pragma: no cover - compiled
    """The nonzeros of A = K + [[M, 0], [0, 0]] (M: the ODE2 block, n2 × n2) in canonical
    CSC form: `indptr` (n + 1) and, when they have room, `indices` and `data` (column by
    column, rows ascending).  Returns the number of nonzeros (larger than the buffers: they
    were not written).  One row-major pass over the dense K and M (K is C-ordered) counts
    the nonzeros per column and lists them in row order (at most as many as the buffers
    hold); a pass over that list puts them in their columns, in the same order, so rows
    ascend within each column."""
    n = K.shape[0]
    n2 = M.shape[0]
    room = data.shape[0]
    rows = np.empty(room, dtype=np.int32)
    cols = np.empty(room, dtype=np.int32)
    vals = np.empty(room)
    for j in range(n + 1):
        indptr[j] = 0
    nnz = 0
    for i in range(n):
        m = n2 if i < n2 else 0  # the row's columns j < m carry M
        for j in range(n):
            a = K[i, j] + M[i, j] if j < m else K[i, j]
            if a != 0.0:
                if nnz < room:
                    rows[nnz] = i
                    cols[nnz] = j
                    vals[nnz] = a
                nnz += 1
                indptr[j + 1] += 1
    for j in range(n):
        indptr[j + 1] += indptr[j]
    if nnz > room:
        return nnz
    fill = indptr[:n].copy()
    for e in range(nnz):
        j = cols[e]
        indices[fill[j]] = rows[e]
        data[fill[j]] = vals[e]
        fill[j] += 1
    return nnz


class ConstraintForces:
    """Index-1 Lagrange multipliers of an Exudyn system at its current state.

    `mbs` must be assembled; `eps` is the step s [s] of the difference along q̇ for γ.
    """

    def __init__(self, mbs, eps: float = EPS_DEFAULT):
        self.mbs = mbs
        self.eps = float(eps)
        self.solver: exu.MainSolverStatic | None = None

    # ---- setup --------------------------------------------------------------------------
    def _init(self) -> exu.MainSolverStatic:
        if self.solver is not None:
            return self.solver
        keep_heap_top_pad()
        sd = self.mbs.systemData
        # InitializeSolver sets current = start-of-step = initial state and the initial time
        # to the load-step start: keep all of it (GetSystemState has no accelerations)
        saved = [(c, sd.GetSystemState(configuration=c), sd.GetODE2Coordinates_tt(configuration=c),
                  sd.GetTime(c)) for c in _STATES]
        solver = exu.MainSolverStatic()
        settings = exu.SimulationSettings()
        settings.solution.file.write = False
        settings.solution.sensors.active = False
        settings.staticSolver.verboseMode = 0
        # Eigen's sparse storage: ComputeJacobianAE fills only the nonzeros (half the cost of
        # the dense one); GetSystemJacobian still returns the dense matrix
        settings.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        try:
            solver.InitializeSolver(self.mbs, settings)
        finally:
            for c, state, acc, t in saved:
                sd.SetSystemState(state, configuration=c)
                if len(acc) == len(state[0]):  # (unsized before the first solver run)
                    sd.SetODE2Coordinates_tt(acc, configuration=c)
                sd.SetTime(t, c)
        if solver.GetODE1size() != 0:
            raise NotImplementedError("ConstraintForces: systems with ODE1 coordinates")
        self.n2 = solver.GetODE2size()
        self.nae = solver.GetAEsize()
        self.n = self.n2 + self.nae
        # the zero Jacobian `constraint_jacobian` sets: one zero seen as n × n (strides 0; Exudyn
        # reads it element by element), not 1.4 MB of zeros read from memory at every evaluation
        self._zero = np.broadcast_to(np.zeros(1), (self.n, self.n))
        # the saddle matrix's row indices and values (`_saddle_matrix`), grown when needed
        self._indices = np.empty(4 * self.n, dtype=np.int32)
        self._data = np.empty(4 * self.n)
        self.solver = solver
        return solver

    # ---- Exudyn's matrices and vectors at the current state -----------------------------
    def mass_matrix(self) -> np.ndarray:
        """M (ODE2 × ODE2) at the current state."""
        s = self._init()
        s.ComputeMassMatrix(self.mbs)
        return s.GetSystemMassMatrix()  # (a new array: pybind11 copies Exudyn's matrix)

    def constraint_jacobian(self) -> np.ndarray:
        """The (ODE2 + AE)² Jacobian of the algebraic equations: [[0, Gᵀ], [G, J_λλ]]."""
        s = self._init()
        s.SetSystemJacobian(self._zero)  # ComputeJacobianAE adds into it
        s.ComputeJacobianAE(self.mbs, scalarFactor_ODE2=1.0, scalarFactor_ODE2_t=0.0,
                            scalarFactor_ODE1=0.0, velocityLevel=False)
        return s.GetSystemJacobian()  # (a new array)

    def rhs(self) -> np.ndarray:
        """f = applied minus internal forces (ODE2), without the constraint reactions."""
        s = self._init()
        s.ComputeODE2RHS(self.mbs)
        return np.array(s.GetSystemResidual()[:self.n2])

    def velocity_constraints(self) -> np.ndarray:
        """g_v = G q̇ (active rows; λ for the λ = 0 rows)."""
        s = self._init()
        s.ComputeAlgebraicEquations(self.mbs, velocityLevel=True)
        return np.array(s.GetSystemResidual()[self.n2:])

    def gamma(self) -> np.ndarray:
        """γ = −(∂(G q̇)/∂q) q̇ by a 4-point central difference along q̇."""
        self._init()
        sd = self.mbs.systemData
        q = sd.GetODE2Coordinates()
        v = sd.GetODE2Coordinates_t()
        e = self.eps
        g = {}
        try:
            for k in (-2, -1, 1, 2):
                sd.SetODE2Coordinates(q + (k * e) * v)
                g[k] = self.velocity_constraints()
        finally:
            sd.SetODE2Coordinates(q)
        return -(8.0 * (g[1] - g[-1]) - (g[2] - g[-2])) / (12.0 * e)

    # ---- the index-1 solve ---------------------------------------------------------------
    def solve(self) -> tuple[np.ndarray, np.ndarray]:
        """(q̈, λ) of the index-1 system at the current state (λ in the AE order)."""
        self._init()
        K = self.constraint_jacobian()
        M = self.mass_matrix()
        b = np.concatenate([self.rhs(), self.gamma()])
        if self.n > SPARSE_ABOVE:
            x = spla.splu(self._saddle_matrix(K, M)).solve(b)
        else:
            K[:self.n2, :self.n2] += M
            x = np.linalg.solve(K, b)
        return x[:self.n2], x[self.n2:]

    def _saddle_matrix(self, K: np.ndarray, M: np.ndarray) -> sparse.csc_matrix:
        """K with M added in its ODE2 block, as a sparse matrix (~1 % of the entries are
        nonzero), in scipy's canonical CSC form (rows sorted in each column), the form its
        conversion of the same nonzeros gives, so the factorisation is the same as from the
        dense sum; gathered by one compiled kernel in one pass over K and M
        (`saddle_csc`)."""
        n = K.shape[0]
        indptr = np.empty(n + 1, dtype=np.int32)
        nnz = saddle_csc(K, M, indptr, self._indices, self._data)
        if nnz > len(self._data):  # more nonzeros than ever before: larger buffers, again
            self._indices = np.empty(2 * nnz, dtype=np.int32)
            self._data = np.empty(2 * nnz)
            nnz = saddle_csc(K, M, indptr, self._indices, self._data)
        return sparse.csc_matrix((self._data[:nnz].copy(), self._indices[:nnz].copy(), indptr), shape=K.shape)

    def multipliers(self) -> np.ndarray:
        """λ (all AE coordinates) at the current state."""
        return self.solve()[1]

    def object_forces(self, objects, lam: np.ndarray | None = None) -> list[np.ndarray]:
        """λ of each object in `objects` (its AE coordinates, `GetObjectLTGAE` order), in the
        convention of `GetObjectOutput(obj, OutputVariableType.Force)`; `lam` from
        `multipliers()` (computed when None)."""
        if lam is None:
            lam = self.multipliers()
        sd = self.mbs.systemData
        return [lam[np.asarray(sd.GetObjectLTGAE(o), dtype=int)] for o in objects]


@contextlib.contextmanager
def held_inputs(model, stepper, inputs):
    """Within the block `model`'s mbs carries `inputs` as `ExudynEngine.advance` applies them
    at the start of the coming period (`stepper.Stepper.set_inputs`, the same code), the
    thrust inertia through a copy of the field part's `_ThrustInertia`, whose own state is
    left alone; the tidal field is that of the sample's own positions (span 0), where the
    integrator holds the one of the period's middle.  Everything set is put back afterwards.

    Why: at a control sample the loads in the mbs are still the last period's, while an
    observable belongs to the sample with the inputs held from it (the reference evaluates
    its reactions with them).  τ_m acts on the rotor coordinates only (no mass coupling)
    and never changes λ; τ_B, thrust and the field do (measured against the reference,
    rigid, h = 7.8 µs: capture 1.7e-5 → 6.9e-7, wrist_bistop 8.1e-7 → 1.2e-7)."""
    mbs = model.mbs
    field_forces = stepper.field_forces
    loads = [(ld, "load") for ld in model.motor_loads]
    loads += [(model.base_torque_load, "loadVector"), (model.thrust_load, "loadVector")]
    objects = [(model.carrier, "forceVector")] if field_forces is not None else []
    old_loads = [mbs.GetLoadParameter(ld, name) for ld, name in loads]
    old_objects = [mbs.GetObjectParameter(ob, name) for ob, name in objects]
    old_mass = stepper.base_mass
    held = (tuple(np.asarray(inputs.tau_m, float)), float(inputs.tau_B), float(inputs.thrust))
    try:
        stepper.set_inputs(held, copy.copy(field_forces.thrust_inertia) if field_forces is not None else None)
        yield
    finally:
        for (ld, name), val in zip(loads, old_loads):
            mbs.SetLoadParameter(ld, name, val)
        for (ob, name), val in zip(objects, old_objects):
            mbs.SetObjectParameter(ob, name, val)
        stepper.set_base_mass(old_mass)  # the base and the integrator's mass matrix


def grasp_forces(cf: ConstraintForces, model, grasp_on, stepper=None, inputs=None) -> np.ndarray:
    """`reaction_forces_I` of the built `model` [N] (4: grasp 1 x, y, grasp 2 x, y; inertial
    axes; zero for a grasp that is off, `grasp_on`) by the index-1 solve of `cf` (on
    `model`'s mbs) at the current state, with the sign of `GetObjectOutput(grasp joint,
    Force)`: the force of the arm on the target (marker 0 of the joint; Exudyn's
    M q̈ + Gᵀλ = f puts −λ on the marker-1 body).

    inputs: the held inputs of the coming period (`rsmcheck.core.engine.Inputs`), applied for the
    evaluation by `held_inputs` through `stepper`; None: the loads as they stand in the mbs
    (those of the period that just ended, the state the integrator's own multipliers belong to)."""
    out = np.zeros(4)
    if not np.any(grasp_on):
        return out
    with held_inputs(model, stepper, inputs) if inputs is not None else contextlib.nullcontext():
        lam = cf.multipliers()
    forces = cf.object_forces(model.grasp_joints, lam)
    for k in range(2):
        if grasp_on[k]:
            out[2 * k:2 * k + 2] = forces[k][:2]
    return out
