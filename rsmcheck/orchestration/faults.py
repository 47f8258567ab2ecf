"""Fault injection: which checks of the suite catch which plausible modelling bugs, case by case.

`make faults` (not in CI; ≈ 50 min on 2 idle cores) = ``python -m rsmcheck.orchestration.faults``.  Each
fault of the `catalogue` (each engine plug-in's own `faults()`, the shared ones, the
controls) is one textual change (an exact string that must occur once) applied to a
temporary copy of the tree.  In that copy every case of the matrix (`matrix_cases`: every
stand-alone case, i.e. every case file but the sequences, and each sequence — the mission,
its short phases flown chained as `rsmcheck report` flies them) is run in its short
variant by the engines the fault can affect, and four kinds of check look at the runs:

* **cross-check** (per case): the case's `[compare]` rows, the first default engine against
  the others (`compare.case_rows`, as `rsmcheck check`); for the mission, each phase of the
  chained flight by its own rows plus what the engines carry into it
  (`collect.mission_checks`, as the report).  When only one engine is faulted, the other
  engine's run is its unfaulted *baseline* run: both engines run the cases once on the
  unfaulted copy before the faults (every sample, so that a metric such as `growth` sees
  the same grid; the baseline must pass its own cross-check and gate, else no catch
  would mean anything and the driver stops);
* **gate** (per case): each re-run engine against its golden (docs/gate.md).  A sequence
  is gated phase by phase: the mission's cell holds its phases' stand-alone short runs
  against their goldens (the runs of those phases' own columns);
* **rigid** (per fault): each checking plug-in's `rigid_checks` (Pinocchio: rigid
  kinematics and dynamics, 20 seeded states per chain, rigid and with modes), for faults
  that reach the engine it checks;
* **analytic** (per fault): the tests of each reached engine against analytic references
  (its plug-in's `analytic_tests`; the reference's: conservation of energy and momentum,
  the Baumgarte decay of eq. (12), Table 2's frequencies), run by pytest in the copy.

A run that fails (diverges, raises) is a catch: of the gate, and of the cross-check where
the case has rows.  The matrix — fault × case × check — goes to docs/data/faults.json:
per fault, per case, the failing rows of each per-case check (`CASE_CHECKS`), the failing
rigid rows and analytic tests, and `caught_by`, the checks that caught it anywhere.  The
report draws it (report/build.py, `fault_matrix`).  The control fault ("noop_commuted_sum")
changes code without changing arithmetic and must be caught by nothing: it shows that the
gate is not a change detector for text.

``--cases A B …`` restricts the columns (development; a restricted run or one of named
faults writes next to the copy unless ``--out`` says where, never over the stored matrix).

Every fault starts from an empty numba cache (compiled once in the probe's process, then
loaded by its workers).  numba keys a cached function on its own file's stamp, not on the
files it calls into: with the copy's cache kept, the compiled integrator
(reference_model/stepping.py) went on calling the unfaulted kernels it had been compiled
against, and a fault of `rhs` — the propellant's mass flow T/(Isp g0) with the wrong g0 — left
thrust_burn's system mass exactly unchanged (918.668075676539 kg both; 918.668168535508
with a fresh cache).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from rsmcheck.core import cases as case_files
from rsmcheck.core.cases import CASES_ENV, Case, list_cases, load_case, sibling_case
from rsmcheck.core.plugins import Fault, default_engines, make_engine, plugin, plugins, simulators, with_capability
from rsmcheck.orchestration.collect import mission_checks
from rsmcheck.orchestration.compare import case_rows
from rsmcheck.orchestration.executor import SCHEDULER_ENV
from rsmcheck.orchestration.gate import compare_with_golden, gated_cases, golden_path, read_golden
from rsmcheck.orchestration.runs import RunSet, get_runs
from rsmcheck.driver.runner import run
from rsmcheck.core.store import EngineRun, git_commit, read_run, write_json, write_run

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "data" / "faults.json"
RIGID_STATES = 20
#: the checks of the catch matrix, in its order
CHECKS = ("crosscheck", "rigid", "gate", "analytic")
#: the checks that look at one case's runs (the others, once per fault)
CASE_CHECKS = ("crosscheck", "gate")
#: where the driver's copy keeps the unfaulted runs of the cases (relative to the copy's root)
BASELINE_DIR = ".faults_baseline"
#: moved observables a gate row names (the largest changes first), the rest counted
GATE_NAMED = 4


@dataclass(frozen=True)
class Injected:
    """A fault of the matrix and where it lives: `layer` is the plug-in whose code it is in,
    "shared" (read by every engine: parameters, controllers, case files) or "none" (the
    control, a change that changes no arithmetic)."""

    fault: Fault
    layer: str


#: faults in what every engine reads; the engines' own come from their plug-ins (`faults()`)
SHARED_FAULTS: tuple[Fault, ...] = (
    Fault("params_link_mass", "rsmcheck/core/params.py",
          'mass: float = _p(36.49, "Table 1.")', 'mass: float = _p(36.59, "Table 1.")',
          "parameter set: link mass 36.59 kg instead of 36.49 kg (Table 1 typo)"),
    Fault("controller_rate_filter", "rsmcheck/driver/control_kernels.py",
          "alpha = 1.0 - math.exp(-2.0 * math.pi * fc * dt) if fc > 0 else 1.0",
          "alpha = 1.0 - math.exp(-math.pi * fc * dt) if fc > 0 else 1.0",
          "controller: the rate filter's corner at f_c/2 (ω = π f_c instead of 2π f_c)"),
    Fault("case_flex_arm_step_torque", "cases/flex_arm_step.toml",
          "motor_torques = [0.0, 0.0, 0.0, 10.0, 0.0, 0.0]",
          "motor_torques = [0.0, 0.0, 0.0, 10.5, 0.0, 0.0]",
          "case file: flex_arm_step's shoulder torque 10.5 N·m instead of 10"),
)


def catalogue() -> list[Injected]:
    """Every fault: each engine plug-in's own, the shared ones, and the controls (a plug-in's
    fault whose name starts with "noop_": code changed, arithmetic not; caught by nothing)."""
    own = [(f, name) for name in simulators() for f in plugin(name).faults()]
    out = [Injected(f, name) for f, name in own if not f.name.startswith("noop_")]
    out += [Injected(f, "shared") for f in SHARED_FAULTS]
    return out + [Injected(f, "none") for f, _ in own if f.name.startswith("noop_")]


def matrix_cases() -> list[str]:
    """The matrix's columns: the project's cases (its case folder; a user's own have no
    goldens), every stand-alone one (those the gate has goldens for, `gate.gated_cases`),
    then every sequence (the mission, flown chained)."""
    own = [load_case(p) for p in list_cases() if p.parent.resolve() == case_files.CASES_DIR.resolve()]
    stand_alone = {c.name for c in gated_cases()}
    return [c.name for c in own if c.name in stand_alone] + [c.name for c in own if c.phases]


def select_cases(names: Sequence[str] | None) -> list[str]:
    """The columns `names` asks for, in the matrix's order (all without names); an unknown
    name stops the driver before anything runs."""
    known = matrix_cases()
    unknown = [n for n in names or () if n not in known]
    if unknown:
        raise SystemExit(f"rsmcheck.orchestration.faults: unknown case(s) {', '.join(unknown)} "
                         f"(the matrix's: {', '.join(known)})")
    return [n for n in known if not names or n in names]


# ---------------------------------------------------------------------------------------
# the driver: one copy of the tree, faults applied and reverted one after the other
# ---------------------------------------------------------------------------------------
def _tree_files(root: Path) -> list[str]:
    out = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True, check=True)
    return [f for f in out.stdout.splitlines() if (root / f).is_file()]


def make_copy(root: Path, dest: Path) -> Path:
    """A copy of every tracked file, the tree every probe runs in (each with an empty numba
    cache, `_in_copy`)."""
    if dest.exists():
        shutil.rmtree(dest)
    for f in _tree_files(root):
        (dest / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / f, dest / f)
    return dest


def apply(fault: Fault, tree: Path) -> None:
    path = tree / fault.path
    text = path.read_text()
    n = text.count(fault.old)
    if n != 1:
        raise RuntimeError(f"fault {fault.name}: the text to change occurs {n} times in {fault.path} "
                           f"(must be once): {fault.old!r}")
    path.write_text(text.replace(fault.old, fault.new))


def revert(fault: Fault, root: Path, tree: Path) -> None:
    shutil.copy2(root / fault.path, tree / fault.path)


def _in_copy(tree: Path, *args: str) -> subprocess.CompletedProcess:
    """`python -m rsmcheck.orchestration.faults ARGS` inside the copy (its own imports), with
    an empty numba cache (module doc: the cache does not see a change in a called file)."""
    cache = tree / ".numba_cache"
    shutil.rmtree(cache, ignore_errors=True)
    # the copy's jobs run its own (faulted) code on this machine, never on a cluster's
    # workers; its case files are its own (`matrix_cases`; a folder of $RSMCHECK_CASES_DIR
    # that is the tree's cases/ would hold every name twice)
    env = {k: v for k, v in os.environ.items() if k not in (SCHEDULER_ENV, CASES_ENV)}
    env.update(PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-m", "rsmcheck.orchestration.faults", *args],
                          cwd=tree, env=env, capture_output=True, text=True)


def _last_json(proc: subprocess.CompletedProcess) -> dict:
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run_baseline(tree: Path, cases: Sequence[str]) -> dict:
    """The unfaulted runs of `cases` in both engines, stored in the copy (module doc); stops
    when they fail their own cross-check or gate.  Returns the baseline's wall times."""
    proc = _in_copy(tree, "baseline", "--cases", *cases)
    if proc.returncode != 0:
        raise RuntimeError(f"the baseline runs failed:\n{proc.stderr[-3000:]}")
    result = _last_json(proc)
    failed = [f"{case} {check}: {row}" for case, cell in result["cases"].items()
              for check in CASE_CHECKS for row in cell[check]]
    if failed:
        raise RuntimeError("the unfaulted baseline fails its own cross-check or gate, so no fault's catch would "
                           "mean anything: " + "; ".join(failed))
    return result


