"""`rsmcheck fuzz`: a randomized cross-check on scenarios nobody wrote down.

    rsmcheck fuzz --n N --seed S [--out DIR] [--engines A,B] [--json] [--serial]

N scenarios (rsmcheck.orchestration.fuzz_scenarios: drawn from fuzz_ranges.toml, each an
ordinary case file under DIR/scenarios/) are each run by both engines twice: at the
scenario's resolution, and refined in space and time by each plug-in's `finer_options`
(the reference: two more eigenmodes per link, rtol/10, h ≤ Δt/2; Exudyn: 1.5 times the
elements, half the step).  For every compared observable (max over samples and
components, `compare.difference`):

    d(A, B)   the engines' difference at the scenario's resolution
    r_X       d(X, X'), engine X's change under refinement: its own discretisation
              uncertainty
    passes    d(A, B) ≤ factor · (r_A + r_B) + relative · motion + absolute

with `motion` = max_t |x(t) − x(0)| of the observable in A's run, and factor, relative
and absolute declared (with their reasons) in fuzz_ranges.toml [criterion].  Two correct
models of one physics differ by less than their discretisation errors, which their
refinement changes measure (to the factor); the floor is the model difference that
refinement does not remove (Exudyn's axial compliance).  A difference that does not
shrink with refinement is a modelling disagreement.

A failing scenario is written to DIR/failures/NAME.toml with the rows that failed as its
`[compare]` table (tolerance = the allowance): `rsmcheck check DIR/failures/NAME.toml`
reproduces the failure.  The document (DIR/fuzz.json, and stdout with --json) holds every
scenario, its rows and the wall time.  Exit 0 when every scenario passes, 1 when one fails
(or could not run), 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from rsmcheck.core.cases import Case, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.plugins import default_engines, finer_options, plugin
from rsmcheck.core.store import EngineRun, git_commit, machine, write_json, write_text
from rsmcheck.orchestration.compare import difference
from rsmcheck.orchestration.fuzz_scenarios import WINDOWED, Scenario, case_text, declared, draw
from rsmcheck.orchestration.runs import Job, run_engine, run_jobs

FORMAT = "rsmcheck-fuzz"
DEFAULT_OUT = "out/fuzz"
RESOLUTIONS = ("default", "finer")

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Row:
    """One observable of one scenario, judged (module doc)."""

    observable: str
    difference: float  # d(A, B)
    refinement: dict[str, float]  # engine → d(X, X')
    motion: float
    allowance: float  # factor · Σ refinement + floor
    passed: bool

    @property
    def ratio(self) -> float:
        """difference / allowance: ≤ 1 passes."""
        return self.difference / self.allowance if self.allowance > 0 else math.inf


def observables(s: Scenario) -> list[str]:
    """The observables a scenario compares: those fuzz_ranges.toml gives a floor, less the
    target's pose where nothing holds it and reactions outside a closed chain."""
    names = [k for k in declared()["criterion"]["absolute"] if k != "why"]
    drop = set()
    if s.chain == "free":
        drop.add("target_pose_B")
    if s.chain != "closed":
        drop.add("reaction_forces_I")
    return [n for n in names if n not in drop]


def motion(run: EngineRun, name: str, window: tuple[float, float] | None = None) -> float:
    """max_t ‖x(t) − x(t0)‖_∞ of observable `name` in `run` (t0 the window's first sample)."""
    t = np.asarray(run.observables["time"], float)
    x = np.asarray(run.observables[name], float).reshape(t.size, -1)
    if window is not None:
        x = x[(t >= window[0] - 1e-12) & (t <= window[1] + 1e-12)]
    return float(np.max(np.abs(x - x[0]))) if x.size else 0.0


