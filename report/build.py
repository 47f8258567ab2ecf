"""`rsmcheck report`'s renderer: one self-contained HTML page from stored results.

It reads what `rsmcheck.orchestration.collect` stored in a folder (runs, verdict, Pinocchio and
eigenfrequency rows) and the project's stored studies (docs/data: refinement and
convergence studies, speed, fault injection) and runs nothing.  The page, top to bottom:

1. the verdict — every check of every case, mission phase, golden and Pinocchio quantity
   in one table, failures first, then by margin (tolerance / error), smallest first — and
   the provenance (commit, versions, platform, solver settings, date);
2. the known departures from the paper with their measured sizes (rsmcheck/core/departures.toml,
   the table of docs/physics.md §9);
3. the mission as one flight: each phase's compared observables on the mission's time
   axis, both engines overlaid, the error below on a log scale with the tolerance, the
   phase's events marked;
4. the paper's figures reproduced from the runs (report.paper);
5. every case: its checks, events, and its observables with the golden overlaid;
6. Pinocchio, eigenfrequencies, engine studies, speed, fault injection (the fault × case
   matrix, `fault_matrix`).

Plots are plotly.js figures (inlined once), drawn when they scroll into view (all at once
before printing, or with ``#render-all`` in the address).  The page is written to a
temporary name and renamed when complete.
"""

from __future__ import annotations

import html
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import jinja2
import plotly.offline

from rsmcheck.core import departures
from rsmcheck.core.cases import Case, list_cases, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import BY_NAME
from rsmcheck.core.plugins import plugins
from rsmcheck.orchestration.bench import per_sample_us
from rsmcheck.orchestration.bench_diff import work
from rsmcheck.orchestration.collect import MODES, VERDICT, phase_runs
from rsmcheck.orchestration.compare import metric_label
from rsmcheck.orchestration.faults import CASE_CHECKS, cell_letters
from rsmcheck.orchestration.gate import golden_path, goldens_dir, read_golden
from rsmcheck.orchestration.targets import TARGETS, read_targets
from rsmcheck.report import paper
from rsmcheck.report.fuzz_section import fuzz_section
from rsmcheck.report.plots import colour, comparison_figure, run_marks, simple_figure
from rsmcheck.core.store import EngineRun, machine_text, read_run, same_machine, write_text

ROOT = Path(__file__).resolve().parent.parent
DATA_DIR = ROOT / "docs" / "data"
#: what a reader looks at in every case besides its compared observables
OVERVIEW = ("base_pose_I", "joint_angles", "motor_torques", "link_deflection", "energy", "momentum_I")


# ---------------------------------------------------------------------------------------
# numbers and cells
# ---------------------------------------------------------------------------------------
def fmt(x: Any, digits: int = 3) -> str:
    """A number for a table: '–' for none/NaN, '∞' for inf, else 3 significant digits."""
    if x is None or x == "inf":
        return "∞" if x == "inf" else "–"
    x = float(x)
    if math.isnan(x):
        return "–"
    if math.isinf(x):
        return "∞"
    return f"{x:.{digits}g}" if 0.01 <= abs(x) < 1e4 or x == 0 else f"{x:.{digits - 1}e}"


def _margin(x: Any) -> float:
    if x is None:
        return -math.inf
    return math.inf if x == "inf" else float(x)


# ---------------------------------------------------------------------------------------
# the verdict: one row per check
# ---------------------------------------------------------------------------------------
@dataclass
class VerdictRow:
    kind: str  # cross-check | mission | gate | Pinocchio
    case: str
    item: str
    metric: str
    error: Any
    tolerance: Any
    margin: float
    passed: bool
    note: str = ""
    anchor: str = ""
    pair: str = ""  # a comparison's engines, the one under test first ("" for gate and rigid rows)


def pair_label(row: dict) -> str:
    """'reference vs exudyn': the engines a comparison row judges, the one under test first."""
    return " vs ".join(row.get("engines", ()))


