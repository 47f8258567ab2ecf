"""The `rsmcheck` command line (docs/commands.md).

Exit codes: 0 all good, 1 a check failed, 2 bad input or usage (one line on stderr, no
traceback; output paths are checked before anything runs).  A diverging simulation is
reported in one line with time, phase and quantity and exits 1.  A reader of the standard
output that goes away (`rsmcheck cases | head -1`) ends the command quietly
(`errors.exit_code`).  Every `--json` document is strict JSON (`store.dumps_json`).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Callable, Sequence

from rsmcheck.core.cases import CASES_ENV, cases_dirs, list_cases, load_case
from rsmcheck.core.errors import InputError, exit_code, flush_stdout
from rsmcheck.core.options import engines_option
from rsmcheck.core import jit
from rsmcheck.orchestration import (bench, benchmark, budget, case_edit, code_paths, compare, executor, fuzz, gate,
                                    kernels)
from rsmcheck.orchestration.chain import run_case
from rsmcheck.orchestration.runs import source_digest
from rsmcheck.core.plugins import (CAPABILITIES, available, broken_plugins, default_engines, engine_names, plugin,
                                   plugins, require)
from rsmcheck.core.derived import DerivedPlugin
from rsmcheck.driver.runner import terminal_progress
from rsmcheck.core.store import dumps_json, output_dir, output_file


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with one line (its default prints usage too; keep it short)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"rsmcheck: {message}\n")
        raise SystemExit(2)


def _cmd_cases(args: argparse.Namespace) -> int:
    for path in list_cases():
        case = load_case(path)
        short = f", --short {case.short_duration:g} s" if case.short_duration != case.duration else ""
        print(f"{case.name:20s} {case.duration:8g} s{short:16s}  {case.description}")
    return 0


def _engine_names(choice: str | None) -> list[str]:
    """The engines `--engines` names ("all", a comma-separated list, or None for the default
    engines), each with its libraries installed."""
    names = engine_names(choice)
    for n in names:
        require(n)
    return names


def _cmd_engines(args: argparse.Namespace) -> int:
    """`rsmcheck engines`: every registered plug-in, what it offers and whether it can run."""
    for name, p in plugins().items():
        role = "simulates" if p.simulates else "checks"
        caps = [c for c in CAPABILITIES if getattr(p, c, None) is not None]
        state = "available" if available(name) else (
            f"NOT INSTALLED: pip install 'rsmcheck[{p.extra}]'" if p.extra else "NOT INSTALLED")
        tables = ", ".join(f"[{t}]" for t in p.tables) or "-"
        origin = f"variant of {p.base.name}" if isinstance(p, DerivedPlugin) else type(p).__module__
        print(f"{name:12s} {p.label:12s} {role:9s} tables {tables:12s} {origin:26s} {state}")
        if isinstance(p, DerivedPlugin):
            print(f"{'':12s} {p.base.name}'s code and case settings; differs: {p.differs}")
        if caps:
            print(f"{'':12s} offers {', '.join(caps)}")
    for name, b in broken_plugins().items():
        print(f"{name:12s} {'-':12s} {'-':9s} {'':19s} {b.distribution:26s} BROKEN: {b.reason}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    out = output_dir(args.out, "--out")  # before anything runs: an existing file there is a bad input
    cases = [load_case(name) for name in args.case]  # validate every case before running any
    engines = _engine_names(args.engines) if args.engines else _engine_names(None)[:1]
    out.mkdir(parents=True, exist_ok=True)
    for case in cases:
        path = run_case(case, engines, args.short, out,
                        from_dir=Path(args.from_dir) if args.from_dir else None,
                        progress=terminal_progress, chain=False if args.standalone else None)
        print(f"{case.name}: wrote {path} ({', '.join(engines)})")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    out = output_file(args.out, "--out")  # before anything runs or is imported
    # lazy: collect and the report read rsmcheck.orchestration.modes, whose scipy (with
    # plotly, jinja2) takes `rsmcheck --help` from 0.4 s to 1.0 s when imported at the top
    from rsmcheck.orchestration.collect import collect
    from rsmcheck.report.build import render

    folder = out.parent
    engines = _engine_names(args.engines) if args.engines else None
    if not args.render_only:
        engines = engines or _engine_names(None)
        res = collect(folder, args.short, engines, args.cases or None, _progress, rerun=args.rerun)
        failures = list(res.failures)
    else:
        failures = []
    path = render(folder, out, args.cases or None, engines=engines)  # those asked for, not all stored
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)"
          + (f"; did not run: {', '.join(failures)}" if failures else ""))
    return 1 if failures else 0


def _engine_options(items: Sequence[str] | None, engines: Sequence[str]) -> dict[str, dict]:
    """`--option ENGINE:KEY=VALUE` items → {engine: {key: value}} for the constructors of
    `engines` (ints, floats, true/false, text)."""
    out: dict[str, dict] = {e: {} for e in engines}
    for item in items or ():
        engine, colon, pair = item.partition(":")
        key, sep, text = pair.partition("=")
        if not colon or not sep or not key:
            raise InputError("--option", item, "must be ENGINE:KEY=VALUE")
        if engine not in out:
            raise InputError("--option", item, f"{engine!r} is not one of the engines run ({', '.join(engines)})")
        allowed = plugin(engine).engine_options
        if key not in allowed:
            raise InputError("--option", item, f"unknown option of {engine} (known: {', '.join(allowed)})")
        value: object = text
        low = text.lower()
        if low in ("true", "false"):
            value = low == "true"
        else:
            for conv in (int, float):
                try:
                    value = conv(text)
                    break
                except ValueError:
                    pass
        out[engine][key] = value
    return out


def _cmd_check(args: argparse.Namespace) -> int:
    out = output_dir(args.out, "--out") if args.out else None
    cases = [load_case(name) for name in args.case]  # validate every case before running any
    engines = _engine_names(args.engines)
    if len(engines) < 2:
        raise InputError("--engines", args.engines, "a check compares two or more engines")
    options = _engine_options(args.option, engines)
    # the runs come from rsmcheck.orchestration.runs.get_runs, as the report's do: stored in
    # and reused from --out when given, else made in memory; the rows by compare.case_rows
    results = compare.check_cases(cases, args.short, options, out, rerun=args.rerun, workers=0 if args.serial else 2,
                                  progress=_progress if not args.json and sys.stderr.isatty() else None,
                                  engines=engines)
    for res in results:
        if res.error is not None:  # reported as before: the cases ahead of it are shown
            raise res.error
        if args.json:
            continue
        if res.skipped:
            print(f"{res.case}: NOT CHECKED: {res.skipped}")
            continue
        case = next(c for c in cases if c.name == res.case)
        variant = "short" if args.short and case.short is not None else "full"
        walls = ", ".join(f"{e} {res.wall_s[e]:.1f} s" for e in engines)
        print(f"{case.name} ({variant}, {res.duration:g} s; wall: {walls})")
        print("\n".join(compare.row_lines(res.rows, pair_headers=len(engines) > 2)))
    rows = [r for res in results for r in res.rows]
    skipped = [{"case": res.case, "reason": res.skipped} for res in results if res.skipped]
    failed = [r for r in rows if not r.passed]
    if args.json:
        doc = {"checks": [r.as_dict() for r in rows], "skipped": skipped,
               "runs": [{"case": res.case, "duration_s": res.duration, "wall_s": res.wall_s}
                        for res in results if not res.skipped],
               "options": options, "engines": engines, "short": bool(args.short)}
        print(dumps_json(doc))
    else:
        pairs = list(dict.fromkeys(r.engines for r in rows))
        per_pair = [f"{a} against {b}: {sum(r.passed for r in rows if r.engines == (a, b))} of "
                    f"{sum(r.engines == (a, b) for r in rows)}" for a, b in pairs] if len(pairs) > 1 else []
        print(f"{len(rows) - len(failed)} of {len(rows)} comparisons pass"
              + (f" ({'; '.join(per_pair)})" if per_pair else "")
              + (f"; {len(skipped)} case(s) not checked (no [compare] table)" if skipped else ""))
    if not rows:
        sys.stderr.write("rsmcheck: nothing was compared (no case has a [compare] table)\n")
        return 1
    return 1 if failed else 0


def _budget_cases(names: Sequence[str], short: bool) -> list:
    """The cases named (each validated before anything runs), or every stand-alone case
    whose variant has [compare] rows."""
    if names:
        return [load_case(n) for n in names]
    cases = [load_case(p) for p in list_cases()]
    return [c for c in cases if not c.phases and c.variant(short).has_initial and c.variant(short).compare]


def _cmd_budget(args: argparse.Namespace) -> int:
    out = output_file(args.out, "--out")  # before anything runs: a directory there is a bad input
    previous = budget.read_document(out)  # and so is a file that is not a budget document
    suggest = budget.Suggest(args.factor, args.out)
    cases = _budget_cases(args.case, args.short)
    engines = _engine_names(args.engines)
    if len(engines) < 2:
        raise InputError("--engines", args.engines, "a budget compares two or more engines")
    if args.apply and len(engines) != 2:
        raise InputError("--apply", ",".join(engines), "writes the rows of one pair of engines: name two")
    # the stated pair writes its rows; another pair only its engines' own errors (engine_errors)
    stated_pair = set(engines) == set(default_engines())
    run_dir = output_dir(args.runs, "--runs") if args.runs else None
    results = budget.measure(cases, args.short, engines, _progress, workers=0 if args.serial else 2,
                             run_dir=run_dir)
    for cb in results:
        print("\n".join(budget.table_lines(cb)))
    if args.suggest:
        print(f"Suggested tolerances ({suggest.rule}):")
        for cb in results:
            lines = budget.suggestion_lines(cb, suggest)
            if lines:
                print("\n".join(lines))
    rows = [r for cb in results for r in cb.rows]
    if rows:
        budget.write_document(out, budget.document(results, args.short, previous, suggest))
    applied = set()
    if args.apply:
        for cb in results:
            if not cb.rows:
                continue
            if cb.case.phases:
                print(f"{cb.case.path}: nothing set: a sequence's phase rows ([compare.PHASE.OBSERVABLE]) are "
                      "written by hand from the suggestions (docs/cases.md §6)")
                continue
            edit = case_edit.apply_rows(cb.case, args.short, budget.suggestions(cb, suggest) if stated_pair
                                        else budget.engine_error_rows(cb))
            applied |= {(cb.name, obs) for obs in edit.changed}
            left = [r.observable for r in cb.rows if r.observable not in {*edit.changed, *edit.refused}]
            print(f"{edit.path}: " + "; ".join(
                [f"set {', '.join(edit.changed)}" if edit.changed else "nothing set"]
                + [f"{obs} not set: {why}" for obs, why in edit.refused.items()]
                + ([f"{', '.join(left)} not set: a run failed or a part of the budget is not measured or zero"]
                   if left else [])))
    print(budget.summary(results) + (f"; wrote {out}" if rows else ""))
    if not rows:
        sys.stderr.write("rsmcheck: nothing was budgeted (no case with [compare] rows could be measured)\n")
        return 1
    failed = any(cb.failures for cb in results)
    return 1 if failed or any(r.verdict == "tight" and (r.case, r.observable) not in applied for r in rows) else 0


def _cmd_modes(args: argparse.Namespace) -> int:
    # lazy: at the top its scipy would add ≈ 0.5 s to every command (`rsmcheck --help` takes 0.4 s)
    from rsmcheck.orchestration.modes import arm_rows, link_rows, modes_text

    engines = _engine_names(args.engines)
    options = _engine_options(args.option, engines)
    links = link_rows(options=options, engines=engines)
    arms = arm_rows(options=options, engines=engines)
    print(dumps_json({"links": links, "arms": arms}) if args.json else modes_text(links, arms, engines))
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    """`rsmcheck export`: each case's problem, reference solution and acceptance."""
    out = output_dir(args.out, "--out")
    cases = [load_case(name) for name in args.case]
    run_dir = output_dir(args.runs, "--runs") if args.runs else None
    engines = _engine_names(args.engines) if args.engines else []
    for line in benchmark.export_cases(cases, args.short, engines, out, run_dir, _progress if sys.stderr.isatty() else None):
        print(line)
    return 0


