"""A bench document against a stored one (`rsmcheck bench --baseline FILE`): the same
work, and the time it took.

Wall times belong to the machine; the work does not.  Each run of a bench document records
the counts behind its time (`bench.SOLVER_KEYS`): the reference's accepted and rejected
steps (each a Dormand–Prince step of six right-hand sides, or an IMEX step of eight in the
quiet segments, `quiet_steps`), Exudyn's Newton iterations, Jacobians and retries at its
fixed step.  The same code on two machines of the project's 2-core kind moved every wall time
by tens of per cent and these counts by a fraction of a per cent at most (the reference's
step-size control sees the last bits of the arithmetic; docs/records.md, "The work,
comparable across machines").  So:

* a run's *work* is one number per engine (`work`): the reference's step attempts
  (accepted + rejected), Exudyn's Newton iterations;
* a count that moved by more than `WORK_TOLERANCE` (1 %, three times the largest spread of
  identical code across machines) is a change of the work: a model, a setting or an
  integrator that costs more or less, on any machine;
* wall times are compared only when both runs ran on the same kind of machine
  (`rsmcheck.core.store.same_machine`; a run's own `machine`, or its document's for a
  document older than the record per run); otherwise the ratio is left out, not printed
  with a warning.  Even then two documents are two runs, minutes or days apart, and wall
  times scatter between sessions (docs/benchmarks.md).

The comparison reports; it does not gate (exit codes stay `rsmcheck bench`'s own): more work
is often the point of a change, and the figure to look at is the ratio it prints.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Mapping

from rsmcheck.core.errors import InputError
from rsmcheck.core.store import machine_text, same_machine

#: relative change of a count above which the work changed (module doc: 3 × the 0.31 % that
#: identical code moved between two machines)
WORK_TOLERANCE = 0.01
#: the counts a run's cost follows; the other solver keys are its settings
COUNT_KEYS = ("steps", "rejected_steps", "quiet_steps", "newton_iterations", "newton_retries", "jacobians")
#: the counts that are parts of a run's work (its steps), measured against the whole of it
STEP_KEYS = ("steps", "rejected_steps", "quiet_steps")
SETTING_KEYS = ("h_max", "rtol", "step", "substeps", "links", "jacobian_per_step", "newton_atol")


def read_bench(path: str | os.PathLike[str], field: str = "--baseline") -> dict[str, Any]:
    """A stored `rsmcheck bench` document; InputError naming the file and `field` (the
    option that named it) when it is missing, not JSON or has no runs to compare."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(str(path), field, "no such file (a document written by rsmcheck bench --out)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(str(path), field, f"not a JSON document ({exc})") from None
    runs = doc.get("runs") if isinstance(doc, dict) else None
    if not isinstance(runs, list):
        raise InputError(str(path), f"{field}: runs", "missing: not a document of rsmcheck bench")
    for i, r in enumerate(runs):
        if not isinstance(r, dict) or not all(isinstance(r.get(k), str) for k in ("case", "engine", "variant")):
            raise InputError(str(path), f"{field}: runs[{i}]",
                             "needs the strings case, engine and variant (not a document of rsmcheck bench)")
    return doc


def work(run: Mapping[str, Any]) -> tuple[str, float | None]:
    """(name, count) of a run's work: Newton iterations where the engine counts them
    (Exudyn), else step attempts, accepted + rejected (the reference); None when the run
    recorded neither (a failed run)."""
    solver = run.get("solver") or {}
    if "newton_iterations" in solver:
        return "Newton iterations", solver["newton_iterations"]
    if "steps" in solver:
        return "step attempts", solver["steps"] + solver.get("rejected_steps", 0)
    return "work", None


def _ratio(new: float | None, old: float | None) -> float | None:
    if new is None or old is None or not (math.isfinite(new) and math.isfinite(old)) or old == 0:
        return None
    return new / old


def _changed_counts(new: Mapping[str, Any], old: Mapping[str, Any], base_work: float | None) -> list[str]:
    """Each count of `COUNT_KEYS` that moved by more than `WORK_TOLERANCE` ("jacobians 151 →
    160"); a count that appears or goes away counts as moved.  The step counts (`STEP_KEYS`)
    are parts of the work and move by their share of it: the rejected steps, ~1 % of the
    attempts, moved by up to 7 % of themselves between two machines (module doc) but by
    0.07 % of the work; Newton iterations, Jacobians and retries by their own size."""
    out = []
    for key in COUNT_KEYS:
        a, b = old.get(key), new.get(key)
        if a is None and b is None:
            continue
        scale = base_work if key in STEP_KEYS and base_work else max(abs(a or 0), 1)
        if a is None or b is None or abs(b - a) > WORK_TOLERANCE * scale:
            out.append(f"{key} {a} → {b}")
    return out


def _changed_settings(new: Mapping[str, Any], old: Mapping[str, Any]) -> list[str]:
    return [f"{key} {old.get(key)} → {new.get(key)}" for key in SETTING_KEYS if old.get(key) != new.get(key)]


def run_machine(run: Mapping[str, Any], doc: Mapping[str, Any]) -> Mapping[str, Any] | None:
    """The machine `run` ran on: its own record (a Dask worker's), else its document's."""
    return run.get("machine") or doc.get("machine")


