"""The `rsmcheck` command line (SPEC §5).

Exit codes: 0 all good, 1 a check failed, 2 bad input or usage (one line on stderr, no
traceback).  A diverging simulation is reported in one line with time, phase and quantity
and exits 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable, Sequence

from rsmcheck.errors import InputError, SimulationDiverged

ENGINES = ("reference", "exudyn")


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with one line (its default prints usage too; keep it short)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"rsmcheck: {message}\n")
        raise SystemExit(2)


def _cmd_cases(args: argparse.Namespace) -> int:
    from cases.loader import list_cases, load_case

    for path in list_cases():
        case = load_case(path)
        short = f", --short {case.short_duration:g} s" if case.short_duration != case.duration else ""
        print(f"{case.name:20s} {case.duration:8g} s{short:16s}  {case.description}")
    return 0


def _engine_names(choice: str) -> list[str]:
    return list(ENGINES) if choice == "all" else [choice]


def make_engine(name: str, case, **options):
    """The engine object for `name` (imported lazily: Exudyn is heavy)."""
    if name == "reference":
        from reference_model.engine import ReferenceEngine

        return ReferenceEngine(case, **options)
    if name == "exudyn":
        try:
            from exudyn_model.engine import ExudynEngine
        except ImportError as exc:
            raise InputError("--engine", "exudyn", f"the Exudyn model is not available ({exc})") from None
        return ExudynEngine(case, **options)
    raise InputError("--engine", name, f"unknown engine (known: {', '.join(ENGINES)}, all)")


def _cmd_run(args: argparse.Namespace) -> int:
    from cases.loader import load_case
    from rsmcheck.runner import run, terminal_progress
    from rsmcheck.store import write_run

    cases = [load_case(name) for name in args.case]  # validate every case before running any
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for case in cases:
        runs = {}
        for name in _engine_names(args.engine):
            engine = make_engine(name, case)
            runs[name] = run(engine, case, case.run_duration(args.short), terminal_progress(name, case.name))
        path = out / f"{case.name}.h5"
        write_run(path, runs, case_name=case.name, case_hash=case.file_hash, param_hash=case.params.digest())
        print(f"{case.name}: wrote {path} ({', '.join(runs)})")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from report.build import build_report

    path = build_report(Path(args.out), _engine_names(args.engine), args.short, args.cases or None)
    print(f"wrote {path}")
    return 0


def _cmd_pinocchio(args: argparse.Namespace) -> int:
    from pinocchio_check.compare import main

    return main(args.rest)


def _cmd_bench(args: argparse.Namespace) -> int:
    from rsmcheck.bench import main

    return main(args.rest)


COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "bench": _cmd_bench,
    "cases": _cmd_cases,
    "run": _cmd_run,
    "pinocchio": _cmd_pinocchio,
    "report": _cmd_report,
}


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rsmcheck", description="Validation benchmark for the dual-arm flexible space robot")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sub.add_parser("cases", help="list the cases, one line each")
    p = sub.add_parser("run", help="simulate cases and write DIR/CASE.h5")
    p.add_argument("case", nargs="+", help="case name (cases/NAME.toml) or path to a case file")
    p.add_argument("--engine", default="reference", choices=[*ENGINES, "all"])
    p.add_argument("--out", default="results", help="output directory (default: results)")
    p.add_argument("--short", action="store_true", help="the compressed variant of each case (CI)")
    p = sub.add_parser("report", help="run the cases and write a self-contained HTML report")
    p.add_argument("--out", default="out/report.html", help="HTML file (run files go to its folder/runs)")
    p.add_argument("--engine", default="reference", choices=[*ENGINES, "all"])
    p.add_argument("--short", action="store_true", help="the compressed variant of each case")
    p.add_argument("--cases", nargs="+", metavar="CASE", help="only these cases (default: all)")
    sub.add_parser("bench", help="speed of each engine on the same work [--json] [--full]", add_help=False)
    p = sub.add_parser("pinocchio", help="rigid checks of the reference against Pinocchio", add_help=False)
    p.add_argument("rest", nargs=argparse.REMAINDER)
    return parser


#: subcommands with their own argument parsing (argparse cannot pass "--json" through)
DELEGATED = {"pinocchio", "bench"}


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in DELEGATED:
        args = argparse.Namespace(command=argv[0], rest=argv[1:])
    else:
        args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        sys.stderr.write(f"rsmcheck: {exc}\n")
        return 2
    except SimulationDiverged as exc:
        sys.stderr.write(f"rsmcheck: {exc}\n")
        return 1
    except KeyboardInterrupt:
        sys.stderr.write("rsmcheck: interrupted\n")
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
