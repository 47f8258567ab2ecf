"""Engine plug-ins: what an engine package declares, and the registry that finds them.

An engine is a Python distribution that registers one object under the entry-point group
``rsmcheck.engines`` (pyproject.toml)::

    [project.entry-points."rsmcheck.engines"]
    myengine = "my_package.plugin:PLUGIN"

The object satisfies `EnginePlugin`.  Everything engine-specific lives there: its name and
label, the tables of a case file it owns and their schema, how to build it, the counters
that measure its work, the perturbation the gate uses to measure its reproducibility, its
linearisation, frequencies, right-hand-side timing and finer run (where it has them:
`CAPABILITIES`), its fault catalogue for `make faults`, and its colour and line style in
the report.  The shared code
(the driver, the orchestration, the report, the command line) reaches engines only through
`plugins()` and `plugin(name)` and names none of them; the engines a cross-check compares
when none are named are one setting (`default_engines`).

A plug-in module is imported to read the case files, so it imports only the foundation
(rsmcheck.core) and its own light modules; its heavy libraries (Exudyn, numba, Pinocchio)
load when `make` (or another capability) is called.  `requires` names those libraries and
`extra` the pip extra that brings them: asking for an engine whose library is missing is
one line naming that extra (`require`).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from importlib import metadata, resources
from typing import Any, Callable, Mapping, Protocol, runtime_checkable

from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import NAMES as OBSERVABLE_NAMES

#: type names of the annotations: a case (rsmcheck.core.cases, which imports this module),
#: an engine (rsmcheck.core.engine.Engine) and a start state (rsmcheck.driver.initial, a
#: layer above): not imported here
Case = Engine = StartState = Any

#: the entry-point group engines register under
GROUP = "rsmcheck.engines"
#: the environment variable that overrides the default engines of a cross-check
ENGINES_ENV = "RSMCHECK_ENGINES"
#: what every plug-in must have (`EnginePlugin`); the registry refuses one that lacks any
REQUIRED = ("name", "label", "style", "simulates", "requires", "extra", "tables", "solver_keys", "work_counters",
            "engine_options", "parse_settings", "make", "step_perturbed", "faults")
#: the optional capabilities a plug-in may offer (absent or None: it has none), listed by
#: `rsmcheck engines`:
#:   linear_plant, coupled_frequencies   its linearisation (closed-loop analysis, `rsmcheck modes`)
#:   link_frequencies                    one link's bending frequencies (`rsmcheck modes`)
#:   rhs_timing                          its right-hand side's cost (`rsmcheck bench`)
#:   refined_options(case) -> dict       the constructor options of a finer run of `case`, with
#:                                       `refinement`, what they refine ("rtol/10"): the run
#:                                       `rsmcheck budget` measures its integration error against
#:   finer_options(case) -> dict         the options of a run of `case` refined in space and time
#:                                       (more modes or elements, and the finer step), with
#:                                       `finer`, what they refine: `rsmcheck fuzz` takes the
#:                                       change to that run as the engine's own discretisation
#:                                       uncertainty
#:   departures(case) -> dict            observable → (δ, why): an allowance for the engine's own
#:                                       listed departures from the paper's physics on `case`'s
#:                                       rows (a soft constraint, say), in the observable's unit,
#:                                       added to the tolerance of its pairs only
#:                                       (rsmcheck.core.tolerances)
#:   kernel_runs                         groups of (case, options): short runs that between them
#:                                       compile the engine's kernels, a group per process
#:                                       (rsmcheck.orchestration.kernels, `rsmcheck compile`)
#:   rigid_checks, aba_timing            a plug-in that checks (Pinocchio)
CAPABILITIES = ("linear_plant", "coupled_frequencies", "link_frequencies", "rhs_timing", "refined_options",
                "finer_options", "departures", "kernel_runs",
                "rigid_checks", "aba_timing")


@dataclass(frozen=True)
class LineStyle:
    """How the report draws an engine: a CSS colour and a Plotly dash ("solid", "dash", …)."""

    colour: str
    dash: str = "solid"


@dataclass(frozen=True)
class WorkCounter:
    """A measure of a run's work: `label` and the solver counters (`EngineRun.solver` keys)
    summed into it, e.g. ("attempted steps", ("steps", "rejected_steps"))."""

    label: str
    keys: tuple[str, ...]


@dataclass(frozen=True)
class Fault:
    """One plausible bug for the fault-injection matrix: `old` → `new` (an exact text that
    occurs once) in `path`, relative to the root of the tree the faults are applied to."""

    name: str
    path: str
    old: str
    new: str
    what: str


class EngineSettings(Protocol):
    """A plug-in's settings of one case (a frozen dataclass of its own)."""

    def given(self) -> dict[str, Any]:
        """The settings a run's provenance records (what the case file gave, and what the
        engine reads from shared tables)."""
        ...


