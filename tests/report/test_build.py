"""rsmcheck.report.build: the page rendered from stored runs (tests/report/conftest.py)."""

from __future__ import annotations

import html
import json
import re

from rsmcheck.orchestration.compare import check_runs
from rsmcheck.report.build import departures_table, fmt, only_engines, render, verdict_rows

SECTIONS = ("verdict", "provenance", "departures", "mission", "paper", "cases", "pinocchio", "modes", "studies",
            "speed", "faults")


def test_every_section_is_on_the_page(rendered):
    for sid in SECTIONS:
        assert f'<section id="{sid}">' in rendered.html, sid
        assert f'href="#{sid}"' in rendered.html, f"table of contents: {sid}"


def test_cross_check_rows_are_those_of_rsmcheck_check(rendered):
    """The verdict's cross-check rows are `check_runs` on the same runs, row for row (what
    `rsmcheck check --json` prints), and each is in the page's verdict table."""
    from rsmcheck.core.cases import load_case

    expected = []
    for name in ("free_drift", "p1_rigid_gains"):
        runs = rendered.runs[name]
        expected += [{**r.as_dict(), "engines": ["reference", "exudyn"]}
                     for r in check_runs(load_case(name).variant(True), runs["reference"], runs["exudyn"])]
    assert rendered.verdict["checks"] == json.loads(json.dumps(expected))
    table = rendered.html[rendered.html.index('id="verdict-table"'):]
    table = table[:table.index("</table>")]
    rows = re.findall(r'<tr class="[^"]*" data-kind="cross-check">(.*?)</tr>', table, re.S)
    assert len(rows) == len(expected)
    for r in expected:
        assert any(f">{r['observable']}<" in row and f">{fmt(r['error'])}<" in row and r["case"] in row
                   for row in rows), r


def test_failures_come_first_then_the_smallest_margin():
    doc = {"checks": [
        {"case": "a", "observable": "x", "error": 1.0, "tolerance": 2.0, "margin": 2.0, "pass": True},
        {"case": "b", "observable": "y", "error": 3.0, "tolerance": 1.0, "margin": 1 / 3, "pass": False},
        {"case": "c", "observable": "z", "error": 1.0, "tolerance": 1.5, "margin": 1.5, "pass": True,
         "at_switches": [{"time": 1.0, "error": 0.9}],
         "between_events": [{"time": 2.5, "error": 0.247}], "event_skew": 0.017}],
        "gate": [{"case": "a", "engine": "exudyn", "unchanged": False, "largest_ratio": 2.4,
                  "moved": [{"observable": "energy", "ratio": 2.4}], "inputs_changed": [], "structure": []}]}
    rows = verdict_rows(doc)
    assert [(r.kind, r.case) for r in rows] == [("cross-check", "b"), ("gate", "a"), ("cross-check", "c"),
                                                ("cross-check", "a")]
    assert "not compared at the constraint switches: t = 1 s (0.9)" in rows[2].note
    assert "(at most 17 ms apart): t = 2.5 s (0.247)" in rows[2].note
    assert rows[1].margin == 1 / 2.4 and "energy 2.4×" in rows[1].note


def test_the_mission_has_a_section_per_phase(rendered):
    """The short mission (p2 → p5) on the shared time axis, one section per phase; with one
    engine there is nothing to compare, and the page says so in red."""
    from rsmcheck.core.cases import load_case

    phases = load_case("mission").variant(True).phases
    for ph in phases:
        assert f'id="mission-{ph}"' in rendered.html
    mission = rendered.html[rendered.html.index('<section id="mission">'):rendered.html.index('<section id="paper">')]
    assert mission.count("no comparison rows for this phase") == len(phases)
    assert "mission phase" in rendered.html and "Not checked in this report:</b> mission phase" in rendered.html


