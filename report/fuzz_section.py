"""The report's section on the randomized cross-check (`rsmcheck fuzz`, docs/data/fuzz.json).

One figure: every compared row of every scenario as a point, the observable across, the
ratio of the engines' difference to the row's allowance up (log axis), one colour per
chain; a row above the dashed line at 1 failed.  Beside it the campaign in numbers and the
failing scenarios with the command that reproduces each."""

from __future__ import annotations

from typing import Any

from rsmcheck.report.plots import simple_figure

#: one colour per chain of the scenarios (fuzz_ranges.toml `chains`)
CHAIN_COLOURS = {"free": "#2ca02c", "open": "#1f77b4", "closed": "#d62728"}


def _chain(scenario: dict) -> str:
    """The chain of a scenario, from its one-line description (fuzz_scenarios.Scenario.describe)."""
    text = scenario.get("scenario", "")
    return "closed" if text.startswith("closed") else "free" if text.startswith("free") else "open"


def fuzz_section(page: Any, doc: dict | None) -> dict | None:
    """What the page shows of a stored campaign (module doc); None without one."""
    if not doc or not doc.get("scenarios"):
        return None
    traces = []
    for chain, colour in CHAIN_COLOURS.items():
        points = [(r["observable"], r["ratio"], s["name"]) for s in doc["scenarios"] if _chain(s) == chain
                  for r in s.get("rows", [])]
        if not points:
            continue
        traces.append({"type": "scatter", "mode": "markers", "name": f"{chain} chain",
                       "x": [p[0] for p in points], "y": [max(p[1], 1e-4) for p in points],
                       "text": [p[2] for p in points], "hovertemplate": "%{text}: %{y:.3g}<extra></extra>",
                       "marker": {"color": colour, "size": 6, "opacity": 0.6}})
    observables = sorted({r["observable"] for s in doc["scenarios"] for r in s.get("rows", [])})
    if observables:
        traces.append({"type": "scatter", "mode": "lines", "name": "allowance (fails above)",
                       "x": [observables[0], observables[-1]], "y": [1.0, 1.0],
                       "line": {"color": "#b00", "dash": "dash", "width": 1.2}})
    fig = simple_figure("difference / allowance, every row of every scenario", traces, xlabel="observable",
                        ylabel="d(A, B) / allowance", height=360, hovermode="closest")
    fig["layout"]["yaxis"]["type"] = "log"
    ratios = [r["ratio"] for s in doc["scenarios"] for r in s.get("rows", [])]
    return {"doc": doc, "figure": page.figure(fig) if traces else "",
            "worst": max(ratios) if ratios else None,
            "failed": [s for s in doc["scenarios"] if not s.get("passed")],
            "chains": {c: sum(_chain(s) == c for s in doc["scenarios"]) for c in CHAIN_COLOURS}}
