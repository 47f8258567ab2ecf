"""The reference's stepper: it advances the ODE state one control interval at a time with
the inputs held (zero-order hold, docs/physics.md §6), by the case's integrator, exactly to
the next sample.

* `dopri5.integrate_dopri5`: embedded Dormand–Prince 5(4), the default (docs/physics.md §7);
* `trbdf2.integrate_trbdf2`: TR-BDF2 for quiet, stiff phases; its iteration matrix
  (`Trbdf2Work`) is kept between control periods and dropped when the system changes
  (capture, release: `Stepper.new_system`);
* `imex.integrate_ark`: the additive pair with the stiff shapes implicit, whose frozen
  Jacobian columns L (`ImexWork`) are kept and dropped in the same way.

The control intervals of a quiet segment (longer than the case's control period) go to the
`quiet_integrator`, the others to the `integrator`; each carries its own step size from one
interval to its next.

Both control the error per component against atol_i + rtol·|x_i|, with atol_i = rtol ×
the scale of its kind of coordinate (`ATOL_SCALE`).  The stepper's mirror in the Exudyn
model is `exudyn_model/stepping.py`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from reference_model import imex
from reference_model.build import Configuration, Layout, ReferenceModel
from reference_model.dopri5 import integrate_dopri5
from reference_model.trbdf2 import N_WORK, W_HAVE_J, W_JACOBIANS, integrate_trbdf2
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
    "stop_deflection": 1.0,  # rad (it adds to the wrist angle one to one)
}


def absolute_tolerance(layout: Layout, rtol: float) -> np.ndarray:
    """atol_i = rtol · scale_i of every component of the ODE state (`ATOL_SCALE`)."""
    lay = layout
    s = np.empty(lay.nx)
    s[:] = ATOL_SCALE["rigid"]
    s[9:lay.nq] = ATOL_SCALE["modal"]
    s[lay.ns:2 * lay.ns] = ATOL_SCALE["rigid_rate"]
    s[lay.ns + 9:lay.ns + lay.nq] = ATOL_SCALE["modal_rate"]
    s[lay.r_O] = ATOL_SCALE["orbit_r"]
    s[lay.v_O] = ATOL_SCALE["orbit_v"]
    s[lay.m_used] = ATOL_SCALE["mass"]
    s[lay.stop_deflection] = ATOL_SCALE["stop_deflection"]
    return rtol * s


@dataclass
class Trbdf2Work:
    """TR-BDF2's iteration matrix, kept between control periods (trbdf2.integrate_trbdf2):
    the Jacobian J, (I − d h J)⁻¹ and the `work` slots (W_HAVE_J, W_JACOBIANS …)."""

    jac: np.ndarray
    minv: np.ndarray
    work: np.ndarray

    @classmethod
    def empty(cls, nx: int) -> "Trbdf2Work":
        return cls(jac=np.zeros((nx, nx)), minv=np.zeros((nx, nx)), work=np.zeros(N_WORK))


@dataclass
class ImexWork:
    """The IMEX integrator's stiff components and its kept matrices (imex.integrate_ark):
    the frozen Jacobian columns L, W⁻¹ and the `work` slots (W_HAVE_L, W_JACOBIANS …)."""

    stiff: np.ndarray
    L: np.ndarray
    Winv: np.ndarray
    work: np.ndarray

    @classmethod
    def for_model(cls, model: ReferenceModel, cfg: Configuration) -> "ImexWork":
        """The stiff set of the model in the bases of `cfg` (imex.stiff_indices) and empty storage."""
        lay = model.layout
        arrays = model.arrays
        k_diag, m_diag = [], []
        for i, n in enumerate(lay.n_modes):
            if model.condensed:
                n = model.n_eigen[i]  # the condensed static shapes are not states
            b = cfg.basis[i]
            k_diag.append(np.diag(arrays.k_ff[i, b])[:n])
            m_diag.append(np.diag(arrays.m_ff[i, b])[:n])
        stiff = imex.stiff_indices(k_diag, m_diag, lay.mode_offset, lay.ns)
        n_s = stiff.shape[0]
        return cls(stiff=stiff, L=np.zeros((lay.nx, n_s)), Winv=np.zeros((n_s, n_s)), work=np.zeros(imex.N_WORK))


class Stepper:
    """Advances the ODE state of one model, one control interval at a time.

    Settings, fixed at construction: `integrator` and `quiet_integrator` (names of
    rsmcheck.core.cases.INTEGRATORS), `rtol` and the per-component `atol`, `h_max` (the
    largest step of each integrator, by name), `engine_name` (named in a divergence).
    Owned and updated by `advance`: `h` (the step each integrator carries to its next
    interval: its own, as the quiet integrator's longer steps would only be rejected by
    the explicit one), the counters `steps`, `rejected`, `quiet_steps` (accepted steps of
    the quiet integrator where it is not the `integrator`), `integrator_wall` (s inside
    the compiled integrator, rsmcheck bench), and the implicit integrators' kept
    matrices `trbdf2` and `imex`.
    """

    def __init__(self, model: ReferenceModel, cfg: Configuration, integrator: str, quiet_integrator: str,
                 rtol: float, h_max: dict[str, float], engine_name: str):
        self.integrator = integrator
        self.quiet_integrator = quiet_integrator
        self.rtol = rtol
        self.atol = absolute_tolerance(model.layout, rtol)
        self.h_max = dict(h_max)
        self.engine_name = engine_name
        self.h = {name: 1e-4 for name in (integrator, quiet_integrator)}
        self.steps = 0
        self.rejected = 0
        self.quiet_steps = 0
        self.integrator_wall = 0.0
        self.trbdf2 = Trbdf2Work.empty(model.layout.nx)
        self.imex = ImexWork.for_model(model, cfg)

    def advance(self, model: ReferenceModel, cfg: Configuration, x: np.ndarray, t: float, t_next: float,
                u: np.ndarray, quiet: bool) -> np.ndarray:
        """The state at t_next from x at t with the inputs u held; `quiet`: the interval is a
        quiet segment's (its own, longer control_period), the quiet integrator's
        (docs/physics.md §7).  Raises SimulationDiverged on a non-finite state or a step
        size underflow."""
        args = model.core_args(cfg)
        name = self.quiet_integrator if quiet else self.integrator
        h0, h_max = self.h[name], self.h_max[name]
        tic = time.perf_counter()
        if name == "dopri5":
            x_next, h, nacc, nrej, status = integrate_dopri5(
                x, t, t_next, h0, self.rtol, self.atol, h_max, u, *args)
        elif name == "imex":
            w = self.imex
            x_next, h, nacc, nrej, status = imex.integrate_ark(
                x, t, t_next, h0, self.rtol, self.atol, h_max, w.stiff, w.L,
                w.Winv, w.work, imex.REFRESH_S, u, *args)
        else:
            w = self.trbdf2
            x_next, h, nacc, nrej, status = integrate_trbdf2(
                x, t, t_next, h0, self.rtol, self.atol, h_max, w.jac,
                w.minv, w.work, u, *args)
        self.integrator_wall += time.perf_counter() - tic
        self.steps += nacc
        self.rejected += nrej
        if quiet and name != self.integrator:
            self.quiet_steps += nacc
        if status != 0 or not np.all(np.isfinite(x_next)):
            finite = np.isfinite(x_next)
            bad = int(np.argmax(~finite)) if not np.all(finite) else int(np.argmax(np.abs(x_next)))
            raise SimulationDiverged(self.engine_name, t, "?", f"state[{bad}] "
                                     + ("non-finite" if status == 1 else "step size underflow"), float(x_next[bad]))
        self.h[name] = h
        return x_next

    def new_system(self) -> None:
        """The system changed (a capture or release): the next implicit step needs a new Jacobian."""
        self.trbdf2.work[W_HAVE_J] = 0.0
        self.imex.work[imex.W_HAVE_L] = 0.0

    def jacobians(self) -> int:
        """TR-BDF2 Jacobians computed so far."""
        return int(self.trbdf2.work[W_JACOBIANS])