def no_golden(g: dict) -> bool:
    """A stored gate row that compared nothing: there was no golden for the run."""
    return bool(g.get("inputs_changed")) and g["inputs_changed"][0].startswith("no golden")


def verdict_rows(verdict: dict, goldens: bool = True) -> list[VerdictRow]:
    """Every row of the stored verdict, failures first, then the smallest margin first.
    `goldens` False (no goldens/ folder: an installed package) leaves out the gate rows
    that had no golden to compare with; the page says so in one line."""
    rows = []
    for kind, key in (("cross-check", "checks"), ("mission phase", "mission")):
        for r in verdict.get(key, []):
            note = r.get("why", "")
            if r.get("inherited"):
                note = (f"tolerance includes the difference the engines carry into the phase, "
                        f"d0 = {fmt(r['inherited'])}; " + note)
            if r.get("at_switches"):
                note += " — not compared at the constraint switches: " + ", ".join(
                    f"t = {a['time']:.6g} s ({fmt(a['error'])})" for a in r["at_switches"])
            if r.get("between_events"):
                note += (f" — not compared between the engines' instants of one event "
                         f"(at most {fmt(r['event_skew'] * 1e3)} ms apart): " + ", ".join(
                             f"t = {a['time']:.6g} s ({fmt(a['error'])})" for a in r["between_events"]))
            anchor = r["case"].replace("/", "-")
            rows.append(VerdictRow(kind, r["case"], r["observable"], metric_label(r.get("metric", ""), r.get("window")),
                                   r["error"], r["tolerance"],
                                   _margin(r.get("margin")), bool(r["pass"]), note, anchor, pair_label(r)))
    for g in verdict.get("gate", []):
        if not goldens and no_golden(g):
            continue
        ratio = g.get("largest_ratio")
        if ratio is not None and g.get("work_ratio") is not None:
            ratio = max(ratio, g["work_ratio"])
        why = "; ".join(g.get("inputs_changed", []) + g.get("structure", []))
        moved = ", ".join(f"{m['observable']} {fmt(m['ratio'])}×" for m in g.get("moved", []))
        more = ", ".join(w["text"] for w in g.get("work", []) if w["grew"])
        work = g.get("work_summary")  # rsmcheck.orchestration.gate.GateResult.work_summary
        note = ("against its golden; error = the larger of largest change / its gate tolerance and "
                "work growth / its limit" + (f"; moved: {moved}" if moved else "")
                + (f"; more work: {more}" if more else "") + (f"; {work}" if work else "")
                + (f"; {why}" if why else ""))
        rows.append(VerdictRow("gate", g["case"], g["engine"], "golden", ratio, 1.0,
                               1.0 / ratio if ratio else math.inf, bool(g.get("unchanged")), note, g["case"]))
    for checker, checks in verdict.get("rigid", {}).items():
        rows += _rigid_rows(checker, checks)
    rows.sort(key=lambda r: (r.passed, r.margin))
    return rows


def _mode_engines(modes: dict | None) -> dict[str, list[dict[str, str]]]:
    """The engines whose frequencies the stored modes tables hold ("ENGINE_hz" keys), in
    registry order, with their labels: the columns of the eigenfrequency section."""
    out = {}
    for part in ("links", "arms"):
        rows = (modes or {}).get(part) or [{}]
        out[part] = [{"name": n, "label": p.label} for n, p in plugins().items() if f"{n}_hz" in rows[0]]
    return out


def _rigid_rows(checker: str, checks: list[dict]) -> list[VerdictRow]:
    """The verdict rows of a checking plug-in's rigid checks."""
    rows = []
    label = plugins()[checker].label if checker in plugins() else checker
    for p in checks:
        err = p.get("max_rel_error")
        rows.append(VerdictRow(label, f"{p['chain']}, holding {p['holding']}, {p['n_modes']} modes",
                               p["quantity"], "rel. max", err, p["tolerance"],
                               p["tolerance"] / err if err else (math.inf if err == 0 else -math.inf),
                               bool(p["pass"]), p.get("error", f"{p['states']} random states; worst entry {p.get('entry', '')}"),
                               "rigid"))
    return rows