def _cmd_judge(args: argparse.Namespace) -> int:
    """`rsmcheck judge`: every file read and judged before anything is printed; exit 1 when a row fails."""
    if args.refined and len(args.results) != 1:
        raise InputError("--refined", args.refined, "goes with one results file")
    problems = Path(args.problems) if args.problems else benchmark.default_problems()
    judged = [benchmark.judge_file(Path(p), problems, Path(args.refined) if args.refined else None) for p in args.results]
    print(dumps_json({"judgements": [j.as_dict() for j in judged]}) if args.json else
          "\n".join(line for j in judged for line in benchmark.judgement_lines(j)))
    return 0 if all(j.passed for j in judged) else 1


def _cmd_compile(args: argparse.Namespace) -> int:
    """`rsmcheck compile`: every engine's kernels into the cache, a group per worker."""
    engines = _engine_names(args.engines or "all")
    walls = kernels.compile_kernels([e for e in engines if plugin(e).simulates], args.workers, print,
                                    again=args.again)
    print(f"compiled: {len(walls)} groups of {', '.join(engines)} (cache {jit.cache_dir()}; a group already"
          " compiled for this code is skipped, --again runs it anyway)")
    return 0


def _plugin_command(args: argparse.Namespace) -> int:
    """A sub-command a plug-in brings (its `commands`), e.g. `rsmcheck pinocchio`."""
    for name, p in plugins().items():
        if args.command in getattr(p, "commands", {}):
            require(name, args.command)
            return p.run_command(args.command, args.rest)
    raise InputError("rsmcheck", args.command, "no plug-in offers this command")