def caught_by(result: Mapping[str, Any]) -> list[str]:
    """The checks that caught a fault anywhere: a per-case check on some case, or a
    per-fault check (rigid, analytic)."""
    return [k for k in CHECKS
            if (any(cell[k] for cell in result["cases"].values()) if k in CASE_CHECKS else result[k])]


def cell_letters(cell: Mapping[str, Sequence[str]]) -> str:
    """The checks that caught a fault on one case, as the report's cell shows them ("CG")."""
    return "".join(k[0].upper() for k in CASE_CHECKS if cell.get(k))


def run_fault(item: Injected, tree: Path, cases: Sequence[str], progress=print) -> dict:
    fault = item.fault
    apply(fault, tree)
    t0 = time.monotonic()
    try:
        proc = _in_copy(tree, "probe", fault.name, "--cases", *cases)
    finally:
        revert(fault, ROOT, tree)
    if proc.returncode != 0:
        raise RuntimeError(f"fault {fault.name}: the probe failed:\n{proc.stderr[-3000:]}")
    result = _last_json(proc)
    result.update(asdict(fault), layer=item.layer, wall_s=round(time.monotonic() - t0, 1))
    result["caught_by"] = caught_by(result)
    cells = {case: cell_letters(cell) for case, cell in result["cases"].items()}
    on = ", ".join(f"{case} {letters}" for case, letters in cells.items() if letters)
    progress(f"{fault.name}: caught by {', '.join(result['caught_by']) or 'NOTHING'}"
             f"{f'; on {on}' if on else ''} ({result['wall_s']:.0f} s)")
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rsmcheck.orchestration.faults",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("command", nargs="?", default="all",
                    help="all (default); probe and baseline run inside the copy")
    ap.add_argument("names", nargs="*", help="only these faults (default: all)")
    ap.add_argument("--cases", nargs="+", metavar="CASE",
                    help="only these cases (default: every stand-alone case and the mission)")
    ap.add_argument("--out", help=f"where the matrix goes (default: {OUT.relative_to(ROOT)} for the whole "
                                  "matrix, faults.json beside the copy for a restricted one)")
    ap.add_argument("--tree", default="/tmp/rsmcheck-faults/tree", help="where the copy of the tree goes")
    args = ap.parse_args(argv)
    cases = select_cases(args.cases)
    if args.command == "probe":
        print(json.dumps(probe(_by_name(args.names[0]), cases)))
        return 0
    if args.command == "baseline":
        print(json.dumps(baseline(cases)))
        return 0
    faults = [_by_name(n) for n in args.names] if args.names else catalogue()
    restricted = bool(args.names or args.cases)
    out_path = Path(args.out) if args.out else (Path(args.tree).parent / "faults.json" if restricted else OUT)
    tree = make_copy(ROOT, Path(args.tree))
    print(f"fault injection: {len(faults)} faults on a copy in {tree}; cases {', '.join(cases)}", flush=True)
    t0 = time.monotonic()
    base = run_baseline(tree, cases)
    base_wall = time.monotonic() - t0
    print(f"baseline: both engines unfaulted, cross-check and gate pass ({base_wall:.0f} s)", flush=True)
    results = [run_fault(f, tree, cases, lambda s: print(s, flush=True)) for f in faults]
    doc = {"cases": cases, "checks": list(CHECKS), "case_checks": list(CASE_CHECKS), "rigid_states": RIGID_STATES,
           "crosscheck_pair": list(default_engines()),
           "commit": git_commit()[0], "wall_s": round(time.monotonic() - t0, 1),
           "baseline": {"wall_s": round(base_wall, 1), "runs_wall_s": base["runs_wall_s"]}, "faults": results}
    out = write_json(out_path, doc)
    missed = [r["name"] for r in results if r["layer"] != "none" and not r["caught_by"]]
    false = [r["name"] for r in results if r["layer"] == "none" and r["caught_by"]]
    print(f"wrote {out}: {len(results) - len(missed) - len(false)} of {len(results)} as expected"
          + (f"; missed: {', '.join(missed)}" if missed else "") + (f"; control caught: {', '.join(false)}" if false else ""))
    return 1 if missed or false else 0


