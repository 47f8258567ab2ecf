"""Linearisation of the Exudyn model: one link's eigenfrequencies (`links.link_frequencies`),
the coupled frequencies of the robot at rest in a case's configuration (`rsmcheck modes`)
and the linear plant of a case at its initial state (the closed-loop analysis,
rsmcheck.orchestration.closed_loop).  `coupled_frequencies` and `linear_plant` mirror
`reference_model/modes.py`: the same signatures (rsmcheck/core/engine.py), `engine_options`
going to `ExudynEngine` (n_elements, default `links.N_ELEMENTS_DEFAULT` here, not the
case's [exudyn] table).

`coupled_frequencies` builds the engine's full model (base, target, six ANCF links with their
frame bodies, rotors, active grasps) in the case's initial configuration *at rest*, without
damping (ζ = 0, C_m = 0: the undamped frequencies both engines can be compared on), and asks
Exudyn for the eigenvalues of M, K projected on the null space of the constraint Jacobian
(`ComputeODE2Eigenvalues(ignoreAlgebraicEquations=False)`).  The zero frequencies of the
free-floating rigid motions (3 for the floating base, 6 joint rotations, and the wrist while a
grasp is on) are dropped.
"""

from __future__ import annotations

import numpy as np

from exudyn_model import links
from exudyn_model.links import link_frequencies
from rsmcheck.core.cases import at_rest, undamped

__all__ = ["at_rest_undamped", "coupled_frequencies", "linear_plant", "link_frequencies"]


def at_rest_undamped(case, params=None):
    """The case in its initial configuration with zero rates and no damping."""
    return undamped(at_rest(case), params)


def coupled_frequencies(case, n: int = 6, f_min: float = 1.0, **engine_options) -> np.ndarray:
    """The first `n` eigenfrequencies [Hz] above `f_min` of Exudyn's robot linearised at
    rest in the initial configuration of `case`, undamped."""
    from exudyn_model.engine import ExudynEngine

    engine_options.setdefault("n_elements", links.N_ELEMENTS_DEFAULT)
    engine = ExudynEngine(at_rest_undamped(case), **engine_options)
    freqs, _ = engine.mbs.ComputeODE2Eigenvalues(convert2Frequencies=True, ignoreAlgebraicEquations=False)
    freqs = np.asarray(freqs)
    return freqs[freqs > f_min][:n]


def linear_plant(case, outputs, n_inputs: int = 7, eps: float = 1e-7, **engine_options):
    """(A, B, C) of Exudyn's model of `case` linearised at rest in its initial state (damping
    kept): ẋ = A x + B u, y = C x, with x = (z, ż) on the null space N of the constraint
    Jacobian (q = q₀ + N z), u = (τ_m1..6, τ_B) and y = `outputs(sensors)`.

    Everything is Exudyn's own: M, G and f(q, q̇) (`exudyn_model.reactions.ConstraintForces`),
    −∂f/∂q, −∂f/∂q̇ and the load vectors by central differences, the sensors of the engine."""
    import scipy.linalg as sl

    from exudyn_model.engine import ExudynEngine
    from exudyn_model.reactions import ConstraintForces

    engine_options.setdefault("n_elements", links.N_ELEMENTS_DEFAULT)
    engine = ExudynEngine(case, **engine_options)
    cf = ConstraintForces(engine.mbs)
    sd = engine.mbs.systemData
    q0 = np.array(sd.GetODE2Coordinates())
    v0 = np.array(sd.GetODE2Coordinates_t())
    n = q0.size

    def f(q, v):
        sd.SetODE2Coordinates(q)
        sd.SetODE2Coordinates_t(v)
        return np.array(cf.rhs()[:n])

    K, D = np.zeros((n, n)), np.zeros((n, n))
    for i in range(n):
        e = eps * max(1.0, abs(q0[i]))
        dq = np.zeros(n)
        dq[i] = e
        K[:, i] = -(f(q0 + dq, v0) - f(q0 - dq, v0)) / (2 * e)
        dv = np.zeros(n)
        dv[i] = 10 * eps
        D[:, i] = -(f(q0, v0 + dv) - f(q0, v0 - dv)) / (20 * eps)
    f0 = f(q0, v0)
    F = np.zeros((n, n_inputs))
    for j in range(n_inputs):
        tau = np.eye(6)[j] if j < 6 else np.zeros(6)  # a unit motor torque, or the base torque
        engine.stepper.set_inputs((tau, 1.0 if j == 6 else 0.0, 0.0), None)
        F[:, j] = f(q0, v0) - f0
    engine.stepper.set_inputs((np.zeros(6), 0.0, 0.0), None)
    G = cf.constraint_jacobian()
    G = G[n:, :n] if G.shape[0] > n else G
    N = sl.null_space(G)
    Mi = np.linalg.inv(N.T @ cf.mass_matrix()[:n, :n] @ N)
    k = N.shape[1]
    A = np.block([[np.zeros((k, k)), np.eye(k)], [-Mi @ N.T @ K @ N, -Mi @ N.T @ D @ N]])
    B = np.vstack([np.zeros((k, n_inputs)), Mi @ N.T @ F])
    cols = []
    for i in range(2 * k):
        dz = np.zeros(2 * k)
        dz[i] = eps
        ys = []
        for sign in (1.0, -1.0):
            sd.SetODE2Coordinates(q0 + sign * N @ dz[:k])
            sd.SetODE2Coordinates_t(v0 + sign * N @ dz[k:])
            ys.append(outputs(engine.sensors()))
        cols.append((ys[0] - ys[1]) / (2 * eps))
    sd.SetODE2Coordinates(q0)
    sd.SetODE2Coordinates_t(v0)
    return A, B, np.array(cols).T