@runtime_checkable
class EnginePlugin(Protocol):
    """What an engine package declares (module doc).  Optional capabilities are None."""

    #: the engine's name in case files, run files, goldens and on the command line
    name: str
    #: how tables and plots name it ("Exudyn")
    label: str
    #: the report's colour and dash for its curves
    style: LineStyle
    #: True for an engine that simulates a case (the `Engine` protocol); False for a plug-in
    #: that only checks (its `rigid_checks`)
    simulates: bool
    #: the importable modules it needs beyond rsmcheck's own dependencies, and the pip extra
    #: that installs them (None: nothing beyond the base install)
    requires: tuple[str, ...]
    extra: str | None
    #: the case-file tables it owns (each may also stand in [short]) and the keys of the
    #: shared [solver] table it reads
    tables: tuple[str, ...]
    solver_keys: tuple[str, ...]
    #: the measures of a run's work, for the gate and the bench
    work_counters: tuple[WorkCounter, ...]
    #: the constructor options `make` takes (`rsmcheck check --option NAME:KEY=VALUE`)
    engine_options: tuple[str, ...]

    def parse_settings(self, tables: Mapping[str, Mapping[str, Any]], solver: Mapping[str, Any],
                       where: str, key: Callable[[str], str]) -> EngineSettings:
        """Its settings of a case from its own tables (absent tables empty) and its keys of
        [solver]; an error is `InputError(where, key(table) + ".field", reason)`."""
        ...

    def make(self, case: Case, start: StartState | None = None, **options) -> Engine:
        """The engine for `case` (constructor `options`), started from `start` or the case's
        [initial]."""
        ...

    def step_perturbed(self, settings: EngineSettings, factor: float) -> EngineSettings:
        """`settings` with the tolerance behind the engine's discrete decisions (steps
        accepted or rejected, Newton stops) scaled by `factor`, at the same accuracy: the
        gate's measure of how far round-off can move a run."""
        ...

    def faults(self) -> tuple[Fault, ...]:
        """Plausible bugs in its own code, for `make faults`."""
        ...


def deferred(module: str, function: str) -> Callable[..., Any]:
    """A plug-in capability that imports `module` when first called and calls its
    `function` (a plug-in module stays light: module doc)."""
    def call(*args, **kwargs):
        return getattr(importlib.import_module(module), function)(*args, **kwargs)
    call.__name__ = function
    call.__doc__ = f"`{module}.{function}`, imported when called."
    return staticmethod(call)


# ---------------------------------------------------------------------------------------
# the registry
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BrokenPlugin:
    """A registered entry point that gives no usable plug-in: its name, the distribution
    that brought it ("name version") and why.  The registry leaves it out, so that it stops
    only the commands that name it (`plugin`); `rsmcheck engines` lists it."""

    name: str
    distribution: str
    reason: str

    def __str__(self) -> str:
        return f"engine plug-in {self.name!r} from {self.distribution} does not load: {self.reason}"


def _distribution(ep: metadata.EntryPoint) -> str:
    """'name version' of the distribution that registered `ep`."""
    dist = getattr(ep, "dist", None)
    return f"{dist.name} {dist.version}" if dist is not None else "an unknown distribution"


