"""The engine factory: an engine's name and a case → the engine object, started where the
case says.

Every command and study builds its engines here (`rsmcheck run`, `check`, `gate`, `bench`,
the studies, the phase chain), so that an engine starts the same way everywhere: from the
case's [initial] conditions, or — a case chained onto another's end state
(rsmcheck.orchestration.chain) — from that end state, the engine's own exact state when it can take it
(`import_state`, same model size), else the rigid part every engine understands.
"""

from __future__ import annotations

from rsmcheck.core.cases import Case
from rsmcheck.core.errors import InputError
from rsmcheck.driver.initial import StartState

#: the simulation engines, in the order reports list them
ENGINES = ("reference", "exudyn")


def make_engine(name: str, case: Case, start: StartState | None = None, **options):
    """The engine `name` for `case` with constructor `options` (the engines are imported
    here, lazily: Exudyn is heavy, and a machine may lack it), started from `start` when
    the run continues another: its rigid part, then the engine's own exact state on top
    when there is one (`import_state`, same model size)."""
    if name == "reference":
        from reference_model.engine import ReferenceEngine

        engine = ReferenceEngine(case, start=start, **options)
    elif name == "exudyn":
        try:
            from exudyn_model.engine import ExudynEngine
        except ImportError as exc:
            raise InputError("--engine", "exudyn", f"the Exudyn model is not available ({exc})") from None
        engine = ExudynEngine(case, start=start, **options)
    else:
        raise InputError("--engine", name, f"unknown engine (known: {', '.join(ENGINES)}, all)")
    if start is not None and start.exact is not None:
        engine.import_state(dict(start.exact))
    return engine
