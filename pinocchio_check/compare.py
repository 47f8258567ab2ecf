"""Seeded comparison of the reference model's rigid quantities against Pinocchio.

For each chain — "open" (arm 1 holds the target, arm 2 free) and "closed" (both hold) —
`run_checks` draws `n_states` consistent random states on the Pinocchio side
(`pinocchio_check.states`, seeds first_seed, first_seed + 1, …; rejected closed-chain
draws are skipped), asks both models the same questions through the same API and
records, per quantity, the worst norm-relative error over the states

    error = max_i |a_i − b_i| / max(max_i |b_i|, tiny),     a = reference, b = Pinocchio,

with the seed of the worst state and the entry where it occurs.  Tolerance 1e-10: both
sides are exact rigid-body algebra in double precision, so anything above round-off
(observed ~1e-13) is a modelling difference.

Quantities (reference coordinates, see pinocchio_check.model):
mass_matrix (9×9), nonlinear_terms (9, JᵀMJ̇q̇), ee{1,2}_position, ee{1,2}_jacobian
(2×9), ee{1,2}_jdot_qd, grasp{1,2}_position (grasp point from X_T), com_position,
com_jacobian (2×12 w.r.t. [q, X_T]), momentum (p_x, p_y, L_z about the origin),
accelerations ([q̈, Ẍ_T], 12, under random u_J, τ_B) and reaction_forces (R_cl, 4).

With ``n_modes > 0`` the reference carries modal amplitudes; they and their rates are set
to zero and the rigid block is compared (mass matrix, bias forces, point kinematics, COM,
momentum).  Constrained accelerations are then not comparable — the elastic coordinates
are coupled inertially to the rigid ones — and are left out.

`main(argv)` is ``rsmcheck pinocchio [--json]`` (docs/commands.md): a table, or one JSON object
``{"checks": [...]}``; exit 0 when every check passes, 1 otherwise.  It runs the open
chain held by arm 1 and by arm 2 and the closed chain, for rigid links (n_modes = 0) and
for the 2-mode reference (rigid block), so a (quantity, chain) pair occurs in several
rows, told apart by the extra keys "holding" and "n_modes".
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np

from pinocchio_check import states as S
from pinocchio_check.model import N_Q, Q_NAMES, TARGET_NAMES, PinocchioRSM
from rsmcheck.core.params import Params

TOLERANCE = 1e-10
TINY = 1e-300
N_STATES = 200
CHAINS = ("open", "closed")

XY = ("x", "y")
_QT = Q_NAMES + TARGET_NAMES
#: quantity → names along each axis (for the "entry" of the worst error)
AXES: dict[str, tuple[tuple[str, ...], ...]] = {
    "mass_matrix": (Q_NAMES, Q_NAMES),
    "nonlinear_terms": (Q_NAMES,),
    "ee1_position": (XY,),
    "ee2_position": (XY,),
    "ee1_jacobian": (XY, Q_NAMES),
    "ee2_jacobian": (XY, Q_NAMES),
    "ee1_jdot_qd": (XY,),
    "ee2_jdot_qd": (XY,),
    "grasp1_position": (XY,),
    "grasp2_position": (XY,),
    "com_position": (XY,),
    "com_jacobian": (XY, _QT),
    "momentum": (("p_x", "p_y", "L_z"),),
    "accelerations": (tuple("dd_" + n for n in _QT),),
    "reaction_forces": (("R1", "R2", "R3", "R4"),),
}
QUANTITIES = tuple(AXES)
DYNAMIC = ("accelerations", "reaction_forces")


# ---------------------------------------------------------------------------------------
# Asking a model (reference or Pinocchio: same API) for every quantity of one state
# ---------------------------------------------------------------------------------------
def quantities(model, st: S.RefState, nq: int, wanted: Iterable[str]) -> dict[str, np.ndarray]:
    """All `wanted` quantities of state `st` from `model`, rigid block only.

    `nq` is the model's number of RSM coordinates (9, or 9 + modal amplitudes); the
    amplitudes and their rates are set to zero and only the rigid rows/columns kept.
    """
    wanted = set(wanted)
    ne = nq - N_Q
    q = np.concatenate([st.q, np.zeros(ne)])
    qd = np.concatenate([st.qd, np.zeros(ne)])
    rigid = np.r_[0:N_Q]
    out: dict[str, np.ndarray] = {}
    if "mass_matrix" in wanted:
        out["mass_matrix"] = np.asarray(model.mass_matrix(q))[np.ix_(rigid, rigid)]
    if "nonlinear_terms" in wanted:
        out["nonlinear_terms"] = np.asarray(model.bias_forces(q, qd))[rigid]
    for k in (1, 2):
        names = (f"ee{k}_position", f"ee{k}_jacobian", f"ee{k}_jdot_qd")
        if wanted.intersection(names):
            r, J, jdq = model.point_kinematics(q, qd, f"ee{k}")
            out[names[0]], out[names[1]], out[names[2]] = np.asarray(r), np.asarray(J)[:, rigid], np.asarray(jdq)
        if f"grasp{k}_position" in wanted:
            out[f"grasp{k}_position"] = np.asarray(model.grasp_point(st.X_T, k))
    if wanted.intersection(("com_position", "com_jacobian")):
        c, Jc = model.com(q, st.X_T)
        out["com_position"] = np.asarray(c)
        out["com_jacobian"] = np.asarray(Jc)[:, np.r_[rigid, nq : nq + 3]]
    if "momentum" in wanted:
        out["momentum"] = np.asarray(model.momentum(q, qd, st.X_T, st.XT_d))
    if wanted.intersection(DYNAMIC):
        if ne:
            raise ValueError("constrained accelerations are compared for rigid links only (n_modes = 0)")
        qdd, XT_dd, R_cl = model.constrained_accelerations(
            q, qd, st.X_T, st.XT_d, grasp=st.grasp, u_J=st.u_J, tau_B=st.tau_B
        )
        out["accelerations"] = np.concatenate([np.asarray(qdd), np.asarray(XT_dd)])
        out["reaction_forces"] = np.asarray(R_cl)
    return {k: v for k, v in out.items() if k in wanted}


def relative_error(a: np.ndarray, b: np.ndarray) -> tuple[float, tuple[int, ...]]:
    """(max|a − b| / max(max|b|, tiny), index of the largest |a − b|); a is the reference."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return math.inf, ()
    d = np.abs(a - b)
    if not np.all(np.isfinite(d)):
        idx = np.unravel_index(int(np.argmax(~np.isfinite(d))), d.shape)
        return math.inf, tuple(int(i) for i in idx)
    idx = np.unravel_index(int(np.argmax(d)), d.shape)
    return float(d[idx] / max(float(np.abs(b).max(initial=0.0)), TINY)), tuple(int(i) for i in idx)


