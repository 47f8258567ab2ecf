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
)
