"""Two variants of the reference engine, made with rsmcheck's `derived` (docs/plugins.md,
"A variant of an engine"): the reference's code and its settings of every case, under a
name of their own.

* `sameref` — the reference unchanged: every row against the reference must be 0;
* `stiffref` — the links' bending stiffness EI 3 % higher (EI follows f1_pp², so f1 × √1.03):
  the rows that see the links' stiffness must fail against the reference, the others pass.
"""

from __future__ import annotations

from dataclasses import replace

from reference_model.plugin import PLUGIN as REFERENCE
from rsmcheck.core.derived import derived
from rsmcheck.core.plugins import LineStyle


def _stiffer(p):
    return replace(p, link=replace(p.link, f1_pp_hz=p.link.f1_pp_hz * 1.03 ** 0.5))


SAMEREF = derived(REFERENCE, "sameref", "same ref", LineStyle("#7f7f7f", "dot"),
                  distributions=("rsmcheck-twomode",))
STIFFREF = derived(REFERENCE, "stiffref", "EI + 3 %", LineStyle("#8c564b", "longdash"), params=_stiffer,
                   differs="the links' bending stiffness EI 3 % higher (f1 × √1.03)",
                   distributions=("rsmcheck-twomode",))
