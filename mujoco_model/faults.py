"""The MuJoCo model's fault catalogue: plausible bugs in this engine's own code, for the
fault-injection matrix (`make faults`).  Each is one exact text that occurs once in its
file (paths relative to the tree's root), replaced by a wrong one."""

from __future__ import annotations

from rsmcheck.core.plugins import Fault

FAULTS: tuple[Fault, ...] = (
    Fault("mj_rotor_armature", "mujoco_model/build.py",
          'armature="{mo.inertia!r}"', 'armature="{0.9 * mo.inertia!r}"',
          "MuJoCo: gear-motor rotor inertia B_m 10 % low"),
    Fault("mj_frame_inertia", "mujoco_model/build.py",
          "    return p.link.inertia_extra\n", "    return 0.0\n",
          "MuJoCo: the links' extra rotary inertia J_extra (frame tendon armature) left out"),
    Fault("mj_reaction_sign", "mujoco_model/switching.py",
          "out[2 * k:2 * k + 2] = -forces[rows[:2]]", "out[2 * k:2 * k + 2] = forces[rows[:2]]",
          "MuJoCo: reaction_forces_I read as the force on the end effector instead of the target"),
)
