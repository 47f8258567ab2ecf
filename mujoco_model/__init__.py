"""The paper's robot built from MuJoCo's own elements (chains of rigid segments, hinges,
armature, tendons, a switched `connect` equality): a third engine, independent of the
reference model and of the Exudyn model (docs/mujoco.md)."""
