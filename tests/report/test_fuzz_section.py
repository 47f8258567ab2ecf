"""The report's randomized cross-check section, drawn from a small synthetic
docs/data/fuzz.json (the campaign itself: tests/crosscheck/test_fuzz_campaign.py)."""

from __future__ import annotations

from rsmcheck.report.build import Page
from rsmcheck.report.fuzz_section import fuzz_section


def _row(obs: str, ratio: float) -> dict:
    return {"observable": obs, "difference": ratio * 1e-6, "refinement": {"reference": 1e-7, "exudyn": 2e-7},
            "motion": 0.1, "allowance": 1e-6, "passed": ratio <= 1.0, "ratio": ratio}


DOC = {"format": "rsmcheck-fuzz", "seed": 5, "n": 3, "first": 0, "engines": ["reference", "exudyn"],
       "finer": {"reference": "2 more eigenmodes", "exudyn": "half step"},
       "criterion": {"factor": 3.0, "relative": 2e-4, "reaction_skip_s": 0.02, "absolute": {}},
       "passed": 2, "failed": 1, "wall_s": 12.0, "workers": 2,
       "scenarios": [
           {"index": 0, "seed": 5, "name": "fuzz_5_0", "scenario": "closed chain, torque sine", "passed": True,
            "case_file": "out/fuzz/scenarios/fuzz_5_0.toml", "rows": [_row("joint_angles", 0.4), _row("momentum_I", 0.1)]},
           {"index": 1, "seed": 5, "name": "fuzz_5_1", "scenario": "arm 1 holds the target, torque step",
            "passed": False, "case_file": "out/fuzz/failures/fuzz_5_1.toml",
            "rows": [_row("joint_angles", 3.5), _row("momentum_I", 0.2)]},
           {"index": 2, "seed": 5, "name": "fuzz_5_2", "scenario": "free target, torque ramp", "passed": True,
            "case_file": "out/fuzz/scenarios/fuzz_5_2.toml", "rows": [_row("joint_angles", 0.05)]}]}


def test_every_row_is_a_point_coloured_by_its_chain():
    page = Page()
    section = fuzz_section(page, DOC)
    assert section["chains"] == {"free": 1, "open": 1, "closed": 1}
    assert section["worst"] == 3.5 and [s["name"] for s in section["failed"]] == ["fuzz_5_1"]
    (fig,) = page.figures
    points = {t["name"]: list(zip(t["x"], t["y"])) for t in fig["data"] if t["mode"] == "markers"}
    assert points["open chain"] == [("joint_angles", 3.5), ("momentum_I", 0.2)]
    assert len(points["closed chain"]) == 2 and len(points["free chain"]) == 1
    assert fig["layout"]["yaxis"]["type"] == "log"
    assert fuzz_section(Page(), None) is None and fuzz_section(Page(), {"scenarios": []}) is None


def test_the_page_lists_the_failing_scenario_with_its_reproduction(render_stored):
    page = render_stored({"fuzz.json": DOC})
    section = page[page.index('<section id="fuzz">'):]
    section = section[:section.index("</section>")]
    assert "<b>2 passed, 1 failed</b>" in section and "1 free, 1 open, 1 closed" in section
    assert "rsmcheck check out/fuzz/failures/fuzz_5_1.toml" in section
    assert section.count("<tr>") == 2  # the head and the one failing scenario
    # without a stored campaign the section says how to make one
    assert "No stored campaign" in render_stored({})
