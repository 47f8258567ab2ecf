"""A tolerance's `why` that states its budget ("Budget 4.1e-06 m on the short run: model
difference …, reference integration …, exudyn integration …") quotes the row stored in
docs/data/budget.json, each figure to the digits it quotes, and the row's parts (`allowance`,
`errors`, by which every other pair of engines is judged) are those figures: a re-measured
budget or an edited why cannot drift apart unnoticed."""

from __future__ import annotations

import functools
import json
import re
from decimal import Decimal
from pathlib import Path

import pytest

from rsmcheck.core.cases import list_cases, load_case

BUDGETS = Path(__file__).resolve().parents[2] / "docs" / "data" / "budget.json"
QUOTE = re.compile(r"^Budget (\S+?)(?: \S+)? on the (full|short) (run|chained flight) \(docs/data/budget\.json")
NUMBER = r"(-?[0-9.]+(?:e[+-]?[0-9]+)?)"
#: the figures a why may quote besides the budget, and where the stored row holds each
FIGURES = {
    "model difference": lambda row: row["model_difference"],
    "d0": lambda row: row.get("inherited") or 0.0,
    "reference integration": lambda row: row["integration_error"]["reference"],
    "exudyn integration": lambda row: row["integration_error"]["exudyn"],
}


def _rows():
    """(label, why, variant, budget case, row name, observable) for every row whose why
    speaks of a budget, stand-alone and in a sequence's replaced rows."""
    out = []
    for path in list_cases():
        case = load_case(path)
        for short in (False, True):
            variant, full = case.variant(short), case.variant(False)
            tables = [(case.name, variant.compare, full.compare)]
            tables += [(f"{case.name}/{phase}", rows, full.phase_compare.get(phase))
                       for phase, rows in variant.phase_compare.items()]
            # a short variant without rows of its own is checked by the full rows
            tables = [(name, rows) for name, rows, full_rows in tables if not (short and rows == full_rows)]
            for name, rows in tables:
                for spec in rows:
                    if spec.why.lower().startswith("budget"):
                        label = f"{name}:{spec.observable}:{'short' if short else 'full'}"
                        out.append((label, spec, "short" if short else "full", name, spec.observable))
    return out


ROWS = _rows()


@functools.cache
def _stored() -> dict:
    return json.loads(BUDGETS.read_text())


def _same(quoted: str, stored: float) -> bool:
    digits = len(Decimal(quoted).as_tuple().digits)
    return float(f"{stored:.{digits}g}") == float(quoted)


def test_rows_quote_budgets():
    # the suite's whys state their budgets; an empty list would make the next test vacuous
    assert len(ROWS) > 40


@pytest.mark.parametrize("label, spec, variant, name, observable", ROWS, ids=[r[0] for r in ROWS])
def test_a_quoted_budget_is_the_stored_one(label, spec, variant, name, observable):
    why = spec.why
    m = QUOTE.match(why)
    assert m, f"{label}: a why about a budget starts 'Budget X UNIT on the full|short run|chained flight " \
              f"(docs/data/budget.json': {why[:80]}"
    assert m.group(2) == variant, f"{label}: a {variant} row quotes the {m.group(2)} budget"
    entry = _stored()["variants"][variant].get(name.split("/")[0])
    assert entry is not None, f"{label}: no {variant} budget of {name.split('/')[0]} in {BUDGETS.name}"
    stored = [r for r in entry["rows"] if r["case"] == name and r["observable"] == observable]
    assert len(stored) == 1, f"{label}: {len(stored)} stored rows {name} {observable}"
    row = stored[0]
    assert _same(m.group(1), row["budget"]), f"{label}: why quotes budget {m.group(1)}, stored {row['budget']:.3g}"
    head = why.split(";")[0]  # the figures come before the tolerance's rule
    for figure, value in FIGURES.items():
        q = re.search(rf"\b{figure} {NUMBER}", head)
        if q:
            assert _same(q.group(1), value(row)), f"{label}: why quotes {figure} {q.group(1)}, stored {value(row):.3g}"
    # the parts other pairs are judged by (rsmcheck.core.tolerances): the same figures
    if "/" not in name:
        assert spec.allowance is not None, f"{label}: a budgeted row states its allowance and errors"
        assert _same(f"{spec.allowance:.2g}", row["model_difference"]), \
            f"{label}: allowance {spec.allowance:.2g}, stored model difference {row['model_difference']:.3g}"
        assert spec.errors.keys() == row["integration_error"].keys(), f"{label}: errors of other engines than measured"
        for e, v in spec.errors.items():
            assert _same(f"{v:.2g}", row["integration_error"][e]), \
                f"{label}: errors.{e} {v:.2g}, stored {row['integration_error'][e]:.3g}"