def verdict_summary(rows: list[VerdictRow]) -> list[dict]:
    """Per kind of check, and per pair of engines within a kind that compares engines: how
    many, how many fail, and the smallest margin (where)."""
    out = []
    for kind in ("cross-check", "mission phase", "gate", "Pinocchio"):
        mine = [r for r in rows if r.kind == kind]
        pairs = list(dict.fromkeys(r.pair for r in mine if r.pair))
        groups = [(f"{kind}, {p}", [r for r in mine if r.pair == p]) for p in pairs] if len(pairs) > 1 else [(kind, mine)]
        for label, group in groups:
            if not group:
                out.append({"kind": label, "n": 0, "failed": 0, "worst": None})
                continue
            worst = min(group, key=lambda r: (r.passed, r.margin))
            out.append({"kind": label, "n": len(group), "failed": sum(not r.passed for r in group), "worst": worst})
    return out


# ---------------------------------------------------------------------------------------
# stored inputs
# ---------------------------------------------------------------------------------------
@dataclass
class Stored:
    """What the renderer reads: the collect folder and the project's stored studies."""

    folder: Path
    verdict: dict
    cases: list[Case]
    runs: dict[str, dict[str, EngineRun]] = field(default_factory=dict)
    modes: dict = field(default_factory=dict)

    @property
    def short(self) -> bool:
        return bool(self.verdict.get("provenance", {}).get("short", True))


def only_engines(verdict: dict, engines: Sequence[str]) -> dict:
    """The verdict's rows that judge `engines` alone: a comparison row whose pair is among
    them, a gate row of one of them (the rigid checks judge the model, not an engine)."""
    keep = set(engines)
    out = dict(verdict)
    for key in ("checks", "mission"):
        out[key] = [r for r in verdict.get(key, []) if set(r.get("engines", ())) <= keep]
    out["gate"] = [g for g in verdict.get("gate", []) if g.get("engine") in keep]
    return out


def load_stored(folder: Path, case_names: Sequence[str] | None = None,
                engines: Sequence[str] | None = None) -> Stored:
    """Read the verdict, runs and tables that `rsmcheck.orchestration.collect` stored in
    `folder`; `engines` (None: every engine stored) keeps those engines' runs and rows only,
    in that order: a run file may hold engines an earlier report ran."""
    path = folder / VERDICT
    if not path.is_file():
        raise InputError(str(path), "verdict", "no stored results: run `rsmcheck report` (it collects first)")
    verdict = json.loads(path.read_text())
    if engines is not None:
        verdict = only_engines(verdict, engines)
    cases = [load_case(n) for n in case_names] if case_names else [load_case(p) for p in list_cases()]
    st = Stored(folder, verdict, cases)
    for case in cases:
        run_path = folder / "runs" / f"{case.name}.h5"
        if run_path.is_file():
            runs = read_run(run_path)[0]
            st.runs[case.name] = runs if engines is None else {e: runs[e] for e in engines if e in runs}
    if (folder / MODES).is_file():
        st.modes = json.loads((folder / MODES).read_text())
    return st


def _stored_json(data_dir: Path, pattern: str) -> list[tuple[Path, dict]]:
    """(path, document) of each readable JSON file of `data_dir` matching `pattern`."""
    out = []
    for path in sorted(data_dir.glob(pattern)):
        try:
            out.append((path, json.loads(path.read_text())))
        except (OSError, json.JSONDecodeError):
            continue
    return out


def departures_table() -> tuple[list[str], list[list[str]]]:
    """The departures from the paper (paper, suite, why, measured size): header, rows, from
    the package's data file (rsmcheck.core.departures; docs/physics.md §9 shows the same)."""
    return departures.table()