def test_paper_figures_are_drawn_from_the_runs(rendered):
    """Figs. 10–17 come from the mission's phases, Fig. 6a from p1_rigid_gains; Fig. 5 needs
    p1_transport, which this page did not run: it says so."""
    page = rendered.html
    for number in ("6a", "10", "11", "12", "13", "14", "15", "16", "17"):
        block = page[page.index(f'id="fig{number}"'):]
        block = block[:block.index("</div>\n", block.index('class="caption"'))]
        assert "data-fig=" in block, number
    assert "the chained mission, phase p4_hohmann" in page
    assert "no run of p1_transport is stored" in page


def _figures(page: str) -> list[dict]:
    return json.loads(html.unescape(re.search(r'<script id="figures" type="application/json">(.*?)</script>',
                                              page, re.S).group(1)))


def test_every_figure_has_its_data_and_the_page_stays_small(rendered):
    figures = _figures(rendered.html)
    divs = re.findall(r"data-fig='(\d+)'", rendered.html)
    assert sorted(int(d) for d in divs) == list(range(len(figures)))
    assert f'data-figures="{len(figures)}"' in rendered.html
    assert rendered.page.stat().st_size < 25e6


def test_departures_come_from_the_data_file(rendered):
    """The package's departures table (rsmcheck/core/departures.toml), each row on the page."""
    from rsmcheck.core.departures import table

    head, rows = departures_table()
    assert (head, rows) == table()
    assert head[0].startswith("paper") and len(head) == 4
    assert rows and all(len(r) == 4 for r in rows)
    section = rendered.html[rendered.html.index('<section id="departures">'):]
    section = section[:section.index("</section>")]
    assert len(re.findall(r"<tr><td", section)) == len(rows)


def test_stored_studies_and_faults_render_from_a_data_folder(rendered, tmp_path):
    doc = {"case": "motor_step", "duration": 1.0, "modes": [2],
           "exudyn": [{"substeps": 256, "h": 1e-3 / 256, "axial_to_bending": 1e6}],
           "tolerances": {"motor_angles": 1e-6}, "errors": {"2,256,1e+06": {"motor_angles": 3.06e-6}}}
    (tmp_path / "refinement_motor_step.json").write_text(json.dumps(doc))
    faults = {"commit": "abc", "cases": ["release"], "faults": [
        {"name": "missed", "layer": "exudyn", "what": "y", "crosscheck": [], "pinocchio": [], "gate": [], "caught_by": []},
        {"name": "noop", "layer": "none", "what": "z", "crosscheck": [], "pinocchio": [], "gate": [], "caught_by": []}]}
    (tmp_path / "faults.json").write_text(json.dumps(faults))
    page = render(rendered.folder, tmp_path / "page.html", ["free_drift"], data_dir=tmp_path).read_text()
    assert 'class="fail">3.06e-06</td>' in page
    assert page.count('<span class="fail">MISSED</span>') == 1
    assert page.count('<span class="pass">as expected</span>') == 1
    assert "No stored speed measurement" in page


def test_stored_bench_shows_where_each_run_spent_its_time(rendered, tmp_path):
    """A bench document whose runs recorded their split gets the µs-per-sample table; a failed
    run has no row."""
    split = {"samples": 1000, "wall_s": 0.5, "wall_integrator_s": 0.3, "wall_advance_s": 0.32,
             "wall_sensors_s": 0.05, "wall_controller_s": 0.06, "wall_observe_s": 0.01}
    bench = {"command": "rsmcheck bench", "commit": "abc", "utc": "now", "engines": ["reference"],
             "runs": [{"case": "p4_hohmann", "engine": "reference", "variant": "short", "wall_s": 0.5,
                       "sim_s": 1.0, "peak_mb": 200.0, "split": split},
                      {"case": "capture", "engine": "exudyn", "variant": "short", "wall_s": None, "sim_s": None,
                       "peak_mb": None, "error": "boom"}]}
    (tmp_path / "bench_short.json").write_text(json.dumps(bench))
    page = render(rendered.folder, tmp_path / "page.html", ["free_drift"], data_dir=tmp_path).read_text()
    assert "µs per control sample" in page
    row = page[page.index('<td class="l">p4_hohmann</td><td class="l">reference</td><td>1000</td>'):]
    assert row.split("</tr>")[0].count("<td>") == 8 and ">500<" in row.split("</tr>")[0]