def _cmd_bench(args: argparse.Namespace) -> int:
    return bench.main(args.rest)


def _gate_cases(names: Sequence[str] | None) -> list:
    if not names or list(names) == ["all"]:
        return gate.gated_cases()
    cases = [load_case(n) for n in names]  # validate every case before running any
    for c in cases:
        if c.phases or not c.variant(True).has_initial:
            raise InputError(str(c.path), "initial", "only stand-alone cases have goldens "
                             "(a sequence is gated phase by phase)")
    return cases


def _cmd_fuzz(args: argparse.Namespace) -> int:
    out = output_dir(args.out, "--out")
    engines = _engine_names(args.engines) if args.engines else None
    doc = fuzz.campaign(args.n, args.seed, out, engines, workers=0 if args.serial else 2,
                        progress=None if args.json else _progress, first=args.first)
    path = fuzz.write_document(doc, out)
    if args.json:
        print(dumps_json(doc))
    else:
        print(fuzz.summary(doc))
        print(f"wrote {path}")
    return 0 if doc["failed"] == 0 else 1


def _whole(least: int) -> Callable[[str], int]:
    """An argparse type: a whole number of at least `least`."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if n < least:
            raise argparse.ArgumentTypeError(f"must be at least {least}, got {n}")
        return n
    return parse


def _progress(text: str) -> None:
    sys.stderr.write(f"  {text}\n")
    sys.stderr.flush()


def _goldens(args: argparse.Namespace) -> Path:
    """The goldens' folder: the hidden --goldens, else $RSMCHECK_GOLDENS_DIR, else goldens/."""
    return Path(args.goldens) if args.goldens else gate.goldens_dir()