# ---------------------------------------------------------------------------------------
# the page
# ---------------------------------------------------------------------------------------
class Page:
    """Collects figures (id → figure dict) while the sections are rendered."""

    def __init__(self) -> None:
        self.figures: list[dict] = []

    def figure(self, fig: dict, cls: str = "plot") -> str:
        self.figures.append(fig)
        return f"<div class='{cls}' data-fig='{len(self.figures) - 1}'></div>"


def _md(text: str) -> str:
    """The little Markdown of docs tables: **bold**, `code`."""
    out = html.escape(text)
    out = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", out)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", out)


def _check_map(rows: list[dict]) -> dict[tuple[str, str], list[dict]]:
    """(case, observable) → its comparison rows, one per pair of engines: with three engines
    a row of one pair must not hide another's."""
    out: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        out.setdefault((r["case"], r["observable"]), []).append(r)
    return out


def _errors_title(rows: list[dict], metric: str) -> str:
    """' — max_abs error 1.2e-07 vs tolerance 3e-07 (pass)', per pair where there are more."""
    parts = [(f"{pair_label(r)}: " if len(rows) > 1 else "")
             + f"error {fmt(r['error'])} vs tolerance {fmt(r['tolerance'])} ({'pass' if r['pass'] else 'FAIL'})"
             for r in rows]
    return f" — {metric} " + "; ".join(parts) if parts else ""


def _tolerances(rows: list[dict]) -> dict[str, float]:
    """Each compared engine's tolerance against the first (the difference panel's lines)."""
    return {r["engines"][1]: r["tolerance"] for r in rows if len(r.get("engines", ())) == 2}


def mission_sections(page: Page, st: Stored, checks: dict[tuple[str, str], list[dict]]) -> list[dict]:
    """One section per phase of the chained mission."""
    out = []
    for case in st.cases:
        if not case.phases or case.name not in st.runs:
            continue
        runs = st.runs[case.name]
        by_engine = {e: phase_runs(case, st.short, r) for e, r in runs.items()}
        names = list(by_engine)
        ref = by_engine[names[0]]
        bounds = [(ph.name, t0, t0 + ph.duration) for ph, t0, _ in ref]
        for k, (ph, t0, _) in enumerate(ref):
            pruns = {e: by_engine[e][k][2] for e in names}
            figs = []
            for spec in ph.compare:
                found = checks.get((f"{case.name}/{ph.name}", spec.observable), [])
                title = (f"{spec.observable} [{BY_NAME[spec.observable].unit}]"
                         + (_errors_title(found, metric_label(spec.metric, spec.window)) if found else
                            f" — tolerance {fmt(spec.tolerance)}"))
                figs.append(page.figure(comparison_figure(
                    title, BY_NAME[spec.observable].unit, pruns, spec.observable,
                    tolerance=spec.tolerance, tolerances=_tolerances(found), metric=spec.metric,
                    compared=spec.window, events=run_marks(pruns[names[0]], t0), time_offset=t0, bands=bounds,
                    window=(t0, t0 + ph.duration))))
            rows = [r for s in ph.compare for r in checks.get((f"{case.name}/{ph.name}", s.observable), [])]
            out.append({"id": f"{case.name}-{ph.name}", "title": f"{case.name}: {ph.name}",
                        "phase": ph, "t0": t0, "rows": rows, "figures": figs,
                        "events": [(e, ev) for e, r in pruns.items() for ev in run_marks(r, t0)]})
    return out