def _load(ep: metadata.EntryPoint) -> tuple[EnginePlugin | None, str]:
    """(the plug-in, "") or (None, why it is not one): any exception of its import, a
    required attribute missing, a name other than the entry point's."""
    try:
        obj = ep.load()
    except Exception as exc:  # a third party's import may raise anything: reported, not raised
        return None, f"{ep.value} does not import ({type(exc).__name__}: {exc})"
    missing = [a for a in REQUIRED if not hasattr(obj, a)]
    if missing:
        return None, f"{ep.value} lacks {', '.join(missing)}"
    if obj.name != ep.name:
        return None, f"{ep.value} calls itself {obj.name!r}"
    return obj, ""


@lru_cache(maxsize=1)
def _registry() -> tuple[dict[str, EnginePlugin], dict[str, BrokenPlugin]]:
    """(the plug-ins by name, the broken entry points by name), read once per process.
    Two distributions that register one name are an `InputError` naming both: which of
    them a command would get depends on the order they were installed in."""
    eps = list(metadata.entry_points(group=GROUP))
    for name in dict.fromkeys(ep.name for ep in eps):
        same = [ep for ep in eps if ep.name == name]
        if len(same) > 1:
            dists = [_distribution(ep) for ep in same]
            others = [d.split()[0] for d in dists if d.split()[0] != "rsmcheck"] or [dists[-1].split()[0]]
            raise InputError(f"entry point {GROUP}", name,
                             f"registered by {' and by '.join(dists)}; keep one: pip uninstall {others[-1]}")
    found: dict[str, EnginePlugin] = {}
    broken: dict[str, BrokenPlugin] = {}
    for ep in eps:
        obj, why = _load(ep)
        if obj is None:
            broken[ep.name] = BrokenPlugin(ep.name, _distribution(ep), why)
        else:
            found[ep.name] = obj
    first = list(_defaults()["check_engines"])
    ordered = dict(sorted(found.items(), key=lambda kv: (not kv[1].simulates,
                                                         first.index(kv[0]) if kv[0] in first else len(first), kv[0])))
    return ordered, broken


def plugins() -> dict[str, EnginePlugin]:
    """Every registered plug-in that loads, by name: the engines that simulate first, the
    default engines of a cross-check (defaults.toml) in their order, then the others by
    name.  Broken entry points are left out (`broken_plugins`)."""
    return _registry()[0]


def broken_plugins() -> dict[str, BrokenPlugin]:
    """The registered entry points that do not load, by name (`BrokenPlugin`)."""
    return _registry()[1]


#: the registry is read once per process; tests read it again
plugins.cache_clear = _registry.cache_clear  # type: ignore[attr-defined]


def plugin(name: str, option: str = "--engines") -> EnginePlugin:
    """The plug-in `name`; an unknown name is an `InputError` listing the known ones, a
    broken one an `InputError` naming its distribution and why it does not load."""
    known = plugins()
    if name in broken_plugins():
        raise InputError(option, name, str(broken_plugins()[name]))
    if name not in known:
        raise InputError(option, name, f"no such engine (registered: {', '.join(known) or 'none'})")
    return known[name]


def simulators() -> tuple[str, ...]:
    """The names of the registered engines that simulate, in registry order."""
    return tuple(n for n, p in plugins().items() if p.simulates)


def with_capability(capability: str) -> tuple[str, ...]:
    """The registered plug-ins that offer `capability` (an attribute that is not None)."""
    return tuple(n for n, p in plugins().items() if getattr(p, capability, None) is not None)


def available(name: str) -> bool:
    """Whether every library plug-in `name` requires can be imported here."""
    return all(importlib.util.find_spec(m) is not None for m in plugin(name).requires)


def require(name: str, option: str = "--engines") -> EnginePlugin:
    """The plug-in `name`, its libraries checked: a missing one is one line naming the pip
    extra that installs it."""
    p = plugin(name, option)
    missing = [m for m in p.requires if importlib.util.find_spec(m) is None]
    if missing:
        how = f"pip install 'rsmcheck[{p.extra}]'" if p.extra else f"install {', '.join(missing)}"
        raise InputError(option, name, f"{p.label} needs {', '.join(missing)}, not installed here: {how}")
    return p


