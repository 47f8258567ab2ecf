"""The MuJoCo model as an rsmcheck engine plug-in (rsmcheck.core.plugins): registered in
pyproject.toml under the entry-point group ``rsmcheck.engines`` as ``mujoco``; its library
comes with the extra ``rsmcheck[mujoco]``.

This module is imported to read case files: it imports the settings schema only, not MuJoCo.
"""

from __future__ import annotations

from mujoco_model import settings
from mujoco_model.faults import FAULTS
from rsmcheck.core.plugins import LineStyle, WorkCounter, deferred, settings_of


#: (case, short) → observable → (size, why), each from MuJoCo's own runs on that variant
#: (docs/mujoco.md §5); a variant not measured declares nothing.
#: motor_step: the rotor band (75–89 Hz) follows ψ_J, which the end pieces give to second
#: order in 1/N (the static end compliance is 1/(4N²) low, exactly), so the refined run's
#: own error is ε/(2² − 1) = ε/3 of the difference ε = |x₈ − x₁₆| that `rsmcheck budget`
#: measures (Richardson): the part of the N = 8 error that ε does not hold.  The reference
#: is not its source; it corroborates it: N = 16 against the reference, `rsmcheck check
#: motor_step --short --engines reference,mujoco --option mujoco:n_segments=16 --option
#: mujoco:timestep=9.92126e-06`, differs by 1.58e-5 (motor) and 3.64e-6 rad (joint).
_END_SECTION = ("the end pieces give the end sections' slope ψ_J to second order in 1/N (static end "
                "compliance 1/(4N²) low), so the refined run at 2N keeps ε/(2² − 1) of its own: ε = {eps} "
                "(N = 8 against N = 16 at 9.9 µs, short run, max_abs), ε/3 = {delta}; N = 16 against "
                "the reference measured {n16}")
DEPARTURES = {
    ("motor_step", True): {
        "motor_angles": (1.46e-05, _END_SECTION.format(eps="4.39e-5 rad", delta="1.46e-5", n16="1.58e-5")),
        "joint_angles": (3.67e-06, _END_SECTION.format(eps="1.10e-5 rad", delta="3.67e-6", n16="3.64e-6")),
    },
}


class MujocoPlugin:
    name = "mujoco"
    label = "MuJoCo"
    style = LineStyle("#2ca02c", "dashdot")
    simulates = True
    requires = ("mujoco",)
    extra = "mujoco"
    distributions = ("mujoco",)
    tables = ("mujoco",)
    solver_keys = ()
    work_counters = (WorkCounter("steps", ("steps",)),)
    rigid_options = None
    analytic_tests = ()
    engine_options = ("n_segments", "timestep", "integrator")

    def parse_settings(self, tables, solver, where, key):
        return settings.parse(tables, solver, where, key)

    def make(self, case, start=None, **options):
        from mujoco_model.engine import MujocoEngine

        return MujocoEngine(case, start=start, **options)

    def step_perturbed(self, s, factor):
        """`s` unchanged: the engine takes fixed steps and its constraint solver runs to
        MuJoCo's iteration cap at a tolerance below round-off, so no discrete decision
        (step acceptance, a Newton stop) depends on a tolerance."""
        return s

    def faults(self):
        return FAULTS

    #: what `refined_options` refines, for the tables of `rsmcheck budget`
    refinement = "2N segments, step/10"

    def refined_options(self, case):
        """Twice the segments at the step they need (the case's step scaled as the default
        step of 2N against N's: ÷10, RK4's bound under the links' Kelvin–Voigt damping), so
        that the difference measures the segments' error, which dominates (second order in
        1/N on the joint rows), together with the step's."""
        from mujoco_model.build import N_SEGMENTS_DEFAULT
        from mujoco_model.engine import default_timestep

        s = settings_of(case, self.name)
        n = s.n_segments or N_SEGMENTS_DEFAULT
        h = s.timestep or default_timestep(n)
        return {"n_segments": 2 * n, "timestep": h * default_timestep(2 * n) / default_timestep(n)}

    def departures(self, case):
        """Allowances for this engine's own departure on `case`'s rows (docs/mujoco.md,
        "Departures"): where a row follows the rotor band, the segment chain's end pieces
        stand for the end sections (ψ_J) to second order in 1/N, and the refined run
        (2N) measures only ¾ of that error; the other ¼, ε/3 by Richardson, is declared
        (`DEPARTURES`)."""
        return dict(DEPARTURES.get((case.name, bool(case.is_short)), {}))

    coupled_frequencies = deferred("mujoco_model.modes", "coupled_frequencies")

    def link_frequencies(self, params, basis, n=2, **options):
        """The first `n` bending frequencies [Hz] of one segmented link in `basis`."""
        from mujoco_model import links

        return links.link_frequencies(params, basis, options.get("n_segments"), n)


PLUGIN = MujocoPlugin()
