"""Plotly figures of the report, as plain figure dictionaries (no plotly Python objects).

A figure is ``{"data": [...], "layout": {...}}``; the page draws it with plotly.js, inlined
once.  Arrays go in as plotly's typed-array form (``{"dtype": "f4", "bdata": base64}``),
about a third of the size of JSON numbers, and every trace is thinned to at most
`MAX_BUCKETS` min/max pairs so that peaks survive: a 6 000-sample run of 12 traces costs
~60 kB.
"""

from __future__ import annotations

import base64
from typing import Any, Iterable, Sequence

import numpy as np

from rsmcheck.core.plugins import plugins
from rsmcheck.core.store import EngineRun

MAX_BUCKETS = 400
#: line style of the golden's traces; each engine's comes from its plug-in (`style`)
GOLDEN_DASH = "dot"
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
EVENT_COLORS = {"capture": "#2ca02c", "release": "#d62728", "bistop": "#9467bd", "burn": "#ff7f0e"}


def dash(engine: str) -> str:
    """The line style of an engine's traces (its plug-in's `style`), or the golden's."""
    known = plugins()
    return known[engine].style.dash if engine in known else GOLDEN_DASH


def colour(engine: str) -> str:
    """The colour that stands for an engine where one colour does (bars, markers)."""
    known = plugins()
    return known[engine].style.colour if engine in known else "#555"


def typed(a: np.ndarray, dtype: str = "f4") -> dict[str, str]:
    """A 1-D array in plotly.js's typed-array form."""
    arr = np.ascontiguousarray(np.asarray(a, dtype="<" + dtype))
    return {"dtype": dtype, "bdata": base64.b64encode(arr.tobytes()).decode("ascii")}


def thin(t: np.ndarray, y: np.ndarray, buckets: int = MAX_BUCKETS) -> tuple[np.ndarray, np.ndarray]:
    """At most 2·`buckets` samples of (t, y): the minimum and the maximum of y in each of
    `buckets` equal runs of samples, in time order (min/max decimation keeps the peaks)."""
    n = t.size
    if n <= 2 * buckets:
        return t, y
    edges = np.linspace(0, n, buckets + 1).astype(int)
    keep = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        seg = y[lo:hi]
        finite = np.isfinite(seg)
        if not finite.all():  # a blow-up is shown, not averaged away
            keep.append(lo + int(np.argmin(finite)))
            continue
        i, j = lo + int(np.argmin(seg)), lo + int(np.argmax(seg))
        keep += sorted({i, j})
    idx = np.asarray(keep)
    return t[idx], y[idx]


def line(t: np.ndarray, y: np.ndarray, name: str, color: str, dash: str = "solid", group: str = "",
         xaxis: str = "x", yaxis: str = "y", width: float = 1.4, show: bool = True, f8: bool = False) -> dict:
    tt, yy = thin(np.asarray(t, float), np.asarray(y, float))
    return {"type": "scatter", "mode": "lines", "name": name, "x": typed(tt), "y": typed(yy, "f8" if f8 else "f4"),
            "line": {"color": color, "dash": dash, "width": width}, "legendgroup": group or name,
            "showlegend": show, "xaxis": xaxis, "yaxis": yaxis, "hovertemplate": "%{y:.5g}<extra>" + name + "</extra>"}


def legend_entry(name: str, color: str, dash: str, group: str = "") -> dict:
    """A legend line with no data (the engines' line styles, the components' colours)."""
    return {"type": "scatter", "mode": "lines", "name": name, "x": [None], "y": [None], "showlegend": True,
            "line": {"color": color, "dash": dash, "width": 2}, "legendgroup": group or name, "hoverinfo": "skip"}


def components(values: np.ndarray) -> np.ndarray:
    """Samples × components."""
    v = np.asarray(values, float)
    return v.reshape(v.shape[0], -1)


def event_marks(events: Iterable[tuple[float, str, str]], yref: str = "paper") -> tuple[list, list]:
    """Vertical lines (shapes) and their labels at (time, kind, detail) events."""
    shapes, notes = [], []
    for time, kind, detail in events:
        # a segment boundary (the programme's next step: a burn, a hold) is named by its detail
        label = detail.split()[0] if kind == "segment" and detail else kind
        color = next((c for k, c in EVENT_COLORS.items() if k in label), "#999")
        shapes.append({"type": "line", "xref": "x", "yref": yref, "x0": time, "x1": time, "y0": 0, "y1": 1,
                       "line": {"color": color, "width": 1, "dash": "dot" if kind != "segment" else "longdash"},
                       "layer": "below"})
        notes.append({"x": time, "y": 1, "xref": "x", "yref": "paper", "yanchor": "bottom", "text": label,
                      "showarrow": False, "font": {"size": 9, "color": color}, "textangle": -30,
                      "hovertext": f"t = {time:.4f} s: {kind} {detail}"})
    return shapes, notes


def run_marks(run: EngineRun, offset: float = 0.0) -> list[tuple[float, str, str]]:
    """(time, kind, detail) of the events to mark on a plot: captures, releases, contacts,
    and the programme's segments (burns, holds) — not the first segment, at the start."""
    return [(e.time + offset, e.kind, e.detail) for e in run.events if not (e.kind == "segment" and e.time == 0.0)]