def _cmd_gate(args: argparse.Namespace) -> int:
    cases = _gate_cases(args.case)
    if args.tolerances:
        rows = gate.tolerance_table(cases, _engine_names(args.engines), _goldens(args))
        if args.json:
            print(dumps_json({"tolerances": rows}))
            return 0
        print(f"{'case':20s} {'engine':9s} {'observable':20s} {'gate tol':>10s} {'masses':>10s} {'decisions':>10s} "
              f"{'code paths':>10s} {'|value|max':>10s}  set by")
        for r in rows:
            print(f"{r['case']:20s} {r['engine']:9s} {r['observable']:20s} {r['tolerance']:10.2e} "
                  f"{r['perturbation_change']:10.2e} {r['step_change']:10.2e} {r['path_change']:10.2e} "
                  f"{r['largest_value']:10.2e}  {r['set_by']}")
        return 0
    results = gate.gate(cases, _engine_names(args.engines), _goldens(args), None if args.json else _progress)
    if args.json:
        print(dumps_json({"gate": [r.as_dict() for r in results]}))
    else:
        for r in results:
            head = f"{r.case} / {r.engine}: "
            if r.unchanged:
                print(head + f"unchanged (largest change {r.largest_ratio:.2g} × its gate tolerance; "
                      f"{r.work_summary()})")
                continue
            print(head + ("INPUTS CHANGED" if r.inputs_changed else "MOVED"))
            for line in r.inputs_changed + r.structure:
                print(f"    {line}")
            for m in r.moved:
                print(f"    {m.observable:20s} changed by {m.change:.3e} > gate tolerance {m.tolerance:.3e} "
                      f"({m.ratio:.3g} ×), first at t = {m.first_time:.4g} s, worst component {m.component}")
            for w in r.more_work:
                print(f"    more work: {w.describe()} > limit {w.limit} (golden + {gate.WORK_TOL:.0%} + "
                      f"{gate.WORK_SLACK})")
        moved = sum(not r.unchanged for r in results)
        print(f"{len(results) - moved} of {len(results)} runs unchanged"
              + (f"; {moved} moved: if the change is intended, rsmcheck bless CASE --reason TEXT" if moved else ""))
    return 0 if all(r.unchanged for r in results) else 1


