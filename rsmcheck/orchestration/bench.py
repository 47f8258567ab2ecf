"""`rsmcheck bench`: how fast is each engine on the same work.

Every (case, engine, variant) run happens in a fresh Python process, so that its peak
resident memory is its own; its wall time excludes the process start, the imports and
numba's compilation (a warm-up run of 0.01 s of the same case comes first).  Each run is
the variant `rsmcheck run/check` would run: with `--variant short` the case's [short]
variant with its own segments and engine settings (`bench_cases`); `--variant targets` runs
what the speed targets read (the mission at full length, every case short).  The mission runs its
phases chained, as `rsmcheck run mission` does, and records each phase's own simulated and
wall seconds (`phases`).  Beside the times, each run records the settings and counts behind
them (`SOLVER_KEYS`: steps, Newton iterations, Jacobians).  Each run is one Dask task
(rsmcheck.orchestration.executor) that starts that process on its worker and waits for it,
and takes the worker's one unit of the resource `executor.BENCH_RESOURCE`: a worker runs one
bench process at a time whatever its threads.  `--jobs 2` starts a local cluster of two
workers, so two of these processes run at a time (on the 2-core machine: the engines side
by side, as the full-length flights of docs/cases.md were measured); with `rsmcheck
--scheduler ADDRESS bench` (or $RSMCHECK_SCHEDULER) the runs go to that cluster's workers
that have the resource (docs/cluster.md), and `--jobs` is not used.  The runs are
submitted, and kept, in the order they were listed in.
Reported per run: simulated seconds, wall seconds, simulated seconds per wall second (×
real time), peak memory; a run that fails is reported with its error and the others go on
(in the JSON, `--json` and `--out`, its numbers are null: the document is strict JSON,
`store.dumps_json`).

`rhs_us`: the cost of one evaluation of the equations of motion,
* `reference_compiled` — one reference right-hand side inside a compiled loop (what the
  integrator pays per stage): the closed chain of `closed_squeeze`, default shapes;
  `reference_rigid_compiled` the same with rigid links (no shapes);
* `reference_call`, `reference_rigid_call` — the same called from Python (numba's
  dispatch of the model's arrays adds ~20 µs), like
* `pinocchio_aba` — one Pinocchio ABA call on the 10-coordinate rigid open chain
  (base + arm 1), from Python: the scale of a compiled rigid-body step.

Last, the speed targets the document measures (rsmcheck.orchestration.targets: the full
mission's wall time per engine, its slowest phase, the rigid RHS in ABA calls) with their
margins.  Ratios are only meaningful within one run of this command (shared, noisy machines).

`--baseline FILE` sets each run beside the same run of a stored document, and `--stored
FILE` shows a stored document instead of running (`rsmcheck.orchestration.bench_diff`):
the work (step attempts, Newton iterations) compares across machines, the wall time only
on the same kind of machine.

`machine` (`rsmcheck.core.store.machine`, the table's first line): the CPU model with its family,
model and clock, logical CPUs, memory, operating system, Python and the numerical packages.
Two machines of the project's 2-core kind, both calling their CPU "AMD EPYC", ran the same
code's full mission tens of per cent apart, and the compiled RHS timing did not show it
(docs/records.md): figures from two documents compare only when their machines do
(`rsmcheck.core.store.same_machine`), and a recorded machine can tell two machines apart, not
prove them alike (a shared host's load is not in the record).  Each run also records the
machine it ran on (`machine` of the run, evaluated on the Dask worker that ran it): the
document's `machine` is this process's, and the table says in one line when the runs ran on
another machine than that, or on more than one (`runs_machines_note`).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from typing import Any, Callable, Sequence

from rsmcheck.core.cases import Case, list_cases, load_case
from rsmcheck.core.errors import InputError
from rsmcheck.core.options import engines_option
from rsmcheck.core.plugins import available, engine_names, plugin, require, with_capability
from rsmcheck.orchestration.bench_diff import compare, diff_table, read_bench
from rsmcheck.orchestration.targets import read_targets, targets_table
from rsmcheck.core.params import Params
from rsmcheck.driver.runner import SPLIT
from rsmcheck.core.store import dumps_json, git_commit, machine, machine_text, output_file, same_machine, write_json
from rsmcheck.orchestration import executor
from rsmcheck.orchestration.runs import source_digest

VARIANTS = ("short", "full")

_CHILD = r"""
import json, pathlib, resource, sys, tempfile, time
from rsmcheck.orchestration.bench import SOLVER_KEYS, SPLIT_KEYS, bench_cases
from rsmcheck.orchestration.chain import run_mission
from rsmcheck.core.plugins import make_engine
from rsmcheck.driver.runner import run
from rsmcheck.core.store import read_run
name, engine_name, short = sys.argv[1], sys.argv[2], sys.argv[3] == "1"
case, first = bench_cases(name, short)
run(make_engine(engine_name, first), first, min(0.01, first.duration))  # warm-up
t0 = time.perf_counter()
phases = {}
if case.phases:
    with tempfile.TemporaryDirectory() as out:
        result = read_run(run_mission(case, [engine_name], short, pathlib.Path(out), phase_runs=phases))[0][engine_name]