def phase_bands(bounds: Sequence[tuple[str, float, float]]) -> tuple[list, list]:
    """Alternating shaded bands with the phase names on top (mission time axis)."""
    shapes, notes = [], []
    for k, (name, t0, t1) in enumerate(bounds):
        if k % 2:
            shapes.append({"type": "rect", "xref": "x", "yref": "paper", "x0": t0, "x1": t1, "y0": 0, "y1": 1,
                           "fillcolor": "#eef2f7", "line": {"width": 0}, "layer": "below"})
        notes.append({"x": 0.5 * (t0 + t1), "y": 1.0, "xref": "x", "yref": "paper", "yanchor": "bottom",
                      "text": f"<b>{name}</b>", "showarrow": False, "font": {"size": 10}})
    return shapes, notes


def base_layout(title: str, height: int = 330, **extra: Any) -> dict:
    # the legend goes under the plot, where it covers neither the curves nor the title
    layout = {"title": {"text": title, "font": {"size": 13}, "x": 0, "xanchor": "left"},
              "height": height + 70, "margin": {"l": 60, "r": 10, "t": 70, "b": 110},
              "legend": {"orientation": "h", "y": -0.16, "yanchor": "top", "x": 0, "xanchor": "left",
                         "font": {"size": 10}},
              "hovermode": "x unified", "template": None, "plot_bgcolor": "white",
              "xaxis": {"title": {"text": "t [s]"}, "gridcolor": "#eee", "zeroline": False},
              "yaxis": {"gridcolor": "#eee", "zeroline": False}}
    layout.update(extra)
    return layout


def comparison_figure(title: str, unit: str, runs: dict[str, EngineRun], name: str,
                      golden: EngineRun | None = None, tolerance: float | None = None, metric: str = "",
                      events: Sequence[tuple[float, str, str]] = (), time_offset: float = 0.0,
                      bands: Sequence[tuple[str, float, float]] = (), labels: Sequence[str] | None = None,
                      window: tuple[float, float] | None = None,
                      compared: Sequence[float] | None = None,
                      tolerances: dict[str, float] | None = None) -> dict:
    """An observable of every engine overlaid (top; each engine in its plug-in's line
    style) and, below, |first − other engine| for each other engine (the largest component;
    the first is the model under test, each curve in the other's line style) on a log scale
    with that pair's tolerance (`tolerances`, other engine → tolerance; `tolerance` where
    it names none), drawn over the interval the check compares (`compared` [s], None: the
    whole run); events marked."""
    data: list[dict] = []
    order = list(runs)
    both = len(order) >= 2
    # the legend: one entry per component (colour), one per engine (line style)
    for k, (engine, run) in enumerate(list(runs.items()) + ([("golden", golden)] if golden is not None else [])):
        t = np.asarray(run.observables["time"], float) + time_offset
        y = components(run.observables[name])
        for c in range(y.shape[1]):
            label = labels[c] if labels and c < len(labels) else (f"[{c}]" if y.shape[1] > 1 else name)
            data.append(line(t, y[:, c], f"{engine} {label}", COLORS[c % len(COLORS)], dash(engine),
                             group=label, show=False, width=1.0 if engine == "golden" else 1.4))
            if k == 0 and y.shape[1] > 1:
                data.append(legend_entry(label, COLORS[c % len(COLORS)], "solid", group=label))
        data.append(legend_entry(engine, "#555", dash(engine), group=engine))
    layout = base_layout(title, height=420 if both else 300)
    layout["yaxis"].update(title={"text": unit}, domain=[0.38, 1.0] if both else [0, 1])
    if both:
        t = np.asarray(runs[order[0]].observables["time"], float) + time_offset
        b = components(runs[order[0]].observables[name])
        span = ([float(t[0]), float(t[-1])] if compared is None
                else [float(compared[0]) + time_offset, float(compared[1]) + time_offset])
        for other in order[1:]:
            a = components(runs[other].observables[name])
            if a.shape != b.shape:
                continue
            err = np.max(np.abs(a - b), axis=1)
            floor = max(float(np.max(err[np.isfinite(err)], initial=0.0)) * 1e-8, 1e-300)
            pair = f"|{order[0]} − {other}|"
            data.append(line(t, np.maximum(err, floor), pair, "#444", dash(other), yaxis="y2", group=pair))
            tol = (tolerances or {}).get(other, tolerance)
            if tol is not None:
                data.append({"type": "scatter", "mode": "lines", "name": f"tolerance of {pair} ({metric})",
                             "x": span, "y": [tol, tol], "yaxis": "y2",
                             "line": {"color": "#b00", "dash": dash(other), "width": 1.2}, "legendgroup": pair})
        layout["yaxis2"] = {"type": "log", "domain": [0, 0.28], "title": {"text": "error"}, "anchor": "x",
                            "gridcolor": "#eee", "exponentformat": "power"}
        layout["xaxis"]["anchor"] = "y2"
    shapes, notes = event_marks(events)
    s2, n2 = phase_bands(bands)
    layout["shapes"], layout["annotations"] = s2 + shapes, n2 + notes
    if window is not None:  # shown first; the rest of the flight is a zoom-out away
        layout["xaxis"]["range"] = list(window)
    return {"data": data, "layout": layout}


def simple_figure(title: str, traces: list[dict], xlabel: str = "t [s]", ylabel: str = "", height: int = 320,
                  events: Sequence[tuple[float, str, str]] = (), **extra: Any) -> dict:
    layout = base_layout(title, height=height, **extra)
    layout["xaxis"]["title"] = {"text": xlabel}
    layout["yaxis"]["title"] = {"text": ylabel}
    shapes, notes = event_marks(events)
    layout["shapes"], layout["annotations"] = shapes, notes
    return {"data": traces, "layout": layout}
