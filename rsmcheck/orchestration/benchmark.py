"""The benchmark any tool can enter: `rsmcheck export` writes problems, `rsmcheck judge`
judges the results files a tool sends back (docs/problems.md).

A problem is one case's variant (short by default) handed to a tool that cannot run as a
plug-in: a folder `DIR/CASE/` with

* `problem.md` and `problem.json` — what to simulate (the case file verbatim, every
  parameter with its source, the output samples, the observables asked for with unit and
  definition) and the acceptance of every observable: the case's `[compare]` rows, each with
  the threshold a tool gets when it sends no refined run (`threshold`), and its parts;
* `reference.csv` (and `reference.h5`) — the reference solution, a results file
  (rsmcheck.core.results) of the first default engine at the case's own settings, the run
  whose integration error the budgets hold;
* `ENGINE.csv` for each further engine asked for — the in-tree engines' own runs as results
  files, so that the judge is tested on known answers.

`judge` reads a results file, finds its problem, and judges it as `rsmcheck check` judges a
pair: the same rows (`compare.check_runs`), with the reference solution as the reference
engine's run and the tool as the engine under test.  The tool's tolerance is the pair's
(rsmcheck.core.tolerances): the row's allowance, the reference's recorded error and the
tool's own error — measured from a second results file of the same tool at finer settings
(`refined`), else taken as zero and said so.  A tool named as a registered engine is judged
as that engine (its recorded errors and departures), which is what makes `judge` on an
engine's export reproduce `check`.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from rsmcheck.core.cases import Case, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import BY_NAME
from rsmcheck.core.params import Params
from rsmcheck.core.plugins import default_engines
from rsmcheck.core.results import Results, columns, read_results, write_results, write_results_h5
from rsmcheck.core.store import EngineRun, dumps_json, machine, machine_text, write_text
from rsmcheck.core.tolerances import pair_tolerance
from rsmcheck.orchestration.compare import Check, check_runs, not_checked, row_lines, unit_of
from rsmcheck.orchestration.runs import get_runs

PROBLEM_FORMAT = "rsmcheck-problem 1"
#: the reference solution's file in a problem's folder (and `.h5` beside it)
SOLUTION = "reference.csv"
#: the name an outside tool's rows are stated for in a problem (it sends no refined run)
ANY_TOOL = "tool"
#: observables every results file carries beside the acceptance rows' (the time grid)
ALWAYS = ("time",)


# ---------------------------------------------------------------------------------------
# export
# ---------------------------------------------------------------------------------------
def results_of(run: EngineRun, case: Case, short: bool, names: Sequence[str] | None = None) -> Results:
    """An engine's run as a results file of `case` (the observables `names`, default all)."""
    names = list(names or run.observables)
    obs = {"time": run.observables["time"], **{n: run.observables[n] for n in names if n != "time"}}
    settings = {k: v for k, v in run.solver.items() if k != "wall_s"}
    cpu = run.solver.get("wall_s")
    version = ", ".join(f"{k} {v}" for k, v in sorted(run.versions.items()))
    return Results(Path(f"{run.engine}.csv"), case.name, run.engine, "short" if short else "full", version,
                   settings, float(cpu) if isinstance(cpu, (int, float)) else None, machine_text(machine()),
                   list(run.events), obs)


def _parameters(params: Params) -> dict[str, dict[str, Any]]:
    """section → key → {"value", "source"} of every parameter (Params' own justifications)."""
    out: dict[str, dict[str, Any]] = {}
    for sec in fields(params):
        section = getattr(params, sec.name)
        if not is_dataclass(section):
            continue
        out[sec.name] = {f.name: {"value": getattr(section, f.name), "source": f.metadata.get("why", "")}
                         for f in fields(section)}
    return out


def acceptance(variant: Case, tool: str = ANY_TOOL) -> list[dict[str, Any]]:
    """Each [compare] row of `variant` for the pair (reference, `tool`) with the tool's own
    error not measured: observable, metric, window, threshold and its parts."""
    reference = default_engines()[0]
    rows = []
    for spec in variant.compare:
        pt = pair_tolerance(spec, (reference, tool), missing={tool: "no refined results file"})
        rows.append({"observable": spec.observable, "columns": columns(spec.observable), "metric": spec.metric,
                     "window": list(spec.window) if spec.window else None, "threshold": pt.tolerance,
                     "unit": unit_of(spec.observable, spec.metric).strip(), "why": spec.why,
                     "parts": pt.as_dict(), "formula": pt.formula()})
    return rows


