"""Stepping of the reference: one control interval at a time with the inputs held
(zero-order hold, docs/physics.md §6), by the case's integrator, exactly to the next sample.

* `dopri5.integrate_dopri5`: embedded Dormand–Prince 5(4), the default (docs/physics.md §7);
* `trbdf2.integrate_trbdf2`: TR-BDF2 for quiet, stiff phases; its iteration matrix (J,
  (I − d h J)⁻¹ and the `work` slots) is kept between control periods and dropped when the
  system changes (capture, release: `_new_system`);
* `imex.integrate_ark`: the additive pair with the stiff shapes implicit, whose frozen
  Jacobian columns L are kept and dropped in the same way.

The control intervals longer than the case's control period (a quiet segment's own
`control_period`) go to the case's `quiet_integrator` ([reference] table), the others to
its `integrator`; each carries its own step size from one interval to its next.

Both control the error per component against atol_i + rtol·|x_i|, with atol_i = rtol ×
the scale of its kind of coordinate (`ATOL_SCALE`).  The engine's mirror in the Exudyn
model is `exudyn_model/stepping.py`; so is `rhs_timing`, the cost of one right-hand side
(`rsmcheck bench`).
"""

from __future__ import annotations

import math
import time
import timeit

import numpy as np
from numba import njit

from reference_model import core
from reference_model import imex
from reference_model.dopri5 import integrate_dopri5
from reference_model.trbdf2 import W_HAVE_J, W_JACOBIANS, integrate_trbdf2
from rsmcheck.core.engine import Inputs
from rsmcheck.core.errors import SimulationDiverged

#: error-control scale per kind of state component: atol_i = rtol · scale_i
ATOL_SCALE = {
    "rigid": 1.0,  # m, rad
    "modal": 1e-3,  # m (amplitudes are micrometres to millimetres)
    "rigid_rate": 1.0,  # m/s, rad/s
    "modal_rate": 1e-1,  # m/s (ω · amplitude)
    "orbit_r": 1e4,  # m (|r_O| ≈ 7e6 m)
    "orbit_v": 1e1,  # m/s
    "mass": 1.0,  # kg
}


