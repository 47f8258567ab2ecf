"""The data the compiled kernels share: plain arrays in, plain arrays out.

Read next to the paper (Sect. 2, Appendix) and docs/physics.md.  The kernels are
`numba.njit` functions on arrays (kinematics.py, link.py, system.py, solve.py, ode.py,
measures.py); `reference_model.build` builds the arrays and gives them names.  The model's
constant arrays travel as one named tuple `ModelArrays`, the switching state (bases,
grasps, held points) as `Switches`.  A compiled call that is not inlined copies such a
tuple and counts a reference to each of its arrays (17 atomic increments and decrements):
the helpers of the right-hand side that take it are therefore `inline="always"` (half the
cost of the rigid RHS).

Coordinates (docs/physics.md §1)
-------------------------------
q_m  = [x_B, y_B, θ_B, θ_J1..θ_J6, a_link1.., .., a_link6..]      (nq)   eq. (4) ordering
X_T  = [x_T, y_T, θ_T]                                             (3)
θ_m  = six motor angles, relative to the parent end section       (6)
Y    = [q_m, X_T] (ny = nq + 3),  Y* = [Y, θ_m] (ns = ny + 6)      eq. (7)
ODE state x = [Y*, Ẏ*, r_O (2), v_O (2), m_used, e (2)]: r_O, v_O are the co-moving
reference point (docs/physics.md §5), m_used the propellant burnt, e the terminal links'
deflection under the wrist stops with the static shapes condensed (condense.py; zero
otherwise).

Newtonian coordinates of a link (the X_m of eq. A.1): X_i = [R_i (2), θ_i, a_i (n_i)] —
origin of the link frame (its proximal pin), frame angle, modal amplitudes.  A material
point at abscissa ξ is at r = R + A(θ) u(ξ), u = (ξ, w(ξ)), w = Σ a_j φ_j (eq. 1); its
cross-section is turned by θ + w'(ξ).  (A(·) is the 2×2 rotation; the constraint Jacobian
of eq. 8 is called `G` here to keep the letters apart.)

Joints (docs/physics.md §3.3): a joint is a hinge between two end sections.  Its
section-relative angle is ψ_J = θ_J + w_child'(0) − w_parent'(L) (the parent of the first
joint is the rigid base), the spring-damper of eq. (5) acts on ψ_J − θ_m, and its
generalised force u_J ∂ψ_J/∂q puts u_J on θ_J and the paper's u_e (eq. 4) on the
amplitudes of both links.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

# --- indices into the scalar parameter vector `sc` -----------------------------------
S_MB0 = 0  # base mass at t = 0 [kg]
S_JB = 1  # base inertia about COM [kg m²]
S_MT = 2  # target mass
S_JT = 3  # target inertia about COM
S_ML = 4  # link mass
S_L = 5  # link length
S_RHO = 6  # ρA [kg/m]
S_I0 = 7  # ∫ρ ξ² dξ = m L²/3, link about its pin
S_JEX = 8  # rotary inertia beyond the slender beam, on the frame rotation
S_ETA = 9  # Kelvin–Voigt coefficient η [s]
S_BM = 10  # motor inertia B_m
S_KM = 11  # K_m
S_CM = 12  # C_m
S_ALPHA = 13  # Baumgarte α
S_BETA = 14  # Baumgarte β
S_WLIM = 15  # wrist bistop half-range
S_WK = 16  # wrist bistop stiffness
S_WC = 17  # wrist bistop damping
S_MU = 18  # Earth μ
S_ISPG0 = 19  # Isp·g0 [m/s]
S_ORBIT = 20  # 1.0: tidal gravity on, 0.0: off
S_MTOT0 = 21  # total mass at t = 0
S_WLAM = 22  # wrist bistop Hunt–Crossley damping λ [N·m·s/rad²]
N_SCALARS = 23

# --- inputs u (held constant over a control period) ----------------------------------
U_TAU_M = 0  # 6 motor torques (after saturation)
U_TAU_B = 6  # base torque
U_THRUST = 7  # thrust magnitude along +x_B
N_INPUTS = 8

N_LINKS = 6

#: The model's constant arrays.  Per link i and basis b (PP = 0, PF = 1), shape index a:
#:   phi_bar[i, b, a] = ∫ρφ_a dξ,  phi_x = ∫ρξφ_a dξ,  m_ff[i, b] = ∫ρφφᵀ,  k_ff = ∫EIφ''φ''ᵀ,
#:   phi_tip = φ_a(L),  slope_0 = φ_a'(0),  slope_L = φ_a'(L),  phi_g[i, b, g, a] = φ_a(x_g[g]);
#:   nm[i] shapes of link i, starting at q[mo[i]]; mount[k] the root of arm k (base frame);
#:   ne[i] ≤ nm[i] of them eigenmodes, the rest (nm[i] − ne[i], 0 or 2) static shapes;
#:   cond = 1: the static shapes are condensed (condense.py: slaved to the rest of the
#:   state by the springs' equilibrium, with their mass), 0: they are states;
#:   order, first: elimination order and envelope of the mass matrix (`elimination_order`),
#:   over the coordinates (with condensed shapes: z = [Y, θ_m] without them);
#:   sl_T, sl_g, sl_h, sl_kg, sl_ce, sl_dw, sl_cols, sl_ncol: the slaving of the condensed shapes per
#:   arm and terminal basis (condense.slaving_tables).
ModelArrays = namedtuple("ModelArrays", [
    "nq", "sc", "nm", "ne", "cond", "mo", "phi_bar", "phi_x", "m_ff", "k_ff", "phi_tip", "slope_0", "slope_L",
    "phi_g", "x_g", "w_g", "mount", "order", "first", "sl_T", "sl_g", "sl_h", "sl_kg", "sl_ce", "sl_dw", "sl_cols",
    "sl_ncol"])
#: The switching part: basis[i] of each link, grasp_on[k], held points rho_G[k] (target frame).
Switches = namedtuple("Switches", ["basis", "grasp_on", "rho_G"])


def input_vector(inputs) -> np.ndarray:
    """The held inputs (rsmcheck.core.engine.Inputs) as the kernels' input vector u
    (τ_m, τ_B, thrust)."""
    u = np.zeros(N_INPUTS)
    u[U_TAU_M:U_TAU_M + 6] = inputs.tau_m
    u[U_TAU_B] = inputs.tau_B
    u[U_THRUST] = inputs.thrust
    return u