def problem(case: Case, short: bool, reference: EngineRun) -> dict[str, Any]:
    """The machine-readable problem of `case` (`problem.json`)."""
    variant = case.variant(short)
    t = np.asarray(reference.observables["time"], float)
    asked = list(dict.fromkeys(s.observable for s in variant.compare))
    return {
        "format": PROBLEM_FORMAT, "case": case.name, "variant": "short" if short else "full",
        "description": case.description, "duration_s": variant.duration,
        "output": {"samples": int(t.size), "first_s": float(t[0]), "last_s": float(t[-1]),
                   "period_s": float(variant.solver.output_period), "times_file": SOLUTION},
        "case_file": Path(case.path).read_text(encoding="utf-8") if case.path else "",
        "parameters": _parameters(variant.params),
        "observables": [{"name": n, "columns": columns(n), "unit": BY_NAME[n].unit, "meaning": BY_NAME[n].meaning}
                        for n in asked],
        "events": [{"time_s": e.time, "kind": e.kind, "detail": e.detail} for e in reference.events],
        "acceptance": acceptance(variant),
        "solution": {"file": SOLUTION, "engine": reference.engine,
                     "settings": {k: v for k, v in reference.solver.items() if k != "wall_s"}},
    }


def problem_page(doc: Mapping[str, Any]) -> str:
    """The human-readable problem (`problem.md`)."""
    out = [f"# Problem {doc['case']} ({doc['variant']})", "", doc["description"], "",
           "Simulate the robot of De Bonis et al. (2021) as docs/physics.md defines it, with the parameters",
           "and the case file below, from t = 0 to "
           f"t = {doc['duration_s']:g} s, and write a results file (docs/problems.md) with the observables",
           f"below at the {doc['output']['samples']} output samples of reference.csv "
           f"(every {doc['output']['period_s']:g} s from {doc['output']['first_s']:g} s).", "",
           "## Observables", "", "| observable | columns | unit | meaning |", "|---|---|---|---|"]
    out += [f"| {o['name']} | {', '.join(o['columns'])} | {o['unit']} | {o['meaning']} |" for o in doc["observables"]]
    out += ["", "## Acceptance", "",
            "A row passes when the error (its metric of tool − reference) is at most the threshold. The",
            "threshold holds the modelling differences two faithful models may have, the reference's own",
            "integration error and none of yours: send a second results file at finer settings",
            "(`rsmcheck judge FILE --refined FINER`) and your own error is added.", "",
            "| observable | metric | threshold | unit | how |", "|---|---|---|---|---|"]
    for a in doc["acceptance"]:
        metric = a["metric"] + (f" [{a['window'][0]:g}, {a['window'][1]:g}] s" if a["window"] else "")
        out.append(f"| {a['observable']} | {metric} | {a['threshold']:.3g} | {a['unit']} | {a['formula']} |")
    if doc["events"]:
        out += ["", "## Events of the reference solution", "", "| t [s] | kind | detail |", "|---|---|---|"]
        out += [f"| {e['time_s']:.6g} | {e['kind']} | {e['detail']} |" for e in doc["events"]]
    out += ["", "## Parameters", "", "| section | key | value | source |", "|---|---|---|---|"]
    for sec, keys in doc["parameters"].items():
        out += [f"| {sec} | {k} | {v['value']!r} | {v['source']} |" for k, v in keys.items()]
    out += ["", "## Case file", "", "```toml", doc["case_file"].rstrip(), "```", ""]
    return "\n".join(out)


def export_case(case: Case, short: bool, runs: Mapping[str, EngineRun], out: Path) -> list[Path]:
    """Write the problem of `case` into `out/CASE/` from its runs (engine → run; the first
    default engine's is the reference solution); the paths written."""
    reference = default_engines()[0]
    if reference not in runs:
        raise InputError(f"export {case.name}", "engines", f"the reference solution needs a run of {reference}")
    folder = out / case.name
    doc = problem(case, short, runs[reference])
    asked = [o["name"] for o in doc["observables"]]
    written = [write_text(folder / "problem.json", dumps_json(doc)), write_text(folder / "problem.md", problem_page(doc))]
    ref = results_of(runs[reference], case, short, asked)
    written += [write_results(folder / SOLUTION, ref), write_results_h5(folder / Path(SOLUTION).with_suffix(".h5"), ref)]
    for engine, run in runs.items():
        if engine != reference:
            written.append(write_results(folder / f"{engine}.csv", results_of(run, case, short, asked)))
    return written


# ---------------------------------------------------------------------------------------
# judge
# ---------------------------------------------------------------------------------------
@dataclass
class Judgement:
    """A results file judged: its rows (compare.Check, pair (reference, tool)) and the
    accuracy / efficiency pair."""

    path: Path
    case: str
    tool: str
    rows: list[Check] = field(default_factory=list)
    cpu_time_s: float | None = None
    refined: Path | None = None

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.rows)

    @property
    def accuracy(self) -> float:
        """The largest error / threshold over the rows (≤ 1: acceptable)."""
        return max((r.error / r.tolerance for r in self.rows), default=float("nan"))

    def as_dict(self) -> dict[str, Any]:
        return {"file": str(self.path), "case": self.case, "tool": self.tool, "pass": self.passed,
                "accuracy": self.accuracy, "cpu_time_s": self.cpu_time_s,
                "refined": str(self.refined) if self.refined else None, "rows": [r.as_dict() for r in self.rows]}


