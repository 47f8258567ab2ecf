"""`rsmcheck bench`: speed of each engine on the same work (SPEC §5).

Each (case, engine) run happens in a fresh Python process so that its peak resident memory
is its own; wall time excludes the process start and numba's compile (a warm-up run of
0.01 s of the same case comes first).  `rhs_us` times one right-hand side of the reference
(closed chain, two modes per link) and one Pinocchio ABA call on the 10-coordinate
open-chain rigid model, from Python: the scale of a compiled rigid-body step.

Ratios are only meaningful within one run of this command (shared, noisy machines).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import timeit
from typing import Sequence

_CHILD = r"""
import json, resource, sys, time
from cases.loader import load_case
from rsmcheck.cli import make_engine
from rsmcheck.runner import run
name, engine_name, short = sys.argv[1], sys.argv[2], sys.argv[3] == "1"
case = load_case(name)
run(make_engine(engine_name, case), case, min(0.01, case.run_duration(short)))  # warm-up
engine = make_engine(engine_name, case)
t0 = time.perf_counter()
result = run(engine, case, case.run_duration(short))
wall = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"case": name, "engine": engine_name, "wall_s": wall,
                  "sim_s": float(result.observables["time"][-1]), "peak_mb": peak}))
"""


def rhs_timings() -> dict[str, float]:
    """µs per call: reference RHS (closed chain, 2 modes/link), Pinocchio ABA (10 dof)."""
    import numpy as np

    from cases.loader import load_case
    from reference_model.engine import ReferenceEngine

    engine = ReferenceEngine(load_case("closed_squeeze"))
    args = engine.model.core_args(engine.cfg)
    from reference_model import core

    u = np.zeros(core.N_INPUTS)
    core.rhs(engine.x, u, *args)
    n = 2000
    ref = timeit.timeit(lambda: core.rhs(engine.x, u, *args), number=n) / n * 1e6
    out = {"reference": ref}
    try:
        import pinocchio as pin

        from pinocchio_check.model import build_model
        from rsmcheck.params import Params

        pm = build_model(Params(), target="arm1")
        model = pm.model
        data = model.createData()
        q = pin.neutral(model)
        v = np.zeros(model.nv)
        tau = np.zeros(model.nv)
        pin.aba(model, data, q, v, tau)
        out["pinocchio_aba"] = timeit.timeit(lambda: pin.aba(model, data, q, v, tau), number=n) / n * 1e6
    except Exception as exc:  # the report says why instead of a number
        out["pinocchio_aba"] = float("nan")
        out["pinocchio_error"] = str(exc)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    from cases.loader import list_cases

    parser = argparse.ArgumentParser(prog="rsmcheck bench")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--full", action="store_true", help="full-length cases (default: --short variants)")
    parser.add_argument("--engine", default="reference", choices=["reference", "exudyn", "all"])
    parser.add_argument("--cases", nargs="+", help="only these cases")
    args = parser.parse_args(argv)
    engines = ["reference", "exudyn"] if args.engine == "all" else [args.engine]
    names = args.cases or [p.stem for p in list_cases()]
    runs = []
    for name in names:
        for engine in engines:
            proc = subprocess.run([sys.executable, "-c", _CHILD, name, engine, "0" if args.full else "1"],
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                last = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"exit {proc.returncode}"
                runs.append({"case": name, "engine": engine, "wall_s": float("nan"), "sim_s": 0.0,
                             "peak_mb": float("nan"), "error": last})
            else:
                runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
            if not args.json:
                r = runs[-1]
                print(f"{r['case']:20s} {r['engine']:10s} sim {r['sim_s']:8.2f} s  wall {r['wall_s']:8.2f} s  "
                      f"({r['wall_s'] / max(r['sim_s'], 1e-9):6.3f} wall/sim)  peak {r['peak_mb']:7.1f} MB"
                      + (f"  ERROR {r['error']}" if "error" in r else ""), flush=True)
    rhs = rhs_timings()
    if args.json:
        print(json.dumps({"runs": runs, "rhs_us": rhs}))
    else:
        print(f"rhs: reference {rhs['reference']:.1f} µs/call, pinocchio aba {rhs['pinocchio_aba']:.1f} µs/call")
    return 1 if any("error" in r for r in runs) else 0
