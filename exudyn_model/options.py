"""The options of one Exudyn engine, resolved: what `exudyn_model.engine.ExudynEngine`'s
constructor decides from its arguments, the case's [exudyn] table and the defaults, handed
to the parts that need it (the builder, the stepper, the field forces).  Fixed for a run.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EngineOptions:
    """The resolved options (their meaning: `ExudynEngine`'s docstring)."""

    rigid: bool  # rigid links (ObjectRigidBody2D) instead of ANCF cables
    n_elements: int  # ANCF elements per link
    substeps: int  # generalized-α steps per control period
    quiet_substeps: int | None  # steps per interval of a quiet segment, None: the step h
    spectral_radius: float  # ρ∞ of generalized-α
    newton_rtol: float
    newton_atol: float  # [N]
    jacobian_per_step: bool  # a new Newton Jacobian at the start of every step
    jacobian_period: float | None  # [s] of flight between Jacobians, None: when Exudyn asks
    orbit: bool  # the case has an orbit (tidal field about O)
    field: bool  # the field/thrust machinery is built
    restart_on_input_change: bool
    restart_threshold: float  # input jump (fraction of its limit) that restarts
    stepping: str  # "continuous" or "period"
    constraints: str  # "index3" or "index2"
    axial_damping: float  # factor on the links' axial damping η·EA
    dt: float  # the case's control period [s]

    @property
    def h(self) -> float:
        """The generalized-α step of a control period [s]: dt/substeps."""
        return self.dt / self.substeps