def make_engine(name: str, case: Case, start: StartState | None = None, **options) -> Engine:
    """The engine `name` for `case`, started from `start` (its rigid part, then the engine's
    own exact state on top when it can take it: `import_state`, same model size)."""
    p = require(name)
    if not p.simulates:
        raise InputError("--engines", name, f"{p.label} checks but does not simulate")
    engine = p.make(case, start=start, **options)
    if start is not None and start.exact is not None:
        engine.import_state(dict(start.exact))
    return engine


def engine_names(choice: str | None) -> list[str]:
    """The engines a command's `--engines` names: "all" (every registered engine
    that simulates), a comma-separated list, or None (the default engines)."""
    if choice is None:
        return list(default_engines())
    names = list(simulators()) if choice == "all" else [n.strip() for n in choice.split(",") if n.strip()]
    for n in names:
        if plugin(n).simulates is False:
            raise InputError("--engines", n, f"{plugin(n).label} checks but does not simulate")
    if len(set(names)) != len(names):
        raise InputError("--engines", choice, "names an engine twice")
    return names


def plugin_distributions() -> list[str]:
    """The installed distributions that provide the libraries the plug-ins require (e.g.
    "exudyn", "pin" for the module pinocchio): what a run's provenance records."""
    by_module = metadata.packages_distributions()
    out: list[str] = []
    for p in plugins().values():
        out += [d for d in getattr(p, "distributions", ()) if d not in out]
        for m in p.requires:
            out += [d for d in by_module.get(m, []) if d not in out]
    return out


def default_engines() -> tuple[str, ...]:
    """The engines a cross-check compares when none are named: the first is the model under
    test, the others the independent engines it is checked against.  Set in the package's
    defaults.toml (`check_engines`), overridden by the environment variable RSMCHECK_ENGINES
    (comma-separated)."""
    env = os.environ.get(ENGINES_ENV, "").strip()
    if env:
        names = tuple(n.strip() for n in env.split(",") if n.strip())
        where, key = ENGINES_ENV, "value"
    else:
        names = tuple(_defaults()["check_engines"])
        where, key = "rsmcheck/core/defaults.toml", "check_engines"
    if len(names) < 2:
        raise InputError(where, key, f"a cross-check needs two engines, got {', '.join(names) or 'none'}")
    for n in names:
        if n not in plugins():
            raise InputError(where, key, f"no such engine {n!r} (registered: {', '.join(plugins())})")
    return names


@lru_cache(maxsize=1)
def _defaults() -> dict[str, Any]:
    return tomllib.loads(resources.files("rsmcheck.core").joinpath("defaults.toml").read_text(encoding="utf-8"))


# ---------------------------------------------------------------------------------------
# a case's engine settings
# ---------------------------------------------------------------------------------------
def owned_tables() -> dict[str, str]:
    """Case-file table → the plug-in that owns it."""
    out: dict[str, str] = {}
    for name, p in plugins().items():
        for t in p.tables:
            if t in out:
                raise InputError(f"entry point {GROUP}", name, f"table [{t}] is owned by {out[t]} too")
            out[t] = name
    return out


def owned_solver_keys() -> dict[str, str]:
    """Key of the shared [solver] table → the plug-in that reads it."""
    return {k: name for name, p in plugins().items() for k in p.solver_keys}


def parse_engine_settings(raw: Mapping[str, Any], solver: Mapping[str, Any], where: str,
                          key: Callable[[str], str]) -> dict[str, EngineSettings]:
    """Every registered plug-in's settings of one case variant: its own tables of `raw` and
    its keys of the [solver] table `solver`."""
    out = {}
    for name, p in plugins().items():
        if not p.simulates:
            continue
        tables = {t: raw.get(t, {}) for t in p.tables}
        out[name] = p.parse_settings(tables, {k: solver[k] for k in p.solver_keys if k in solver}, where, key)
    return out


def step_perturbed_settings(settings: Mapping[str, EngineSettings], factor: float) -> dict[str, EngineSettings]:
    """Each engine's settings with its decision tolerance scaled by `factor` (the gate)."""
    return {name: plugin(name).step_perturbed(s, factor) for name, s in settings.items()}


