"""The Exudyn model's fault catalogue: plausible bugs in this engine's own code, for the fault-injection matrix
(`make faults`, rsmcheck.orchestration.faults).  Each is one exact text that occurs once in
its file (paths relative to the tree's root), replaced by a wrong one."""

from __future__ import annotations

from rsmcheck.core.plugins import Fault

FAULTS: tuple[Fault, ...] = (
    Fault("exu_rotor_inertia", "exudyn_model/build.py",
          "M[6, 6] = mo.inertia", "M[6, 6] = 0.9 * mo.inertia",
          "Exudyn: gear-motor rotor inertia B_m 10 % low"),
    Fault("exu_hub_inertia", "exudyn_model/build.py",
          "inertia=p.link.inertia_extra))", "inertia=0.0))",
          "Exudyn: the links' extra rotary inertia (hub body) left out"),
    Fault("exu_bistop_stiffness", "exudyn_model/build.py",
          "stiffness=w.stiffness, damping=w.contact_damping,",
          "stiffness=0.5 * w.stiffness, damping=w.contact_damping,",
          "Exudyn: wrist bistop stiffness halved"),
    Fault("exu_reaction_sign", "exudyn_model/reactions.py",
          "out[2 * k:2 * k + 2] = forces[k][:2]", "out[2 * k:2 * k + 2] = -forces[k][:2]",
          "Exudyn: reaction_forces_I read on the joint's marker-1 side (−λ, the force on the end "
          "effector) instead of the arm's force on the target"),
    Fault("exu_held_point_rotation", "exudyn_model/switching.py",
          "state.rho_G[k] = rot(XT[2]).T @ (rE[k] - XT[:2])", "state.rho_G[k] = rot(XT[2]) @ (rE[k] - XT[:2])",
          "Exudyn: the held point at a capture taken into the target frame by A(θ_T) instead of "
          "A(θ_T)ᵀ (off the end effector unless θ_T = 0)"),
)
