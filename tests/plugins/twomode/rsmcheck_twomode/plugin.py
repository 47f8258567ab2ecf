"""The rsmcheck engine plug-in `twomode` (entry point ``rsmcheck.engines``, pyproject.toml).

Imported to read case files: it imports rsmcheck.core and its own settings only; the model
(numba) loads in `make`.
"""

from __future__ import annotations

from dataclasses import replace

from rsmcheck.core.plugins import LineStyle, WorkCounter
from rsmcheck_twomode import settings


class TwomodePlugin:
    name = "twomode"
    label = "two modes"
    style = LineStyle("#17becf", "dashdot")
    simulates = True
    #: numba comes with rsmcheck; the reference model is part of rsmcheck's base install
    requires = ("numba",)
    extra = None
    #: this distribution's version goes into a run's provenance
    distributions = ("rsmcheck-twomode",)
    tables = ("twomode",)
    solver_keys = ()
    work_counters = (WorkCounter("attempted steps", ("steps", "rejected_steps")),
                     WorkCounter("Jacobians", ("jacobians",)))
    #: `rsmcheck check --option twomode:KEY=VALUE` (static_modes is fixed: off)
    engine_options = ("n_modes", "rtol", "h_max")
    # optional capabilities: none
    linear_plant = None
    coupled_frequencies = None
    link_frequencies = None
    rhs_timing = None
    rigid_options = None
    analytic_tests = ()

    def parse_settings(self, tables, solver, where, key):
        return settings.parse(tables, where, key)

    def make(self, case, start=None, **options):
        from rsmcheck_twomode.engine import make

        return make(case, start=start, **options)

    def step_perturbed(self, s, factor):
        """The relative tolerance scaled: another sequence of accepted and rejected steps."""
        return replace(s, rtol=s.rtol * factor)

    def faults(self):
        return ()


PLUGIN = TwomodePlugin()
