"""The tables of README.md and docs/*.md that quote data, generated from that data.

A generated block is the text between two marker lines,

    <!-- generated:NAME -->
    ...
    <!-- /generated:NAME -->

and NAME is one of `BLOCKS`: the function that renders it from the data it quotes (the
stored bench and check in docs/data/, the case files, the departures and observables of
rsmcheck.core).  A figure of a data file is quoted inside such a block only, so that the
page and the data cannot disagree (tests/docs/test_doc_tables.py).

    python -m rsmcheck.orchestration.doc_tables            # rewrite every block
    python -m rsmcheck.orchestration.doc_tables --check    # exit 1 naming each stale block
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import textwrap
from pathlib import Path
from typing import Any, Callable, Sequence

from rsmcheck.core import departures
from rsmcheck.core.cases import CASES_DIR, load_case
from rsmcheck.core.observables import OBSERVABLES
from rsmcheck.core.plugins import owned_tables, plugins
from rsmcheck.orchestration.targets import read_targets

ROOT = Path(__file__).resolve().parents[2]
#: the stored measurements the blocks quote
DATA = ROOT / "docs" / "data"
#: the stored bench: `rsmcheck bench --variant targets --engine all --jobs 2` (docs/benchmarks.md)
BENCH = "bench_targets.json"
#: a block: its opening marker, its text, its closing marker
BLOCK = re.compile(r"<!-- generated:(?P<name>[\w-]+) -->\n(?P<body>.*?)<!-- /generated:(?P=name) -->", re.S)


def documents(root: Path = ROOT) -> list[Path]:
    """The pages that may hold generated blocks: README.md and docs/*.md."""
    return [root / "README.md"] + sorted((root / "docs").glob("*.md"))


def _read(data: Path, name: str) -> dict[str, Any]:
    return json.loads((data / name).read_text(encoding="utf-8"))


def _g(x: float, digits: int = 3) -> str:
    """A figure to `digits` significant digits, thousands apart from 10 000 on."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if abs(x) >= 1000:
        return f"{x:,.0f}".replace(",", " ")
    return f"{x:.{digits}g}"


def _para(text: str) -> list[str]:
    """A sentence of prose as lines of at most 98 characters."""
    return textwrap.wrap(text, 98, break_long_words=False, break_on_hyphens=False)


def _row(*cells: Any) -> str:
    return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"


def _table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    return [_row(*head), "|" + "---|" * len(head)] + [_row(*r) for r in rows]


def _machine(doc: dict[str, Any]) -> str:
    m = doc.get("machine") or {}
    return (f"{m.get('cpu', 'machine not recorded')}, {m.get('logical_cpus', '?')} logical CPUs, "
            f"{_g(m.get('memory_gib', math.nan))} GiB")


def _command(doc: dict[str, Any]) -> str:
    """The command that made a bench document, without where it wrote it, in today's
    spelling (`--engine` is now `--engines`)."""
    command = re.sub(r"\s+--(?:out \S+|json)\b", "", doc.get("command", "rsmcheck bench"))
    return re.sub(r"--engine\b(?!s)", "--engines", command)


# ---------------------------------------------------------------------------------------
# the blocks
# ---------------------------------------------------------------------------------------
def targets_lines(doc: dict[str, Any]) -> list[str]:
    """The speed targets one bench document measures (rsmcheck.orchestration.targets):
    measured, margin (≥ 1 when met), the margin of the engine's integrator alone."""
    rows = []
    for r in read_targets(doc):
        if r.measured is None:
            continue
        bound = f"{'≤' if r.target.upper else '≥'} {_g(r.target.bound)} {r.target.unit}"
        alone = "–" if r.floor_margin is None else f"{r.floor_margin:.2f}"
        rows.append((f"{r.target.text} {bound}", f"{_g(r.measured)} {r.target.unit}", f"{r.margin:.2f}", alone,
                     "met" if r.met else "not met"))
    return _table(("target", "measured", "margin", "engine alone", "verdict"), rows)


def speed(data: Path = DATA) -> str:
    """README: the speed targets read off the stored bench (docs/data/bench_targets.json)."""
    doc = _read(data, BENCH)
    lines = _para(f"Measured by `{_command(doc)}` on {_machine(doc)} (docs/data/{BENCH}):") + [""]
    return "\n".join(lines + targets_lines(doc)) + "\n"


def _runs_by_case(doc: dict[str, Any], variant: str) -> dict[str, dict[str, dict[str, Any]]]:
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for r in doc.get("runs", []):
        if r.get("variant") == variant:
            out.setdefault(r["case"], {})[r["engine"]] = r
    return out


def _wall(run: dict[str, Any] | None) -> str:
    if not run or "error" in run or not run.get("wall_s"):
        return "failed" if run and "error" in run else "–"
    return f"{_g(run['wall_s'])} ({_g(run['sim_s'] / run['wall_s'], 2)} ×)"


def bench_runs(data: Path = DATA) -> str:
    """docs/benchmarks.md: every run of the stored bench, wall seconds (× real time), the
    full mission's phases, where its control sample went, and one right-hand side."""
    doc = _read(data, BENCH)
    engines = list(doc.get("engines", []))
    lines = _para(f"docs/data/{BENCH}, on {_machine(doc)}; wall s (× real time) per engine.") + [""]
    for variant in ("full", "short"):
        runs = _runs_by_case(doc, variant)
        if not runs:
            continue
        order = (["mission"] if "mission" in runs else []) + sorted(c for c in runs if c != "mission")
        rows = [(f"**{c}**" if c == "mission" else c,
                 _g(next(iter(runs[c].values()))["sim_s"]), *(_wall(runs[c].get(e)) for e in engines))
                for c in order]
        lines += [f"{variant.capitalize()} length:", ""]
        lines += _table(("case", "sim s", *(f"{e} wall s" for e in engines)), rows) + [""]
    lines += _phases_lines(doc) + [""] + _sample_lines(doc)
    rhs = doc.get("rhs_us") or {}
    lines += [""] + _para("One right-hand side, µs per call: " + ", ".join(
        f"{k} {_g(v)}" for k, v in rhs.items() if isinstance(v, float)) + ".")
    return "\n".join(lines) + "\n"


def _phases_lines(doc: dict[str, Any]) -> list[str]:
    """The full mission's phases per engine, wall s (× real time)."""
    missions = _runs_by_case(doc, "full").get("mission", {})
    engines = [e for e in doc.get("engines", []) if e in missions]
    phases = {e: {p["phase"]: p for p in missions[e].get("phases") or []} for e in engines}
    names = list(dict.fromkeys(n for e in engines for n in phases[e]))
    if not names:
        return []
    rows = [(n, _g(phases[engines[0]][n]["sim_s"]), *(_wall(phases[e].get(n)) for e in engines)) for n in names]
    return ["The full mission's phases, each timed in the chained flight:", ""] + _table(
        ("phase", "sim s", *(f"{e} wall s" for e in engines)), rows)


def _work(engine: str, solver: dict[str, Any]) -> str:
    """A run's work by its plug-in's counters (the gate's), e.g. 'attempted steps 8 250 610'."""
    counters = getattr(plugins().get(engine), "work_counters", ())
    return ", ".join(f"{c.label} {_g(sum(int(solver[k]) for k in c.keys))}" for c in counters
                     if all(k in solver for k in c.keys))


def _sample_lines(doc: dict[str, Any]) -> list[str]:
    """Where a control sample of the full mission went, µs per sample (the runs' own timers,
    rsmcheck.driver.runner.SPLIT), and the work behind it."""
    missions = _runs_by_case(doc, "full").get("mission", {})
    rows = []
    for e in doc.get("engines", []):
        run = missions.get(e) or {}
        s = run.get("split") or {}
        if not s.get("samples"):
            continue
        us = {k: 1e6 * float(v) / s["samples"] for k, v in s.items() if k.startswith("wall_")}
        rows.append((e, _g(us["wall_s"]), _g(us["wall_integrator_s"]),
                     _g(us["wall_advance_s"] - us["wall_integrator_s"]), _g(us["wall_sensors_s"]),
                     _g(us["wall_controller_s"]), _g(us["wall_observe_s"]), _work(e, run.get("solver") or {})))
    if not rows:
        return []
    head = ("engine", "µs per sample", "integrator", "rest of the step", "sensors", "controller", "output samples",
            "work")
    return ["A control sample of the full mission, µs (the runs' own timers) and the work behind it:", ""] + \
        _table(head, rows)


def check_short(data: Path = DATA) -> str:
    """docs/exudyn.md §8: the stored `rsmcheck check --short --json` (docs/data/check_short.json)."""
    doc = _read(data, "check_short.json")
    checks = doc["checks"]
    rows = [(c["case"], c["observable"], c["metric"], f"{c['error']:.2e}", f"{c['tolerance']:g}",
             "∞" if c["margin"] in ("inf", None) else f"{float(c['margin']):.3g}", "pass" if c["pass"] else "FAIL")
            for c in checks]
    finite = [c for c in checks if c["margin"] not in ("inf", None)]
    low = min(finite, key=lambda c: float(c["margin"]))
    high = max(finite, key=lambda c: float(c["margin"]))
    passed = sum(bool(c["pass"]) for c in checks)
    tail = _para(f"{passed} of {len(checks)} pass; margins {float(low['margin']):.3g} ({low['case']} {low['observable']}) "
            f"to {float(high['margin']):.3g} ({high['case']} {high['observable']}).  Not compared: "
            + "; ".join(f"{s['case']} ({s['reason']})" for s in doc.get("skipped", [])) + ".")
    head = ("case", "observable", "metric", "error", "tolerance", "margin", "result")
    return "\n".join(_table(head, rows) + [""] + tail) + "\n"


def _settings(case) -> str:
    """The engine tables of a case file (each plug-in's own), without their `why`."""
    parts = []
    for table in owned_tables():
        given = {k: v for k, v in (case.raw.get(table) or {}).items() if k != "why"}
        if given:
            parts.append(f"{table}: " + ", ".join(f"{k} = {json.dumps(v)}" for k, v in given.items()))
    return "; ".join(parts) or "defaults"


def cases() -> str:
    """docs/cases.md: one entry per shipped case file, from the file itself."""
    rows = []
    for path in sorted(CASES_DIR.glob("*.toml")):
        c = load_case(path)
        short = c.variant(True)
        if c.phases:
            chain = " → ".join(c.phases) + f" (short: {' → '.join(c.raw.get('short_phases', c.phases))})"
            compared = f"each phase's own rows; {sum(len(v) for v in c.phase_compare.values())} replaced for the chain"
            rows.append((f"`{c.name}`", c.description, f"{_g(c.duration)} s ({_g(c.short_duration)} s)", chain,
                         compared, _settings(c)))
            continue
        start = f"after {c.start_from}" if c.start_from else "its [initial]"
        compared = ", ".join(s.observable for s in short.compare) or "— (rigid equivalence only)"
        rows.append((f"`{c.name}`", c.description, f"{_g(c.duration)} s ({_g(c.short_duration)} s)", start,
                     compared, _settings(c)))
    head = ("case", "what it is", "length (short)", "starts from", "compared (short variant)", "engine settings")
    return "\n".join(_table(head, rows)) + "\n"


def departure_table() -> str:
    """docs/physics.md §9: rsmcheck/core/departures.toml."""
    return departures.markdown()


def observables() -> str:
    """docs/observables.md: rsmcheck.core.observables.OBSERVABLES."""
    rows = [(f"`{s.name}`", "–" if s.shape == () else " × ".join(map(str, s.shape)), s.unit, s.meaning)
            for s in OBSERVABLES]
    return "\n".join(_table(("name", "shape", "unit", "meaning"), rows)) + "\n"


def faults(data: Path = DATA) -> str:
    """docs/gate.md: the stored fault matrix (docs/data/faults.json, `make faults`): per
    fault the checks that caught it, on how many cases the cross-check (C) and the gate (G)
    did, the first failing cross-check row and the analytic tests that failed."""
    doc = _read(data, "faults.json")
    cases = doc["cases"]
    rows = []
    for f in doc["faults"]:
        caught = ", ".join(f["caught_by"]) or "nothing"
        per_case = f["cases"]
        on = {check: sum(1 for c in cases if per_case.get(c, {}).get(check)) for check in ("crosscheck", "gate")}
        first = next((f"{c} {per_case[c]['crosscheck'][0]}" for c in cases
                      if per_case.get(c, {}).get("crosscheck")), "—")
        analytic = f"{len(f['analytic'])}" if f.get("analytic") else "—"
        rows.append((f"`{f['name']}`", f["layer"], f["what"], caught,
                     f"{on['crosscheck']} / {on['gate']}", first, analytic))
    head = ("fault", "layer", "what it changes", "caught by", f"cases C / G (of {len(cases)})",
            "first cross-check row that fails", "analytic tests failed")
    lines = _para(f"docs/data/faults.json: {len(doc['faults'])} changes on {len(cases)} cases (every "
                  f"stand-alone case's short variant and the chained short mission); Pinocchio at "
                  f"{doc['rigid_states']} states; {doc['wall_s'] / 60:.0f} min on 2 workers.") + [""]
    return "\n".join(lines + _table(head, rows)) + "\n"


def rigid_equivalence(data: Path = DATA) -> str:
    """docs/exudyn.md §6: the stored rigid-equivalence study, its worst row per case."""
    doc = _read(data, "rigid_equivalence.json")
    tol = float(doc["tolerance"])
    rows = []
    for name, c in doc["cases"].items():
        obs = c["observables"]
        worst = max(obs, key=lambda o: obs[o]["error"])
        rows.append((name, c["substeps"], f"{c['h'] * 1e6:.3g}", f"{worst} {obs[worst]['error']:.1e}",
                     f"{sum(bool(o['pass']) for o in obs.values())} of {len(obs)}"))
    head = ("case", "steps per 1 ms", "h [µs]", "largest error / scale", f"within {tol:g}")
    return "\n".join(_table(head, rows)) + "\n"


#: block name → the function that renders it
BLOCKS: dict[str, Callable[[], str]] = {
    "speed": speed, "bench_runs": bench_runs, "check_short": check_short,
    "cases": cases, "departures": departure_table, "observables": observables, "faults": faults,
    "rigid_equivalence": rigid_equivalence,
}


# ---------------------------------------------------------------------------------------
# rewriting and checking the pages
# ---------------------------------------------------------------------------------------
def regenerate(text: str, rendered: dict[str, str] | None = None) -> tuple[str, list[str]]:
    """`text` with every block rewritten, and the names of the blocks that changed.  An
    unknown block name is a ValueError."""
    rendered = {} if rendered is None else rendered
    changed: list[str] = []

    def replace(m: re.Match) -> str:
        name = m["name"]
        if name not in BLOCKS:
            raise ValueError(f"unknown generated block {name!r} (known: {', '.join(BLOCKS)})")
        if name not in rendered:
            rendered[name] = BLOCKS[name]()
        if m["body"] != rendered[name]:
            changed.append(name)
        return f"<!-- generated:{name} -->\n{rendered[name]}<!-- /generated:{name} -->"

    return BLOCK.sub(replace, text), changed


def stale(root: Path = ROOT) -> list[str]:
    """'PAGE: block NAME' for each block whose text is not what its data makes now."""
    rendered: dict[str, str] = {}
    out = []
    for page in documents(root):
        _, changed = regenerate(page.read_text(encoding="utf-8"), rendered)
        out += [f"{page.relative_to(root)}: block {name}" for name in changed]
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rsmcheck.orchestration.doc_tables",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="rewrite nothing; exit 1 naming each stale block")
    args = parser.parse_args(argv)
    try:
        if args.check:
            found = stale()
            for line in found:
                sys.stderr.write(f"stale: {line} (python -m rsmcheck.orchestration.doc_tables)\n")
            return 1 if found else 0
        rendered: dict[str, str] = {}
        for page in documents():
            text = page.read_text(encoding="utf-8")
            new, changed = regenerate(text, rendered)
            if changed:
                page.write_text(new, encoding="utf-8")
                print(f"{page.relative_to(ROOT)}: rewrote {', '.join(changed)}")
    except ValueError as exc:
        sys.stderr.write(f"{parser.prog}: {exc}\n")
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