def compare(doc: Mapping[str, Any], base: Mapping[str, Any], base_name: str = "") -> dict[str, Any]:
    """Each run of `doc` beside the same (case, engine, variant) of `base`.

    Per row: `work` (its name, `work`, `base_work`, `work_ratio`), `verdict` ("same work",
    "more work", "less work", "failed", "not in the baseline"), the counts and settings that
    changed, and `wall_ratio` (doc / base) only when the two runs' machines (`run_machine`)
    are the same kind.  `same_machine`: whether they are for every run compared (without
    one, whether the documents' are)."""
    pairs: list[bool] = []
    old = {(r["case"], r["engine"], r["variant"]): r for r in base["runs"]}
    rows = []
    for r in doc["runs"]:
        key = (r["case"], r["engine"], r["variant"])
        row: dict[str, Any] = {"case": key[0], "engine": key[1], "variant": key[2]}
        b = old.get(key)
        if "error" in r or b is None or "error" in b:
            row["verdict"] = "failed" if "error" in r else ("not in the baseline" if b is None
                                                             else "failed in the baseline")
            rows.append(row)
            continue
        name, count = work(r)
        _, base_count = work(b)
        ratio = _ratio(count, base_count)
        solver, base_solver = r.get("solver") or {}, b.get("solver") or {}
        counts = _changed_counts(solver, base_solver, base_count)
        alike = same_machine(run_machine(r, doc), run_machine(b, base))
        pairs.append(alike)
        row.update(work=name, work_count=count, base_work=base_count, work_ratio=ratio,
                   counts=counts, settings=_changed_settings(solver, base_solver),
                   wall_s=r["wall_s"], base_wall_s=b["wall_s"],
                   wall_ratio=_ratio(r["wall_s"], b["wall_s"]) if alike else None)
        if ratio is None or abs(ratio - 1.0) <= WORK_TOLERANCE:
            row["verdict"] = "same work" if not counts else "counts moved"
        else:
            row["verdict"] = "more work" if ratio > 1.0 else "less work"
        rows.append(row)
    alike = all(pairs) if pairs else same_machine(doc.get("machine"), base.get("machine"))
    return {"file": base_name, "commit": base.get("commit"), "utc": base.get("utc"),
            "same_machine": alike,
            "machine": machine_text(base.get("machine")), "rows": rows}


def summary(cmp: Mapping[str, Any]) -> str:
    """One line: how many runs did the same work, more, less; the largest change."""
    rows = cmp["rows"]
    by: dict[str, int] = {}
    for row in rows:
        by[row["verdict"]] = by.get(row["verdict"], 0) + 1
    moved = [row for row in rows if row["verdict"] in ("more work", "less work")]
    text = f"{len(rows)} runs: " + ", ".join(f"{n} {v}" for v, n in sorted(by.items(), key=lambda kv: -kv[1]))
    if moved:
        top = max(moved, key=lambda row: abs(math.log(row["work_ratio"])))
        text += f"; largest change {top['case']} {top['engine']} {top['variant']} × {top['work_ratio']:.3f}"
    return text + f" (work within {WORK_TOLERANCE:.0%} counts as the same)"


def diff_table(cmp: Mapping[str, Any]) -> str:
    """The comparison for people: the baseline and its machine, one row per run."""
    where = "the same kind of machine" if cmp["same_machine"] else \
        ("runs partly on other machines: wall times compared where a run's machine is its baseline run's"
         if any(r.get("wall_ratio") is not None for r in cmp["rows"]) else "another machine, or one not recorded: wall times not compared")
    commit = (cmp.get("commit") or "?")[:7]
    lines = [f"against {cmp['file'] or 'the baseline'} ({commit}, {cmp.get('utc') or '?'}; "
             f"{where})", f"baseline machine: {cmp['machine']}"]
    head = (f"{'case':20s} {'variant':7s} {'engine':9s} {'work':18s} {'this':>12s} {'baseline':>12s} "
            f"{'ratio':>7s} {'wall ratio':>10s}  verdict")
    lines += [head, "-" * len(head)]
    absent = [f"{r['case']} {r['variant']} {r['engine']}" for r in cmp["rows"] if r["verdict"] == "not in the baseline"]
    for row in cmp["rows"]:
        if row["verdict"] == "not in the baseline":
            continue
        line = f"{row['case']:20s} {row['variant']:7s} {row['engine']:9s} "
        if "work" not in row:
            lines.append(line + f"{'':18s} {'':>12s} {'':>12s} {'':>7s} {'':>10s}  {row['verdict']}")
            continue
        wall = f"{row['wall_ratio']:10.3f}" if row["wall_ratio"] is not None else f"{'—':>10s}"
        ratio = f"{row['work_ratio']:7.4f}" if row["work_ratio"] is not None else f"{'—':>7s}"
        notes = "; ".join(row["settings"] + row["counts"])
        lines.append(line + f"{row['work']:18s} {_count(row['work_count'])} {_count(row['base_work'])} {ratio} "
                     f"{wall}  {row['verdict']}" + (f" ({notes})" if notes else ""))
    if absent:
        lines.append(f"not in the baseline ({len(absent)}): " + ", ".join(absent[:4])
                     + (", …" if len(absent) > 4 else ""))
    lines.append(summary(cmp))
    return "\n".join(lines)


def _count(value: float | None) -> str:
    return f"{value:12.0f}" if value is not None else f"{'—':>12s}"

