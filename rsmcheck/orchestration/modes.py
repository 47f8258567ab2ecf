"""`rsmcheck modes`: link and arm eigenfrequencies — analytic and each engine's.

Links (one link, basis PP = pinned-pinned, PF = pinned-free, modes 1–2): the analytic
Euler–Bernoulli frequencies f_j = (β_j L)² sqrt(EI/ρA) / (2π L²), with EI derived from
Table 2's PP f1 (docs/physics.md §2; `rsmcheck.core.params`), βL = jπ (PP) or the roots of
tan βL = tanh βL (PF), from `rsmcheck.core.beams`; against them each engine plug-in's
`link_frequencies` (the reference: its modal matrices' generalised eigenvalues; Exudyn:
the meshed link's eigenvalues from its own solver).

Arms (the whole robot linearised at rest in a case's initial configuration, undamped,
orbit off): each plug-in's `coupled_frequencies`, computed by each engine from its own
equations alone (rsmcheck.core.plugins).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from rsmcheck.core.beams import analytic_frequencies
from rsmcheck.core.cases import at_rest, load_case, undamped, without_orbit
from rsmcheck.core.params import TABLE2_HZ, Params
from rsmcheck.core.plugins import default_engines, plugin

#: (name, case, what it is) of the configurations `rsmcheck modes` linearises
CONFIGURATIONS = (
    ("open", "free_drift", "arm 1 holds the target, arm 2 free (terminal link PF)"),
    ("closed", "closed_squeeze", "both arms hold the target (all links PP)"),
    ("free_arms", "flex_arm_step", "target away: two free arms on the base"),
    ("stretched_closed", "thrust_burn", "thrust configuration: arms nearly stretched, both holding"),
)
N_ARM_MODES = 6


def link_rows(params=None, options: Mapping[str, Mapping[str, Any]] | None = None,
              engines: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """One row per basis and mode: Table 2, the analytic frequency, and each engine's
    (`link_frequencies` of its plug-in, with its `options`) with its relative error:
    keys "ENGINE_hz", "ENGINE_rel"."""
    params = params or Params()
    options = options or {}
    engines = [e for e in (engines or default_engines()) if getattr(plugin(e), "link_frequencies", None)]
    rows = []
    for basis in ("PP", "PF"):
        fa = analytic_frequencies(params.link, basis)
        f = {e: plugin(e).link_frequencies(params, basis, 2, **options.get(e, {})) for e in engines}
        for j in range(2):
            row = {"basis": basis, "mode": j + 1, "analytic_hz": float(fa[j]), "table2_hz": TABLE2_HZ[basis][j]}
            for e in engines:
                row[f"{e}_hz"] = float(f[e][j])
                row[f"{e}_rel"] = float(f[e][j] / fa[j] - 1)
            rows.append(row)
    return rows


def modal_case(case):
    """`case` at rest in its initial configuration, undamped, without orbit."""
    return without_orbit(undamped(at_rest(case)))


def arm_rows(configurations: Sequence[tuple[str, str, str]] = CONFIGURATIONS, n: int = N_ARM_MODES,
             options: Mapping[str, Mapping[str, Any]] | None = None,
             engines: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The first `n` coupled frequencies of each configuration in each engine
    (`coupled_frequencies` of its plug-in): keys "ENGINE_hz", and "ENGINE_rel" of every engine
    after the first: its relative difference from the first engine's ("against")."""
    options = options or {}
    engines = [e for e in (engines or default_engines()) if getattr(plugin(e), "coupled_frequencies", None)]
    rows = []
    for label, case_name, what in configurations:
        case = modal_case(load_case(case_name))
        f = {e: plugin(e).coupled_frequencies(case, n, **options.get(e, {})) for e in engines}
        for j in range(min(len(v) for v in f.values())):
            row = {"configuration": label, "case": case_name, "description": what, "mode": j + 1}
            row.update({f"{e}_hz": float(f[e][j]) for e in engines})
            if len(engines) > 1:
                row["against"] = engines[0]
                row.update({f"{e}_rel": float(f[e][j] / f[engines[0]][j] - 1) for e in engines[1:]})
            rows.append(row)
    return rows


def modes_report(options: Mapping[str, Mapping[str, Any]] | None = None) -> dict[str, Any]:
    """The JSON object of `rsmcheck modes --json` (docs/commands.md)."""
    return {"links": link_rows(options=options), "arms": arm_rows(options=options)}


def modes_text(links: Sequence[Mapping[str, Any]], arms: Sequence[Mapping[str, Any]], engines: Sequence[str]) -> str:
    """The tables of `rsmcheck modes`: link frequencies against the analytic ones, then the
    coupled frequencies with each engine's difference from the first."""
    out: list[str] = []
    lk = [e for e in engines if f"{e}_hz" in links[0]]
    out.append("Link eigenfrequencies [Hz]")
    out.append(f"  {'basis':5s} {'mode':>4s} {'Table 2':>9s} {'analytic':>10s}" + "".join(f" {e[:10]:>10s}" for e in lk)
               + "".join(f" {e[:5] + '-an':>9s}" for e in lk))
    for r in links:
        out.append(f"  {r['basis']:5s} {r['mode']:4d} {r['table2_hz']:9.2f} {r['analytic_hz']:10.4f}"
                   + "".join(f" {r[e + '_hz']:10.4f}" for e in lk) + "".join(f" {100 * r[e + '_rel']:+8.4f}%" for e in lk))
    ak = [e for e in engines if arms and f"{e}_hz" in arms[0]]
    rk = [e for e in ak if arms and f"{e}_rel" in arms[0]]
    out.append("Coupled frequencies of the robot at rest, undamped [Hz]"
               + (f"; differences from {ak[0]}" if rk else ""))
    out.append(f"  {'configuration':17s} {'mode':>4s}" + "".join(f" {e[:10]:>10s}" for e in ak)
               + "".join(f" {e[:9] + ' diff':>14s}" for e in rk))
    for r in arms:
        out.append(f"  {r['configuration']:17s} {r['mode']:4d}" + "".join(f" {r[e + '_hz']:10.4f}" for e in ak)
                   + "".join(f" {100 * r[e + '_rel']:+13.4f}%" for e in rk))
    return "\n".join(out)
