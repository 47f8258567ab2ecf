"""Engine-vs-engine studies behind docs/exudyn.md §6–7 (results in docs/data/*.json).

* `rigid_step_study`: rigid links in both engines (reference with 0 modes, Exudyn with
  `rigid=True`), every observable of each case, for a sequence of generalized-α steps
  h = control period / substeps.  The difference is then the integrators' only: the
  reference (Dormand–Prince 5(4), rtol 1e-12) is checked against itself at rtol 1e-11, and
  the Exudyn error must fall as h² (generalized-α is second order; the obstacle is the
  phase of the undamped 92 Hz rotor ripple, docs/exudyn.md §4).
* `convergence_study`: flexible links, reference with 1…4 modes per link against Exudyn
  with 2…16 ANCF elements per link, every observable: the difference shrinks as both
  discretisations converge, down to the integrator floor.
* `refinement_study`: the rows of a case's own `[compare]` table (error against its
  tolerance) for reference modes × Exudyn (step, EA/EI): which refinement of which engine
  brings a case to its tolerance (docs/exudyn.md §8, motor_step and release).
* `integrator_study`: the reference's integrators at equal footing: each (integrator,
  rtol) of a grid on a case's short variant against a Dormand–Prince solution at rtol
  1e-10, the error of every row of the case's `[compare]` table beside the wall time and
  the steps per control sample — what an integrator buys is judged at equal accuracy
  (docs/records.md, "An L-stable integrator at equal accuracy").
* `orbit_study`: what flying in orbit changes in a mission phase: the phase's short
  variant with and without its `[orbit]` (reference engine; without it the base holds its
  attitude instead of tracking the retrograde direction), the largest difference of each
  observable (docs/cases.md §4).

Run: `python -m rsmcheck.orchestration.studies rigid [CASE…]`,
`python -m rsmcheck.orchestration.studies convergence`,
`python -m rsmcheck.orchestration.studies refinement CASE --modes 2,4 --exudyn 32:1e5,256:1e6`,
`python -m rsmcheck.orchestration.studies orbit [CASE…]`,
`python -m rsmcheck.orchestration.studies integrators CASE --grid dopri5:1e-7,imex:1e-7,imex:1e-8`.
The Exudyn numbers come from Exudyn alone (`exudyn_model` never imports the reference);
this module only compares the two.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from rsmcheck.core.cases import OrbitSpec, load_case
from rsmcheck.core.errors import exit_code
from rsmcheck.core.observables import NAMES
from rsmcheck.orchestration.compare import SCALE_FLOORS, check_runs, compare_runs
from rsmcheck.core.plugins import default_engines, make_engine, plugin, settings_of
from rsmcheck.driver.runner import run
from rsmcheck.core.store import read_run, write_json

DATA_DIR = Path(__file__).resolve().parents[2] / "docs" / "data"
FEATURE_CASES = ("free_drift", "flex_arm_step", "motor_step", "closed_squeeze", "capture", "release",
                 "wrist_bistop", "gravity_gradient", "thrust_burn")
OBSERVABLES = tuple(n for n in NAMES if n != "time")
#: rigid links: these are identically zero in both engines (nothing to compare)
RIGID_ZERO = ("link_deflection",)


def pair() -> tuple[str, str]:
    """The engines a study compares: the model under test (its tight runs are the
    reference solution) and the independent engine whose step and mesh the study derives
    (rsmcheck.core.plugins.default_engines)."""
    first, second = default_engines()[:2]
    return first, second


def _run(engine: str, case, duration: float, **options):
    t0 = time.monotonic()
    r = run(make_engine(engine, case, **options), case, duration)
    return r, time.monotonic() - t0


def _ranges(run) -> dict[str, float]:
    return {n: float(np.max(np.abs(np.asarray(run.observables[n], float)))) for n in OBSERVABLES}


def _errors(name: str, ref, other, names=OBSERVABLES) -> dict[str, dict[str, float]]:
    rows = compare_runs(name, ref, other, {n: 1.0 for n in names})
    return {r.observable: {"error": r.error, "scale": r.scale, "worst_time": r.worst_time} for r in rows}


def _write(path: Path | None, doc: dict) -> None:
    if path is None:
        return
    write_json(path, doc)  # strict JSON, atomically


#: reference tolerance of the rigid study: the reaction forces feel the rotor twist through
#: K_m = 40 000 N·m/rad, so a twist error of rtol·1 rad is 4e4·rtol N·m — rtol 1e-9 (the
#: cases' value) leaves 2e-4 of the reaction force of free_drift; 1e-12 is checked against 1e-11
REFERENCE_RTOL = 1e-12
CHECK_RTOL = 1e-11


def rigid_step_study(cases: Sequence[str] = FEATURE_CASES, substeps: Sequence[int] = (2, 4, 8, 16, 32, 64),
                     short: bool = True, duration: float | None = None, out: Path | None = None,
                     log=None, reference_rtol: float = REFERENCE_RTOL, check_rtol: float = CHECK_RTOL,
                     exudyn_options: dict | None = None) -> dict[str, Any]:
    """Relative differences (compare_runs) per case, observable and Exudyn step."""
    first, second = pair()
    exudyn_options = dict(exudyn_options or {})
    doc: dict[str, Any] = {"study": "rigid equivalence vs generalized-alpha step", "short": short,
                           f"{first}_rtol": reference_rtol, "check_rtol": check_rtol,
                           f"{second}_options": exudyn_options,
                           "metric": "max_t max_c |exudyn - reference| / max(max_t |reference|, floor)",
                           "scale_floors": SCALE_FLOORS, "cases": {}}
    for name in cases:
        case = load_case(name).variant(short)
        T = duration or case.duration
        ref, w_ref = _run(first, case, T, n_modes=0, rtol=reference_rtol)
        coarse, _ = _run(first, case, T, n_modes=0, rtol=check_rtol)
        entry = {"duration": T, "control_period": case.solver.control_period,
                 f"{first}_wall_s": w_ref, f"{first}_range": _ranges(ref),
                 f"{first}_self_error": {k: v["error"] for k, v in _errors(name, ref, coarse).items()},
                 "steps": []}
        for s in substeps:
            opts = {"stepping": "continuous" if s < 16 else "period", **exudyn_options}
            ex, w = _run(second, case, T, rigid=True, substeps=s, **opts)
            errs = _errors(name, ref, ex)
            entry["steps"].append({"substeps": s, "h": case.solver.control_period / s, "wall_s": w,
                                   "errors": {k: v["error"] for k, v in errs.items()},
                                   "worst_time": {k: v["worst_time"] for k, v in errs.items()}})
            if log:
                worst = max((v["error"], k) for k, v in errs.items() if k not in RIGID_ZERO)
                log(f"{name} substeps={s} h={case.solver.control_period / s:.3g} wall={w:.1f}s "
                    f"worst {worst[1]}={worst[0]:.2e}")
            doc["cases"][name] = entry
            _write(out, doc)
    return doc


#: the rigid-equivalence configuration (tests/crosscheck/test_rigid_equivalence.py):
#: reference rigid at rtol 1e-12; Exudyn rigid, Newton tight enough that its angular
#: momentum drift (∝ Newton tolerance: 8e-10 at rtol 1e-8, 3e-12 at 1e-12 in 1 s of
#: closed_squeeze) is negligible, restarted at every change of the held inputs (a change
#: carried by the algorithmic acceleration costs O(h): first-order convergence in the
#: controlled cases otherwise), one SolveSteps per control period
RIGID_REFERENCE = {"n_modes": 0, "rtol": REFERENCE_RTOL}
RIGID_EXUDYN = {"rigid": True, "stepping": "period", "newton_rtol": 1e-10, "newton_atol": 1e-11,
                "restart_threshold": 0.0}
#: generalized-α steps per 1 ms control period per case: from the step study, the coarsest
#: power of two at which every observable reaches 1e-5 — the reaction forces decide it in
#: the grasp cases: computed by the index-1 solve (exudyn_model.reactions) they are as
#: accurate as the state, whose 92 Hz rotor-ripple phase error falls as h² and grows with
#: t (docs/exudyn.md §6)
RIGID_SUBSTEPS = {"free_drift": 256, "flex_arm_step": 128, "motor_step": 1024, "closed_squeeze": 4096,
                  "capture": 2048, "release": 2048, "wrist_bistop": 2048, "gravity_gradient": 128,
                  "thrust_burn": 256}
#: per-case departures from RIGID_EXUDYN: gravity_gradient's rotor ripple is 5e-11 rad and its
#: grasp forces mN, so the index-3 Newton iteration meets its round-off floor (at h = 7.8 µs
#: two Jacobians and 216 iterations in the period ending at t = 6.23 s, a 1e-12 rad kick to
#: the ripple, 1e-7 N on the grasp force; with rtol 1e-10 it fails there); Newmark with
#: velocity-level constraints has no such floor: ripple within 2.8e-13 rad over 10 s
RIGID_CASE_OPTIONS = {"gravity_gradient": {"constraints": "index2"}}
RIGID_TOLERANCE = 1e-5


def rigid_options(case: str) -> dict:
    return {**RIGID_EXUDYN, "substeps": RIGID_SUBSTEPS[case], **RIGID_CASE_OPTIONS.get(case, {})}


def rigid_equivalence(cases: Sequence[str] = FEATURE_CASES, out: Path | None = None, log=None) -> dict[str, Any]:
    """Every observable of every feature case (short) in the rigid-equivalence configuration:
    relative error, scale (max of reference range and floor), reference range."""
    first, second = pair()
    doc: dict[str, Any] = {"study": "rigid equivalence", "tolerance": RIGID_TOLERANCE,
                           f"{first}_options": RIGID_REFERENCE, f"{second}_options": RIGID_EXUDYN,
                           "substeps": RIGID_SUBSTEPS, "scale_floors": SCALE_FLOORS, "cases": {}}
    for name in cases:
        case = load_case(name).variant(True)
        ref, w_ref = _run(first, case, case.duration, **RIGID_REFERENCE)
        ex, w_ex = _run(second, case, case.duration, **rigid_options(name))
        rows = compare_runs(name, ref, ex, {n: RIGID_TOLERANCE for n in OBSERVABLES})
        doc["cases"][name] = {
            "duration": case.duration, "substeps": RIGID_SUBSTEPS[name],
            f"{second}_options": rigid_options(name), f"{first}_case_settings": settings_of(case, first).given(),
            "h": case.solver.control_period / RIGID_SUBSTEPS[name], "wall_s": {first: w_ref, second: w_ex},
            "observables": {r.observable: {"error": r.error, "scale": r.scale, f"{first}_range": _ranges(ref)[r.observable],
                                           "worst_time": r.worst_time, "pass": r.passed} for r in rows}}
        if log:
            bad = {r.observable: f"{r.error:.1e}" for r in rows if not r.passed}
            log(f"{name} substeps={RIGID_SUBSTEPS[name]} wall {second} {w_ex:.1f}s {first} {w_ref:.1f}s; above 1e-5: {bad}")
        _write(out, doc)
    return doc


def convergence_study(case_name: str = "flex_arm_step", modes: Sequence[int] = (1, 2, 3, 4),
                      elements: Sequence[int] = (2, 4, 8, 16), short: bool = True, substeps: int | None = None,
                      duration: float | None = None, out: Path | None = None, log=None,
                      observables: Sequence[str] = OBSERVABLES) -> dict[str, Any]:
    """Relative differences per observable for every (reference modes, Exudyn elements)."""
    first, second = pair()
    case = load_case(case_name).variant(short)
    T = duration or case.duration
    sub = substeps or plugin(second).option_default("substeps")
    doc: dict[str, Any] = {"study": "flexible convergence: reference modes x Exudyn elements",
                           "case": case_name, "short": short, "duration": T, "substeps": sub,
                           "h": case.solver.control_period / sub, "modes": list(modes), "elements": list(elements),
                           "metric": "max_t max_c |exudyn - reference| / max(max_t |reference|, floor)",
                           first: {}, second: {}, "errors": {}}
    refs, exus = {}, {}
    for n in modes:
        refs[n], w = _run(first, case, T, n_modes=n)
        doc[first][str(n)] = {"wall_s": w, "range": _ranges(refs[n])}
    for m in elements:
        exus[m], w = _run(second, case, T, n_elements=m, substeps=sub,
                          stepping="continuous" if sub < 16 else "period")
        doc[second][str(m)] = {"wall_s": w}
        for n in modes:
            errs = _errors(case_name, refs[n], exus[m], observables)
            doc["errors"][f"{n},{m}"] = {k: v["error"] for k, v in errs.items()}
            if log:
                log(f"{case_name} modes={n} elements={m}: deflection {errs.get('link_deflection', {}).get('error', math.nan):.2e}"
                    f" joint {errs.get('joint_angles', {}).get('error', math.nan):.2e}")
        _write(out, doc)
    return doc


def refinement_study(case_name: str, modes: Sequence[int], exudyn: Sequence[tuple[int, float]],
                     short: bool = True, out: Path | None = None, log=None) -> dict[str, Any]:
    """The case's `[compare]` rows (error, tolerance) for every (reference modes, Exudyn
    (substeps, EA/EI)): the EA/EI of the Exudyn links replaces the case's
    `params.link.axial_to_bending` (the reference is axially rigid and ignores it)."""
    first, second = pair()
    case = load_case(case_name).variant(short)
    doc: dict[str, Any] = {"study": "refinement: the case's [compare] rows, reference modes x Exudyn (substeps, EA/EI)",
                           "case": case_name, "short": short, "duration": case.duration,
                           "control_period": case.solver.control_period, "modes": list(modes),
                           second: [{"substeps": s, "h": case.solver.control_period / s, "axial_to_bending": ea}
                                      for s, ea in exudyn],
                           "tolerances": {c.observable: c.tolerance for c in case.compare},
                           f"{first}_wall_s": {}, f"{second}_wall_s": {}, "errors": {}}
    refs = {}
    for n in modes:
        refs[n], doc[f"{first}_wall_s"][str(n)] = _run(first, case, case.duration, n_modes=n)
    for s, ea in exudyn:
        p = case.params
        params = replace(p, link=replace(p.link, axial_to_bending=ea))
        exu, w = _run(second, case, case.duration, substeps=s, params=params)
        doc[f"{second}_wall_s"][f"{s},{ea:g}"] = w
        doc[f"{second}_links"] = exu.solver["links"]  # the case's [exudyn] elements
        for n in modes:
            rows = check_runs(case, refs[n], exu)
            doc["errors"][f"{n},{s},{ea:g}"] = {r.observable: r.error for r in rows}
            if log:
                log(f"{case_name} modes={n} substeps={s} EA/EI={ea:g}: "
                    + "  ".join(f"{r.observable} {r.error:.2e}/{r.tolerance:g}" for r in rows))
        _write(out, doc)
    return doc


MISSION_PHASES = ("p1_transport", "p2_capture_regrasp", "p3_com_alignment")
#: what orbit_study reports: the observables a phase is judged by
ORBIT_OBSERVABLES = ("base_pose_I", "ee1_pos_B", "ee2_pos_B", "target_pose_B", "target_attitude", "wrist_angles",
                     "com_pos_B", "motor_torques", "base_torque", "link_deflection", "capture_gap_B")


def orbit_study(cases: Sequence[str] = MISSION_PHASES, out: Path | None = None, log=None,
                with_runs: Path | None = None) -> dict[str, Any]:
    """Each phase's short variant (stand-alone start) with its orbit and without it, the
    reference engine: max_t |with − without| per observable (the base attitude is compared
    relative to the orbital frame's turn: without the orbit the base holds its attitude,
    with it the base tracks the retrograde direction, n = 1.06e-3 rad/s).  `with_runs`: a
    folder of run files of the short variants as they are (`rsmcheck check --short --out`),
    whose reference runs are used instead of running the phases with the orbit again."""
    first, second = pair()
    doc: dict[str, Any] = {"study": "orbit: max_t |with orbit − without| of a phase's short variant, reference",
                           "observables": list(ORBIT_OBSERVABLES), "cases": {}}
    for name in cases:
        case = load_case(name).variant(True)
        flat = replace(case, orbit=False, orbit_spec=OrbitSpec(),
                       initial=replace(case.initial, base_rate=(0.0, 0.0, 0.0)),
                       segments=tuple(replace(sg, base="hold" if sg.base == "retrograde" else sg.base)
                                      for sg in case.segments))
        if with_runs is not None:
            with_orbit, w1 = read_run(Path(with_runs) / f"{name}.h5")[0][first], None
        else:
            with_orbit, w1 = _run(first, case, case.duration)
        without, w2 = _run(first, flat, flat.duration)
        row = {}
        for n in ORBIT_OBSERVABLES:
            a = np.asarray(with_orbit.observables[n], float)
            b = np.asarray(without.observables[n], float)
            if n == "base_pose_I":
                # displacement from the start: in orbit O is the system's initial COM, without
                # it the origin of the case's inertial frame; the attitude relative to the
                # frame it is held in (the orbital frame turns at n in orbit)
                a = a - a[0]
                b = b - b[0]
                a[:, 2] -= case.initial.base_rate[2] * np.asarray(with_orbit.observables["time"])
            row[n] = float(np.max(np.abs(a - b)))
        doc["cases"][name] = {"duration": case.duration, "max_abs": row, "wall_s": [w1, w2],
                              "events": {"with": [(e.time, e.kind) for e in with_orbit.events if e.kind != "segment"],
                                         "without": [(e.time, e.kind) for e in without.events if e.kind != "segment"]}}
        if log:
            log(f"{name}: " + "  ".join(f"{k} {v:.2e}" for k, v in row.items()))
        _write(out, doc)
    return doc


#: the reference solution of `integrator_study`
TIGHT = ("dopri5", 1e-10)


def integrator_study(case_name: str, grid: Sequence[tuple[str, float]], out: Path | None = None,
                     log=None) -> dict[str, Any]:
    """The case's short variant in the reference with each (integrator, rtol) of `grid`:
    wall seconds, steps and rejected steps per control sample, and max_t |x − x_tight| of
    every observable of the case's `[compare]` table, x_tight from Dormand–Prince at rtol
    1e-10 (`TIGHT`).  Wall times are one run each, on whatever the machine is doing: read
    them as ratios within one study."""
    first, _ = pair()
    case = load_case(case_name).variant(True)
    rows = [c.observable for c in case.compare]
    tight, w = _run(first, case, case.duration, integrator=TIGHT[0], rtol=TIGHT[1])
    doc: dict[str, Any] = {"study": "integrators: the case's [compare] rows against Dormand–Prince at rtol 1e-10",
                           "case": case_name, "duration": case.duration, "tight_wall_s": w, "runs": []}
    for integrator, rtol in grid:
        r, w = _run(first, case, case.duration, integrator=integrator, rtol=rtol)
        n = r.solver["samples"]
        errors = {o: float(np.max(np.abs(np.asarray(r.observables[o], float)
                                         - np.asarray(tight.observables[o], float)))) for o in rows}
        doc["runs"].append({"integrator": integrator, "rtol": rtol, "wall_s": w,
                            "steps_per_sample": r.solver["steps"] / n,
                            "rejected_per_sample": r.solver["rejected_steps"] / n, "error": errors})
        if log:
            log(f"{case_name} {integrator} rtol {rtol:g}: {w:.2f} s, {r.solver['steps'] / n:.2f} steps/sample | "
                + "  ".join(f"{o} {e:.2e}" for o, e in errors.items()))
        _write(out, doc)
    return doc


def _integrator_grid(text: str) -> list[tuple[str, float]]:
    """'dopri5:1e-7,imex:1e-8' -> [("dopri5", 1e-7), ("imex", 1e-8)] (an argparse type)."""
    grid = []
    for item in text.split(","):
        name, _, rtol = item.partition(":")
        try:
            value = float(rtol)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{item!r} is not INTEGRATOR:RTOL (e.g. imex:1e-8)") from None
        if name not in ("dopri5", "trbdf2", "imex") or not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"{item!r}: the integrator is dopri5, trbdf2 or imex, rtol finite and > 0")
        grid.append((name, value))
    return grid


def _exudyn_grid(text: str) -> list[tuple[int, float]]:
    """'32:1e5,256:1e6' -> [(32, 1e5), (256, 1e6)] (an argparse type: a bad item is a
    one-line usage error)."""
    grid = []
    for item in text.split(","):
        s, _, ea = item.partition(":")
        try:
            pair = (int(s), float(ea))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{item!r} is not SUBSTEPS:EA/EI (e.g. 256:1e6)") from None
        if pair[0] < 1 or not math.isfinite(pair[1]) or pair[1] <= 0:
            raise argparse.ArgumentTypeError(f"{item!r}: substeps must be ≥ 1 and EA/EI finite and > 0")
        grid.append(pair)
    return grid


def _int_list(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of integers") from None


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rsmcheck.orchestration.studies")
    sub = p.add_subparsers(dest="study", required=True)
    r = sub.add_parser("rigid")
    r.add_argument("cases", nargs="*", default=list(FEATURE_CASES))
    r.add_argument("--substeps", type=_int_list, default=[2, 4, 8, 16, 32, 64])
    r.add_argument("--duration", type=float)
    r.add_argument("--constraints", default="index3", choices=("index3", "index2"))
    r.add_argument("--out")
    q = sub.add_parser("equivalence")
    q.add_argument("cases", nargs="*", default=list(FEATURE_CASES))
    q.add_argument("--out", default=str(DATA_DIR / "rigid_equivalence.json"))
    c = sub.add_parser("convergence")
    c.add_argument("case", nargs="?", default="flex_arm_step")
    c.add_argument("--modes", type=_int_list, default=[1, 2, 3, 4])
    c.add_argument("--elements", type=_int_list, default=[2, 4, 8, 16])
    c.add_argument("--substeps", type=int)
    c.add_argument("--duration", type=float)
    c.add_argument("--out")
    f = sub.add_parser("refinement")
    f.add_argument("case")
    f.add_argument("--modes", type=_int_list, default=[2, 4, 6])
    f.add_argument("--exudyn", type=_exudyn_grid, default=_exudyn_grid("32:1e5,128:1e5,128:1e6,256:1e6"),
                   help="SUBSTEPS:EA/EI pairs, comma-separated")
    f.add_argument("--out")
    o = sub.add_parser("orbit")
    o.add_argument("cases", nargs="*", default=list(MISSION_PHASES))
    o.add_argument("--out", default=str(DATA_DIR / "orbit_effect.json"))
    o.add_argument("--with-runs", help="folder of short run files (rsmcheck check --short --out) to take the runs in orbit from")
    g = sub.add_parser("integrators")
    g.add_argument("case")
    g.add_argument("--grid", type=_integrator_grid, default=_integrator_grid("dopri5:1e-7,imex:1e-7,imex:1e-8"),
                   help="INTEGRATOR:RTOL pairs, comma-separated")
    g.add_argument("--out")
    a = p.parse_args(argv)

    def log(msg: str) -> None:
        print(msg, flush=True)

    def dispatch() -> int:
        if a.study == "equivalence":
            rigid_equivalence(a.cases, out=Path(a.out), log=log)
        elif a.study == "rigid":
            out = Path(a.out) if a.out else DATA_DIR / f"rigid_steps_{a.constraints}.json"
            rigid_step_study(a.cases, a.substeps, duration=a.duration,
                             out=out, log=log, exudyn_options={"constraints": a.constraints})
        elif a.study == "orbit":
            orbit_study(a.cases, out=Path(a.out), log=log, with_runs=Path(a.with_runs) if a.with_runs else None)
        elif a.study == "integrators":
            out = Path(a.out) if a.out else DATA_DIR / f"integrators_{a.case}.json"
            integrator_study(a.case, a.grid, out=out, log=log)
        elif a.study == "refinement":
            out = Path(a.out) if a.out else DATA_DIR / f"refinement_{a.case}.json"
            refinement_study(a.case, a.modes, a.exudyn, out=out, log=log)
        else:
            out = Path(a.out) if a.out else DATA_DIR / f"convergence_{a.case}.json"
            convergence_study(a.case, a.modes, a.elements,
                              substeps=a.substeps, duration=a.duration, out=out, log=log)
        return 0

    return exit_code("rsmcheck.orchestration.studies", dispatch)


if __name__ == "__main__":
    sys.exit(main())
