"""Fault injection: which checks of the suite catch which plausible modelling bugs.

`make faults` (not in CI; ≈ 20 min on 2 cores) = ``python -m rsmcheck.orchestration.faults``.  Each
fault of the `catalogue` (each engine plug-in's own `faults()`, the shared ones, the
controls) is one textual change (an exact string that must occur once) applied to a
temporary copy of the tree; in that copy the short variants of `CASES` are run by the
engines the fault can affect, and four kinds of check look at them:

* **cross-check**: the case's `[compare]` rows, the first default engine against the
  others (rsmcheck.core.plugins.default_engines).  When only one
  engine is faulted, the other engine's run is its unfaulted *baseline* run: both engines
  run the cases once on the unfaulted copy before the faults (every sample, so that a
  metric such as `growth` sees the same grid; the baseline's own cross-check must pass,
  else every catch would be meaningless and the driver stops);
* **rigid**: each checking plug-in's `rigid_checks` (Pinocchio: rigid kinematics and
  dynamics, 20 seeded states per chain, rigid and with modes), for faults that reach the
  engine it checks;
* **gate**: each re-run engine against its golden (docs/gate.md);
* **analytic**: the tests of each reached engine against analytic references (its
  plug-in's `analytic_tests`; the reference's: conservation of energy and momentum, the
  Baumgarte decay of eq. (12), Table 2's frequencies), run by pytest in the copy.

The catch matrix goes to docs/data/faults.json and into the report.  The control fault
("noop_commuted_sum") changes code without changing arithmetic and must be caught by
nothing: it shows that the gate is not a change detector for text.

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

from rsmcheck.core.cases import Case, load_case
from rsmcheck.core.plugins import Fault, default_engines, make_engine, plugin, plugins, simulators, with_capability
from rsmcheck.orchestration.compare import check_runs
from rsmcheck.orchestration.executor import SCHEDULER_ENV
from rsmcheck.orchestration.gate import compare_with_golden, golden_path, read_golden
from rsmcheck.orchestration.runs import Job, expected_wall, run_engine, run_jobs
from rsmcheck.driver.runner import run
from rsmcheck.core.store import EngineRun, git_commit, read_run, write_json, write_run

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "data" / "faults.json"
#: the cases every fault is tried on: fast short variants that together exercise every
#: mechanism (open/closed chain, capture-free release, bistop, orbit, thrust, growth)
CASES = ("p1_rigid_gains", "flex_arm_step", "release", "gravity_gradient", "wrist_bistop", "thrust_burn")
RIGID_STATES = 20
#: the checks of the catch matrix, in its order
CHECKS = ("crosscheck", "rigid", "gate", "analytic")
#: where the driver's copy keeps the unfaulted runs of CASES (relative to the copy's root)
BASELINE_DIR = ".faults_baseline"


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
    # the copy's jobs run its own (faulted) code on this machine, never on a cluster's workers
    env = {k: v for k, v in os.environ.items() if k != SCHEDULER_ENV}
    env.update(PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-m", "rsmcheck.orchestration.faults", *args],
                          cwd=tree, env=env, capture_output=True, text=True)


def run_baseline(tree: Path) -> None:
    """The unfaulted runs of CASES in both engines, stored in the copy (module doc)."""
    proc = _in_copy(tree, "baseline")
    if proc.returncode != 0:
        raise RuntimeError(f"the baseline runs failed:\n{proc.stderr[-3000:]}")
    failed = json.loads(proc.stdout.strip().splitlines()[-1])["crosscheck"]
    if failed:
        raise RuntimeError("the unfaulted baseline fails its own cross-check, so no fault's catch would "
                           "mean anything: " + "; ".join(failed))


def run_fault(item: Injected, tree: Path, progress=print) -> dict:
    fault = item.fault
    apply(fault, tree)
    t0 = time.monotonic()
    try:
        proc = _in_copy(tree, "probe", fault.name)
    finally:
        revert(fault, ROOT, tree)
    if proc.returncode != 0:
        raise RuntimeError(f"fault {fault.name}: the probe failed:\n{proc.stderr[-3000:]}")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    result.update(asdict(fault), layer=item.layer, wall_s=round(time.monotonic() - t0, 1))
    result["caught_by"] = [k for k in CHECKS if result[k]]
    progress(f"{fault.name}: caught by {', '.join(result['caught_by']) or 'NOTHING'} "
             f"({result['wall_s']:.0f} s)")
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rsmcheck.orchestration.faults",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("command", nargs="?", default="all",
                    help="all (default); probe and baseline run inside the copy")
    ap.add_argument("names", nargs="*", help="only these faults (default: all)")
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--tree", default="/tmp/rsmcheck-faults/tree", help="where the copy of the tree goes")
    args = ap.parse_args(argv)
    if args.command == "probe":
        print(json.dumps(probe(_by_name(args.names[0]))))
        return 0
    if args.command == "baseline":
        print(json.dumps(baseline()))
        return 0
    faults = [_by_name(n) for n in args.names] if args.names else catalogue()
    tree = make_copy(ROOT, Path(args.tree))
    print(f"fault injection: {len(faults)} faults on a copy in {tree}; cases {', '.join(CASES)}", flush=True)
    t0 = time.monotonic()
    run_baseline(tree)
    print(f"baseline: both engines unfaulted, cross-check passes ({time.monotonic() - t0:.0f} s)", flush=True)
    results = [run_fault(f, tree, lambda s: print(s, flush=True)) for f in faults]
    doc = {"cases": list(CASES), "rigid_states": RIGID_STATES, "commit": git_commit()[0],
           "faults": results}
    out = write_json(Path(args.out), doc)
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
# the probe: runs inside the faulted copy (its own imports)
# ---------------------------------------------------------------------------------------
def _run_cases(engines: list[str]) -> tuple[list[Case], dict[tuple[str, str], EngineRun]]:
    """The short variants of CASES run by `engines` in this tree: (variants, (case, engine) → run)."""
    for name in engines:  # compile each engine once, in this process, before the workers
        c = load_case("p1_rigid_gains").variant(True)
        run(make_engine(name, c), c, 0.002)
    variants = [load_case(n).variant(True) for n in CASES]
    jobs = [Job(f"{v.name} / {e}", run_engine, (e, v), expected_wall(v, e), (v.name, e))
            for v in variants for e in engines]
    done = run_jobs(jobs)  # the one pool; a failed job raises once all have ended
    for job in jobs:
        if done[job].error is not None:
            raise done[job].error
    return variants, {job.key: done[job].value for job in jobs}


def _crosscheck(v: Case, pair: dict[str, EngineRun]) -> list[str]:
    first, *others = [e for e in default_engines() if e in pair]
    failed = [c for o in others for c in check_runs(v, pair[first], pair[o]) if not c.passed]
    return [f"{v.name}: {c.observable} {c.error:.2e} > {c.tolerance:.1e}" for c in failed]


def baseline() -> dict:
    """Run CASES unfaulted in both engines, store the runs (BASELINE_DIR) and cross-check them."""
    variants, runs = _run_cases(list(default_engines()))
    out: dict[str, list[str]] = {"crosscheck": []}
    for v in variants:
        pair = {e: runs[(v.name, e)] for e in default_engines()}
        write_run(Path(BASELINE_DIR) / f"{v.name}.h5", pair, case_name=v.name, case_hash=v.file_hash,
                  param_hash=v.params.digest())
        out["crosscheck"] += _crosscheck(v, pair)
    return out


def probe(item: Injected) -> dict:
    """Run the fault's engines on CASES in this (faulted) tree and apply every check."""
    engines = [item.layer] if item.layer in plugins() else list(default_engines())
    variants, runs = _run_cases(engines)
    out: dict[str, list[str]] = {k: [] for k in CHECKS}
    for v in variants:
        new = {e: runs[(v.name, e)] for e in engines}
        for e, r in new.items():
            g = compare_with_golden(v, r, read_golden(golden_path(v.name, e), e))
            if not g.unchanged:
                parts = (["inputs changed"] if g.inputs_changed else []) + g.structure[:1] + [m.observable for m in g.moved] \
                    + [f"more {w.describe()}" for w in g.more_work]
                out["gate"].append(f"{v.name}/{e}: " + ", ".join(parts))
        # one engine faulted: the other engine's unfaulted baseline run of the same case
        pair = new if len(new) == 2 else {**read_run(Path(BASELINE_DIR) / f"{v.name}.h5")[0], **new}
        out["crosscheck"] += _crosscheck(v, pair)
    reached = set(engines) if item.layer in plugins() else set(plugins())
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