def judge(s: Scenario, runs: Mapping[tuple[str, str], EngineRun], engines: Sequence[str]) -> list[Row]:
    """Every observable of `s` by the criterion (module doc); `runs` by (engine, resolution)."""
    c = declared()["criterion"]
    a, b = engines
    out = []
    for name in observables(s):
        window = (c["reaction_skip_s"], s.duration) if name in WINDOWED else None

        def d(x: EngineRun, y: EngineRun) -> float:
            return difference(x, y, name, "max_abs", s.name, window)[0]

        diff = d(runs[(a, "default")], runs[(b, "default")])
        refinement = {e: d(runs[(e, "default")], runs[(e, "finer")]) for e in engines}
        m = motion(runs[(a, "default")], name, window)
        allowance = c["factor"] * sum(refinement.values()) + c["relative"] * m + c["absolute"][name]
        out.append(Row(name, diff, refinement, m, allowance, bool(diff <= allowance)))
    return out


def failing_case(s: Scenario, rows: Sequence[Row], engines: Sequence[str]) -> Scenario:
    """`s` with the rows that failed as its [compare] table: tolerance = the allowance, the
    why its figures."""
    c = declared()["criterion"]
    compare = {}
    for r in rows:
        if r.passed:
            continue
        parts = ", ".join(f"{e} {r.refinement[e]:.2e} ({plugin(e).finer})" for e in engines)
        compare[r.observable] = (r.allowance, (
            f"Allowance of `rsmcheck fuzz`: {c['factor']:g} x the engines' refinement changes ({parts}) "
            f"+ {c['relative']:g} x the motion {r.motion:.2e} + {c['absolute'][r.observable]:g}; the engines "
            f"differed by {r.difference:.3e}, {r.ratio:.2f} x the allowance."))
    return replace(s, compare=compare)


def _write_scenario(s: Scenario, folder: Path) -> Case:
    path = write_text(folder / f"{s.name}.toml", case_text(s))
    return load_case(path)


def campaign(n: int, seed: int, out_dir: Path, engines: Sequence[str] | None = None, workers: int = 2,
             progress: Progress | None = None, first: int = 0) -> dict[str, Any]:
    """Draw, run and judge scenarios first … first + n − 1 of campaign `seed` (module doc);
    the document."""
    engines = list(engines or default_engines())
    if len(engines) != 2:
        raise InputError("--engines", ",".join(engines), "fuzz compares two engines, the model under test first")
    for e in engines:
        if getattr(plugin(e), "finer_options", None) is None:
            raise InputError("--engines", e, "its plug-in declares no finer_options: no refinement to judge by")
    t0 = time.monotonic()
    scenarios = [draw(seed, i) for i in range(first, first + n)]
    cases = {s.name: _write_scenario(s, out_dir / "scenarios") for s in scenarios}
    jobs = []
    for s in scenarios:
        case = cases[s.name]
        for e in engines:
            for res in RESOLUTIONS:
                options = finer_options(e, case) if res == "finer" else {}
                cost = s.duration * (4.0 if res == "finer" else 1.0) * (3.0 if e != engines[0] else 1.0)
                jobs.append(Job(f"{s.name} / {e} / {res}", run_engine, (e, case, options), cost, (s.name, e, res)))
    done = run_jobs(jobs, progress, workers)
    results = []
    for s in scenarios:
        mine = {(job.key[1], job.key[2]): done[job] for job in jobs if job.key[0] == s.name}
        errors = {f"{e}/{res}": o.error_text for (e, res), o in mine.items() if o.error is not None}
        entry: dict[str, Any] = {"index": s.index, "seed": s.seed, "name": s.name, "scenario": s.describe(),
                                 "case_file": str(out_dir / "scenarios" / f"{s.name}.toml"),
                                 "wall_s": {f"{e}/{res}": round(o.wall_s, 2) for (e, res), o in mine.items()}}
        if errors:
            entry.update(passed=False, errors=errors, rows=[])
        else:
            rows = judge(s, {k: o.value for k, o in mine.items()}, engines)
            entry.update(passed=all(r.passed for r in rows), rows=[{**asdict(r), "ratio": r.ratio} for r in rows])
            if not entry["passed"]:
                failed = failing_case(s, rows, engines)
                entry["case_file"] = str(write_text(out_dir / "failures" / f"{s.name}.toml", case_text(failed)))
        results.append(entry)
    c = declared()["criterion"]
    return {"format": FORMAT, "seed": seed, "n": n, "first": first, "engines": engines,
            "finer": {e: plugin(e).finer for e in engines},
            "criterion": {k: c[k] for k in ("factor", "relative", "reaction_skip_s")} | {"absolute": {
                k: v for k, v in c["absolute"].items() if k != "why"}},
            "passed": sum(r["passed"] for r in results), "failed": sum(not r["passed"] for r in results),
            "wall_s": round(time.monotonic() - t0, 1), "workers": workers, "commit": git_commit()[0],
            "machine": machine(), "scenarios": results}


