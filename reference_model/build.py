"""Building the reference model: parameters → the arrays of the compiled kernels
(model_arrays.py), and named access.

`ReferenceModel(params, n_modes)` fixes the number of modes per link (an int for all six
links, or a sequence of six).  The modal basis of each link (PP or PF) is part of the
*configuration* (`Configuration`): it changes at capture and release (docs/physics.md §4).

The methods below the simulation API are the quantities that `pinocchio_check` compares
(rigid Jacobians, mass matrices, closed-loop dynamics); they are thin views on the same
compiled functions the simulation uses, so the check checks what runs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from reference_model import condense, kinematics, measures, ode, solve, system
from reference_model.beam_modes import PF, PP, ModalBasis, modal_basis
from reference_model.model_arrays import (
    ModelArrays, N_INPUTS, N_LINKS, N_SCALARS, S_ALPHA, S_BETA, S_BM, S_CM, S_ETA, S_I0, S_ISPG0, S_JB,
    S_JEX, S_JT, S_KM, S_L, S_MB0, S_ML, S_MT, S_MTOT0, S_MU, S_ORBIT, S_RHO, S_WC, S_WK, S_WLAM, S_WLIM,
    Switches, U_TAU_B)
from rsmcheck.core.geometry import rot
from rsmcheck.driver.initial import InitialConfiguration
from rsmcheck.core.params import Params

N_MAX_MODES = 6
#: static correction shapes per flexible link when they are on (one per end couple)
N_STATIC = 2
#: how the static correction shapes enter (docs/physics.md §2.4): "condensed" (massless,
#: solved from the springs at every right-hand side: condense.py), "explicit" (Ritz
#: coordinates with their inertia, states of the ODE) or "off"
STATIC_SHAPES = ("condensed", "explicit", "off")
STATIC_MODES_DEFAULT = "condensed"


def static_shapes(value) -> str:
    """The `static_modes` option as one of STATIC_SHAPES: a name, or a flag (True: the
    default way, "condensed"; False: "off")."""
    if isinstance(value, (bool, np.bool_)):
        return STATIC_MODES_DEFAULT if value else "off"
    if value not in STATIC_SHAPES:
        raise ValueError(f"static_modes must be one of {STATIC_SHAPES} or a flag, got {value!r}")
    return str(value)


@dataclass(frozen=True)
class Layout:
    """Index ranges of the ODE state x = [Y*, Ẏ*, r_O, v_O, m_used, e] (model_arrays module doc)."""

    nq: int
    n_modes: tuple[int, ...]
    mode_offset: tuple[int, ...]

    @property
    def ny(self) -> int:
        return self.nq + 3

    @property
    def ns(self) -> int:
        return self.ny + 6

    @property
    def nx(self) -> int:
        return 2 * self.ns + 7

    # position blocks
    @property
    def q(self) -> slice:
        return slice(0, self.nq)

    @property
    def target(self) -> slice:
        return slice(self.nq, self.ny)

    @property
    def motors(self) -> slice:
        return slice(self.ny, self.ns)

    # velocity blocks
    @property
    def qd(self) -> slice:
        return slice(self.ns, self.ns + self.nq)

    @property
    def target_d(self) -> slice:
        return slice(self.ns + self.nq, self.ns + self.ny)

    @property
    def motors_d(self) -> slice:
        return slice(self.ns + self.ny, 2 * self.ns)

    @property
    def r_O(self) -> slice:
        return slice(2 * self.ns, 2 * self.ns + 2)

    @property
    def v_O(self) -> slice:
        return slice(2 * self.ns + 2, 2 * self.ns + 4)

    @property
    def m_used(self) -> int:
        return 2 * self.ns + 4

    @property
    def stop_deflection(self) -> slice:
        """e of both arms: the terminal link's deflection under its wrist stop, a state with
        the static shapes condensed (condense.py), zero otherwise."""
        return slice(2 * self.ns + 5, 2 * self.ns + 7)

    def modes(self, link: int) -> slice:
        """Amplitudes of link 0..5 inside q."""
        return slice(self.mode_offset[link], self.mode_offset[link] + self.n_modes[link])


@dataclass
class Configuration:
    """The switching part of the model: which arm holds the target, where, in which basis.

    grasp_on[k]  1 where arm k+1 holds the target
    rho_G[k]     held point, target frame relative to the target COM [m]
    basis[i]     PP or PF for link i (terminal links: PF when their arm is free)
    """

    grasp_on: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    rho_G: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    basis: np.ndarray = field(default_factory=lambda: np.array([PP, PP, PF, PP, PP, PF], dtype=np.int64))

    def copy(self) -> "Configuration":
        return Configuration(self.grasp_on.copy(), self.rho_G.copy(), self.basis.copy())


def terminal_basis(grasp_on: Sequence[int]) -> np.ndarray:
    """Basis of every link for a grasp state: inner links PP; terminal PP if holding, else PF."""
    return np.array([PP, PP, PP if grasp_on[0] else PF, PP, PP, PP if grasp_on[1] else PF],
                    dtype=np.int64)


class ReferenceModel:
    """The Kane–Newton model of the paper built from `params`.

    n_modes:      eigenmodes per link, one int for all or six ints (0 = rigid link).
    static_modes: the two static correction shapes (the response to unit end couples,
                  docs/physics.md §2.4) of every flexible link: "condensed" (the default),
                  "explicit", "off" (`static_shapes`).  Condensed, they keep their slots in
                  q (after the link's eigenmodes) but are not states: `complete` fills them.
    orbit:        tidal gravity about the co-moving reference point on (True) or off.
    """

    def __init__(self, params: Params, n_modes: int | Sequence[int] = 2, orbit: bool = False,
                 static_modes: bool | str = STATIC_MODES_DEFAULT):
        if isinstance(n_modes, (int, np.integer)):
            n_modes = (int(n_modes),) * N_LINKS
        n_eigen = tuple(int(n) for n in n_modes)
        if len(n_eigen) != N_LINKS or any(n < 0 or n > N_MAX_MODES for n in n_eigen):
            raise ValueError(f"n_modes must be 6 integers in 0..{N_MAX_MODES}, got {n_eigen}")
        self.params = params
        self.orbit = orbit
        self.static_shapes = static_shapes(static_modes)
        self.static_modes = self.static_shapes != "off"
        self.condensed = self.static_shapes == "condensed"
        self.n_eigen = n_eigen
        lk = params.link
        n_static = N_STATIC if self.static_modes else 0
        #: bases[i][kind]: the modal basis of link i in basis kind (PP, PF)
        self.bases: list[dict[int, ModalBasis]] = [
            {kind: modal_basis(kind, n, lk.length, lk.rho_a, lk.ei, n_static if n else 0) for kind in (PP, PF)}
            for n in n_eigen]
        shapes = tuple(b[PP].n for b in self.bases)
        offsets = tuple(9 + sum(shapes[:i]) for i in range(N_LINKS))
        self.layout = Layout(nq=9 + sum(shapes), n_modes=shapes, mode_offset=offsets)
        self.arrays = self._pack()

    # ---- packing -------------------------------------------------------------------
    def _pack(self) -> ModelArrays:
        p = self.params
        lk = p.link
        sc = np.zeros(N_SCALARS)
        sc[S_MB0] = p.base.mass
        sc[S_JB] = p.base.inertia_z
        sc[S_MT] = p.target.mass
        sc[S_JT] = p.target.inertia_z
        sc[S_ML] = lk.mass
        sc[S_L] = lk.length
        sc[S_RHO] = lk.rho_a
        sc[S_I0] = lk.mass * lk.length**2 / 3.0
        sc[S_JEX] = lk.inertia_extra
        sc[S_ETA] = lk.kelvin_voigt_eta
        sc[S_BM] = p.motor.inertia
        sc[S_KM] = p.motor.stiffness
        sc[S_CM] = p.motor.damping
        sc[S_ALPHA] = p.grasp.baumgarte_alpha
        sc[S_BETA] = p.grasp.baumgarte_beta
        sc[S_WLIM] = p.wrist.limit
        sc[S_WK] = p.wrist.stiffness
        sc[S_WC] = p.wrist.damping
        sc[S_WLAM] = p.wrist.contact_damping
        sc[S_MU] = p.orbit.mu
        sc[S_ISPG0] = p.actuators.isp * p.actuators.g0
        sc[S_ORBIT] = 1.0 if self.orbit else 0.0
        sc[S_MTOT0] = p.base.mass + p.target.mass + 6 * lk.mass
        nmax = max(max(self.layout.n_modes), 1)

        def stack(attr: str) -> np.ndarray:
            """(6, 2, ...) array of a ModalBasis attribute over links and bases; the shape
            index (last axis) zero-padded to nmax."""
            lead = getattr(self.bases[0][PP], attr).shape[:-1]
            if attr in ("m_ff", "k_ff"):
                lead = (nmax,)
            out = np.zeros((N_LINKS, 2) + lead + (nmax,))
            for i in range(N_LINKS):
                for kind in (PP, PF):
                    v = getattr(self.bases[i][kind], attr)
                    out[(i, kind) + tuple(slice(0, d) for d in v.shape)] = v
            return out

        phi_tip = stack("phi_tip")
        phi_tip[:, PP] = 0.0  # φ(L) = 0 exactly: the PP chord frame passes through both pins
        mount = np.array([p.geometry.mount_B(1), p.geometry.mount_B(2)], dtype=float)
        ref = self.bases[0][PP]
        nm = np.array(self.layout.n_modes, dtype=np.int64)
        ne = np.array(self.n_eigen, dtype=np.int64)
        mo = np.array(self.layout.mode_offset, dtype=np.int64)
        order, first = solve.elimination_order(self.layout.nq, nm, mo, ne if self.condensed else nm,
                                               rotors=self.condensed)
        arrays = ModelArrays(
            nq=self.layout.nq, sc=sc,
            nm=nm, ne=ne if self.static_modes else nm, cond=1 if self.condensed else 0, mo=mo,
            phi_bar=stack("phi_bar"), phi_x=stack("phi_x"), m_ff=stack("m_ff"), k_ff=stack("k_ff"),
            phi_tip=phi_tip, slope_0=stack("slope_0"), slope_L=stack("slope_L"),
            phi_g=stack("phi_gauss"), x_g=ref.x_gauss.copy(), w_g=ref.w_gauss.copy(), mount=mount,
            order=order, first=first, sl_T=np.zeros((2, 2, condense.N_ARM, condense.N_COLS)),
            sl_g=np.zeros((2, 2, condense.N_ARM)), sl_h=np.zeros((2, 2)), sl_kg=np.zeros((2, 2, condense.N_ARM)),
            sl_ce=np.zeros((2, 2)), sl_dw=np.zeros((2, 2, condense.N_ARM)),
            sl_cols=np.zeros((2, condense.N_COLS), dtype=np.int64), sl_ncol=np.zeros(2, dtype=np.int64))
        if self.condensed:
            T, g, h, kg, ce, dw, cols, ncol = condense.slaving_tables(arrays)
            arrays = arrays._replace(sl_T=T, sl_g=g, sl_h=h, sl_kg=kg, sl_ce=ce, sl_dw=dw, sl_cols=cols,
                                     sl_ncol=ncol)
        return arrays

    @property
    def scalars(self) -> np.ndarray:
        return self.arrays.sc

    def switches(self, cfg: Configuration) -> Switches:
        return Switches(cfg.basis, cfg.grasp_on, cfg.rho_G)

    def core_args(self, cfg: Configuration) -> tuple:
        """Arguments of `ode.rhs`/`system.assemble` after (x, u): model arrays, switches."""
        return self.arrays, self.switches(cfg)

    def kinematics(self, q: np.ndarray, qd: np.ndarray, cfg: Configuration) -> kinematics.Kinematics:
        """`kinematics.kinematics` for this model (frames, Jacobians, end effectors; `kin.th`, `kin.rE` …)."""
        return kinematics.kinematics(np.asarray(q, float), np.asarray(qd, float), self.arrays, cfg.basis)

    def joint_section_angles(self, q: np.ndarray, qd: np.ndarray, cfg: Configuration) -> tuple:
        """ψ_J and ψ̇_J of the six joints (docs/physics.md §3.3)."""
        return kinematics.joint_section_angles(np.asarray(q, float), np.asarray(qd, float), self.arrays, cfg.basis)

    # ---- state helpers -------------------------------------------------------------
    def zero_state(self) -> np.ndarray:
        x = np.zeros(self.layout.nx)
        return x

    def assemble(self, x: np.ndarray, u: np.ndarray, cfg: Configuration) -> tuple:
        return system.assemble(np.asarray(x, float), np.asarray(u, float), *self.core_args(cfg))

    def rhs(self, x: np.ndarray, u: np.ndarray, cfg: Configuration) -> np.ndarray:
        return ode.rhs(np.asarray(x, float), np.asarray(u, float), *self.core_args(cfg))

    def complete(self, x: np.ndarray, cfg: Configuration, settle: bool = False) -> np.ndarray:
        """x with the condensed static shapes' slots filled from the rest of the state and
        the stop deflections in their admissible range (condense.condense; a copy of x when
        the shapes are not condensed); `settle`: the stop deflections where the stop's law
        holds with ė = 0, for a start."""
        xc = measures.completed(np.asarray(x, float), *self.core_args(cfg), settle)
        return xc if self.condensed else np.array(xc, float)

    @property
    def coordinates(self) -> np.ndarray:
        """Indices of Y (= [q, X_T]) that are coordinates: all but the slaved static shapes."""
        o = self.arrays.order
        return np.sort(o[o < self.layout.ny])

    def slaving(self, x: np.ndarray, cfg: Configuration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`condense.condense` as dense arrays: the completed state, T (12 × n_z: ∂a_s/∂z,
        z = [Y, θ_m]) and the q-index of each of its rows (−1: no shape)."""
        xc, Tc, cols, ncol, idx, *_ = condense.condense(np.asarray(x, float), *self.core_args(cfg), False)
        T = np.zeros((2 * condense.N_ARM, self.layout.ny + 6))
        for k in range(2):
            T[condense.N_ARM * k:condense.N_ARM * (k + 1), cols[k, :ncol[k]]] = Tc[k, :, :ncol[k]]
        return xc, T, idx.reshape(-1)

    def reduced(self, x: np.ndarray, u: np.ndarray, cfg: Configuration) -> tuple:
        """`system.assemble_reduced` (slaved static shapes: the system over [Y, θ_m])."""
        return system.assemble_reduced(np.asarray(x, float), np.asarray(u, float), *self.core_args(cfg))

    # ---- quantities checked by Pinocchio (no orbit, no inputs) ----------------------
    def _state(self, q, qd, X_T=None, XT_d=None) -> np.ndarray:
        lay = self.layout
        x = self.zero_state()
        x[lay.q] = q
        x[lay.qd] = qd
        if X_T is not None:
            x[lay.target] = X_T
        if XT_d is not None:
            x[lay.target_d] = XT_d
        # motors at the section angles ψ_J: no spring torque, so u_J enters only where asked for
        psi, psid = self.joint_section_angles(x[lay.q], x[lay.qd], self._cfg_for((False, False)))
        x[lay.motors] = psi
        x[lay.motors_d] = psid
        return x

    def _cfg_for(self, grasp: Sequence[bool]) -> Configuration:
        g = np.array([1 if grasp[0] else 0, 1 if grasp[1] else 0], dtype=np.int64)
        rho = np.array([self.params.geometry.grasp_T(1), self.params.geometry.grasp_T(2)], float)
        return Configuration(grasp_on=g, rho_G=rho, basis=terminal_basis(g))

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Jᵀ M J of the RSM (no target, no rotors), eq. (A.6) [kg, kg·m, kg·m²]."""
        nq = self.layout.nq
        x = self._state(q, np.zeros(nq))
        Mg = self.assemble(x, np.zeros(N_INPUTS), self._cfg_for((False, False)))[0]
        return Mg[:nq, :nq].copy()

    def bias_forces(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Jᵀ M J̇ q̇ − Jᵀ V: the velocity-dependent generalized force on the left-hand side
        of (A.6), without elastic and damping forces (amplitudes must be zero for that)."""
        nq = self.layout.nq
        lay = self.layout
        x = self._state(q, qd)
        f = self.assemble(x, np.zeros(N_INPUTS), self._cfg_for((False, False)))[1][:nq]
        # remove the elastic/Kelvin–Voigt part so the result is purely inertial
        ar = self.arrays
        cfg = self._cfg_for((False, False))
        for i in range(N_LINKS):
            sl = lay.modes(i)
            n = lay.n_modes[i]
            kf = ar.k_ff[i, cfg.basis[i], :n, :n]
            f[sl] += kf @ (q[sl] + ar.sc[S_ETA] * qd[sl])
        return -f

    def point_kinematics(self, q, qd, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, Jacobian (2×nq) and J̇q̇ of end effector 'ee1' or 'ee2', inertial [m]."""
        k = {"ee1": 0, "ee2": 1}[name]
        kin = self.kinematics(q, qd, self._cfg_for((False, False)))
        return kin.rE[k].copy(), kin.JE[k].copy(), kin.cE[k].copy()

    def grasp_point(self, X_T: np.ndarray, arm: int) -> np.ndarray:
        """Inertial position of the designated grasp point of `arm` (1, 2) on the target."""
        rho = np.asarray(self.params.geometry.grasp_T(arm))
        c, s = np.cos(X_T[2]), np.sin(X_T[2])
        return np.array([X_T[0] + c * rho[0] - s * rho[1], X_T[1] + s * rho[0] + c * rho[1]])

    def com(self, q: np.ndarray, X_T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """System COM (RSM + target) and its Jacobian w.r.t. [q, X_T] (2×(nq+3))."""
        nq = self.layout.nq
        cfg = self._cfg_for((False, False))
        kin = self.kinematics(q, np.zeros(nq), cfg)
        th, R, JR, Jth = kin.th, kin.R, kin.JR, kin.Jth
        p = self.params
        m_tot = p.base.mass + p.target.mass + 6 * p.link.mass
        pos = p.base.mass * q[0:2] + p.target.mass * np.asarray(X_T[0:2])
        jac = np.zeros((2, nq + 3))
        jac[0, 0] = jac[1, 1] = p.base.mass
        jac[0, nq] = jac[1, nq + 1] = p.target.mass
        phi_bar = self.arrays.phi_bar
        for i in range(N_LINKS):
            n = self.layout.n_modes[i]
            sl = self.layout.modes(i)
            s1 = np.array([0.5 * p.link.mass * p.link.length, phi_bar[i, cfg.basis[i], :n] @ q[sl]])
            A = rot(th[i])
            pos += p.link.mass * R[i] + A @ s1
            jac[:, :nq] += p.link.mass * JR[i] + np.outer(A @ np.array([-s1[1], s1[0]]), Jth[i])
            jac[:, sl] += np.outer(A[:, 1], phi_bar[i, cfg.basis[i], :n])
        return pos / m_tot, jac / m_tot

    def momentum(self, q, qd, X_T, XT_d) -> np.ndarray:
        """Linear momentum (x, y) and angular momentum about the origin, RSM + target."""
        return measures.momentum(self._state(q, qd, X_T, XT_d), *self.core_args(self._cfg_for((False, False))))

    def constrained_accelerations(self, q, qd, X_T, XT_d, grasp=(True, False), u_J=None,
                                  tau_B: float = 0.0):
        """q̈, Ẍ_T and R_cl (force on the target, inertial; zero where a grasp is off) from
        eqs. (6) and (11) with Baumgarte off, for joint torques u_J on the joint coordinates
        and a base torque τ_B.  Grasp points are the designated ones (Params)."""
        lay = self.layout
        nq = lay.nq
        x = self._state(q, qd, X_T, XT_d)
        if u_J is not None:
            # u_J = −K_m(ψ_J − θ_m) with θ̇_m = ψ̇_J: set the motor angles to produce it
            x[lay.motors] = x[lay.motors] + np.asarray(u_J, float) / self.params.motor.stiffness
        u = np.zeros(N_INPUTS)
        u[U_TAU_B] = tau_B
        cfg = self._cfg_for(grasp)
        sc = self.scalars.copy()
        sc[S_ALPHA] = 0.0
        sc[S_BETA] = 0.0
        sc[S_WK] = 0.0
        sc[S_WC] = 0.0
        sc[S_WLAM] = 0.0
        arrays = self.arrays._replace(sc=sc)  # the stop off: its deflection e is 0
        reduce = system.assemble_reduced if self.condensed else system.assemble
        Mg, f, G, _, _, Bs, *_ = reduce(x, u, arrays, self.switches(cfg))
        ydd, Rc = solve.solve_constrained(Mg, f, G, Bs, arrays)
        R_cl = np.zeros(4)
        row = 0
        for k in range(2):
            if cfg.grasp_on[k]:
                R_cl[2 * k:2 * k + 2] = Rc[row:row + 2]
                row += 2
        return ydd[:nq].copy(), ydd[nq:nq + 3].copy(), R_cl


def initial_state(model: ReferenceModel, init: InitialConfiguration) -> tuple[np.ndarray, Configuration]:
    """ODE state and configuration from shared initial conditions: links undeformed and at
    rest relative to their frames, motors at the joint angles (springs relaxed)."""
    lay = model.layout
    x = model.zero_state()
    x[0:3] = init.base_pose
    x[3:9] = init.joint_angles
    x[lay.target] = init.target_pose
    x[lay.motors] = init.joint_angles
    x[lay.ns:lay.ns + 3] = init.base_rate
    x[lay.ns + 3:lay.ns + 9] = init.joint_rates
    x[lay.target_d] = init.target_rate
    x[lay.motors_d] = init.joint_rates
    x[lay.r_O] = init.orbit_r
    x[lay.v_O] = init.orbit_v
    cfg = Configuration(grasp_on=init.grasp.copy(), rho_G=init.rho_G.copy(), basis=terminal_basis(init.grasp))
    return model.complete(x, cfg, settle=True), cfg