def test_stored_benches_name_their_machines_and_say_when_they_differ(rendered, tmp_path):
    """Each bench says its machine and each run's work; when the stored documents did not all
    run on one recorded machine the section says so (their wall times do not compare, their
    work does), and not when they did."""
    epyc = {"cpu": "AMD EPYC (family 25, model 17)", "logical_cpus": 2, "memory_gib": 23.5, "system": "Linux",
            "python": "3.11.7", "packages": {}}
    doc = {"command": "rsmcheck bench", "commit": "abc", "utc": "now", "engines": ["reference"],
           "runs": [{"case": "free_drift", "engine": "reference", "variant": "short", "wall_s": 1.0, "sim_s": 1.0,
                     "peak_mb": 1.0, "solver": {"steps": 12000, "rejected_steps": 345}}]}

    def speed(machines):
        for f in tmp_path.glob("bench_*.json"):
            f.unlink()
        for i, machine in enumerate(machines):
            (tmp_path / f"bench_{i}.json").write_text(json.dumps(dict(doc, machine=machine) if machine else doc))
        page = render(rendered.folder, tmp_path / "page.html", ["free_drift"], data_dir=tmp_path).read_text()
        return page[page.index('<section id="speed">'):]

    one = speed([epyc, dict(epyc, memory_gib=31.0)])  # another kernel or memory: the same processor
    assert one.count("AMD EPYC (family 25, model 17), 2 logical CPUs") == 2 and "compare wall times" not in one
    assert one.count("<td>12\u202f345 step attempts</td>") == 2  # the work, which compares across machines
    xeon = dict(epyc, cpu="Intel Xeon (family 6, model 85)")
    three = speed([epyc, xeon, epyc])
    assert "These 3 documents ran on 2 recorded machines: compare wall times within one document only" in three
    assert "Its work (the <em>work</em> column" in three
    old = speed([epyc, None])
    assert "machine not recorded" in old and "ran on 1 recorded machine, and 1 did not record theirs" in old


def test_stored_bench_shows_the_mission_phases(rendered, tmp_path):
    """A bench of the mission gets a row per phase and engine with its own × real time; the
    header says how many runs shared the machine."""
    bench = {"command": "rsmcheck bench --jobs 2", "commit": "abc", "utc": "now", "engines": ["reference"],
             "jobs": 2, "runs": [{"case": "mission", "engine": "reference", "variant": "full", "wall_s": 40.0,
                                  "sim_s": 100.0, "peak_mb": 200.0,
                                  "phases": [{"phase": "p1_transport", "sim_s": 60.0, "wall_s": 30.0},
                                             {"phase": "p2_capture_regrasp", "sim_s": 40.0, "wall_s": 10.0}]}]}
    (tmp_path / "bench_full.json").write_text(json.dumps(bench))
    page = render(rendered.folder, tmp_path / "page.html", ["free_drift"], data_dir=tmp_path).read_text()
    assert "2 runs at a time" in page
    row = page[page.index('<td class="l">p2_capture_regrasp</td>'):].split("</tr>")[0]
    assert '<td class="l">full</td><td class="l">reference</td>' in row
    assert [cell.split("<")[0] for cell in row.split("<td>")[1:]] == ["40", "10", "4"]


