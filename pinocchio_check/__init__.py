"""Pinocchio as the independent authority for the rigid part of the reference model.

`model` builds Pinocchio models of the rigid space robot (base, two 3-link arms,
target) from a `rsmcheck.core.params.Params` and maps Pinocchio's quantities into the
reference model's inertial coordinates; `states` draws random states that satisfy the
grasp constraints using Pinocchio's own kinematics; `compare` runs the seeded
comparison against `reference_model` (`rsmcheck pinocchio`).
"""
