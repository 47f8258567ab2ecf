"""The Exudyn model as an rsmcheck engine plug-in (rsmcheck.core.plugins): registered in
pyproject.toml under the entry-point group ``rsmcheck.engines`` as ``exudyn``; its library
comes with the extra ``rsmcheck[exudyn]``.

This module is imported to read case files: it imports the settings schema only, not Exudyn.
"""

from __future__ import annotations

from dataclasses import replace

from exudyn_model import settings
from exudyn_model.faults import FAULTS
from rsmcheck.core.plugins import LineStyle, WorkCounter, deferred, settings_of


class ExudynPlugin:
    name = "exudyn"
    label = "Exudyn"
    style = LineStyle("#ff7f0e", "dash")
    simulates = True
    requires = ("exudyn", "numba")
    extra = "exudyn"
    #: the distributions that bring `requires` (a run's provenance records their versions)
    distributions = ("exudyn",)
    tables = ("exudyn",)
    solver_keys = ()
    work_counters = (WorkCounter("steps", ("steps",)), WorkCounter("Newton iterations", ("newton_iterations",)),
                     WorkCounter("Jacobians", ("jacobians",)))
    rigid_options = None
    analytic_tests = ()
    #: the engine's constructor options (`rsmcheck check --option exudyn:KEY=VALUE`)
    engine_options = ("rigid", "n_elements", "substeps", "quiet_substeps", "spectral_radius", "newton_rtol",
                      "newton_atol", "jacobian_per_step", "jacobian_period", "field", "restart_on_input_change",
                      "stepping", "constraints", "axial_damping", "restart_threshold")

    #: short runs that compile the kernels (rsmcheck.orchestration.kernels): the sensors and
    #: observables of open and closed chains, the tidal field and the thrust
    kernel_runs = ((("free_drift", {}), ("thrust_burn", {}), ("capture", {})),)

    def parse_settings(self, tables, solver, where, key):
        return settings.parse(tables, solver, where, key)

    def make(self, case, start=None, **options):
        from exudyn_model.engine import ExudynEngine

        return ExudynEngine(case, start=start, **options)

    def step_perturbed(self, s, factor):
        """The absolute Newton tolerance scaled, whichever it is: other steps where the
        iteration stops."""
        return replace(s, newton_atol_scale=(s.newton_atol_scale or 1.0) * factor)

    def faults(self):
        return FAULTS

    #: what `refined_options` refines, for the tables of `rsmcheck budget`
    refinement = "half step"

    def refined_options(self, case):
        """The constructor options of a finer run of `case` (the variant to run): twice the
        generalized-α steps per control period of the case's (its [exudyn] substeps, else
        the engine's default), i.e. half the step; mesh and Newton tolerances stay the
        case's.  `rsmcheck budget` takes the difference to that run as the engine's
        integration error."""
        return {"substeps": 2 * (settings_of(case, self.name).substeps or self.option_default("substeps"))}

    #: what `finer_options` refines, for the tables of `rsmcheck fuzz`
    finer = "1.5× elements per link, half the step"

    def finer_options(self, case):
        """The constructor options of a run of `case` refined in space and time: half as many
        ANCF elements per link again (8 → 12) on top of `refined_options`' half step.
        `rsmcheck fuzz` takes the difference to that run as the engine's discretisation
        uncertainty.  Not twice the elements: 16 cost 2.6× the run of 8, 12 cost 1.7×
        (measured with a Jacobian per step), and 8 → 12 still measures the mesh error to a
        factor 1/(1 − (8/12)²) = 1.8 for a second-order error, which fuzz's factor 3 covers."""
        from exudyn_model import links

        n = settings_of(case, self.name).n_elements or links.N_ELEMENTS_DEFAULT
        return {**self.refined_options(case), "n_elements": n + n // 2}

    # the engine's own linearisation and timing, imported when called
    linear_plant = deferred("exudyn_model.modes", "linear_plant")
    coupled_frequencies = deferred("exudyn_model.modes", "coupled_frequencies")
    rhs_timing = deferred("exudyn_model.stepping", "rhs_timing")

    def link_frequencies(self, params, basis, n=2, **options):
        """The first `n` bending frequencies [Hz] of one meshed link in `basis`."""
        from exudyn_model import links

        return links.link_frequencies(params, basis, options.get("n_elements") or links.N_ELEMENTS_DEFAULT, n)

    def option_default(self, key):
        """The engine's default of constructor option `key` (e.g. "substeps")."""
        from exudyn_model import engine

        return {"substeps": engine.SUBSTEPS_DEFAULT}[key]


PLUGIN = ExudynPlugin()
