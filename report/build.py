"""`rsmcheck report`: run the cases, write the run files and one self-contained HTML page.

The page has, per case: what the case isolates, the run statistics of every engine, the
event log, conservation drifts, and the observables against time with every engine
overlaid; at the top, the Pinocchio rigid checks.  Everything is embedded (PNG as base64),
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
from rsmcheck.runner import run, terminal_progress
from rsmcheck.store import EngineRun, git_commit, write_run

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
    parts.append(f"<img alt='conservation {case.name}' src='data:image/png;base64,{conservation_figure(runs)}'>")
    parts.append(f"<img alt='observables {case.name}' src='data:image/png;base64,{case_figure(runs)}'>")
    return "\n".join(parts)


def build_report(out: Path, engines: Sequence[str], short: bool, case_names: Sequence[str] | None = None) -> Path:
    """Run the cases through `engines`, store DIR/CASE.h5 next to the page, write the page."""
    from rsmcheck.cli import make_engine

    cases = [load_case(n) for n in case_names] if case_names else [load_case(p) for p in list_cases()]
    out.parent.mkdir(parents=True, exist_ok=True)
    run_dir = out.parent / "runs"
    run_dir.mkdir(exist_ok=True)
    sections = []
    started = time.monotonic()
    for case in cases:
        runs = {}
        for name in engines:
            engine = make_engine(name, case)
            runs[name] = run(engine, case, case.run_duration(short), terminal_progress(name, case.name))
        write_run(run_dir / f"{case.name}.h5", runs, case_name=case.name, case_hash=case.file_hash,
                  param_hash=case.params.digest())
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
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>rsmcheck report</title>"
            f"<style>{CSS}</style></head><body>{head}{toc}{pin_html}{''.join(sections)}</body></html>")
    tmp = out.with_name(out.name + ".tmp")
    try:
        tmp.write_text(page, encoding="utf-8")
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return out