def summary(doc: Mapping[str, Any]) -> str:
    """The document as a table: one line per scenario, its worst row, and the verdict."""
    lines = [f"fuzz: seed {doc['seed']}, {doc['n']} scenario(s), {' against '.join(doc['engines'])}, "
             f"{doc['wall_s']:.0f} s on {doc['workers'] or 1} worker(s)"]
    for s in doc["scenarios"]:
        if s.get("errors"):
            lines.append(f"  {s['name']:14s} FAILED TO RUN: " + "; ".join(f"{k}: {v}" for k, v in s["errors"].items()))
            continue
        worst = max(s["rows"], key=lambda r: r["ratio"])
        lines.append(f"  {s['name']:14s} {'pass' if s['passed'] else 'FAIL'}  worst {worst['observable']:18s} "
                     f"{worst['difference']:.2e} of {worst['allowance']:.2e} ({worst['ratio']:.2f})  {s['scenario']}")
        for r in s["rows"]:
            if not r["passed"]:
                lines.append(f"  {'':14s}   {r['observable']}: {r['difference']:.3e} > {r['allowance']:.3e}; "
                             f"refinement " + ", ".join(f"{e} {v:.2e}" for e, v in r["refinement"].items())
                             + f"; motion {r['motion']:.2e}")
        if not s["passed"]:
            lines.append(f"  {'':14s}   reproduce: rsmcheck check {s['case_file']}")
    lines.append(f"{doc['passed']} passed, {doc['failed']} failed")
    return "\n".join(lines)


def write_document(doc: Mapping[str, Any], out_dir: Path) -> Path:
    return write_json(out_dir / "fuzz.json", doc)


def combine(parts: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """One campaign's document from documents of its consecutive parts (`--first`): the
    same seed, engines and criterion; the scenarios in order, the counts and wall times
    summed.  A part that does not continue the one before is an InputError."""
    if not parts:
        raise InputError("fuzz combine", "parts", "no document given")
    first = parts[0]
    out = dict(first, scenarios=[], passed=0, failed=0, wall_s=0.0, n=0, parts=[])
    for i, p in enumerate(parts):
        for key in ("seed", "engines", "criterion", "finer"):
            if p.get(key) != first.get(key):
                raise InputError("fuzz combine", f"part {i + 1}.{key}", f"{p.get(key)!r} differs from part 1's")
        if p.get("first") != first["first"] + out["n"]:
            raise InputError("fuzz combine", f"part {i + 1}.first",
                             f"starts at scenario {p.get('first')}, not at {first['first'] + out['n']}")
        out["scenarios"] += p["scenarios"]
        out["n"] += p["n"]
        out["passed"] += p["passed"]
        out["failed"] += p["failed"]
        out["wall_s"] = round(out["wall_s"] + p["wall_s"], 1)
        out["parts"].append({k: p.get(k) for k in ("first", "n", "wall_s", "workers", "commit")})
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m rsmcheck.orchestration.fuzz combine OUT PART…`: one document from parts."""
    ap = argparse.ArgumentParser(prog="python -m rsmcheck.orchestration.fuzz", description=main.__doc__)
    ap.add_argument("command", choices=["combine"])
    ap.add_argument("out")
    ap.add_argument("parts", nargs="+")
    args = ap.parse_args(argv)
    parts = []
    for path in args.parts:
        try:
            parts.append(json.loads(Path(path).read_text()))
        except (OSError, ValueError) as exc:
            raise SystemExit(f"{path}: not a fuzz document ({exc})") from None
    doc = combine(parts)
    write_json(args.out, doc)
    print(f"wrote {args.out}: {doc['n']} scenarios, {doc['passed']} passed, {doc['failed']} failed")
    return 0 if doc["failed"] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