def _code_paths(spec: str | None) -> list | None:
    """--code-paths: None (every path this CPU can run), 'none', or names from
    rsmcheck.orchestration.code_paths.CODE_PATHS (one this CPU cannot run: exit 2)."""
    if spec is None:
        return None
    if spec.strip() == "none":
        return []
    known = {p.name: p for p in code_paths.CODE_PATHS}
    out = []
    for name in (n.strip() for n in spec.split(",") if n.strip()):
        if name not in known:
            raise InputError("--code-paths", name, f"no such code path (known: {', '.join(known)}, or none)")
        if not code_paths.runnable(known[name]):
            raise InputError("--code-paths", name, "this CPU cannot run it (it lacks "
                             + ", ".join(f for f in known[name].needs if not code_paths.cpu_features().get(f)) + ")")
        out.append(known[name])
    return out


def _cmd_bless(args: argparse.Namespace) -> int:
    if not args.reason or not args.reason.strip():
        raise InputError("bless", "--reason", "a bless needs a reason: what changed and why the new results are right")
    root = _goldens(args)
    output_dir(str(root), "--goldens")
    cases = _gate_cases(args.case)
    entries = gate.bless(cases, _engine_names(args.engines), args.reason, root, _progress,
                         _code_paths(args.code_paths))
    for case, engine, what in entries:
        print(f"{case} / {engine}: " + "; ".join(what))
    print(f"wrote {len(entries)} golden(s) and an entry in {root / gate.CHANGELOG}")
    return 0


COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "bench": _cmd_bench,
    "bless": _cmd_bless,
    "budget": _cmd_budget,
    "gate": _cmd_gate,
    "cases": _cmd_cases,
    "check": _cmd_check,
    "modes": _cmd_modes,
    "run": _cmd_run,
    "report": _cmd_report,
    "engines": _cmd_engines,
    "compile": _cmd_compile,
    "export": _cmd_export,
    "judge": _cmd_judge,
    "fuzz": _cmd_fuzz,
}


SCHEDULER_HELP = (f"run the jobs of check, budget, gate, bless, report, fuzz and bench on the Dask cluster whose "
                  f"scheduler is at ADDRESS (e.g. tcp://host:8786; ${executor.SCHEDULER_ENV} too; default: this "
                  f"machine's processes; docs/cluster.md)")
CASES_DIR_HELP = (f"also read the case files of folder DIR (repeatable; before or after the command; "
                  f"${CASES_ENV} too, {os.pathsep}-separated); a name in two folders is an error")