def test_stored_bench_shows_the_speed_targets_and_the_phases_against_theirs(rendered, tmp_path):
    """A full mission in a bench document gets the targets it measures with their margins
    (a miss shown as one), the integrator's share and its margin where the run recorded it,
    and a bar chart of the phases' × real time with the 20× line; a short bench gets neither
    the mission targets nor the chart."""
    phases = [{"phase": "p1_transport", "sim_s": 60.0, "wall_s": 30.0},
              {"phase": "p2_capture_regrasp", "sim_s": 40.0, "wall_s": 1.0}]
    bench = {"command": "rsmcheck bench --full", "commit": "abc", "utc": "now", "engines": ["reference", "exudyn"],
             "runs": [{"case": "mission", "engine": e, "variant": "full", "wall_s": w, "sim_s": 100.0,
                       "peak_mb": 1.0, "phases": phases, **extra}
                      for e, w, extra in (("reference", 600.0, {"split": {"wall_integrator_s": 500.0}}),
                                          ("exudyn", 600.0, {}))],
             "rhs_us": {"reference_compiled": 10.0, "reference_states": 89, "reference_rigid_compiled": 5.0,
                        "pinocchio_aba": 2.0}}
    (tmp_path / "bench_full.json").write_text(json.dumps(bench))
    short = dict(bench, command="rsmcheck bench", runs=[dict(r, variant="short") for r in bench["runs"]])
    (tmp_path / "bench_short.json").write_text(json.dumps(short))
    page = render(rendered.folder, tmp_path / "page.html", ["free_drift"], data_dir=tmp_path).read_text()
    assert page.count('<td class="l">reference: full mission</td>') == 1
    assert page.count('<td class="l">reference rigid RHS / Pinocchio ABA</td>') == 2
    row = page[page.index('<td class="l">reference: full mission</td>'):].split("</tr>")[0]
    assert ">600<" in row and ">0.5<" in row and '<span class="fail">no</span>' in row
    assert "<td>500</td><td>0.6</td>" in row  # 300 s against the integrator's 500 s
    exu = page[page.index('<td class="l">Exudyn: full mission</td>'):].split("</tr>")[0]
    assert ">2<" in exu and '<span class="pass">yes</span>' in exu and "<td>–</td><td>–</td>" in exu
    slowest = page[page.index('<td class="l">reference: each mission phase</td>'):].split("</tr>")[0]
    assert ">2<" in slowest and "slowest p1_transport" in slowest
    bars = [f for f in _figures(page) if any(t.get("type") == "bar" for t in f["data"])]
    assert len(bars) == 1 and bars[0]["layout"]["yaxis"]["type"] == "log"
    assert [t["y"] for t in bars[0]["data"] if t["type"] == "bar"] == [[2.0, 40.0], [2.0, 40.0]]
    assert [t["y"] for t in bars[0]["data"] if t["type"] == "scatter"] == [[20.0, 20.0]]


def test_without_stored_studies_or_goldens_each_section_says_so(rendered, tmp_path, monkeypatch):
    """An installed package has no docs/data/ and no goldens/: the page still renders, and
    each section with nothing to show says so in one line; the gate rows that had no golden
    are left out of the verdict (counted in one line), not shown as failures."""
    import rsmcheck.report.build as build

    monkeypatch.setenv("RSMCHECK_GOLDENS_DIR", str(tmp_path / "no-goldens"))
    doc = json.loads((rendered.folder / "verdict.json").read_text())
    doc["gate"] = doc.get("gate", []) + [
        {"case": "free_drift", "engine": "exudyn", "unchanged": False, "inputs_changed": ["no golden x.h5"],
         "structure": [], "moved": [], "largest_ratio": None}]
    folder = tmp_path / "stored"
    folder.mkdir()
    for item in rendered.folder.iterdir():
        (folder / item.name).symlink_to(item)
    (folder / "verdict.json").unlink()
    (folder / "verdict.json").write_text(json.dumps(doc))
    empty = tmp_path / "data"
    empty.mkdir()
    page = render(folder, tmp_path / "page.html", ["free_drift"], data_dir=empty).read_text()
    for line in ("No stored engine studies here", "No stored speed measurement", "No stored fault-injection matrix",
                 "No goldens here"):
        assert page.count(line) == 1, line
    n = sum(build.no_golden(g) for g in doc["gate"])
    assert f"{n} gate comparisons left out" in page
    assert len(verdict_rows(doc, goldens=False)) == len(verdict_rows(doc)) - n
    assert not any(r.kind == "gate" and "no golden" in r.note for r in verdict_rows(doc, goldens=False))


