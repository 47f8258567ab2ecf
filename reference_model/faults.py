"""The reference model's fault catalogue: plausible bugs in this engine's own code, for the fault-injection matrix
(`make faults`, rsmcheck.orchestration.faults).  Each is one exact text that occurs once in
its file (paths relative to the tree's root), replaced by a wrong one."""

from __future__ import annotations

from rsmcheck.core.plugins import Fault

FAULTS: tuple[Fault, ...] = (
    Fault("ref_coriolis_factor", "reference_model/link.py",
          "V[0] = w * w * (c * s1x - s * s1y) + 2.0 * w * c * pbd",
          "V[0] = w * w * (c * s1x - s * s1y) + 1.0 * w * c * pbd",
          "Coriolis term 2θ̇ A S e_y (φ̄·ȧ) of a link's x force with factor 1 instead of 2"),
    Fault("ref_rotary_inertia", "reference_model/link.py",
          "mtt = sc[S_I0] + sc[S_JEX]", "mtt = sc[S_I0]",
          "the links' rotary inertia beyond the slender beam (J_extra) left out"),
    Fault("ref_kelvin_voigt_half", "reference_model/link.py",
          "kf += m.k_ff[i, b, a, e] * (q[o + e] + sc[S_ETA] * qd[o + e])",
          "kf += m.k_ff[i, b, a, e] * (q[o + e] + 0.5 * sc[S_ETA] * qd[o + e])",
          "Kelvin–Voigt coefficient η = ζ/ω₁ instead of 2ζ/ω₁ (half the structural damping)"),
    Fault("ref_tidal_exponent", "reference_model/field.py",
          "f = -math.expm1(-1.5 * math.log1p(qv))", "f = -math.expm1(-1.45 * math.log1p(qv))",
          "gravity-gradient law: (1+q)^(−1.45) instead of (1+q)^(−3/2) (tidal coefficient 2.9 instead of 3)"),
    Fault("ref_mass_flow_g0", "reference_model/ode.py",
          "dx[2 * ns + 4] = u[U_THRUST] / m.sc[S_ISPG0]",
          "dx[2 * ns + 4] = u[U_THRUST] / (m.sc[S_ISPG0] * 9.81 / 9.80665)",
          "mass flow T/(Isp g0) with g0 = 9.81 instead of 9.80665 m/s²"),
    Fault("ref_thrust_direction", "reference_model/system.py",
          "f[0] += mB * aunif[0] + thrust * cb", "f[0] += mB * aunif[0] + thrust * cb * 0.99",
          "thrust x component 1 % short (a misaligned nozzle in one engine only)"),
    Fault("ref_baumgarte_damping", "reference_model/system.py",
          "- 2.0 * sc[S_ALPHA] * phid[row + d]", "- sc[S_ALPHA] * phid[row + d]",
          "Baumgarte eq. (12): φ̈ + α φ̇ + β² φ instead of φ̈ + 2α φ̇ + β² φ"),
    Fault("ref_modal_stiffness", "reference_model/beam_modes.py",
          "k_ff = ei * (phi2.T * w) @ phi2", "k_ff = 1.02 * ei * (phi2.T * w) @ phi2",
          "modal stiffness 2 % high (a wrong EI in the reference's modal integrals)"),
    Fault("ref_modal_mass", "reference_model/beam_modes.py",
          "m_ff = rho_a * (phi.T * w) @ phi", "m_ff = 1.02 * rho_a * (phi.T * w) @ phi",
          "modal mass 2 % high"),
    Fault("ref_basis_switch_drops_momentum", "reference_model/switching.py",
          "switch_basis(model, x, cfg, 3 * k + 2, PF)\n    project_velocities(model, x, cfg, report.dropped_momentum)",
          "switch_basis(model, x, cfg, 3 * k + 2, PF)\n    project_velocities(model, x, cfg, None)",
          "release: the generalised momentum the PF basis cannot carry is dropped, not given back"),
    # ---- the closed chain and the capture (docs/physics.md §4) ----------------------------
    Fault("ref_reaction_sign", "reference_model/observe.py",
          "reaction[2 * k:2 * k + 2] = Rc[row:row + 2]", "reaction[2 * k:2 * k + 2] = -Rc[row:row + 2]",
          "reaction_forces_I reported as −R_cl, the force on the end effector (W = −Gᵀ), "
          "instead of R_cl, the force on the target"),
    Fault("ref_grasp_moment_arm_sign", "reference_model/system.py",
          "G[row, nq + 2] = gy  # −A S ρ_G = −(−gy, gx)", "G[row, nq + 2] = -gy  # −A S ρ_G = −(−gy, gx)",
          "grasp constraint, x row, target-rotation entry −gy instead of gy (a sign of −A S ρ_G slipped): "
          "the moment of the reaction about the target COM (W = −Gᵀ) and φ's Jacobian wrong in one entry"),
    Fault("ref_baumgarte_stiffness", "reference_model/system.py",
          "- sc[S_BETA] ** 2 * phi[row + d])", "- sc[S_BETA] * phi[row + d])",
          "Baumgarte eq. (12): φ̈ + 2α φ̇ + β φ instead of φ̈ + 2α φ̇ + β² φ (stiffness 10 instead of 100 s⁻²)"),
    Fault("ref_impact_euclidean", "reference_model/switching.py",
          "MinvAt = np.linalg.solve(M, A.T)", "MinvAt = A.T",
          "plastic impact projected in the Euclidean metric, Ẏ⁺ = Ẏ − Aᵀ(AAᵀ)⁻¹AẎ, instead of the "
          "kinetic-energy one: the capture's impulse is not internal, momentum is not conserved"),
    # ---- the static shapes slaved, and the wrist stop through them (docs/physics.md §2.4) --
    Fault("ref_condensation_1pct", "reference_model/condense.py",
          "T[k, term, :, :ncol[k]] = np.linalg.solve(Kt, B[:, cols[k, :ncol[k]]])",
          "T[k, term, :, :ncol[k]] = 1.01 * np.linalg.solve(Kt, B[:, cols[k, :ncol[k]]])",
          "slaved shapes: the condensation transform T 1 % large (a_s = T z off the springs' equilibrium)"),
    Fault("ref_stop_compliance", "reference_model/condense.py",
          "h[k, term] = dw @ g[k, term]", "h[k, term] = 0.9 * (dw @ g[k, term])",
          "slaved shapes: the terminal link's compliance under the stop h = d_wᵀ K̃⁻¹ d_w 10 % low"),
    Fault("ref_stop_deflection_damping", "reference_model/condense.py",
          "ce[k, term] = g[k, term] @ kg[k, term] / h[k, term] ** 2",
          "ce[k, term] = 0.5 * g[k, term] @ kg[k, term] / h[k, term] ** 2",
          "slaved shapes: the Kelvin–Voigt damping c_e of the stop deflection halved"),
    Fault("ref_stop_deflection_rate_force", "reference_model/condense.py",
          "fkv[k, r] = m.sl_kg[k, term, r] * s_side * edot[k] / h",
          "fkv[k, r] = 0.0 * m.sl_kg[k, term, r] * s_side * edot[k] / h",
          "slaved shapes: the Kelvin–Voigt force of the stop deflection's rate left off the shapes"),
    Fault("ref_stop_clamp", "reference_model/condense.py",
          "    if e / h + ce * edot - s * x_kv < 0.0:  # the stop would pull: it lets go, push = 0\n"
          "        edot = (s * x_kv - e / h) / ce if ce > 0.0 else 0.0\n"
          "    if e <= 0.0 and edot < 0.0:\n"
          "        edot = 0.0\n"
          "    push = e / h + ce * edot - s * x_kv\n"
          "    return e, edot, -s * max(push, 0.0)\n",
          "    if e <= 0.0 and edot < 0.0:\n"
          "        edot = 0.0\n"
          "    push = e / h + ce * edot - s * x_kv\n"
          "    return e, edot, -s * push\n",
          "slaved shapes: the stop's clamp dropped, in its torque and in the deflection's rate "
          "(the Hunt–Crossley law pulls the target back as it leaves)"),
    # ---- control: a change that changes no arithmetic (a name starting with noop_) -------
    Fault("noop_commuted_sum", "reference_model/link.py",
          "mtt = sc[S_I0] + sc[S_JEX]", "mtt = sc[S_JEX] + sc[S_I0]",
          "control: a commuted sum (exact in IEEE arithmetic); must be caught by nothing"),
)
