"""A variant engine (rsmcheck.core.derived): the base engine's code and its settings of every
case under a name of its own, on changed parameters.  The variants run end to end in
tests/plugins/test_third_party_engine.py (sameref, stiffref); here, what they hand the base."""

from __future__ import annotations

from dataclasses import replace

import pytest

from rsmcheck.core import plugins as reg
from rsmcheck.core.cases import load_case
from rsmcheck.core.derived import DerivedPlugin, derived
from rsmcheck.core.plugins import EnginePlugin, LineStyle


def _stiffer(p):
    return replace(p, link=replace(p.link, f1_pp_hz=p.link.f1_pp_hz * 1.03 ** 0.5))


@pytest.fixture
def variant() -> DerivedPlugin:
    return derived(reg.plugin("reference"), "stiffref", "EI + 3 %", LineStyle("#8c564b", "longdash"),
                   params=_stiffer, differs="EI 3 % higher")


def test_a_variant_is_a_plug_in_with_the_bases_refinement(variant):
    assert isinstance(variant, EnginePlugin)
    ref = reg.plugin("reference")
    assert variant.tables == () and variant.engine_options == ref.engine_options
    assert variant.work_counters == ref.work_counters and variant.refinement == ref.refinement
    case = load_case("flex_arm_step").variant(True)
    assert variant.refined_options(case) == ref.refined_options(case)


def test_the_base_runs_the_changed_parameters_with_its_own_case_settings(variant):
    """flex_arm_step sets [reference] n_modes = 4 and explicit static shapes: the variant's
    run gets them (a hand-written subclass with a table of its own would not)."""
    case = load_case("flex_arm_step").variant(True)
    given = reg.settings_of(case, "reference")
    run_as = variant.variant_case(case)
    assert reg.settings_of(run_as, "reference") == given
    assert run_as.params.link.f1_pp_hz == pytest.approx(case.params.link.f1_pp_hz * 1.03 ** 0.5, rel=1e-15)
    assert run_as.params.target == case.params.target  # nothing else changes
    # the gate's step perturbation of the variant reaches the base's settings
    perturbed = replace(case, engine_settings={
        **case.engine_settings, "stiffref": variant.step_perturbed(variant.parse_settings({}, {}, "", str), 1.001)})
    assert reg.settings_of(variant.variant_case(perturbed), "reference") == \
        reg.plugin("reference").step_perturbed(given, 1.001)


def test_the_engine_carries_the_variants_name():
    made = []

    class Base:
        name = "base"
        requires, extra, work_counters, engine_options, tables = (), None, (), (), ()

        def parse_settings(self, tables, solver, where, key):
            return None

        def make(self, case, start=None, **options):
            made.append(case)
            return type("E", (), {"name": "base"})()

    v = derived(Base(), "other", "other", LineStyle("#000"))
    case = load_case("free_drift")
    assert v.make(case).name == "other" and made[0].params == case.params
    assert v.differs == "the same model under another name"
    with pytest.raises(ValueError, match="a name of its own"):
        derived(Base(), "base", "b", LineStyle("#000"))
    with pytest.raises(ValueError, match="say in `differs`"):
        derived(Base(), "x", "x", LineStyle("#000"), params=_stiffer)



def test_the_stored_runs_digest_covers_the_variants_parameters(tmp_path, monkeypatch):
    """Editing the function that changes a variant's parameters must make its stored runs
    stale: the source digest covers the package `params` comes from."""
    import importlib
    import sys

    from rsmcheck.orchestration import runs

    pkg = tmp_path / "vpkg_params"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "stiff.py").write_text("def stiffer(p):\n    return p\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    stiff = importlib.import_module("vpkg_params.stiff")
    v = derived(reg.plugin("reference"), "stiffref", "s", LineStyle("#000"), params=stiff.stiffer, differs="d")
    assert v.source_module == "vpkg_params.stiff"
    monkeypatch.setattr(runs, "plugins", lambda: {"reference": reg.plugin("reference"), "stiffref": v})
    before = runs.source_digest()
    (pkg / "stiff.py").write_text("def stiffer(p):\n    return p  # EI + 3 %\n")
    assert runs.source_digest() != before
    sys.modules.pop("vpkg_params.stiff", None)
    sys.modules.pop("vpkg_params", None)


def test_a_variant_takes_its_bases_departures(monkeypatch):
    ref = reg.plugin("reference")
    monkeypatch.setattr(type(ref), "departures", lambda self, c: {"energy": (1e-3, "x")}, raising=False)
    v = derived(ref, "same", "same", LineStyle("#000"))
    assert v.departures(load_case("free_drift")) == {"energy": (1e-3, "x")}