def test_the_page_draws_the_engines_asked_for_only(rendered, tmp_path):
    """A run file may hold engines an earlier report ran: `engines` keeps those asked for,
    their curves and the rows that judge them alone (here the reference alone: no pair)."""
    page = render(rendered.folder, tmp_path / "page.html", ["free_drift"], data_dir=tmp_path,
                  engines=["reference"]).read_text()
    full = render(rendered.folder, tmp_path / "full.html", ["free_drift"], data_dir=tmp_path).read_text()
    for html_text, drawn in ((page, False), (full, True)):
        names = {tr.get("name", "") for fig in _figures(html_text) for tr in fig["data"]}
        assert any(n.startswith("reference") for n in names)
        assert any(n.startswith("exudyn") for n in names) is drawn
    doc = only_engines(rendered.verdict, ["reference"])
    assert doc["checks"] == [] and all(g["engine"] == "reference" for g in doc["gate"])
    assert only_engines(rendered.verdict, ["reference", "exudyn"])["checks"] == rendered.verdict["checks"]


def test_three_engines_rows_of_one_pair_do_not_hide_another_pairs(rendered):
    """A third engine (Exudyn's run under another name, with its own rows and errors): each
    case keeps the rows of both pairs, each plot draws one difference curve per pair with
    that pair's tolerance, and the verdict table names each row's pair."""
    import rsmcheck.report.build as build
    from rsmcheck.core.cases import load_case

    runs = dict(rendered.runs["p1_rigid_gains"])
    runs["exudyn2"] = runs["exudyn"]
    pair = [r for r in rendered.verdict["checks"] if r["case"] == "p1_rigid_gains"]
    assert pair and all(r["engines"] == ["reference", "exudyn"] for r in pair)
    third = [dict(r, engines=["reference", "exudyn2"], error=2 * r["error"], tolerance=3 * r["tolerance"]) for r in pair]
    st = build.Stored(rendered.folder, {"checks": pair + third}, [load_case("p1_rigid_gains")], {"p1_rigid_gains": runs})
    page = build.Page()
    section, = build.case_sections(page, st, build._check_map(pair + third), {})
    assert len(section["rows"]) == 2 * len(pair)
    for spec in load_case("p1_rigid_gains").variant(True).compare:
        mine = [r for r in section["rows"] if r["observable"] == spec.observable]
        assert sorted(tuple(r["engines"]) for r in mine) == [("reference", "exudyn"), ("reference", "exudyn2")]
    fig = page.figures[0]
    names = [t["name"] for t in fig["data"]]
    assert "|reference − exudyn|" in names and "|reference − exudyn2|" in names
    tols = {t["name"]: t["y"][0] for t in fig["data"] if t["name"].startswith("tolerance of")}
    first = pair[0]
    assert tols[f"tolerance of |reference − exudyn| ({first['metric']})"] == first["tolerance"]
    assert tols[f"tolerance of |reference − exudyn2| ({first['metric']})"] == 3 * first["tolerance"]
    assert "reference vs exudyn: error" in fig["layout"]["title"]["text"]
    assert "reference vs exudyn2: error" in fig["layout"]["title"]["text"]
    rows = build.verdict_rows({"checks": pair + third})
    assert {r.pair for r in rows} == {"reference vs exudyn", "reference vs exudyn2"}
    summary = {s["kind"]: s["n"] for s in build.verdict_summary(rows)}
    assert summary["cross-check, reference vs exudyn"] == summary["cross-check, reference vs exudyn2"] == len(pair)