def case_sections(page: Page, st: Stored, checks: dict[tuple[str, str], list[dict]], gates: dict) -> list[dict]:
    """One section per stand-alone case: its checks, events, golden verdicts and plots."""
    out = []
    for case in st.cases:
        if case.phases:
            continue
        variant = case.variant(st.short)
        runs = st.runs.get(case.name)
        if runs is None:
            out.append({"id": case.name, "title": case.name, "case": variant, "missing": True})
            continue
        golden = None
        first = next(iter(runs))  # the model under test: its golden is drawn with it
        gpath = golden_path(case.name, first)
        if st.short and gpath.exists():
            golden = read_golden(gpath, first).run
        compared = [s.observable for s in variant.compare]
        figs = []
        for name in compared + [n for n in OVERVIEW if n not in compared]:
            spec = next((s for s in variant.compare if s.observable == name), None)
            found = checks.get((case.name, name), []) if spec else []
            title = f"{name} [{BY_NAME[name].unit}]" + (
                _errors_title(found, metric_label(spec.metric, spec.window)) if found else "")
            first = next(iter(runs.values()))
            figs.append(page.figure(comparison_figure(title, BY_NAME[name].unit, runs, name, golden=golden,
                                                      tolerance=spec.tolerance if spec else None,
                                                      tolerances=_tolerances(found),
                                                      compared=spec.window if spec else None,
                                                      metric=spec.metric if spec else "", events=run_marks(first))))
        out.append({"id": case.name, "title": case.name, "case": variant, "missing": False,
                    "rows": [r for s in variant.compare for r in checks.get((case.name, s.observable), [])],
                    "gates": gates.get(case.name, []), "figures": figs,
                    "events": [(e, ev) for e, r in runs.items() for ev in r.events if ev.kind != "segment"],
                    "stats": {e: {"wall_s": r.solver.get("wall_s"), "steps": r.solver.get("steps"),
                                  "sim_s": float(r.observables["time"][-1])} for e, r in runs.items()}})
    return out


def _environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent),
                             autoescape=jinja2.select_autoescape(["html", "j2"]), trim_blocks=True, lstrip_blocks=True)
    env.filters["fmt"] = fmt
    env.filters["metric"] = lambda row: metric_label(row.get("metric", ""), row.get("window"))
    env.filters["md"] = lambda s: jinja2.utils.markupsafe.Markup(_md(s))
    return env


def render(folder: Path, out: Path, case_names: Sequence[str] | None = None, data_dir: Path = DATA_DIR,
           engines: Sequence[str] | None = None) -> Path:
    """Write the page for the results stored in `folder` (and the studies in `data_dir`) to
    `out`: of `engines` only (None: every engine stored)."""
    st = load_stored(folder, case_names, engines)
    page = Page()
    v = st.verdict
    checks = _check_map(v.get("checks", []) + v.get("mission", []))
    gates: dict[str, list] = {}
    for g in v.get("gate", []):
        gates.setdefault(g["case"], []).append(g)
    goldens = goldens_dir().is_dir()
    rows = verdict_rows(v, goldens)
    missing_goldens = 0 if goldens else sum(no_golden(g) for g in v.get("gate", []))
    missions = mission_sections(page, st, checks)
    cases = case_sections(page, st, checks, gates)
    figures = paper.figures(page, st)
    dep_head, dep_rows = departures_table()
    bench = speed_sections(page, _stored_json(data_dir, "bench_*.json"))
    faults = next((doc for _, doc in _stored_json(data_dir, "faults.json")), None)
    fuzz = fuzz_section(page, next((doc for _, doc in _stored_json(data_dir, "fuzz.json")), None))
    html_text = _environment().get_template("page.html.j2").render(
        prov=v.get("provenance", {}), rows=rows, summary=verdict_summary(rows), n_fail=sum(not r.passed for r in rows),
        kinds=sorted({r.kind for r in rows}), missing_goldens=missing_goldens, missions=missions, cases=cases,
        paper=figures, dep_head=dep_head, dep_rows=dep_rows,
        rigid=[{"label": plugins()[n].label if n in plugins() else n, "checks": c} for n, c in v.get("rigid", {}).items()],
        modes=st.modes, mode_engines=_mode_engines(st.modes),
        studies=_studies(data_dir), bench=bench, bench_note=machines_note(bench),
        fuzz=fuzz, faults=faults, fault_list=fault_rows(faults) if faults else [], fault_matrix=fault_matrix(faults),
        figures_count=len(page.figures), figures_json=json.dumps(page.figures, separators=(",", ":"), allow_nan=False),
        plotly_js=plotly.offline.get_plotlyjs(), short=st.short, engine_labels=_labels(st))
    return write_text(out, html_text)