def _global_options() -> argparse.ArgumentParser:
    """The options every command takes, before or after its name (`--cases-dir`); given
    after it they land in `cases_dir_after` (a subcommand's default would overwrite the
    value parsed before it)."""
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument("--cases-dir", dest="cases_dir_after", action="append", metavar="DIR",
                   default=argparse.SUPPRESS, help=CASES_DIR_HELP)
    p.add_argument("--scheduler", dest="scheduler_after", metavar="ADDRESS", default=argparse.SUPPRESS,
                   help=SCHEDULER_HELP)
    return p


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rsmcheck", description="Validation benchmark for the dual-arm flexible space robot")
    parser.add_argument("--cases-dir", action="append", metavar="DIR", default=[], help=CASES_DIR_HELP)
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None, help=SCHEDULER_HELP)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    common = [_global_options()]
    add_parser = sub.add_parser
    sub.add_parser = lambda *a, **k: add_parser(*a, parents=common, **k)  # type: ignore[method-assign]
    sub.add_parser("cases", help="list the cases, one line each")
    p = sub.add_parser("run", help="simulate cases and write DIR/CASE.h5")
    p.add_argument("case", nargs="+", help="case name (cases/NAME.toml) or path to a case file")
    engines_option(p, "ENGINE, A,B or all (default: the first default engine, the model under test)")
    p.add_argument("--out", default="results", help="output directory (default: results)")
    p.add_argument("--short", action="store_true", help="the compressed variant of each case (CI)")
    p.add_argument("--from", dest="from_dir", default=None,
                   help="folder with the predecessors' end states of chained phases (default: --out)")
    p.add_argument("--standalone", action="store_true",
                   help="start a phase from its own [initial] even where a predecessor's end state exists")
    p = sub.add_parser("check", help="run the reference and Exudyn, compare by the case's [compare] table")
    p.add_argument("case", nargs="+", help="case name (cases/NAME.toml) or path to a case file")
    p.add_argument("--short", action="store_true", help="the compressed variant of each case (CI)")
    p.add_argument("--json", action="store_true", help="one JSON object {\"checks\": [...]} on stdout")
    engines_option(p, "the engines compared, the model under test first "
                                                     "(default: the default engines, `rsmcheck engines`)")
    p.add_argument("--option", action="append", metavar="ENGINE:KEY=VALUE",
                   help="an engine's constructor option, e.g. reference:n_modes=4 (repeatable)")
    p.add_argument("--out", help="store DIR/CASE.h5 with both runs, and reuse the runs stored there "
                                 "that are current (same case inputs without [compare] rows, parameters, variant, options, "
                                 "code)")
    p.add_argument("--rerun", action="store_true", help="with --out: run again even what is stored and current")
    p.add_argument("--serial", action="store_true",
                   help="run the engines one after the other in this process (default: 2 processes)")
    p = sub.add_parser("export", help="cases as problems for any tool (docs/problems.md)")
    p.add_argument("case", nargs="+", help="case names (stand-alone cases with a [compare] table)")
    p.add_argument("--out", required=True, help="the folder: a sub-folder per case")
    p.add_argument("--short", action="store_true", help="the compressed variant of each case (CI)")
    engines_option(p, "engines whose runs are written as results files beside the reference solution's")
    p.add_argument("--runs", help="store the runs in DIR, reusing those current there (as check --out)")
    p = sub.add_parser("judge", help="judge results files of any tool against their problems (docs/problems.md)")
    p.add_argument("results", nargs="+", help="results files (CSV, or HDF5 by their .h5 suffix)")
    p.add_argument("--problems", help="what rsmcheck export wrote (default: $RSMCHECK_PROBLEMS_DIR, out/benchmark)")
    p.add_argument("--refined", help="the same tool on the same problem at finer settings: its own error counts")
    p.add_argument("--json", action="store_true", help="one JSON object {\"judgements\": [...]} on stdout")
    p = sub.add_parser("budget", help="each [compare] row's error budget: the engines' difference plus each "
                                      "one's integration error (docs/cases.md §1)")
    p.add_argument("case", nargs="*", help="case names (default: every stand-alone case with a [compare] table; "
                                                  "a sequence named: the rows of its chained flight)")
    p.add_argument("--short", action="store_true", help="the compressed variant of each case (CI)")
    p.add_argument("--out", default=budget.DEFAULT_OUT,
                   help=f"the JSON document; its other cases are kept (default: {budget.DEFAULT_OUT})")
    engines_option(p, "the engines, the model under test first "
                                                     "(default: the default engines, `rsmcheck engines`)")
    p.add_argument("--runs", metavar="DIR", help="read the runs at the case's settings from DIR/CASE.h5 where "
                                                 "current, store the ones made there (as check --out and the "
                                                 "report do: out/full/runs is make fullcheck's)")
    p.add_argument("--suggest", action="store_true", help="print each row's suggested tolerance and why")
    p.add_argument("--factor", type=float, default=budget.SUGGEST_FACTOR, metavar="K",
                   help=f"suggested tolerance = K x budget, rounded up to {budget.SUGGEST_DIGITS} significant "
                        f"figures; 1 <= K <= {budget.BLIND_MARGIN:g} (default {budget.SUGGEST_FACTOR:g})")
    p.add_argument("--apply", action="store_true",
                   help="write each row's suggested tolerance and why into its case file (the two lines only)")
    p.add_argument("--serial", action="store_true",
                   help="run one after the other in this process (default: 2 processes)")
    p = sub.add_parser("modes", help="link and arm eigenfrequencies: analytic, reference, Exudyn")
    p.add_argument("--json", action="store_true", help="one JSON object {\"links\": [...], \"arms\": [...]}")
    engines_option(p, "the engines (default: the default engines)")
    p.add_argument("--option", action="append", metavar="ENGINE:KEY=VALUE",
                   help="an engine's constructor option, e.g. reference:n_modes=4 (repeatable)")
    p = sub.add_parser("report", help="run what is not stored yet, then write one self-contained HTML page")
    p.add_argument("--out", default="out/report.html",
                   help="HTML file; the runs and tables it is built from are stored in its folder")
    engines_option(p, "ENGINE, A,B or all (default: the default engines)")
    p.add_argument("--short", action="store_true", help="the compressed variant of each case")
    p.add_argument("--cases", nargs="+", metavar="CASE", help="only these cases (default: all)")
    p.add_argument("--rerun", action="store_true", help="run everything again, even what is stored and current")
    p.add_argument("--render-only", action="store_true",
                   help="only render what is stored (seconds); run nothing")
    p = sub.add_parser("gate", help="run the cases' short variants and compare each engine with its golden")
    p.add_argument("case", nargs="*", help="case names (default: every stand-alone case)")
    engines_option(p, "ENGINE, A,B or all (default: the default engines)")
    p.add_argument("--json", action="store_true", help="one JSON object {\"gate\": [...]} on stdout")
    p.add_argument("--tolerances", action="store_true",
                   help="print the goldens' gate tolerances and what they were measured from; run nothing")
    p.add_argument("--goldens", default=None, help=argparse.SUPPRESS)
    p = sub.add_parser("bless", help="re-run cases and rewrite their goldens (with --reason, into the changelog)")
    p.add_argument("case", nargs="+", help="case names, or 'all'")
    p.add_argument("--reason", help="why the results changed and why the new ones are right (required)")
    engines_option(p, "ENGINE, A,B or all (default: the default engines)")
    p.add_argument("--code-paths", metavar="P,Q|none", default=None,
                   help="the other CPUs' code paths to measure the gate tolerances on (default: every one this "
                        "CPU can run: x86-64-v4, x86-64-v3, x86-64-v2, blas-1-thread; docs/gate.md)")
    p.add_argument("--goldens", default=None, help=argparse.SUPPRESS)
    p = sub.add_parser("fuzz", help="randomized cross-check: N drawn scenarios, both engines at two resolutions")
    p.add_argument("--n", type=_whole(1), default=10, help="number of scenarios (default 10)")
    p.add_argument("--seed", type=_whole(0), default=0, help="the campaign's seed (default 0): scenario i of seed S "
                                                         "is the same on every machine")
    p.add_argument("--first", type=_whole(0), default=0, help="index of the first scenario (default 0)")
    p.add_argument("--out", default=fuzz.DEFAULT_OUT, help=f"folder of the scenarios, the failing case files and "
                                                            f"fuzz.json (default: {fuzz.DEFAULT_OUT})")
    engines_option(p, "the two engines, the model under test first "
                                                     "(default: the default engines)")
    p.add_argument("--json", action="store_true", help="the document on stdout: {\"scenarios\": [...], ...}")
    p.add_argument("--serial", action="store_true", help="run one after the other in this process")
    sub.add_parser("bench", help="speed of each engine on the same work [--json] [--full]", add_help=False)
    sub.add_parser("engines", help="the registered engine plug-ins, what they offer, whether they are installed")
    p = sub.add_parser("compile", help="compile the engines' kernels into the cache, before runs that need them")
    engines_option(p, "ENGINE, A,B or all (default: all)")
    p.add_argument("--workers", type=int, default=2, help="processes compiling side by side (default: 2)")
    p.add_argument("--again", action="store_true", help="run the groups also of the engines compiled already")
    for p_name, text in _plugin_commands().items():
        p = sub.add_parser(p_name, help=text, add_help=False)
        p.add_argument("rest", nargs=argparse.REMAINDER)
    return parser