def load_problem(problems: Path, case: str, where: str) -> tuple[dict[str, Any], Results]:
    """The problem of `case` under `problems` and its reference solution."""
    folder = problems / case
    if not (folder / "problem.json").is_file():
        raise InputError(where, "case", f"no problem {case!r} in {problems} (rsmcheck export {case} --out {problems})")
    doc = json.loads((folder / "problem.json").read_text(encoding="utf-8"))
    return doc, read_results(folder / doc["solution"]["file"])


def _check_grid(res: Results, ref: Results) -> None:
    t, tr = np.asarray(res.observables["time"]), np.asarray(ref.observables["time"])
    if t.shape != tr.shape or np.max(np.abs(t - tr)) > 1e-9:
        raise InputError(str(res.path), "time", f"{t.size} samples from {t[0]:g} to {t[-1]:g} s; the problem "
                                                f"has {tr.size} from {tr[0]:g} to {tr[-1]:g} s ({SOLUTION})")


def _check_columns(res: Results, doc: Mapping[str, Any]) -> None:
    for o in doc["observables"]:
        if o["name"] not in res.observables:
            raise InputError(str(res.path), o["columns"][0], f"missing: the problem asks for {o['name']}")


def judge_file(path: Path, problems: Path, refined: Path | None = None) -> Judgement:
    """Judge one results file (and the same tool's finer run, `refined`) against its problem."""
    res = read_results(path)
    doc, ref = load_problem(problems, res.case, str(path))
    if res.variant != doc["variant"]:
        raise InputError(str(path), "variant", f"{res.variant!r}; the problem {res.case} is {doc['variant']!r}")
    _check_grid(res, ref)
    _check_columns(res, doc)
    case = load_case(res.case)
    variant = case.variant(doc["variant"] == "short")
    reference = doc["solution"]["engine"]
    if res.tool == reference:
        raise InputError(str(path), "tool", f"{reference!r} is the reference solution's engine: name the tool")
    measured, missing = {}, {res.tool: "no refined results file"}
    if refined is not None:
        fine = read_results(refined)
        if (fine.case, fine.tool, fine.variant) != (res.case, res.tool, res.variant):
            raise InputError(str(refined), "case", "the refined run must be the same tool on the same problem")
        _check_grid(fine, ref)
        _check_columns(fine, doc)
        own = check_runs(variant, fine.as_run(res.tool), res.as_run(res.tool))
        measured = {res.tool: {r.observable: r.error for r in own}}
        missing = {}
    rows = check_runs(variant, ref.as_run(reference), res.as_run(), measured=measured, missing=missing)
    return Judgement(path, res.case, res.tool, rows, res.cpu_time_s, refined)


def default_problems() -> Path:
    return Path(os.environ.get("RSMCHECK_PROBLEMS_DIR") or "out/benchmark")


# ---------------------------------------------------------------------------------------
# the commands' bodies (rsmcheck.cli parses, these run and print)
# ---------------------------------------------------------------------------------------
def export_cases(cases: Sequence[Case], short: bool, engines: Sequence[str], out: Path, run_dir: Path | None,
                 progress=None) -> list[str]:
    """`rsmcheck export`: the runs (rsmcheck.orchestration.runs.get_runs; the first default
    engine first), then each case's problem; one line per file written."""
    for case in cases:  # every case looked at before anything runs, as check looks at it
        reason = not_checked(case, short)
        if reason:
            raise InputError(case.name, "compare", f"not a problem: {reason}")
    reference = default_engines()[0]
    engines = [reference] + [e for e in engines if e != reference]
    got = get_runs(cases, engines, short, run_dir, progress=progress)
    if got.errors:
        raise next(iter(got.errors.values()))
    return [f"{case.name}: wrote {path}" for case in cases
            for path in export_case(case, short, got.runs[case.name], out)]


def judgement_lines(j: Judgement) -> list[str]:
    """A judgement as `rsmcheck judge` prints it: a verdict line, then the rows as `check`
    prints them, each with how its threshold is made."""
    cpu = f"{j.cpu_time_s:.3g} s" if j.cpu_time_s is not None else "not given"
    return [f"{j.path}: {j.tool} on {j.case}: accuracy {j.accuracy:.3g} (largest error / threshold), "
            f"CPU time {cpu}: {'acceptable' if j.passed else 'NOT acceptable'}"] + row_lines(
        j.rows, threshold="threshold", every_formula=True)
