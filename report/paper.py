"""The paper's figures (De Bonis et al. 2021, Figs. 5–17) reproduced from the stored runs.

Each entry names the paper's figure, what the paper plots and says of it, the run it is
drawn from (a phase of the chained mission where the mission was run, else the phase's
stand-alone case), and a line computed from that run, so that the caption states what the
run shows in numbers.  Figs. 5 and 11 are drawings of the robot (report.drawing); the
others are the paper's quantities against time with both engines overlaid and their
difference below.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from rsmcheck.core.observables import BY_NAME
from rsmcheck.orchestration.collect import phase_runs
from rsmcheck.core.params import Params
from rsmcheck.report.drawing import snapshot_figure
from rsmcheck.report.plots import comparison_figure, run_marks
from rsmcheck.core.store import EngineRun


@dataclass(frozen=True)
class PaperFigure:
    number: str
    phase: str  # the case (a mission phase or a feature case) the figure is drawn from
    observable: str  # "" for a drawing
    paper_says: str
    components: tuple[int, ...] = ()  # which components the paper plots (all when empty)
    labels: tuple[str, ...] = ()
    measure: Callable[[EngineRun], str] | None = None  # what the run shows, in numbers


def _span(name: str, comp: int, unit: str, scale: float = 1.0) -> Callable[[EngineRun], str]:
    def measure(run: EngineRun) -> str:
        y = np.asarray(run.observables[name], float).reshape(len(run.observables["time"]), -1)[:, comp] * scale
        return f"from {y[0]:.4g} to {y[-1]:.4g} {unit} (range {y.min():.4g} … {y.max():.4g})"
    return measure


def _peak(name: str, comps: tuple[int, ...], unit: str, scale: float = 1.0) -> Callable[[EngineRun], str]:
    def measure(run: EngineRun) -> str:
        y = np.asarray(run.observables[name], float).reshape(len(run.observables["time"]), -1)[:, list(comps)] * scale
        k = int(np.argmax(np.max(np.abs(y), axis=1)))
        return f"peak |value| {np.max(np.abs(y)):.4g} {unit} at t = {run.observables['time'][k]:.4g} s"
    return measure


def _speed_end(run: EngineRun) -> str:
    """The inertial speed (the observable) and the speed relative to the base, which the
    paper's rest condition is about (differences of ee2_pos_B over the output period)."""
    v = np.asarray(run.observables["ee2_speed"], float)
    t = np.asarray(run.observables["time"], float)
    rel = np.linalg.norm(np.diff(np.asarray(run.observables["ee2_pos_B"], float), axis=0), axis=1) / np.diff(t)
    return (f"inertial speed peaks at {1e3 * v.max():.4g} mm/s and ends at {1e3 * v[-1]:.3g} mm/s; relative to "
            f"the base it ends at {1e3 * rel[-1]:.2g} mm/s")


def _lvlh(run: EngineRun) -> str:
    p = np.asarray(run.observables["target_rel_lvlh"], float)
    d = np.linalg.norm(p - p[0], axis=1)
    return f"the target moves {d[-1]:.3g} m from its start; distance grows monotonically: {bool(np.all(np.diff(d[len(d) // 2:]) >= -1e-6))} (second half)"


FIGURES: tuple[PaperFigure, ...] = (
    PaperFigure("5", "p1_transport", "", "The robot during the first phase: arm 1 carries the target from its "
                "initial condition (a) into arm 2's reach (c); a rest condition is reached at the end."),
    PaperFigure("6a", "p1_rigid_gains", "ee2_speed", "Gains sized on the rigid model: the end-effector speed "
                "oscillates and diverges during the maintenance phase (instability).", measure=_speed_end),
    PaperFigure("6b", "p1_transport", "ee2_speed", "Gains sized with the flexibility: the speed goes to zero "
                "(a quiet condition after the maintenance phase).", measure=_speed_end),
    PaperFigure("7", "p1_transport", "ee1_pos_B", "Coordinates of end effector 1 in the base frame during the "
                "first phase: a smooth move to the target position and rest.", labels=("x", "y"),
                measure=_span("ee1_pos_B", 0, "m")),
    PaperFigure("8", "p1_transport", "ee2_pos_B", "Coordinates of end effector 2 in the base frame during the "
                "first phase: arm 2 prepares for the capture.", labels=("x", "y"),
                measure=_span("ee2_pos_B", 0, "m")),
    PaperFigure("9", "wrist_bistop", "target_attitude", "The target's attitude: the wrist bistop stops the "
                "relative rotation and reverses it.", measure=_span("target_attitude", 0, "rad")),
    PaperFigure("10", "p2_capture_regrasp", "capture_gap_B", "Distance of end effector 2 from its capture "
                "point during the approach: it goes to zero at the capture.", labels=("x", "y"),
                measure=_peak("capture_gap_B", (0, 1), "m")),
    PaperFigure("11", "p2_capture_regrasp", "", "The second phase: capture (a), repositioning with both arms "
                "(b), arm 1 released and repositioned (c), new capture (d)."),
    PaperFigure("12", "p3_com_alignment", "com_pos_B", "The system COM in the base frame during the alignment: "
                "its lateral offset from the thrust axis goes to zero.", labels=("x", "y"),
                measure=_span("com_pos_B", 1, "mm", 1e3)),
    PaperFigure("13", "p4_hohmann", "joint_angles", "Second and third joint angles of arm 1 during the transfer: "
                "a small perturbation at each burn.", components=(1, 2), labels=("ψ2", "ψ3"),
                measure=_span("joint_angles", 1, "rad")),
    PaperFigure("14", "p4_hohmann", "motor_torques", "Torques of the second and third gear-motors of arm 1: "
                "they counteract the thrust and saturate.", components=(1, 2), labels=("τ2", "τ3"),
                measure=_peak("motor_torques", (1, 2), "N·m")),
    PaperFigure("15", "p4_hohmann", "link_deflection", "Elastic deformation of the second and third links of "
                "arm 1: a transient at each burn, damped very quickly.", components=(1, 2), labels=("w2", "w3"),
                measure=_peak("link_deflection", (1, 2), "mm", 1e3)),
    PaperFigure("16", "p4_hohmann", "altitude", "The COM's altitude: 700 km down to 300 km by two burns.",
                measure=_span("altitude", 0, "km", 1e-3)),
    PaperFigure("17", "p5_release", "target_rel_lvlh", "The target relative to the robot in the base's LVLH frame "
                "after the release: it moves away.", labels=("x_LVLH", "y_LVLH"), measure=_lvlh),
)