def _plugin_commands() -> dict[str, str]:
    """The sub-commands the plug-ins bring: name → help."""
    return {c: text for p in plugins().values() for c, text in getattr(p, "commands", {}).items()}


#: subcommands with their own argument parsing (argparse cannot pass "--json" through)
DELEGATED = {"bench"}


#: commands that only list something (also `gate --tolerances`): cut short by a reader that
#: went away (`| head`), they exit 0; every other command exits 1 then (its work was not all
#: done or not all shown, so "all good" cannot be claimed)
LISTINGS = {"cases", "modes"}

#: commands whose runs go through rsmcheck.orchestration.runs.run_jobs (--scheduler)
JOB_COMMANDS = {"check", "budget", "gate", "bless", "report", "fuzz", "compile"}


#: the global options that take a value, taken out of the arguments before the command is
#: parsed (`_take_globals`): option → the Namespace field it fills
GLOBAL_VALUES = {"--cases-dir": "cases_dir", "--scheduler": "scheduler"}


def _take_globals(argv: list[str], anywhere: bool) -> tuple[dict[str, list[str]], list[str]]:
    """({field: values} of the GLOBAL_VALUES options, the other arguments): from the leading
    options only, or from `anywhere` (the delegated commands, whose own parsers do not know
    them: `rsmcheck bench --scheduler ADDRESS`)."""
    found: dict[str, list[str]] = {f: [] for f in GLOBAL_VALUES.values()}
    rest: list[str] = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if not anywhere and not a.startswith("-"):
            rest += argv[i:]
            break
        if a in GLOBAL_VALUES:
            if i + 1 == len(argv):
                sys.stderr.write(f"rsmcheck: argument {a}: expected one argument\n")
                raise SystemExit(2)
            found[GLOBAL_VALUES[a]].append(argv[i + 1])
            i += 2
            continue
        name, eq, value = a.partition("=")
        if eq and name in GLOBAL_VALUES:
            found[GLOBAL_VALUES[name]].append(value)
        elif a == "--" and anywhere:
            rest += argv[i:]
            break
        else:
            rest.append(a)
        i += 1
    return found, rest


