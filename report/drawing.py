"""Drawings of the robot at an instant (the paper's Figs. 5 and 11), from a run's observables.

Everything is drawn in the base frame B (base COM at the origin, base axes), as the paper
draws it.  Each link is drawn from its proximal pin along its frame's x-axis (the chord: the
link frames of docs/physics.md §2.1 put the distal pin on it) and bent by its measured
mid-span deflection `link_deflection`, magnified `k` times, with a half-sine shape
w(x) = k · w(L/2) · sin(πx/L) — the shape of the first pinned-pinned mode; the drawing is
a picture of the observables, not a second model.  The end effectors are also marked where
the observables `ee1_pos_B`, `ee2_pos_B` put them, so that a drawing which disagrees with
its run shows it.
"""

from __future__ import annotations

import math

import numpy as np

from rsmcheck.core.geometry import arm_pins, rot
from rsmcheck.core.params import Params
from rsmcheck.report.plots import dash as engine_dash
from rsmcheck.core.store import EngineRun

ARM_COLORS = {1: "#1f77b4", 2: "#d62728"}
N_POINTS = 21  # points along a drawn link


def _square(centre: np.ndarray, side: float, angle: float) -> np.ndarray:
    h = 0.5 * side
    corners = np.array([[-h, -h], [h, -h], [h, h], [-h, h], [-h, -h]])
    return centre + corners @ rot(angle).T


def magnification(runs: dict[str, EngineRun], indices: dict[str, list[int]], length: float) -> float:
    """k of the 1-2-5 series that draws the largest mid-span deflection at the drawn
    instants as about 4 % of a link length (1 where the links are not bent)."""
    w = max((float(np.max(np.abs(run.observables["link_deflection"][indices[name]]))) for name, run in runs.items()),
            default=0.0)
    if w <= 0.0:
        return 1.0
    raw = 0.04 * length / w
    exp = math.floor(math.log10(raw))
    mant = max(m for m in (1, 2, 5) if m * 10**exp <= raw) if raw >= 1 else 1
    return float(max(mant * 10**exp, 1.0))


def robot_traces(run: EngineRun, i: int, params: Params, k: float, show_legend: bool) -> list[dict]:
    """Plotly traces of base, arms (links bent ×k), target and grasp points at sample `i`."""
    o = run.observables
    dash = engine_dash(run.engine)
    g = params.geometry
    L = params.link.length
    traces = []

    def add(xy: np.ndarray, name: str, color: str, width: float = 2.0, mode: str = "lines", **kw) -> None:
        traces.append({"type": "scatter", "mode": mode, "x": [round(float(v), 5) for v in xy[:, 0]],
                       "y": [round(float(v), 5) for v in xy[:, 1]], "name": f"{run.engine}: {name}",
                       "legendgroup": run.engine + name, "showlegend": show_legend,
                       "line": {"color": color, "dash": dash, "width": width}, "hoverinfo": "name", **kw})

    add(_square(np.zeros(2), params.base.side, 0.0), "base", "#555")
    theta = np.asarray(o["joint_frame_angles"][i], float)
    w_mid = np.asarray(o["link_deflection"][i], float)
    x = np.linspace(0.0, L, N_POINTS)
    for arm in (1, 2):
        mount = g.mount_B(arm)
        pins = np.array(arm_pins(float(mount[0]), float(mount[1]), 0.0, L, theta[3 * (arm - 1):3 * arm]))
        angle = 0.0
        pts = [pins[0][None, :]]
        for j in range(3):
            angle += theta[3 * (arm - 1) + j]
            shape = np.stack([x, k * w_mid[3 * (arm - 1) + j] * np.sin(math.pi * x / L)], axis=1)
            pts.append(pins[j] + shape[1:] @ rot(angle).T)
        add(np.concatenate(pts), f"arm {arm}", ARM_COLORS[arm], 3.0)
        ee = np.asarray(o[f"ee{arm}_pos_B"][i], float)[None, :]
        add(ee, f"end effector {arm} (observable)", ARM_COLORS[arm], mode="markers",
            marker={"symbol": "circle-open", "size": 9, "color": ARM_COLORS[arm]})
    tx, ty, ta = (float(v) for v in o["target_pose_B"][i])
    com = np.array([tx, ty])
    centre = com - rot(ta) @ np.asarray(g.target_com_offset_T, float)
    add(_square(centre, params.target.side, ta), "target", "#2ca02c")
    grasp = np.array([com + rot(ta) @ np.asarray(g.grasp_T(arm), float) for arm in (1, 2)])
    add(grasp, "grasp points", "#2ca02c", mode="markers", marker={"symbol": "x", "size": 8, "color": "#2ca02c"})
    add(com[None, :], "target COM", "#2ca02c", mode="markers", marker={"symbol": "cross", "size": 7})
    return traces


def snapshot_figure(title: str, runs: dict[str, EngineRun], instants: list[tuple[str, float]], params: Params) -> dict:
    """One panel per (label, time) instant, every engine overlaid (reference solid, Exudyn
    dashed); the links' deflection magnified by one common k, given in the title."""
    indices = {name: [int(np.argmin(np.abs(run.observables["time"] - t))) for _, t in instants]
               for name, run in runs.items()}
    k = magnification(runs, indices, params.link.length)
    n = len(instants)
    data: list[dict] = []
    layout: dict = {"title": {"text": f"{title} — link deflection ×{k:g}", "font": {"size": 13}, "x": 0},
                    "height": 520, "margin": {"l": 40, "r": 10, "t": 70, "b": 30}, "showlegend": True,
                    "legend": {"orientation": "h", "y": -0.1, "yanchor": "top", "font": {"size": 9}},
                    "plot_bgcolor": "white", "annotations": []}
    gap = 0.03
    width = (1.0 - gap * (n - 1)) / n
    for p, (label, t) in enumerate(instants):
        ax = "" if p == 0 else str(p + 1)
        for name, run in runs.items():
            for tr in robot_traces(run, indices[name][p], params, k, show_legend=p == 0):
                tr.update(xaxis=f"x{ax}", yaxis=f"y{ax}")
                data.append(tr)
    # one frame for every panel: all that is drawn, 0.5 m around it
    xs = [v for tr in data for v in tr["x"]]
    ys = [v for tr in data for v in tr["y"]]
    x_range = [min(xs) - 0.5, max(xs) + 0.5]
    y_range = [min(ys) - 0.5, max(ys) + 0.5]
    for p, (label, t) in enumerate(instants):
        ax = "" if p == 0 else str(p + 1)
        x0 = p * (width + gap)
        layout[f"xaxis{ax}"] = {"domain": [x0, x0 + width], "range": x_range, "showgrid": False,
                                "zeroline": False, "title": {"text": "x_B [m]", "font": {"size": 9}}}
        layout[f"yaxis{ax}"] = {"range": y_range, "scaleanchor": f"x{ax}", "showgrid": False,
                                "zeroline": False}
        layout["annotations"].append({"text": f"{label}<br>t = {t:.1f} s", "x": x0 + 0.5 * width, "y": 1.0,
                                      "xref": "paper", "yref": "paper", "yanchor": "bottom", "showarrow": False,
                                      "font": {"size": 11}})
    return {"data": data, "layout": layout}
