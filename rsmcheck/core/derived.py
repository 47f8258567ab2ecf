"""A variant engine: another engine's code and case settings under a name of its own,
optionally on changed parameters (docs/plugins.md, "A variant of an engine").

The commonest third-party plug-in runs an existing engine on other parameters — a stiffer
link, a heavier target — or is the same model under another name.  Written by hand, such a
plug-in owns a case-file table of its own and so loses the base engine's settings of every
case (`[reference] n_modes = 4`, `static_modes = "explicit"`) without a word.  `derived`
builds it from the base plug-in instead: the variant owns no table, every case's settings
of the base engine are the variant's too, its refinement and finer run are the base's, and
its runs carry its own name.  Only the parameters change, by `params`, a function of the
case's `Params`; `differs` says in one sentence what changes (`rsmcheck engines`, each
run's provenance).

    from dataclasses import replace
    from reference_model.plugin import PLUGIN as REFERENCE
    from rsmcheck.core.derived import derived
    from rsmcheck.core.plugins import LineStyle

    def stiffer(p):
        return replace(p, link=replace(p.link, f1_pp_hz=p.link.f1_pp_hz * 1.03 ** 0.5))

    PLUGIN = derived(REFERENCE, "stiffref", "EI + 3 %", LineStyle("#8c564b", "dot"),
                     params=stiffer, differs="the links' EI 3 % higher (f1 × √1.03)")
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable, Mapping

from rsmcheck.core.params import Params
from rsmcheck.core.plugins import EnginePlugin, LineStyle


@dataclass(frozen=True)
class VariantSettings:
    """A variant's settings of a case: none of its own (the base engine's apply), and the
    gate's decision-tolerance factor, handed to the base's `step_perturbed`."""

    base: str
    differs: str
    factor: float = 1.0

    def given(self) -> dict[str, Any]:
        return {"derived_from": self.base, "differs": self.differs}


@dataclass(frozen=True, eq=False)
class DerivedPlugin:
    """The plug-in `derived` returns (module doc): the `EnginePlugin` of `base` under `name`."""

    base: EnginePlugin
    name: str
    label: str
    style: LineStyle
    params: Callable[[Params], Params] | None = None
    differs: str = "the same model under another name"
    distributions: tuple[str, ...] = ()

    simulates = True
    tables: tuple[str, ...] = ()
    solver_keys: tuple[str, ...] = ()
    linear_plant = coupled_frequencies = link_frequencies = rhs_timing = None
    rigid_checks = aba_timing = None
    analytic_tests: tuple[str, ...] = ()

    @property
    def requires(self) -> tuple[str, ...]:
        return tuple(self.base.requires)

    @property
    def extra(self) -> str | None:
        return self.base.extra

    @property
    def work_counters(self):
        return self.base.work_counters

    @property
    def engine_options(self) -> tuple[str, ...]:
        return tuple(self.base.engine_options)

    @property
    def departures(self) -> Callable[[Any], Mapping[str, tuple[float, str]]] | None:
        """The base's listed departures are the variant's too (the same model)."""
        return getattr(self.base, "departures", None)

    @property
    def source_module(self) -> str:
        """The module whose code makes its runs differ from the base's (the source digest of
        stored runs covers its package): that of `params`, else the base plug-in's."""
        return getattr(self.params, "__module__", None) or type(self.base).__module__

    @property
    def refinement(self) -> str:
        return str(getattr(self.base, "refinement", "") or "")

    @property
    def refined_options(self) -> Callable[[Any], Mapping[str, Any]] | None:
        return getattr(self.base, "refined_options", None)

    @property
    def finer_options(self) -> Callable[[Any], Mapping[str, Any]] | None:
        return getattr(self.base, "finer_options", None)

    def parse_settings(self, tables, solver, where, key) -> VariantSettings:
        return VariantSettings(self.base.name, self.differs)

    def step_perturbed(self, s: VariantSettings, factor: float) -> VariantSettings:
        return replace(s, factor=s.factor * factor)

    def faults(self) -> tuple:
        return ()

    def variant_case(self, case: Any) -> Any:
        """`case` as the base engine is to run it for this variant: the parameters changed,
        the base's own settings of the case (perturbed by the gate's factor, if any)."""
        own = case.engine_settings.get(self.name)
        base = case.engine_settings.get(self.base.name)
        if base is None:  # a case read before the base was registered: the base's defaults
            base = self.base.parse_settings({t: {} for t in self.base.tables}, {}, case.path, lambda k: k)
        if isinstance(own, VariantSettings) and own.factor != 1.0:
            base = self.base.step_perturbed(base, own.factor)
        params = self.params(case.params) if self.params is not None else case.params
        return replace(case, params=params, engine_settings={**case.engine_settings, self.base.name: base})

    def make(self, case: Any, start: Any = None, **options) -> Any:
        engine = self.base.make(self.variant_case(case), start=start, **options)
        engine.name = self.name  # its runs, states and errors carry the variant's name
        return engine


def derived(base: EnginePlugin, name: str, label: str, style: LineStyle,
            params: Callable[[Params], Params] | None = None, differs: str | None = None,
            distributions: tuple[str, ...] = ()) -> DerivedPlugin:
    """The plug-in of a variant of `base` (an engine's plug-in object) named `name`: the
    base's code and case settings, the parameters changed by `params` (None: unchanged;
    then `differs` defaults to "the same model under another name")."""
    if name == base.name:
        raise ValueError(f"a variant of {base.name!r} needs a name of its own")
    if params is not None and not differs:
        raise ValueError(f"variant {name!r}: say in `differs` what its parameters change")
    return DerivedPlugin(base, name, label, style, params, differs or "the same model under another name",
                         tuple(distributions))