def _use_cases_dirs(dirs: Sequence[str]) -> None:
    """Check each --cases-dir folder and add it to $RSMCHECK_CASES_DIR, which
    rsmcheck.core.cases reads (and the worker processes inherit)."""
    for d in dirs:
        if not Path(d).is_dir():
            raise InputError("--cases-dir", d, "no such folder")
    given = [e for e in os.environ.get(CASES_ENV, "").split(os.pathsep) if e]
    os.environ[CASES_ENV] = os.pathsep.join(given + [str(Path(d).resolve()) for d in dirs])
    cases_dirs()  # a missing folder in the variable: one line before anything runs


def _use_scheduler(args: argparse.Namespace) -> None:
    """--scheduler (else $RSMCHECK_SCHEDULER): for a command that will run jobs on it, the
    scheduler must answer and its workers run this code, before anything runs (else one
    line, exit 2: rsmcheck.orchestration.executor.connect)."""
    executor.use_scheduler(args.scheduler)
    address = executor.scheduler_address()
    runs_nothing = any(getattr(args, flag, False) for flag in ("serial", "render_only", "tolerances"))
    if address and args.command in JOB_COMMANDS and not runs_nothing:
        executor.connect(address, source_digest)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    lead, argv = _take_globals(argv, anywhere=False)
    dirs = lead["cases_dir"]
    try:
        plugin_commands = _plugin_commands() if argv else {}
    except InputError as exc:  # two distributions register one engine name: one line, exit 2
        sys.stderr.write(f"rsmcheck: {exc}\n")
        return 2
    if argv and argv[0] != "engines":  # `engines` lists them itself
        for b in broken_plugins().values():  # left out, so only a command that names one stops
            sys.stderr.write(f"rsmcheck: ignoring {b}\n")
    if argv and argv[0] in (DELEGATED | set(plugin_commands)):
        more, rest = _take_globals(argv[1:], anywhere=True)
        schedulers = lead["scheduler"] + more["scheduler"]
        args = argparse.Namespace(command=argv[0], rest=rest, cases_dir=dirs + more["cases_dir"],
                                  scheduler=schedulers[-1] if schedulers else None)
    else:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit:  # --help (0) or a usage error (2): the help may meet a closed pipe
            flush_stdout()
            raise
        args.cases_dir = dirs + args.cases_dir + getattr(args, "cases_dir_after", [])
        args.scheduler = (getattr(args, "scheduler_after", None) or args.scheduler
                          or (lead["scheduler"][-1] if lead["scheduler"] else None))
    saved = os.environ.get(CASES_ENV)
    run = COMMANDS.get(args.command, _plugin_command)

    def command() -> int:
        _use_cases_dirs(args.cases_dir)
        _use_scheduler(args)
        return run(args)

    try:
        return exit_code("rsmcheck", command,
                         cut_short=0 if args.command in LISTINGS or getattr(args, "tolerances", False) else 1)
    finally:  # main() called in-process (tests) leaves the environment as it was
        executor.use_scheduler(None)
        if saved is None:
            os.environ.pop(CASES_ENV, None)
        else:
            os.environ[CASES_ENV] = saved

if __name__ == "__main__":
    raise SystemExit(main())
