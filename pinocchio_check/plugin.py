"""Pinocchio as an rsmcheck plug-in that checks and does not simulate
(rsmcheck.core.plugins): registered under the entry-point group ``rsmcheck.engines`` as
``pinocchio``; its library comes with the extra ``rsmcheck[pinocchio]``.  It offers the
seeded rigid checks of the reference model (`rigid_checks`, `rsmcheck pinocchio`) and the
time of one articulated-body call (`aba_timing`, `rsmcheck bench`).
"""

from __future__ import annotations

from rsmcheck.core.plugins import LineStyle


class PinocchioPlugin:
    name = "pinocchio"
    label = "Pinocchio"
    style = LineStyle("#2ca02c", "dot")
    simulates = False
    requires = ("pinocchio",)
    extra = "pinocchio"
    #: the distributions that bring `requires` (a run's provenance records their versions)
    distributions = ("pin",)
    tables = ()
    solver_keys = ()
    work_counters = ()
    #: the engine whose rigid kinematics and dynamics `rigid_checks` judges
    checks_engine = "reference"
    engine_options = ()
    #: its own sub-command: name → (help, main(argv) → exit code)
    commands = {"pinocchio": "rigid checks of the reference against Pinocchio"}

    def parse_settings(self, tables, solver, where, key):
        return None

    def make(self, case, start=None, **options):
        raise NotImplementedError("Pinocchio checks the reference's rigid dynamics; it does not simulate a case")

    def step_perturbed(self, s, factor):
        return s

    def faults(self):
        return ()

    def rigid_checks(self, n_states=20, first_seed=0, n_modes=0, open_arms=(1, 2)):
        """Rows {"quantity", "chain", "states", "max_rel_error", "tolerance", "pass", …}
        of the seeded comparison (pinocchio_check.compare.run_checks)."""
        from pinocchio_check.compare import run_checks

        return run_checks(n_states=n_states, first_seed=first_seed, n_modes=n_modes, open_arms=open_arms)

    def run_command(self, name, argv):
        from pinocchio_check.compare import main

        return main(argv)

    def aba_timing(self, params, n=2000):
        from pinocchio_check.model import aba_timing

        return aba_timing(params, n)


PLUGIN = PinocchioPlugin()