def entry_label(quantity: str, idx: tuple[int, ...]) -> str:
    """Readable entry, e.g. "J1_1,x_B" for the mass matrix."""
    axes = AXES.get(quantity, ())
    try:
        return ",".join(axes[n][i] for n, i in enumerate(idx))
    except IndexError:
        return ",".join(str(i) for i in idx)


# ---------------------------------------------------------------------------------------
# The comparison
# ---------------------------------------------------------------------------------------
@dataclass
class _Worst:
    error: float = 0.0
    seed: int | None = None
    entry: str = ""
    message: str = ""


def make_states(pin_model: PinocchioRSM, chain: str, n_states: int, first_seed: int,
                holding: int = 1) -> list[S.RefState]:
    """States of `chain`; for "open", `holding` is the arm that holds the target."""
    if chain == "open":
        return S.open_states(pin_model, n_states, first_seed, arm=holding)
    if chain == "closed":
        return S.closed_states(pin_model, n_states, first_seed)
    raise ValueError(f"chain must be 'open' or 'closed', got {chain!r}")


def default_reference(params: Params, n_modes: int):
    from reference_model.build import ReferenceModel

    # the static shapes as Ritz states: slaved (the default) they would load the rigid rows
    # with their own inertial forces through the springs (docs/physics.md §2.4), as the
    # elastic coordinates couple into the constrained accelerations
    return ReferenceModel(params, n_modes=n_modes, static_modes="explicit")