def _labels(st: Stored) -> list[str]:
    """The labels (the registry's; the name of an engine not installed) of the engines whose
    runs the page draws, in the order they were run, and of the rigid checkers."""
    found = plugins()
    drawn = list(dict.fromkeys(e for runs in st.runs.values() for e in runs))
    drawn += [n for n in st.verdict.get("rigid", {}) if n not in drawn]
    return [found[e].label if e in found else e for e in drawn]


def machines_note(bench: list[tuple[Path, dict]]) -> str:
    """'' when every stored bench document ran on one recorded machine (rsmcheck.core.store.same_machine),
    else a sentence saying how many machines they ran on and how many did not record theirs:
    wall times then compare within one document only."""
    recorded = [doc["machine"] for _, doc in bench if doc.get("machine")]
    kinds: list[dict] = []
    for m in recorded:
        if not any(same_machine(m, k) for k in kinds):
            kinds.append(m)
    unknown = len(bench) - len(recorded)
    if len(kinds) + unknown <= 1:
        return ""
    return (f"These {len(bench)} documents ran on {len(kinds)} recorded machine{'s' if len(kinds) != 1 else ''}"
            + (f", and {unknown} did not record theirs" if unknown else "")
            + ": compare wall times within one document only (ratios between its runs).")


def speed_sections(page: Page, bench: list[tuple[Path, dict]]) -> list[tuple[Path, dict]]:
    """Each stored bench document with what the page shows beside its runs: the machine it
    ran on, each run's work (`bench_diff.work`: what compares across machines), the speed
    targets it measures (target, measured, margin), the × real time of the mission's phases
    per engine against the phase target, and where each run's time went (µs per control
    sample)."""
    for _, doc in bench:
        doc["machine_text"] = machine_text(doc.get("machine"))
        for r in doc.get("runs", []):
            name, count = work(r)
            r["work_text"] = f"{count:,.0f} {name}".replace(",", "\u202f") if count is not None else "–"
        doc["targets"] = [r for r in read_targets(doc) if r.measured is not None]
        doc["phase_fig"] = _phase_speed_figure(page, doc)
        doc["per_sample"] = [{"case": r["case"], "engine": r["engine"], "samples": r["split"]["samples"],
                              "us": per_sample_us(r["split"])}
                             for r in doc.get("runs", []) if "error" not in r and r.get("split", {}).get("samples")]
    return bench


def _phase_speed_figure(page: Page, doc: dict) -> str:
    """Bars of × real time per phase of the full mission, one colour per engine, log axis,
    with the phase target as a dashed line; '' when the document has no full mission (the
    target is about the full length; a short mission's phases stay in the table)."""
    runs = [r for r in doc.get("runs", []) if r.get("phases") and r.get("variant") == "full" and "error" not in r]
    if not runs:
        return ""
    bound = next(t.bound for t in TARGETS if t.key == "reference_phases")
    traces = [{"type": "bar", "name": r["engine"],
               "x": [p["phase"] for p in r["phases"]],
               "y": [p["sim_s"] / p["wall_s"] if p.get("wall_s") else None for p in r["phases"]],
               "marker": {"color": colour(r["engine"])}} for r in runs]
    phases = [p["phase"] for p in runs[0]["phases"]]
    traces.append({"type": "scatter", "mode": "lines", "name": f"target ≥ {bound:g} × real time",
                   "x": [phases[0], phases[-1]], "y": [bound, bound],
                   "line": {"color": "#b00", "dash": "dash", "width": 1.2}})
    fig = simple_figure("× real time of each mission phase (simulated s per wall s)", traces, xlabel="phase",
                        ylabel="× real time", height=300, barmode="group", hovermode="closest")
    fig["layout"]["yaxis"]["type"] = "log"
    return page.figure(fig)


def _studies(data_dir: Path) -> dict[str, list]:
    """The stored engine studies of docs/data, by kind."""
    return {kind: _stored_json(data_dir, f"{kind}_*.json") for kind in ("rigid_steps", "convergence", "refinement")}