class SteppingMixin:
    """`ReferenceEngine`'s stepping: reads model, cfg, rtol, integrator, quiet_integrator,
    _h_max; advances x, t, the carried steps _h, the step counters and the integrator's
    wall time; owns the TR-BDF2 iteration matrix (_jac, _minv, _work) and the IMEX's L."""

    def _atol(self) -> np.ndarray:
        lay = self.model.layout
        s = np.empty(lay.nx)
        s[:] = ATOL_SCALE["rigid"]
        s[9:lay.nq] = ATOL_SCALE["modal"]
        s[lay.ns:2 * lay.ns] = ATOL_SCALE["rigid_rate"]
        s[lay.ns + 9:lay.ns + lay.nq] = ATOL_SCALE["modal_rate"]
        s[lay.r_O] = ATOL_SCALE["orbit_r"]
        s[lay.v_O] = ATOL_SCALE["orbit_v"]
        s[lay.m_used] = ATOL_SCALE["mass"]
        return self.rtol * s

    def u_vector(self, inputs: Inputs) -> np.ndarray:
        """The held inputs as `core`'s input vector u (τ_m, τ_B, thrust)."""
        u = np.zeros(core.N_INPUTS)
        u[core.U_TAU_M:core.U_TAU_M + 6] = inputs.tau_m
        u[core.U_TAU_B] = inputs.tau_B
        u[core.U_THRUST] = inputs.thrust
        return u

    def _advance(self, t_next: float, inputs: Inputs) -> None:
        args = self.model.core_args(self.cfg)
        u = self.u_vector(inputs)
        # an interval longer than the case's control period belongs to a quiet segment (its
        # own, longer control_period): the quiet integrator's (docs/physics.md §7)
        quiet = self.case.solver.is_quiet(t_next - self.t)
        name = self.quiet_integrator if quiet else self.integrator
        h0, h_max = self._h[name], self._h_max[name]
        tic = time.perf_counter()
        if name == "dopri5":
            x, h, nacc, nrej, status = integrate_dopri5(
                self.x, self.t, t_next, h0, self.rtol, self.atol, h_max, u, *args)
        elif name == "imex":
            x, h, nacc, nrej, status = imex.integrate_ark(
                self.x, self.t, t_next, h0, self.rtol, self.atol, h_max, self._stiff, self._L,
                self._Winv, self._imex_work, imex.REFRESH_S, u, *args)
        else:
            x, h, nacc, nrej, status = integrate_trbdf2(
                self.x, self.t, t_next, h0, self.rtol, self.atol, h_max, self._jac,
                self._minv, self._work, u, *args)
        self.integrator_wall += time.perf_counter() - tic
        self.steps += nacc
        self.rejected += nrej
        if quiet and name != self.integrator:
            self.quiet_steps += nacc
        if status != 0 or not np.all(np.isfinite(x)):
            bad = int(np.argmax(~np.isfinite(x))) if not np.all(np.isfinite(x)) else int(np.argmax(np.abs(x)))
            raise SimulationDiverged(self.name, self.t, "?", f"state[{bad}] "
                                     + ("non-finite" if status == 1 else "step size underflow"), float(x[bad]))
        self.x, self.t = x, t_next
        self._h[name] = h

    def _imex_setup(self) -> None:
        """The IMEX integrator's stiff components and the storage of L, W⁻¹ (imex.py)."""
        lay = self.model.layout
        arrays = self.model.arrays
        k_diag, m_diag = [], []
        for i, n in enumerate(lay.n_modes):
            b = self.cfg.basis[i]
            k_diag.append(np.diag(arrays.k_ff[i, b])[:n])
            m_diag.append(np.diag(arrays.m_ff[i, b])[:n])
        self._stiff = imex.stiff_indices(k_diag, m_diag, lay.mode_offset, lay.ns)
        n_s = self._stiff.shape[0]
        self._L = np.zeros((lay.nx, n_s))
        self._Winv = np.zeros((n_s, n_s))
        self._imex_work = np.zeros(imex.N_WORK)

    def _new_system(self) -> None:
        """The system changed (a capture or release): the next implicit step needs a new Jacobian."""
        self._work[W_HAVE_J] = 0.0
        self._imex_work[imex.W_HAVE_L] = 0.0

    def _jacobians(self) -> int:
        """TR-BDF2 Jacobians computed so far."""
        return int(self._work[W_JACOBIANS])


@njit(cache=True)
def _rhs_loop(x, u, m, sw, n):  # pragma: no cover - compiled
    s = 0.0
    for _ in range(n):
        s += core.rhs(x, u, m, sw)[0]
    return s


def rhs_timing(case, n: int = 2000, **engine_options) -> dict[str, float]:
    """µs per evaluation of the right-hand side `core.rhs` at the initial state of `case`
    (best of 3): `call_us` called from Python (numba's dispatch of the model's arrays
    included), `compiled_us` inside a compiled loop (what the integrators pay per stage),
    and `states`, the size of the ODE state.  `engine_options` go to `ReferenceEngine`."""
    from reference_model.engine import ReferenceEngine  # the engine imports this module

    engine = ReferenceEngine(case, **engine_options)
    m, sw = engine.model.core_args(engine.cfg)
    u = np.zeros(core.N_INPUTS)
    core.rhs(engine.x, u, m, sw)
    call = min(timeit.repeat(lambda: core.rhs(engine.x, u, m, sw), number=n, repeat=3)) / n * 1e6
    _rhs_loop(engine.x, u, m, sw, 10)
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _rhs_loop(engine.x, u, m, sw, 10 * n)
        best = min(best, (time.perf_counter() - t0) / (10 * n) * 1e6)
    return {"call_us": call, "compiled_us": best, "states": int(engine.model.layout.nx)}