def run_checks(
    params: Params | None = None,
    pin_params: Params | None = None,
    n_states: int = N_STATES,
    first_seed: int = 0,
    chains: Sequence[str] = CHAINS,
    open_arms: Sequence[int] = (1,),
    n_modes: int = 0,
    wanted: Sequence[str] | None = None,
    reference_factory: Callable[[Params, int], object] | None = None,
    tolerance: float = TOLERANCE,
) -> list[dict]:
    """Rows {"quantity", "chain", "states", "max_rel_error", "tolerance", "pass", "seed",
    "entry", "n_modes", "holding"} — one per (chain, holding arm, quantity).

    `open_arms`: which arm holds the target in the open-chain runs (one set of rows
    each; "holding" = "arm1"/"arm2", "both" for the closed chain).

    `params` builds the reference; `pin_params` (default: the same) builds the Pinocchio
    side and its states — giving them different values is how a test shows that the
    comparison can fail.  `reference_factory(params, n_modes)` builds the reference
    (default: `default_reference`, i.e. ``ReferenceModel(params, n_modes=n_modes)``).  A reference call that raises makes its row fail with the
    message in "error" and max_rel_error None.
    """
    params = params or Params()
    pin_params = pin_params or params
    if wanted is None:
        wanted = [q for q in QUANTITIES if not (n_modes and q in DYNAMIC)]
    pin_model = PinocchioRSM(pin_params)
    ref = (reference_factory or default_reference)(params, n_modes)
    nq_ref = getattr(getattr(ref, "layout", None), "nq", N_Q + 6 * n_modes)
    rows: list[dict] = []
    cases = [(c, a) for c in chains for a in (open_arms if c == "open" else (0,))]
    for chain, arm in cases:
        sts = make_states(pin_model, chain, n_states, first_seed, holding=arm or 1)
        worst = {q: _Worst() for q in wanted}
        for st in sts:
            b = quantities(pin_model, st, N_Q, wanted)
            try:
                a = quantities(ref, st, nq_ref, wanted)
            except Exception as exc:  # the reference failing is a failed check, not a crash
                for q in wanted:
                    if not worst[q].message:
                        worst[q] = _Worst(math.inf, st.seed, "", f"{type(exc).__name__}: {exc}")
                continue
            for q in wanted:
                err, idx = relative_error(a[q], b[q])
                if not err <= worst[q].error:  # also catches NaN
                    worst[q] = _Worst(err, st.seed, entry_label(q, idx), worst[q].message)
        for q in wanted:
            w = worst[q]
            finite = math.isfinite(w.error)
            row = {
                "quantity": q,
                "chain": chain,
                "states": len(sts),
                "max_rel_error": w.error if finite else None,
                "tolerance": tolerance,
                "pass": bool(finite and w.error <= tolerance and not w.message),
                "seed": w.seed,
                "entry": w.entry,
                "n_modes": n_modes,
                "holding": f"arm{arm}" if arm else "both",
            }
            if w.message:
                row["error"] = w.message
            rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------
# Command line: rsmcheck pinocchio [--json]
# ---------------------------------------------------------------------------------------
def format_table(rows: list[dict]) -> str:
    head = ("quantity", "chain", "holding", "modes", "states", "max error", "tolerance", "pass", "worst seed", "entry")
    lines = []
    for r in rows:
        err = "failed" if r["max_rel_error"] is None else f"{r['max_rel_error']:.2e}"
        lines.append((r["quantity"], r["chain"], r["holding"], str(r["n_modes"]), str(r["states"]), err,
                      f"{r['tolerance']:.0e}", "PASS" if r["pass"] else "FAIL",
                      "" if r["seed"] is None else str(r["seed"]), r["entry"]))
    widths = [max(len(h), *(len(l[i]) for l in lines)) if lines else len(h) for i, h in enumerate(head)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    out = [fmt.format(*head), fmt.format(*("-" * w for w in widths))]
    out += [fmt.format(*l) for l in lines]
    for r in rows:
        if "error" in r:
            out.append(f"{r['quantity']} ({r['chain']}, {r['holding']}, n_modes={r['n_modes']}): {r['error']}")
    n_fail = sum(not r["pass"] for r in rows)
    out.append(f"{len(rows) - n_fail} of {len(rows)} checks pass")
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    """``rsmcheck pinocchio [--json] [--states N] [--seed S] [--modes M]``; 0 = all pass."""
    ap = argparse.ArgumentParser(prog="rsmcheck pinocchio",
                                 description="Rigid kinematics and dynamics of the reference model vs Pinocchio.")
    ap.add_argument("--json", action="store_true", help="print one JSON object {\"checks\": [...]}")
    ap.add_argument("--states", type=int, default=N_STATES, help=f"random states per chain (default {N_STATES})")
    ap.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    ap.add_argument("--modes", type=int, nargs="*", default=[0, 2],
                    help="reference modes per link to run: the rigid block is compared (default: 0 2)")
    args = ap.parse_args(argv)
    if args.states < 1 or any(m < 0 for m in args.modes):
        print("rsmcheck pinocchio: --states must be ≥ 1 and --modes ≥ 0", file=sys.stderr)
        return 2
    rows: list[dict] = []
    for n_modes in args.modes:
        rows += run_checks(n_states=args.states, first_seed=args.seed, n_modes=n_modes, open_arms=(1, 2))
    if args.json:
        from rsmcheck.core.store import dumps_json

        print(dumps_json({"checks": rows}, indent=None))  # strict JSON: no NaN/Infinity
    else:
        print(format_table(rows))
    return 0 if all(r["pass"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
