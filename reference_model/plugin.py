"""The reference model as an rsmcheck engine plug-in (rsmcheck.core.plugins): registered in
pyproject.toml under the entry-point group ``rsmcheck.engines`` as ``reference``.

This module is imported to read case files: it imports the settings schema only; the model
(numba-compiled) loads when an engine, a linearisation or a timing is asked for.
"""

from __future__ import annotations

from dataclasses import replace

from reference_model import settings
from reference_model.faults import FAULTS
from rsmcheck.core.plugins import LineStyle, WorkCounter, deferred, settings_of


class ReferencePlugin:
    name = "reference"
    label = "reference"
    style = LineStyle("#1f77b4", "solid")
    simulates = True
    requires = ("numba",)
    extra = None
    tables = ("reference",)
    solver_keys = ("rtol", "integrator")
    work_counters = (WorkCounter("attempted steps", ("steps", "rejected_steps")),
                     WorkCounter("Jacobians", ("jacobians",)))
    #: constructor options of the rigid model (no modes, no static shapes): the bench's rigid
    #: right-hand side, the rigid studies
    rigid_options = {"n_modes": 0, "static_modes": False}
    #: the model's tests against analytic references (conservation of energy and momentum,
    #: the Baumgarte decay of eq. (12), Table 2's frequencies) and of the slaved shapes
    #: against their definition (the explicit shapes' static equilibrium, the stop's law at
    #: the slaved wrist): the fault matrix runs them
    analytic_tests = ("tests/reference_model/test_conservation.py", "tests/reference_model/test_link_modes.py",
                      "tests/reference_model/test_condense.py::"
                      "test_condensed_shapes_are_the_explicit_shapes_static_equilibrium",
                      "tests/reference_model/test_condense.py::test_stop_torque_is_the_stop_law_at_the_slaved_wrist")
    #: the engine's constructor options (`rsmcheck check --option reference:KEY=VALUE`)
    engine_options = ("n_modes", "rtol", "integrator", "h_max", "static_modes", "quiet_integrator")
    #: short runs that compile the kernels (rsmcheck.orchestration.kernels), a group per
    #: process: each integrator's loop inlines the whole right-hand side, so the explicit
    #: pair (open and closed chains, slaved and explicit shapes, orbit and thrust, a motion
    #: programme) and the two implicit integrators compile side by side
    kernel_runs = ((("free_drift", {}), ("thrust_burn", {}), ("wrist_bistop", {}), ("capture", {}),
                    ("p1_transport", {})),
                   (("free_drift", {"integrator": "trbdf2"}),
                    ("free_drift", {"integrator": "imex", "static_modes": "explicit"})))

    def parse_settings(self, tables, solver, where, key):
        return settings.parse(tables, solver, where, key)

    def make(self, case, start=None, **options):
        from reference_model.engine import ReferenceEngine

        return ReferenceEngine(case, start=start, **options)

    def step_perturbed(self, s, factor):
        """The relative tolerance scaled: another sequence of accepted and rejected steps."""
        return replace(s, rtol=s.rtol * factor)

    def faults(self):
        return FAULTS

    #: what `refined_options` refines, for the tables of `rsmcheck budget`
    refinement = "rtol/10, h ≤ Δt/2"

    def refined_options(self, case):
        """The constructor options of a finer run of `case` (the variant to run): the
        relative tolerance of every integrator a tenth of the case's (the absolute ones
        follow it, reference_model/stepper.py) and the largest step half the control
        period.  The step bound matters: with the static shapes slaved DP5 often takes one
        step per sample, well inside rtol, and a tenth of rtol alone then repeats the same
        steps to the bit (a zero error that is no estimate).  `rsmcheck budget` takes the
        difference to that run as the engine's integration error."""
        given = settings_of(case, self.name)
        h_max = min(given.h_max or case.solver.control_period, case.solver.control_period) / 2
        return {"rtol": given.rtol / 10, "h_max": h_max}

    #: what `finer_options` refines, for the tables of `rsmcheck fuzz`
    finer = "2 more eigenmodes per link, rtol/10, h ≤ Δt/2"

    def finer_options(self, case):
        """The constructor options of a run of `case` refined in space and time: two more
        eigenmodes per link (up to the model's six) on top of `refined_options`' step.
        `rsmcheck fuzz` takes the difference to that run as the engine's discretisation
        uncertainty: the modal truncation and the integration error together."""
        from reference_model.build import N_MAX_MODES

        n_modes = tuple(min(n + 2, N_MAX_MODES) for n in settings_of(case, self.name).n_modes)
        return {**self.refined_options(case), "n_modes": n_modes}

    # the engine's own linearisation and timing, imported when called
    linear_plant = deferred("reference_model.modes", "linear_plant")
    coupled_frequencies = deferred("reference_model.modes", "coupled_frequencies")
    rhs_timing = deferred("reference_model.stepping", "rhs_timing")
    link_frequencies = deferred("reference_model.beam_modes", "link_frequencies")


PLUGIN = ReferencePlugin()
