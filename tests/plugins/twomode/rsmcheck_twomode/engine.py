"""The engine: the reference model's engine class under the name "twomode".

Imported only when an engine is made (it loads the numba-compiled reference model).  The
name is a class attribute, so that it holds from the constructor on: the class reads its
case settings by it (this package's [twomode] table, not [reference]), names it in a
divergence, and every run it drives records it (`EngineRun.engine`, from `engine.name`).
"""

from __future__ import annotations

from reference_model.engine import ReferenceEngine


class TwomodeEngine(ReferenceEngine):
    name = "twomode"


def make(case, start=None, **options):
    """The engine for `case`: two eigenmodes per link (or [twomode] n_modes), no static shapes."""
    return TwomodeEngine(case, start=start, static_modes=False, **options)
