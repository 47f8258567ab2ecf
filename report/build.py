"""`rsmcheck report`: run the cases, write the run files and one self-contained HTML page.

The page has, per case: what the case isolates, the run statistics of every engine, the
event log, conservation drifts, the engine comparison by the case's [compare] table
(observable, metric, error, tolerance, margin, result, why — the rows of `rsmcheck check`,
when both engines ran), and the observables against time with every engine overlaid; at
the top, the Pinocchio rigid checks, the eigenfrequencies of `rsmcheck modes` (with
Exudyn) and the stored engine studies (docs/data/*.json from `rsmcheck.studies`).  Everything is embedded (PNG as base64),
so the file can be mailed or archived alone.  It is written to a temporary name and
renamed when complete.
"""

from __future__ import annotations

import html
import json
import os
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

import numpy as np

from cases.loader import Case, list_cases, load_case
from report.figures import case_figure, conservation_figure
from rsmcheck.runner import terminal_progress
from rsmcheck.errors import InputError, SimulationDiverged
from rsmcheck.store import EngineRun, git_commit, read_run

CSS = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:1300px;color:#222}
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}
table{border-collapse:collapse;font-size:0.85em;margin:0.5em 0}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#f3f3f3}
td.l,th.l{text-align:left}.pass{color:#070}.fail{color:#b00;font-weight:bold}
.small{font-size:0.85em;color:#555}img{max-width:100%}
"""


def _drifts(r: EngineRun) -> dict[str, float]:
    o = r.observables
    e = o["energy"].sum(axis=1)
    p = o["momentum_I"]
    return {
        "energy_drift_J": float(np.max(np.abs(e - e[0]))),
        "momentum_drift": float(np.max(np.abs(p - p[0]))),
        "residual_max_m": float(np.max(np.abs(o["constraint_residual"]))),
        "deflection_max_m": float(np.max(np.abs(o["link_deflection"]))),
    }


def _pinocchio_rows() -> list[dict]:
    """The Pinocchio check's JSON (`rsmcheck pinocchio --json`), run in a subprocess."""
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "pinocchio", "--json"],
                          capture_output=True, text=True)
    try:
        return json.loads(proc.stdout)["checks"]
    except (json.JSONDecodeError, KeyError):
        return [{"quantity": "pinocchio check did not run", "chain": "-", "states": 0,
                 "max_rel_error": float("nan"), "tolerance": 0.0, "pass": False,
                 "error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "no output"}]


def _table(header: Sequence[str], rows: Sequence[Sequence[str]], left: int = 1) -> str:
    th = "".join(f"<th class='l'>{h}</th>" if i < left else f"<th>{h}</th>" for i, h in enumerate(header))
    body = "".join("<tr>" + "".join(f"<td class='l'>{c}</td>" if i < left else f"<td>{c}</td>"
                                   for i, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<table><tr>{th}</tr>{body}</table>"


def _cell(error: float, tolerance: float) -> str:
    """An error against its tolerance: red when above it (or not a number)."""
    text = _fmt(error)
    return text if error <= tolerance else f"<span class='fail'>{text}</span>"


def _fmt(x: float) -> str:
    if x != x:
        return "–"
    if x == float("inf"):
        return "∞"
    return f"{x:.3g}" if 0.01 <= abs(x) < 1e4 else f"{x:.2e}"


def _compare_html(case: Case, runs: dict[str, EngineRun], short: bool) -> str:
    """The engine comparison of one case: its [compare] table applied to the runs."""
    from rsmcheck.compare import check_runs

    variant = case.variant(short)
    if not variant.compare:
        return ("<p><b>Engine comparison:</b> the case file has no [compare] table: "
                "nothing is compared for this case.</p>")
    if "reference" not in runs or "exudyn" not in runs:
        return ("<p><b>Engine comparison:</b> needs both engines (<code>--engine all</code>); "
                f"this report ran {', '.join(runs)}.</p>")
    rows = []
    for r in check_runs(variant, runs["reference"], runs["exudyn"]):
        rows.append([html.escape(r.observable), r.metric, f"{r.error:.3e}", f"{r.tolerance:.3e}", _fmt(r.margin),
                     "<span class='pass'>pass</span>" if r.passed else "<span class='fail'>FAIL</span>",
                     f"{r.reference_range:.3e}",
                     f"<span class='small'>{html.escape(r.why)}"
                     + (f"<br><i>{html.escape(r.switch_note())}</i>" if r.at_switches else "") + "</span>"])
    return ("<p><b>Engine comparison</b> (reference vs Exudyn, the case's [compare] table; error in the "
            "observable's unit, margin = tolerance / error)</p>"
            + _table(["observable", "metric", "error", "tolerance", "margin", "result", "reference range", "why"],
                     rows, left=2).replace("<td>" + "<span class='small'>", "<td class='l'><span class='small'>"))


def _modes_html() -> str:
    """`rsmcheck modes`: link frequencies and coupled frequencies, reference vs Exudyn."""
    try:
        from rsmcheck.modes import arm_rows, link_rows

        links, arms = link_rows(), arm_rows()
    except Exception as exc:  # noqa: BLE001 — the report shows why instead of failing
        return f"<h2 id='modes'>Eigenfrequencies</h2><p class='fail'>not computed: {html.escape(str(exc))}</p>"
    lrows = [[r["basis"], str(r["mode"]), f"{r['table2_hz']:.2f}", f"{r['analytic_hz']:.4f}", f"{r['reference_hz']:.4f}",
              f"{r['exudyn_hz']:.4f}", f"{100 * r['reference_rel']:+.4f} %", f"{100 * r['exudyn_rel']:+.4f} %"]
             for r in links]
    arows = [[html.escape(r["configuration"]), html.escape(r["case"]), str(r["mode"]), f"{r['reference_hz']:.4f}",
              f"{r['exudyn_hz']:.4f}", f"{100 * r['rel_difference']:+.4f} %"] for r in arms]
    return ("<h2 id='modes'>Eigenfrequencies (rsmcheck modes)</h2>"
            f"<p>One link, pinned-pinned (PP) and pinned-free (PF): Euler–Bernoulli from Table 2, the "
            f"reference's modal K, M, and Exudyn with {links[0]['exudyn_elements']} ANCF elements.</p>"
            + _table(["basis", "mode", "Table 2 [Hz]", "analytic", "reference", "Exudyn", "ref − analytic",
                      "Exudyn − analytic"], lrows, left=1)
            + "<p>The robot linearised at rest in a case's initial configuration, undamped [Hz] (reference: the "
              "case's modes per link; the known differences are modal truncation and the axial compliance of "
              "the FE links, docs/exudyn.md §3).</p>"
            + _table(["configuration", "case", "mode", "reference", "Exudyn", "difference"], arows, left=2))


DATA_DIR = Path(__file__).resolve().parent.parent / "docs" / "data"


def _stored(data_dir: Path, pattern: str):
    """(path, document) of each readable JSON file matching `pattern`, sorted by name."""
    for path in sorted(data_dir.glob(pattern)):
        try:
            yield path, json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            continue


def _studies_html(data_dir: Path = DATA_DIR) -> str:
    """The stored engine studies (rsmcheck.studies → docs/data/*.json), if present."""
    parts = []
    for path, doc in _stored(data_dir, "rigid_steps_*.json"):
        opts = doc.get("exudyn_options", {})
        parts.append(f"<h3>Rigid equivalence vs step ({html.escape(path.name)}, Exudyn {html.escape(str(opts))}, "
                     f"reference rtol {doc.get('reference_rtol')})</h3><p class='small'>{html.escape(doc.get('metric', ''))}"
                     "; worst observable per case and step, and the reaction forces</p>")
        rows = []
        for name, entry in doc.get("cases", {}).items():
            for st in entry.get("steps", []):
                errs = {k: v for k, v in st["errors"].items() if k != "link_deflection"}
                worst = max(errs, key=errs.get)
                others = {k: v for k, v in errs.items() if k != "reaction_forces_I"}
                w2 = max(others, key=others.get)
                rows.append([html.escape(name), str(st["substeps"]), f"{st['h'] * 1e3:.4g}", f"{st['wall_s']:.1f}",
                             f"{worst} {errs[worst]:.2e}", f"{w2} {others[w2]:.2e}",
                             f"{errs.get('reaction_forces_I', float('nan')):.2e}"])
        parts.append(_table(["case", "substeps", "h [ms]", "wall [s]", "worst", "worst except reaction",
                             "reaction"], rows, left=1))
    for _, doc in _stored(data_dir, "convergence_*.json"):
        modes, elements = doc.get("modes", []), doc.get("elements", [])
        for obs in ("link_deflection", "joint_angles", "ee2_pos_B", "energy"):
            rows = []
            for n in modes:
                rows.append([str(n)] + [f"{doc['errors'].get(f'{n},{m}', {}).get(obs, float('nan')):.2e}"
                                        for m in elements])
            parts.append(f"<h3>Flexible convergence, {html.escape(doc.get('case', ''))} ({doc.get('duration')} s, "
                         f"h = {doc.get('h', 0) * 1e3:.3g} ms): {obs}</h3>"
                         + _table(["reference modes ↓ / Exudyn elements →"] + [str(m) for m in elements], rows))
    for _, doc in _stored(data_dir, "refinement_*.json"):
        tols = doc.get("tolerances", {})
        settings = [f"{e['substeps']},{e['axial_to_bending']:g}" for e in doc.get("exudyn", [])]
        rows = []
        for n in doc.get("modes", []):
            for key, e in zip(settings, doc.get("exudyn", [])):
                errs = doc["errors"].get(f"{n},{key}", {})
                rows.append([str(n), f"{e['h'] * 1e6:.3g}", f"{e['axial_to_bending']:.0e}"]
                            + [_cell(errs.get(obs, float("nan")), tol) for obs, tol in tols.items()])
        parts.append(f"<h3>Refinement, {html.escape(doc.get('case', ''))} ({doc.get('duration')} s): the case's "
                     "[compare] rows, error in the observable's unit (red: above the tolerance)</h3>"
                     + _table(["reference modes", "Exudyn h [µs]", "EA/EI"]
                              + [f"{html.escape(o)} (≤ {t:g})" for o, t in tols.items()], rows, left=3))
    if not parts:
        return ""
    return ("<h2 id='studies'>Engine studies (stored results, docs/data)</h2><p>From "
            "<code>python -m rsmcheck.studies</code>; relative differences (rsmcheck.compare.compare_runs).</p>"
            + "".join(parts))


def _faults_html(data_dir: Path = DATA_DIR) -> str:
    """The fault-injection catch matrix (`make faults` → docs/data/faults.json), if present."""
    docs = [doc for _, doc in _stored(data_dir, "faults.json")]
    if not docs:
        return ""
    doc = docs[0]
    rows = []
    for f in doc.get("faults", []):
        expected = f.get("layer") == "none"
        ok = (not f.get("caught_by")) if expected else bool(f.get("caught_by"))
        verdict = "<span class='pass'>as expected</span>" if ok else "<span class='fail'>MISSED</span>" if not expected \
            else "<span class='fail'>FALSE ALARM</span>"
        rows.append([html.escape(f.get("name", "")), html.escape(f.get("layer", "")), html.escape(f.get("what", "")),
                     html.escape("; ".join(f.get("crosscheck", [])[:3]) or "—"),
                     html.escape("; ".join(f.get("pinocchio", [])[:3]) or "—"),
                     html.escape("; ".join(f.get("gate", [])[:3]) or "—"), verdict])
    return ("<h2 id='faults'>Fault injection: what the suite catches</h2><p class='small'>"
            f"<code>make faults</code> at commit {html.escape(str(doc.get('commit', ''))[:12])}: each fault applied "
            f"to a copy of the tree, the short variants of {html.escape(', '.join(doc.get('cases', [])))} re-run by "
            "the engines it reaches; which checks fail (docs/gate.md).</p>"
            + _table(["fault", "layer", "what", "cross-check", "Pinocchio", "gate", "verdict"], rows, left=3))


def _case_section(case: Case, runs: dict[str, EngineRun], short: bool) -> str:
    parts = [f"<h2 id='{case.name}'>{html.escape(case.name)}</h2>",
             f"<p>{html.escape(case.description)}</p>",
             f"<p class='small'>case file {html.escape(Path(case.path).name)} "
             f"(sha256 {case.file_hash[:12]}), {'short' if short else 'full'} run of "
             f"{case.run_duration(short):g} s, control period {case.solver.control_period:g} s</p>"]
    rows = []
    for name, r in runs.items():
        d = _drifts(r)
        s = r.solver
        rows.append([name, f"{r.observables['time'][-1]:.3g}", f"{s.get('wall_s', float('nan')):.2f}",
                     str(s.get("steps", "")), f"{d['energy_drift_J']:.2e}", f"{d['momentum_drift']:.2e}",
                     f"{d['residual_max_m']:.2e}", f"{d['deflection_max_m']:.2e}"])
    parts.append(_table(["engine", "sim s", "wall s", "steps", "max |E − E(0)| [J]", "max |p − p(0)| [SI]",
                         "max |φ_T| [m]", "max |w(L/2)| [m]"], rows))
    events = [[name, f"{ev.time:.4f}", html.escape(ev.kind), html.escape(ev.detail)]
              for name, r in runs.items() for ev in r.events]
    if events:
        parts.append(_table(["engine", "t [s]", "event", "detail"], events, left=1))
    parts.append(_compare_html(case, runs, short))
    parts.append(f"<img alt='conservation {case.name}' src='data:image/png;base64,{conservation_figure(runs)}'>")
    parts.append(f"<img alt='observables {case.name}' src='data:image/png;base64,{case_figure(runs)}'>")
    return "\n".join(parts)


def build_report(out: Path, engines: Sequence[str], short: bool,
                 case_names: Sequence[str] | None = None) -> tuple[Path, list[str]]:
    """Run the cases through `engines`, store DIR/runs/CASE.h5, write the page; returns the
    page's path and the cases that did not run (shown on the page in red)."""
    from rsmcheck.chain import run_case

    cases = [load_case(n) for n in case_names] if case_names else [load_case(p) for p in list_cases()]
    out.parent.mkdir(parents=True, exist_ok=True)
    run_dir = out.parent / "runs"
    run_dir.mkdir(exist_ok=True)
    sections = []
    started = time.monotonic()
    failures = []
    for case in cases:
        try:
            # chained phases start from their predecessor's end state in run_dir when it exists
            path = run_case(case, engines, short, run_dir, progress=terminal_progress)
            runs, _ = read_run(path)
        except (SimulationDiverged, InputError, ValueError, RuntimeError) as exc:
            failures.append(case.name)
            sections.append(f"<h2 id='{case.name}'>{html.escape(case.name)}</h2>"
                            f"<p class='fail'>did not run: {html.escape(str(exc))}</p>")
            continue
        sections.append(_case_section(case, runs, short))
    pin = _pinocchio_rows()
    pin_rows = [[html.escape(str(c.get("quantity"))), str(c.get("chain")), str(c.get("holding", "")),
                 str(c.get("n_modes", "")), str(c.get("states")), f"{c.get('max_rel_error', float('nan')):.2e}",
                 f"{c.get('tolerance', 0):.0e}",
                 "<span class='pass'>pass</span>" if c.get("pass") else "<span class='fail'>FAIL</span>"]
                for c in pin]
    commit, dirty = git_commit()
    head = (f"<h1>rsmcheck report</h1><p class='small'>generated {datetime.now(timezone.utc).isoformat(timespec='seconds')}"
            f", git {commit[:12]}{' (modified)' if dirty == 'yes' else ''}, engines: {', '.join(engines)}, "
            f"{'short' if short else 'full'} cases, {time.monotonic() - started:.0f} s</p>")
    toc = "<p>" + " · ".join(f"<a href='#{c.name}'>{c.name}</a>" for c in cases) + "</p>"
    pin_html = ("<h2>Pinocchio: rigid kinematics and dynamics</h2><p>Reference vs Pinocchio at seeded "
                "random states, norm-relative error.</p>"
                + _table(["quantity", "chain", "holding", "modes", "states", "max error", "tolerance", "result"], pin_rows))
    modes_html = _modes_html() if "exudyn" in engines else ""
    studies_html = _studies_html()
    faults_html = _faults_html()
    extra = [(a, t) for a, t, h in (("modes", "eigenfrequencies", modes_html), ("studies", "engine studies", studies_html),
                                    ("faults", "fault injection", faults_html)) if h]
    if extra:
        toc = toc.replace("<p>", "<p>" + " · ".join(f"<a href='#{a}'>{t}</a>" for a, t in extra) + " · ", 1)
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>rsmcheck report</title>"
            f"<style>{CSS}</style></head><body>{head}{toc}{pin_html}{modes_html}{studies_html}{faults_html}"
            f"{''.join(sections)}</body></html>")
    tmp = out.with_name(out.name + ".tmp")
    try:
        tmp.write_text(page, encoding="utf-8")
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return out, failures