def _by_name(name: str) -> Injected:
    for item in catalogue():
        if item.fault.name == name:
            return item
    raise SystemExit(f"rsmcheck.orchestration.faults: unknown fault {name!r} "
                     f"(known: {', '.join(i.fault.name for i in catalogue())})")


# ---------------------------------------------------------------------------------------
# the probe and the baseline: run inside the (faulted) copy, with its own imports
# ---------------------------------------------------------------------------------------
def _to_run(columns: Sequence[Case], gate_phases: bool) -> list[Case]:
    """The cases to run for `columns`: each column and, with `gate_phases`, each sequence's
    short phases (their stand-alone runs are its gate cell; a phase that starts the short
    flight is cut from the flight instead, `runs.get_runs`)."""
    out = {c.name: c for c in columns}
    for c in columns if gate_phases else ():
        for phase in c.variant(True).phases:
            out.setdefault(phase, load_case(sibling_case(phase, Path(c.path))))
    return list(out.values())


def _run_cases(columns: Sequence[Case], engines: Sequence[str], gate_phases: bool) -> RunSet:
    """The short runs of `columns` (and what their gate needs) by `engines` in this tree;
    a run that fails is left out, its error in `RunSet.errors`."""
    for name in engines:  # compile each engine once, in this process, before the workers
        c = load_case("p1_rigid_gains").variant(True)
        run(make_engine(name, c), c, 0.002)
    return get_runs(_to_run(columns, gate_phases), list(engines), True, None)


