"""The right-hand side of the reference's ODE, compiled: ẋ = rhs(x, u) of the state of
model_arrays.py, what every integrator calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from reference_model.model_arrays import S_ISPG0, U_THRUST
from reference_model.solve import solve_constrained
from reference_model.system import assemble, assemble_reduced


@njit(cache=True)
def rhs(x, u, m, sw):
    """ẋ of the full ODE: eq. (7) with (11)–(12), the reference point and mass depletion.
    The slots of condensed static shapes (condense.py) get ẋ = 0: the engine refills them
    from the rest of the state after every interval (`ReferenceModel.complete`); the stop
    deflections e are states only then."""
    ny = m.nq + 3
    ns = ny + 6
    if m.cond:  # the static shapes slaved (condense.py): Ÿ and θ̈_m from one system
        Mz, fz, Gz, phi, phid, Bs, uJ, tauw, aO, edot = assemble_reduced(x, u, m, sw)
        zdd, Rcl = solve_constrained(Mz, fz, Gz, Bs, m)
        ydd = zdd[:ny]
        thmdd = zdd[ny:]
    else:
        Mg, f, G, phi, phid, Bs, thmdd, uJ, tauw, aO = assemble(x, u, m, sw)
        ydd, Rcl = solve_constrained(Mg, f, G, Bs, m)
    dx = np.empty_like(x)
    dx[0:ns] = x[ns:2 * ns]
    dx[ns:ns + ny] = ydd
    dx[ns + ny:2 * ns] = thmdd
    dx[2 * ns:2 * ns + 2] = x[2 * ns + 2:2 * ns + 4]
    dx[2 * ns + 2:2 * ns + 4] = aO
    dx[2 * ns + 4] = u[U_THRUST] / m.sc[S_ISPG0]
    dx[2 * ns + 5:2 * ns + 7] = 0.0
    if m.cond:  # condensed static shapes are not states: their slots stay as they are
        dx[2 * ns + 5:2 * ns + 7] = edot  # the stop deflections e (condense.py)
        for i in range(m.nm.shape[0]):
            for a in range(m.ne[i], m.nm[i]):
                dx[m.mo[i] + a] = 0.0
                dx[ns + m.mo[i] + a] = 0.0
    return dx