def refined_options(name: str, case: Case) -> dict[str, Any] | None:
    """Plug-in `name`'s constructor options of a finer run of `case` (the variant to run),
    from its optional `refined_options`; None when it declares none.  Options it does not
    accept (`engine_options`), or none at all, are an InputError naming the plug-in."""
    return _options_of(name, case, "refined_options")


def finer_options(name: str, case: Case) -> dict[str, Any] | None:
    """Plug-in `name`'s constructor options of a run of `case` refined in space and in time
    (its optional `finer_options`), as `refined_options`."""
    return _options_of(name, case, "finer_options")


def kernel_runs(name: str) -> tuple[tuple[tuple[str, dict[str, Any]], ...], ...]:
    """Plug-in `name`'s groups of (case name, constructor options) that compile its kernels
    (its optional `kernel_runs`); () without.  An option outside its `engine_options`, or a
    group that is not a sequence of (case, options) pairs, is an InputError naming it."""
    p = plugin(name)
    groups = getattr(p, "kernel_runs", None) or ()
    out = []
    for i, group in enumerate(groups):
        try:
            runs = tuple((str(c), dict(o)) for c, o in group)
        except (TypeError, ValueError):
            raise InputError(f"plug-in {name}", f"kernel_runs[{i}]", "must be a sequence of (case, options)") from None
        for c, o in runs:
            unknown = sorted(set(o) - set(p.engine_options))
            if unknown:
                raise InputError(f"plug-in {name}", f"kernel_runs[{i}]",
                                 f"{c}: options {', '.join(unknown)} are not among its engine_options")
        out.append(runs)
    return tuple(out)


def _options_of(name: str, case: Case, capability: str) -> dict[str, Any] | None:
    p = plugin(name)
    make_finer = getattr(p, capability, None)
    if make_finer is None:
        return None
    options = dict(make_finer(case))
    unknown = sorted(set(options) - set(p.engine_options))
    if not options or unknown:
        raise InputError(f"plug-in {name}", capability,
                         f"options {', '.join(unknown)} are not among its engine_options" if unknown
                         else "gives no option: a finer run must differ")
    return options


def departure_allowances(name: str, case: Case) -> dict[str, tuple[float, str]]:
    """Plug-in `name`'s allowances for its own departures on the rows of `case` (the variant
    run): observable → (δ ≥ 0, why), from its optional `departures`; {} without one, or for
    an engine not installed (its runs read from a file).  A malformed answer is an
    InputError naming the plug-in."""
    p = plugins().get(name)
    get = getattr(p, "departures", None) if p is not None else None
    if get is None:
        return {}
    try:
        declared = get(case)
    except Exception as exc:  # noqa: BLE001 — a plug-in's bug is one line naming it, not a traceback
        raise InputError(f"plug-in {name}", "departures", f"raised {type(exc).__name__}: {exc}") from None
    if not isinstance(declared, Mapping):
        raise InputError(f"plug-in {name}", "departures", f"must return a mapping, got {type(declared).__name__}")
    out = {}
    for obs, item in declared.items():
        if obs not in OBSERVABLE_NAMES or obs == "time":
            raise InputError(f"plug-in {name}", f"departures.{obs}", "not an observable (docs/observables.md)")
        try:
            size, why = item
            size = float(size)
        except (TypeError, ValueError):
            raise InputError(f"plug-in {name}", f"departures.{obs}", "must be (size, why)") from None
        if not (size >= 0.0 and size < float("inf")) or not isinstance(why, str) or not why.strip():
            raise InputError(f"plug-in {name}", f"departures.{obs}",
                             f"needs a finite size >= 0 and a reason, got ({size!r}, {why!r})")
        out[str(obs)] = (size, why)
    return out


def given_settings(settings: Mapping[str, EngineSettings]) -> dict[str, dict[str, Any]]:
    """Each engine's settings as a run's provenance records them."""
    return {name: s.given() for name, s in settings.items()}


def settings_of(case: Case, name: str) -> EngineSettings:
    """Plug-in `name`'s settings of `case` (the plug-in's defaults when the case was parsed
    before it was registered)."""
    s = case.engine_settings.get(name)
    if s is None:
        s = plugin(name).parse_settings({t: {} for t in plugin(name).tables}, {}, case.path, lambda k: k)
    return s