def _source(st, phase: str) -> tuple[str, dict[str, EngineRun], float] | None:
    """(where from, runs by engine, start time) of `phase`: the chained mission if it ran
    the phase, else the phase's own stand-alone run."""
    for case in st.cases:
        if case.phases and case.name in st.runs and phase in case.variant(st.short).phases:
            runs = {}
            for engine, run in st.runs[case.name].items():
                for ph, t0, r in phase_runs(case, st.short, run):
                    if ph.name == phase:
                        runs[engine] = r
                        start = t0
            return f"the chained {case.name}, phase {phase}", runs, start
    if phase in st.runs:
        return f"the case {phase}", st.runs[phase], 0.0
    return None


def _select(run: EngineRun, name: str, comps: tuple[int, ...]) -> EngineRun:
    if not comps:
        return run
    obs = dict(run.observables)
    y = np.asarray(obs[name], float).reshape(len(obs["time"]), -1)
    obs[name] = y[:, list(comps)]
    return EngineRun(run.engine, obs, run.events, run.phases, run.solver, run.versions)


def _instants(fig: PaperFigure, run: EngineRun) -> list[tuple[str, float]]:
    t_end = float(run.observables["time"][-1])
    if fig.number == "5":
        return [("(a) start", 0.0), ("(b) transport", 0.25 * t_end), ("(c) end", t_end)]
    caps = [e.time for e in run.events if e.kind == "capture"]
    rels = [e.time for e in run.events if e.kind == "release"]
    reposition = next((p for p in run.phases if p.name.endswith(":reposition")), None)
    pts = [("(a) capture", caps[0] if caps else 0.0)]
    if reposition is not None:
        pts.append(("(b) repositioned", reposition.t_end))
    if rels:
        regrasp = next((p for p in run.phases if p.name.endswith(":regrasp")), None)
        pts.append(("(c) arm 1 released, repositioned", regrasp.t_start if regrasp else rels[0]))
    if len(caps) > 1:
        pts.append(("(d) new capture", caps[1]))
    return pts


def figures(page, st) -> list[dict]:
    """The figure entries of the page: number, captions, the figure's div."""
    out = []
    for fig in FIGURES:
        src = _source(st, fig.phase)
        entry = {"number": fig.number, "paper_says": fig.paper_says, "phase": fig.phase}
        if src is None or not src[1]:
            entry.update(missing=f"no run of {fig.phase} is stored", div="", run_shows="")
            out.append(entry)
            continue
        where, runs, t0 = src
        first = next(iter(runs.values()))
        if not fig.observable:
            params = Params()
            entry["div"] = page.figure(snapshot_figure(f"Fig. {fig.number} from {where}", runs,
                                                       _instants(fig, first), params), cls="plot wide")
            entry["run_shows"] = (f"{len(runs)} engine(s) drawn at the instants above (reference solid, Exudyn "
                                  "dashed); circles: the end effectors where the observables put them.")
        else:
            sel = {e: _select(r, fig.observable, fig.components) for e, r in runs.items()}
            unit = BY_NAME[fig.observable].unit
            entry["div"] = page.figure(comparison_figure(
                f"Fig. {fig.number}: {fig.observable} [{unit}] — {where}", unit, sel, fig.observable,
                events=run_marks(first, t0),
                time_offset=t0, labels=fig.labels or None))
            entry["run_shows"] = "; ".join(f"{e}: {fig.measure(r)}" for e, r in runs.items()) if fig.measure else ""
        entry["where"] = where
        out.append(entry)
    return out