else:
    result = run(make_engine(engine_name, case), case, case.duration)
wall = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"case": name, "engine": engine_name, "variant": "short" if short else "full",
                  "wall_s": wall, "sim_s": float(result.observables["time"][-1]), "peak_mb": peak,
                  "split": {k: result.solver[k] for k in SPLIT_KEYS if k in result.solver},
                  "solver": {k: result.solver[k] for k in SOLVER_KEYS if k in result.solver},
                  "phases": [{"phase": p, "sim_s": float(r[engine_name].observables["time"][-1]),
                              "wall_s": r[engine_name].solver["wall_s"]} for p, r in phases.items()]}))
"""

#: what a run reports about where its wall time went (rsmcheck.driver.runner.SPLIT, the engines'
#: `wall_integrator_s`): the bench's second table, µs per control sample
SPLIT_KEYS = ("samples", "wall_s", "wall_integrator_s", *(f"wall_{part}_s" for part in SPLIT))
#: the engine settings and counts that decide a run's cost, stored beside its times so that
#: a figure can be traced to what was run (the variant's own [solver] / [exudyn] settings)
SOLVER_KEYS = ("steps", "rejected_steps", "quiet_steps", "h_max", "rtol", "step", "substeps", "links",
               "newton_iterations", "newton_retries", "jacobians", "jacobian_per_step", "newton_atol")
#: the parts of a control sample's wall time (`per_sample_us`), in the table's order
PARTS = ("integrator", "engine", "sensors", "controller", "observe", "runner")


def bench_cases(name: str, short: bool) -> tuple[Case, Case]:
    """(what the bench times, what it warms up on) for case `name`: the variant that
    `rsmcheck run/check [--short]` runs — with `short`, the case's [short] variant with its
    own segments and [solver]/[exudyn] settings, not the full case cut at the short
    duration — and, for the mission, the same variant of its first phase."""
    case = load_case(name).variant(short)
    first = load_case(case.phases[0]).variant(short) if case.phases else case
    return case, first


def bench_run(case: str, engine: str, variant: str, script: str = _CHILD) -> dict[str, Any]:
    """One run in a fresh process (`python -c script CASE ENGINE 1|0`, this process's
    Python: on a Dask worker, the worker's): {case, engine, variant, wall_s, sim_s, peak_mb,
    …, machine} or, when it fails, the same keys with NaN and `error` (the last line the
    process printed).  `machine` is the machine this function ran on (`store.machine()`,
    taken after the process ended: not in its time)."""
    proc = subprocess.run([sys.executable, "-c", script, case, engine, "1" if variant == "short" else "0"],
                          capture_output=True, text=True)
    lines = proc.stdout.strip().splitlines()
    if proc.returncode == 0 and lines:
        try:
            return {**json.loads(lines[-1]), "machine": machine()}
        except json.JSONDecodeError:
            pass
    err = proc.stderr.strip().splitlines()
    return dict(failed_run(case, engine, variant, err[-1] if err else f"exit code {proc.returncode}, no output"),
                machine=machine())


def failed_run(case: str, engine: str, variant: str, error: str) -> dict[str, Any]:
    """The record of a run that gave no figures: NaN and its `error`."""
    return {"case": case, "engine": engine, "variant": variant, "wall_s": math.nan, "sim_s": math.nan,
            "peak_mb": math.nan, "error": error}


def run_all(work: Sequence[tuple[str, str, str]], jobs: int, progress: Callable[[dict], None] | None = None,
            script: str = _CHILD) -> list[dict[str, Any]]:
    """Each (case, engine, variant) of `work` as one Dask task (`bench_run`, taking one unit
    of `executor.BENCH_RESOURCE`: one at a time per worker) on the local cluster of `jobs`
    workers, or on the cluster --scheduler / $RSMCHECK_SCHEDULER names; the runs in the
    order of `work` (also the order of priority), `progress(run)` as each finishes.  A task
    Dask could not run (its worker kept dying: KilledWorker) is a failed run with that error."""
    out: list[dict[str, Any] | None] = [None] * len(work)
    tasks = [(bench_run, (*item, script) if script is not _CHILD else tuple(item)) for item in work]
    for i, value, exc in executor.completed(tasks, jobs, source_digest, resources={executor.BENCH_RESOURCE: 1}):
        out[i] = value if exc is None else failed_run(*work[i], f"{type(exc).__name__}: {exc}")
        if progress:
            progress(out[i])
    return out  # type: ignore[return-value]


def rhs_timings(n: int = 2000, engines: Sequence[str] | None = None) -> dict[str, Any]:
    """µs per evaluation: each engine plug-in's right-hand side compiled and from Python
    (`rhs_timing`; also its rigid model where it declares `rigid_options`), and each checking
    plug-in's articulated-body call (`aba_timing`), keys "ENGINE_call", "ENGINE_compiled",
    "ENGINE_states", "ENGINE_rigid_…", "CHECKER_aba" (module doc)."""
    case = load_case("closed_squeeze")
    out: dict[str, Any] = {}
    for name in engines or with_capability("rhs_timing"):
        p = plugin(name)
        if not getattr(p, "rhs_timing", None) or not available(name):
            continue
        variants = [(name, {})] + ([(f"{name}_rigid", dict(p.rigid_options))] if getattr(p, "rigid_options", None) else [])
        for key, options in variants:
            timing = p.rhs_timing(case, n, **options)
            out[f"{key}_call"] = timing["call_us"]
            out[f"{key}_compiled"] = timing["compiled_us"]
            out[f"{key}_states"] = timing["states"]
    for name in with_capability("aba_timing"):
        try:
            require(name)
            timing = plugin(name).aba_timing(Params(), n)
            out[f"{name}_aba"] = timing["call_us"]
            out[f"{name}_nv"] = timing["nv"]
        except Exception as exc:  # noqa: BLE001 — reported instead of a number
            out[f"{name}_aba"] = math.nan
            out[f"{name}_error"] = f"{type(exc).__name__}: {exc}"
    return out


def _speed(r: dict) -> float:
    return r["sim_s"] / r["wall_s"] if r.get("wall_s", 0) and math.isfinite(r["wall_s"]) else math.nan


def table(doc: dict) -> str:
    """The runs side by side: one row per (case, variant), one column group per engine."""
    engines = doc["engines"]
    rows: dict[tuple[str, str], dict[str, dict]] = {}
    for r in doc["runs"]:
        rows.setdefault((r["case"], r["variant"]), {})[r["engine"]] = r
    head = f"{'case':20s} {'variant':7s} {'sim s':>8s}"
    for e in engines:
        head += f" | {e + ' wall s':>16s} {'× real':>8s} {'MB':>6s}"
    if len(engines) == 2:
        head += f" | {engines[1] + '/' + engines[0]:>18s}"
    note = runs_machines_note(doc)
    lines = [f"machine: {machine_text(doc.get('machine'))}", *([note] if note else []), "", head, "-" * len(head)]
    for (case, variant), by in rows.items():
        sim = next((r["sim_s"] for r in by.values() if math.isfinite(r["sim_s"])), math.nan)
        line = f"{case:20s} {variant:7s} {sim:8.2f}"
        for e in engines:
            r = by.get(e)
            if r is None or "error" in r:
                line += f" | {'failed':>16s} {'':>8s} {'':>6s}"
            else:
                line += f" | {r['wall_s']:16.2f} {_speed(r):8.3f} {r['peak_mb']:6.0f}"
        if len(engines) == 2 and all(e in by and "error" not in by[e] for e in engines):
            line += f" | {by[engines[1]]['wall_s'] / by[engines[0]]['wall_s']:18.2f}"
        lines.append(line)
    rhs = doc.get("rhs_us", {})
    if rhs:
        lines.append("")
        lines.append(f"RHS per call: reference {rhs['reference_compiled']:.1f} µs compiled "
                     f"({rhs.get('reference_states', '?')} states), {rhs['reference_call']:.1f} µs from Python; "
                     f"rigid reference (closed chain, {rhs.get('reference_rigid_states', '?')} states) "
                     f"{rhs['reference_rigid_compiled']:.1f} µs compiled, {rhs['reference_rigid_call']:.1f} µs from "
                     f"Python; Pinocchio ABA {rhs['pinocchio_aba']:.1f} µs from Python "
                     f"({rhs.get('pinocchio_nv', '?')} dof open chain)"
                     + (f" — rigid reference compiled / ABA = {rhs['reference_rigid_compiled'] / rhs['pinocchio_aba']:.1f}"
                        if math.isfinite(rhs.get("pinocchio_aba", math.nan)) else f" — {rhs.get('pinocchio_error')}"))
    for part in (phase_table(doc["runs"], engines), split_table(doc["runs"]), targets_table(read_targets(doc))):
        if part:
            lines += ["", part]
    failed = [r for r in doc["runs"] if "error" in r]
    for r in failed:
        lines.append(f"FAILED {r['case']} {r['engine']} {r['variant']}: {r['error']}")
    return "\n".join(lines)


def runs_machines_note(doc: dict) -> str:
    """'' when every run ran on the document's machine (the same kind: `same_machine`) or
    no run recorded its own (older documents), else one line: the one other machine the
    runs ran on, or how many kinds of machine they ran on (and how many runs did not
    record theirs): wall times then compare only between runs of one machine."""
    runs = doc.get("runs", [])
    recorded = [r["machine"] for r in runs if r.get("machine")]
    if not recorded:
        return ""
    kinds: list[tuple[dict, int]] = []
    for m in recorded:
        for n, (k, count) in enumerate(kinds):
            if same_machine(m, k):
                kinds[n] = (k, count + 1)
                break
        else:
            kinds.append((m, 1))
    unknown = len(runs) - len(recorded)
    if len(kinds) == 1 and not unknown:
        if same_machine(kinds[0][0], doc.get("machine")):
            return ""
        return f"runs ran on another machine: {machine_text(kinds[0][0])}"
    return (f"runs ran on {len(kinds)} machine{'s' if len(kinds) != 1 else ''} ("
            + "; ".join(f"{count} on {k.get('cpu', 'unknown')}, {k.get('logical_cpus', '?')} logical CPUs"
                        for k, count in kinds)
            + (f"; {unknown} not recorded" if unknown else "")
            + "): compare wall times between runs of one machine only (each run's machine in the JSON)")


def phase_table(runs: Sequence[dict], engines: Sequence[str]) -> str:
    """Each phase of a chained mission run: its simulated seconds, and per engine its wall
    seconds and × real time (where README's target "each phase ≥ 20 × real time" is read)."""
    rows: dict[tuple[str, str, str], dict[str, dict]] = {}
    for r in runs:
        for p in r.get("phases") or []:
            rows.setdefault((r["case"], r["variant"], p["phase"]), {})[r["engine"]] = p
    if not rows:
        return ""
    head = f"{'mission phase':28s} {'variant':7s} {'sim s':>8s}" + "".join(
        f" | {e + ' wall s':>16s} {'× real':>8s}" for e in engines)
    lines = [head, "-" * len(head)]
    for (case, variant, phase), by in rows.items():
        sim = next(iter(by.values()))["sim_s"]
        line = f"{case + ' ' + phase:28s} {variant:7s} {sim:8.2f}"
        for e in engines:
            p = by.get(e)
            line += f" | {p['wall_s']:16.2f} {_speed(p):8.3f}" if p else f" | {'—':>16s} {'':>8s}"
        lines.append(line)
    return "\n".join(lines)


def per_sample_us(split: dict[str, float]) -> dict[str, float]:
    """A run's wall time per control sample [µs], by where it went: `integrator` (the
    compiled DP5 or Exudyn's `SolveSteps` up to the sample), `engine` (the rest of
    `advance`: setting the inputs, the field, checks), `sensors`, `controller`, `observe`
    (the recorded samples, amortised), `runner` (the sampled-data loop itself: events,
    supervision)."""
    n = split["samples"]
    advance = split["wall_advance_s"]
    integ = split.get("wall_integrator_s", advance)
    parts = {"integrator": integ, "engine": advance - integ, "sensors": split["wall_sensors_s"],
             "controller": split["wall_controller_s"], "observe": split["wall_observe_s"]}
    parts["runner"] = split["wall_s"] - sum(parts.values())
    return {k: v / n * 1e6 for k, v in parts.items()}


def split_table(runs: Sequence[dict]) -> str:
    """Where a control sample's wall time goes, per run (µs per sample; `per_sample_us`)."""
    rows = [r for r in runs if "error" not in r and r.get("split", {}).get("samples")]
    if not rows:
        return ""
    head = f"{'µs per control sample':28s} {'samples':>9s} " + " ".join(f"{k:>10s}" for k in PARTS) + f" {'total':>8s}"
    lines = [head, "-" * len(head)]
    for r in rows:
        us = per_sample_us(r["split"])
        lines.append(f"{r['case'] + ' ' + r['engine'][:3]:28s} {r['split']['samples']:9d} "
                     + " ".join(f"{us[k]:10.1f}" for k in PARTS) + f" {sum(us.values()):8.1f}")
    return "\n".join(lines)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive whole number")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rsmcheck bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout instead of the table")
    parser.add_argument("--variant", default="short", choices=[*VARIANTS, "both", "targets"],
                        help="the cases' --short variants (default), their full length, both, or what the "
                             "speed targets read: the full mission and every case short")
    parser.add_argument("--full", action="store_true", help="same as --variant full")
    engines_option(parser, "ENGINE, A,B or all (default: every engine that simulates)", default="all")
    parser.add_argument("--cases", nargs="+", help="only these cases (default: every case and the mission)")
    parser.add_argument("--jobs", type=_positive_int, default=1,
                        help="runs at a time: the local Dask cluster's workers, each running one run at a time in "
                             "its own process (default 1; 2 on the 2-core machine puts the engines side by side; "
                             "not used with rsmcheck --scheduler, whose workers decide)")
    parser.add_argument("--out", help="also write the JSON document to this file (e.g. docs/data/bench_targets.json)")
    parser.add_argument("--baseline", metavar="FILE",
                        help="compare the runs with a stored bench document: the work (steps, Newton iterations) "
                             "of each run, and its wall time when the machines are alike (bench_diff)")
    parser.add_argument("--stored", metavar="FILE",
                        help="run nothing: show this stored bench document (with --baseline, against that one)")
    args = parser.parse_args(argv)
    if args.stored:
        given = [f"--{k}" for k in _RUN_OPTIONS if getattr(args, k) != parser.get_default(k)]
        if given:
            raise InputError("rsmcheck bench", "--stored", f"shows a stored document and runs nothing: "
                             f"{', '.join(given)} would not be used")
        return _show_stored(args)
    base = read_bench(args.baseline) if args.baseline else None  # before an hour of runs, not after
    out = output_file(args.out, "--out") if args.out else None
    engines = engine_names(args.engines)
    for e in engines:
        require(e)
    variants = ["full"] if args.full else (list(VARIANTS) if args.variant == "both" else
                                           ["short"] if args.variant == "targets" else [args.variant])
    names = args.cases or [p.stem for p in list_cases()]
    for name in names:  # a misspelt case is a bad input (exit 2), not a failed run
        load_case(name)
    commit, dirty = git_commit()  # the code the runs import, not the tree at the end of hours of runs
    started = time.monotonic()
    work = [(name, engine, variant) for name in names for variant in variants for engine in engines]
    if args.variant == "targets":  # the long runs first (on two workers side by side), then the short
        work = [("mission", engine, "full") for engine in engines] + \
            [(name, engine, "short") for name in names for engine in engines]

    def progress(r: dict) -> None:
        state = f"ERROR {r['error']}" if "error" in r else \
            f"{r['sim_s']:.2f} s in {r['wall_s']:.2f} s ({_speed(r):.3f} × real time)"
        print(f"[{time.monotonic() - started:7.0f} s] {r['case']} {r['variant']} {r['engine']}: {state}",
              file=sys.stderr, flush=True)

    address = executor.scheduler_address()
    if address:  # the cluster answers, runs this code and has a worker for bench runs: else exit 2 now
        executor.require_resources(executor.connect(address, source_digest), address, {executor.BENCH_RESOURCE: 1})
    print(f"{len(work)} run{'s' if len(work) != 1 else ''} " + (f"on the Dask cluster at {address}" if address else
                                  f"on {args.jobs} local Dask worker{'s' if args.jobs != 1 else ''}")
          + ", one run per worker at a time", file=sys.stderr, flush=True)
    # each run is a task that starts its own process on a worker, one per worker at a time
    runs = run_all(work, args.jobs, progress)
    doc = {"command": "rsmcheck bench " + " ".join(argv if argv is not None else sys.argv[2:]),
           "commit": commit, "dirty": dirty, "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
           "machine": machine(), "engines": engines, "jobs": args.jobs, "runs": runs, "rhs_us": rhs_timings()}
    if base is not None:
        doc["baseline"] = compare(doc, base, args.baseline)
    if out is not None:
        write_json(out, doc)
    _print(doc, args.json)
    return 1 if any("error" in r for r in runs) else 0


def _print(doc: dict, as_json: bool) -> None:
    """The document as one JSON line, or its tables with the comparison last."""
    if as_json:
        print(dumps_json(doc, indent=None))
        return
    print(table(doc))
    if "baseline" in doc:
        print()
        print(diff_table(doc["baseline"]))


#: the options that make runs, meaningless with --stored
_RUN_OPTIONS = ("variant", "full", "engines", "cases", "jobs", "out")


def _show_stored(args: argparse.Namespace) -> int:
    """`--stored FILE`: the stored document's tables (and its comparison with --baseline);
    exit 0, or 1 when the stored document has failed runs, like the run that wrote it."""
    doc = read_bench(args.stored, "--stored")
    doc.setdefault("engines", list(dict.fromkeys(r["engine"] for r in doc["runs"])))
    if args.baseline:
        doc["baseline"] = compare(doc, read_bench(args.baseline), args.baseline)
    _print(doc, args.json)
    return 1 if any("error" in r for r in doc["runs"]) else 0