def _number(x: Any) -> str:
    return x if isinstance(x, str) else f"{x:.2e}"  # a stored row's error may be "inf"


def _failures(got: RunSet, case: str) -> list[str]:
    """'ENGINE: run failed: …' for each engine whose run of `case` failed."""
    return [f"{label.split(' / ', 1)[1]}: run failed: {text}" for label, text in got.failures.items()
            if label.split(" / ", 1)[0] == case]


def _crosscheck(case: Case, pair: Mapping[str, EngineRun]) -> list[str]:
    """The failing cross-check rows of one column: a stand-alone case's `[compare]` rows, a
    sequence's rows of each chained phase ('PHASE: …')."""
    if case.phases:
        return [f"{r['case'].split('/', 1)[1]}: {r['observable']} {_number(r['error'])} > {r['tolerance']:.1e}"
                for r in mission_checks(case, True, dict(pair)) if not r["pass"]]
    return [f"{r.observable} {r.error:.2e} > {r.tolerance:.1e}" for r in case_rows(case, True, pair) if not r.passed]


def _gate(name: str, engine: str, run_: EngineRun) -> list[str]:
    """'ENGINE: what moved' for a run of stand-alone case `name` that left its golden."""
    v = load_case(name).variant(True)
    g = compare_with_golden(v, run_, read_golden(golden_path(v.name, engine), engine))
    if g.unchanged:
        return []
    moved = sorted(g.moved, key=lambda m: -m.ratio)
    parts = (["inputs changed"] if g.inputs_changed else []) + g.structure[:1] \
        + [f"{m.observable} {m.ratio:.3g}×" for m in moved[:GATE_NAMED]] \
        + ([f"{len(moved) - GATE_NAMED} more observables"] if len(moved) > GATE_NAMED else []) \
        + [f"more {w.describe()}" for w in g.more_work]
    return [f"{engine}: " + ", ".join(parts)]