# ---------------------------------------------------------------------------------------
# the fault-injection matrix (rsmcheck.orchestration.faults, docs/data/faults.json)
# ---------------------------------------------------------------------------------------
#: the per-fault checks drawn after the cases' columns, with their letters
FAULT_CHECKS = {"rigid": "R", "analytic": "A"}
#: characters of a cell's tooltip (the failing rows)
TITLE_CHARS = 900


def _cell_class(letters: str, control: bool) -> str:
    """A matrix cell's colour: caught by the control (a false alarm), by the cross-check
    and the gate, by one of them, by a per-fault check, or by nothing."""
    if not letters:
        return "fm-none"
    if control:
        return "fm-false"
    return {"CG": "fm-cg", "C": "fm-c", "G": "fm-g"}.get(letters, "fm-x")


def _title(head: str, lines: Sequence[str]) -> str:
    text = "\n".join([head, *lines]) if lines else f"{head}: caught by nothing"
    return text if len(text) <= TITLE_CHARS else text[:TITLE_CHARS - 1] + "…"


def fault_rows(doc: dict) -> list[dict]:
    """One row per fault of a stored matrix: its name, layer, what, the failing rows of each
    check ('CASE: row' for the per-case ones) and whether it came out as expected (a
    control caught by nothing, any other fault caught by something).  A document from
    before the matrix had cells per case holds the per-case rows in flat lists already."""
    out = []
    for f in doc.get("faults", []):
        cells = f.get("cases")
        rows = {k: ([f"{case}: {row}" for case, cell in cells.items() for row in cell.get(k, [])]
                    if isinstance(cells, dict) else list(f.get(k) or [])) for k in CASE_CHECKS}
        control = f.get("layer") == "none"
        caught = bool(f.get("caught_by"))
        out.append({"name": f.get("name", ""), "layer": f.get("layer", ""), "what": f.get("what", ""), **rows,
                    "rigid": list(f.get("rigid") or []), "analytic": list(f.get("analytic") or []),
                    "control": control, "ok": not caught if control else caught})
    return out


def fault_matrix(doc: dict | None) -> dict | None:
    """The fault × case × check matrix as the page draws it: one row per fault, one column
    per case, each cell the letters of the per-case checks that caught the fault on that
    case (`CASE_CHECKS`: C cross-check, G gate; '·' nothing) with the failing rows as its
    tooltip, then one column per per-fault check (R rigid, A analytic), and a last row
    counting, per column, the faults caught there (controls aside).  None without a stored
    document or for one without cells per case."""
    if not doc or not doc.get("faults") or not all(isinstance(f.get("cases"), dict) for f in doc["faults"]):
        return None
    cases = list(doc.get("cases") or [])
    rows, totals = [], [0] * (len(cases) + len(FAULT_CHECKS))
    for f, summary in zip(doc["faults"], fault_rows(doc)):
        cells = []
        for case in cases:
            cell = f["cases"].get(case)
            if cell is None:
                cells.append({"text": "", "cls": "fm-out", "title": f"{case}: not run"})
                continue
            letters = cell_letters(cell)
            lines = [f"{k}: {row}" for k in CASE_CHECKS for row in cell.get(k, [])]
            cells.append({"text": letters or "·", "cls": _cell_class(letters, summary["control"]),
                          "title": _title(f"{f['name']} on {case}", lines)})
        for k, letter in FAULT_CHECKS.items():
            found = summary[k]
            cells.append({"text": letter if found else "·", "cls": _cell_class(letter if found else "", summary["control"]),
                          "title": _title(f"{f['name']}, {k}", found)})
        if not summary["control"]:
            totals = [n + (c["text"] not in ("", "·")) for n, c in zip(totals, cells)]
        rows.append({**summary, "cells": cells})
    return {"cases": cases, "checks": list(FAULT_CHECKS), "rows": rows, "totals": totals}