def _gate_rows(got: RunSet, case: Case, engines: Sequence[str]) -> list[str]:
    """The gate cell of one column: each engine's run against its golden; a sequence's, its
    phases' stand-alone runs ('PHASE/ENGINE: …')."""
    if case.phases:
        return [f"{phase}/{row}" for phase in case.variant(True).phases
                for row in _gate_rows(got, load_case(sibling_case(phase, Path(case.path))), engines)]
    runs = got.runs.get(case.name, {})
    return _failures(got, case.name) + [row for e in engines if e in runs for row in _gate(case.name, e, runs[e])]


def _cells(got: RunSet, columns: Sequence[Case], engines: Sequence[str],
           others: Mapping[str, Mapping[str, EngineRun]]) -> dict[str, dict[str, list[str]]]:
    """Per column, the failing rows of each per-case check.  `others`: per case, the runs of
    the engines not re-run here (the baseline), paired with the new ones."""
    out = {}
    for case in columns:
        runs = got.runs.get(case.name, {})
        compared = case.phases or case.variant(True).compare
        cross = _failures(got, case.name) if compared else []
        if len(runs) == len(engines):
            cross += _crosscheck(case, {**others.get(case.name, {}), **runs})
        out[case.name] = {"crosscheck": cross, "gate": _gate_rows(got, case, engines)}
    return out


def _walls(got: RunSet) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for (case, engine), wall in got.wall_s.items():
        out.setdefault(case, {})[engine] = round(wall, 1)
    return out


def baseline(cases: Sequence[str]) -> dict:
    """Run `cases` unfaulted in both engines, store the runs (BASELINE_DIR) and check them
    (cross-check, and the gate of the stand-alone ones)."""
    engines = list(default_engines())
    columns = [load_case(n) for n in cases]
    got = _run_cases(columns, engines, gate_phases=False)
    for case in columns:
        pair = got.runs.get(case.name, {})
        if len(pair) == len(engines):
            write_run(Path(BASELINE_DIR) / f"{case.name}.h5", pair, case_name=case.name, case_hash=case.file_hash,
                      param_hash=case.params.digest())
    cells = _cells(got, columns, engines, {})
    for case in columns:  # a sequence's gate is its phases': their own columns when asked for
        if case.phases:
            cells[case.name]["gate"] = []
    return {"cases": cells, "runs_wall_s": _walls(got)}


def probe(item: Injected, cases: Sequence[str]) -> dict:
    """Run the fault's engines on `cases` in this (faulted) tree and apply every check."""
    engines = [item.layer] if item.layer in plugins() else list(default_engines())
    columns = [load_case(n) for n in cases]
    got = _run_cases(columns, engines, gate_phases=True)
    others = {}
    if len(engines) < len(default_engines()):  # one engine faulted: the others' baseline runs
        others = {c.name: {e: r for e, r in read_run(Path(BASELINE_DIR) / f"{c.name}.h5")[0].items()
                           if e not in engines} for c in columns}
    out: dict[str, Any] = {"cases": _cells(got, columns, engines, others), "engines": engines,
                           "runs_wall_s": _walls(got)}
    reached = set(engines) if item.layer in plugins() else set(plugins())
    out["rigid"] = []
    for name in with_capability("rigid_checks"):  # a checker of an engine the fault reaches
        if plugin(name).checks_engine not in reached:
            continue
        for n_modes in (0, 2):
            rows = plugin(name).rigid_checks(n_states=RIGID_STATES, first_seed=0, n_modes=n_modes, open_arms=(1, 2))
            out["rigid"] += sorted({f"{name}: {r['quantity']} ({r['chain']}, {n_modes} modes)"
                                    for r in rows if not r["pass"]})
    tests = [t for e in sorted(reached & set(simulators())) for t in getattr(plugin(e), "analytic_tests", ())]
    out["analytic"] = _failed_tests(tuple(tests)) if tests else []
    return out


def _failed_tests(node_ids: tuple[str, ...]) -> list[str]:
    """The tests of `node_ids` that fail in this tree (pytest, this process's environment)."""
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rf", "-p", "no:cacheprovider", "-m", "not study",
                           *node_ids], capture_output=True, text=True)
    if proc.returncode not in (0, 1):  # 0 all passed, 1 some failed; anything else: not run
        raise RuntimeError(f"the analytic tests did not run (pytest exit {proc.returncode}):\n{proc.stdout[-2000:]}")
    return [line.split(" - ")[0].removeprefix("FAILED ").split("::")[-1]
            for line in proc.stdout.splitlines() if line.startswith("FAILED ")]


if __name__ == "__main__":
    raise SystemExit(main())
