"""The plug-in registry (rsmcheck.core.plugins): what it finds through the entry points,
the order, the default engines as one setting, and the one-line errors for a plug-in that
is incomplete, misnamed or unknown."""

from __future__ import annotations

from importlib import metadata

import pytest

from rsmcheck.core import plugins as reg
from rsmcheck.core.cases import load_case
from rsmcheck.core.errors import InputError


@pytest.fixture
def fresh_registry():
    """The registry read again (it is cached per process), and again after the test."""
    reg.plugins.cache_clear()
    yield
    reg.plugins.cache_clear()


def test_the_in_tree_plug_ins_are_registered_through_the_entry_points():
    names = [ep.name for ep in metadata.entry_points(group=reg.GROUP)]
    assert {"reference", "exudyn", "pinocchio"} <= set(names)
    found = reg.plugins()
    # the engines that simulate first, the default engines in their order, checkers last
    assert list(found)[:2] == ["reference", "exudyn"] and list(found)[-1] == "pinocchio"
    assert reg.simulators()[:2] == ("reference", "exudyn") and "pinocchio" not in reg.simulators()
    assert reg.with_capability("rigid_checks") == ("pinocchio",)
    for p in found.values():
        assert all(hasattr(p, a) for a in reg.REQUIRED), p.name


def test_the_default_engines_are_one_setting(monkeypatch):
    monkeypatch.delenv(reg.ENGINES_ENV, raising=False)
    assert reg.default_engines() == ("reference", "exudyn")
    monkeypatch.setenv(reg.ENGINES_ENV, "exudyn, reference")
    assert reg.default_engines() == ("exudyn", "reference")
    monkeypatch.setenv(reg.ENGINES_ENV, "reference")
    with pytest.raises(InputError, match="needs two engines"):
        reg.default_engines()
    monkeypatch.setenv(reg.ENGINES_ENV, "reference,warp")
    with pytest.raises(InputError, match="no such engine 'warp'"):
        reg.default_engines()


def test_engine_names_from_the_command_line():
    assert reg.engine_names("reference") == ["reference"]
    assert reg.engine_names("all")[:2] == ["reference", "exudyn"]
    with pytest.raises(InputError, match="registered: reference, exudyn"):
        reg.engine_names("warp")
    with pytest.raises(InputError, match="checks but does not simulate"):
        reg.engine_names("reference,pinocchio")
    with pytest.raises(InputError, match="twice"):
        reg.engine_names("reference,reference")


class _Distribution:
    def __init__(self, name, version):
        self.name, self.version = name, version


class _EntryPoint:
    """An entry point as importlib.metadata gives it: a name, a value, `load()`, `dist`."""

    def __init__(self, name, obj, dist=("fakedist", "0.1")):
        self.name, self.value, self._obj = name, f"fake.module:{name}", obj
        self.dist = _Distribution(*dist)

    def load(self):
        if isinstance(self._obj, BaseException):
            raise self._obj
        return self._obj


def _complete(name):
    """A plug-in object with every required attribute (values borrowed from the reference)."""
    ref = reg.plugins()["reference"]
    obj = type("Fake", (), {a: getattr(ref, a) for a in reg.REQUIRED})()
    obj.name = name
    obj.tables = ()
    obj.solver_keys = ()
    return obj


def _real_plus(monkeypatch, *extra):
    """The real entry points and `extra` ones after them."""
    real = list(metadata.entry_points(group=reg.GROUP))
    monkeypatch.setattr(reg.metadata, "entry_points", lambda group: real + list(extra))
    reg.plugins.cache_clear()


def test_an_incomplete_misnamed_or_failing_plug_in_is_left_out_and_named(monkeypatch, fresh_registry):
    """Whatever goes wrong with a plug-in (an import that raises anything, an attribute
    missing, another name), the registry leaves it out with the distribution that brought
    it and why; the others stay usable, and asking for it is one line naming both."""
    incomplete, misnamed = _complete("half"), _complete("other")
    del type(incomplete).step_perturbed, type(incomplete).faults
    _real_plus(monkeypatch, _EntryPoint("half", incomplete), _EntryPoint("alias", misnamed),
               _EntryPoint("boom", RuntimeError("no licence server"), dist=("boomdist", "2.3")))
    assert list(reg.plugins())[:2] == ["reference", "exudyn"]
    assert not {"half", "alias", "boom"} & set(reg.plugins())
    broken = reg.broken_plugins()
    assert "lacks step_perturbed, faults" in broken["half"].reason
    assert "calls itself 'other'" in broken["alias"].reason
    assert broken["boom"].distribution == "boomdist 2.3"
    assert "RuntimeError: no licence server" in broken["boom"].reason
    with pytest.raises(InputError) as info:
        reg.plugin("boom")
    assert str(info.value) == ("--engines: boom: engine plug-in 'boom' from boomdist 2.3 does not load: "
                               "fake.module:boom does not import (RuntimeError: no licence server)")
    with pytest.raises(InputError, match="boomdist 2.3"):
        reg.engine_names("reference,boom")


def test_two_distributions_registering_one_name_are_refused_naming_both(monkeypatch, fresh_registry):
    clash = _complete("reference")
    _real_plus(monkeypatch, _EntryPoint("reference", clash, dist=("clashref", "0.1")))
    with pytest.raises(InputError) as info:
        reg.plugins()
    msg = str(info.value)
    assert msg.startswith(f"entry point {reg.GROUP}: reference: registered by rsmcheck ")
    assert "and by clashref 0.1" in msg and msg.endswith("keep one: pip uninstall clashref")


def test_two_plug_ins_cannot_own_one_table(monkeypatch, fresh_registry):
    a, b = _complete("a"), _complete("b")
    a.tables = b.tables = ("shared",)
    monkeypatch.setattr(reg.metadata, "entry_points", lambda group: [_EntryPoint("a", a), _EntryPoint("b", b)])
    reg.plugins.cache_clear()  # _complete read the real registry
    with pytest.raises(InputError, match=r"table \[shared\] is owned by a too"):
        reg.owned_tables()


def test_each_engine_reads_its_own_settings_and_perturbs_its_own_tolerance():
    case = load_case("p4_hohmann")
    ref, exu = reg.settings_of(case, "reference"), reg.settings_of(case, "exudyn")
    assert ref.rtol == 1e-7 and ref.quiet_integrator is None  # [solver] rtol; no [reference] table
    flex = reg.settings_of(load_case("motor_step"), "reference")
    assert flex.n_modes == (4,) * 6 and flex.static_modes == "explicit"  # its [reference] table
    assert exu.newton_atol == 1e-4 and exu.newton_atol_scale is None  # [exudyn]
    stepped = reg.step_perturbed_settings(case.engine_settings, 1.001)
    assert stepped["reference"].rtol == pytest.approx(1.001e-7, rel=1e-15)
    assert stepped["exudyn"].newton_atol_scale == pytest.approx(1.001, rel=1e-15)
    assert stepped["exudyn"].newton_atol == exu.newton_atol  # the scale, not the setting


def test_each_engine_declares_its_finer_run_for_the_budget():
    """`refined_options` (rsmcheck budget): the reference's rtol exactly a tenth of the
    case's, of the variant run (p4 short: 1e-7), and its step at most half the control
    period (1 ms: 0.5 ms), so that a run at one step per sample is refined too; Exudyn's
    substeps twice the case's
    (motor_step: 128 → 256) or twice the engine's default where the case gives none
    (free_drift); a plug-in without it (Pinocchio) is None."""
    p4, motor, drift = load_case("p4_hohmann").variant(True), load_case("motor_step"), load_case("free_drift")
    assert reg.refined_options("reference", p4) == {"rtol": reg.settings_of(p4, "reference").rtol / 10,
                                                    "h_max": 0.5e-3}
    assert reg.refined_options("reference", motor)["rtol"] == 1e-9 / 10
    assert reg.refined_options("exudyn", motor) == {"substeps": 2 * reg.settings_of(motor, "exudyn").substeps} \
        == {"substeps": 256}
    assert reg.settings_of(drift, "exudyn").substeps is None
    assert reg.refined_options("exudyn", drift) == {"substeps": 2 * reg.plugin("exudyn").option_default("substeps")}
    assert reg.refined_options("pinocchio", motor) is None
    assert set(reg.with_capability("refined_options")) >= {"reference", "exudyn"}
    for name in ("reference", "exudyn"):
        assert isinstance(reg.plugin(name).refinement, str) and reg.plugin(name).refinement


def test_a_finer_run_with_options_the_engine_does_not_take_is_refused(monkeypatch):
    """A plug-in whose refined_options name an option outside its engine_options (or none):
    one line naming the plug-in, not a run that fails in a worker."""
    ref = reg.plugin("reference")
    case = load_case("motor_step")
    monkeypatch.setattr(type(ref), "refined_options", lambda self, c: {"tolerance": 1e-10}, raising=False)
    with pytest.raises(InputError, match="plug-in reference: refined_options: options tolerance are not among"):
        reg.refined_options("reference", case)
    monkeypatch.setattr(type(ref), "refined_options", lambda self, c: {}, raising=False)
    with pytest.raises(InputError, match="gives no option"):
        reg.refined_options("reference", case)


def test_a_broken_plug_in_stops_only_the_commands_that_name_it(monkeypatch, fresh_registry, capsys):
    """`--help`, `cases` and `engines` run beside a plug-in whose import raises; the first
    two say in one line that it is ignored, `engines` lists it as broken with its
    distribution; a command that names it is one line, exit 2, no traceback."""
    from rsmcheck.cli import main

    _real_plus(monkeypatch, _EntryPoint("boom", RuntimeError("no licence server"), dist=("boomdist", "2.3")))
    line = ("rsmcheck: ignoring engine plug-in 'boom' from boomdist 2.3 does not load: "
            "fake.module:boom does not import (RuntimeError: no licence server)\n")
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0 and capsys.readouterr().err == line
    assert main(["cases"]) == 0
    out = capsys.readouterr()
    assert out.err == line and "free_drift" in out.out
    assert main(["engines"]) == 0
    out = capsys.readouterr()
    assert out.err == "" and "reference" in out.out
    assert [s for s in out.out.splitlines() if s.startswith("boom")] == [
        f"{'boom':12s} {'-':12s} {'-':9s} {'':19s} {'boomdist 2.3':26s} BROKEN: "
        "fake.module:boom does not import (RuntimeError: no licence server)"]
    assert main(["run", "free_drift", "--short", "--engines", "boom"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and "Traceback" not in err
    assert err.endswith("rsmcheck: --engines: boom: engine plug-in 'boom' from boomdist 2.3 does not load: "
                        "fake.module:boom does not import (RuntimeError: no licence server)\n")


def test_a_name_clash_stops_every_command_in_one_line(monkeypatch, fresh_registry, capsys):
    from rsmcheck.cli import main

    _real_plus(monkeypatch, _EntryPoint("reference", _complete("reference"), dist=("clashref", "0.1")))
    assert main(["cases"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "registered by rsmcheck" in err and "pip uninstall clashref" in err


def test_departures_are_read_from_the_plug_in_and_a_malformed_one_is_one_line(monkeypatch):
    """`departures(case)`: observable → (size ≥ 0, why), an allowance for the engine's own
    listed departures (rsmcheck.core.tolerances); none declared is {}; an engine not
    installed is {} (runs read from a file); a size without a reason is an InputError."""
    ref = reg.plugin("reference")
    case = load_case("motor_step")
    assert reg.departure_allowances("reference", case) == {}
    assert reg.departure_allowances("not_installed", case) == {}
    monkeypatch.setattr(type(ref), "departures", lambda self, c: {"motor_angles": (1e-6, "measured softness")},
                        raising=False)
    assert reg.departure_allowances("reference", case) == {"motor_angles": (1e-6, "measured softness")}
    for bad in ({"motor_angles": 1e-6}, {"motor_angles": (-1.0, "x")}, {"motor_angles": (1e-6, "")},
                {"motor_angle": (1e-6, "misspelt")}):
        monkeypatch.setattr(type(ref), "departures", lambda self, c, bad=bad: bad, raising=False)
        with pytest.raises(InputError, match="plug-in reference: departures.motor_angle"):
            reg.departure_allowances("reference", case)

    def raises(self, c):
        raise RuntimeError("no table")

    for bad in (raises, lambda self, c: [("motor_angles", 1e-6)]):
        monkeypatch.setattr(type(ref), "departures", bad, raising=False)
        with pytest.raises(InputError, match="plug-in reference: departures: (raised RuntimeError|must return)"):
            reg.departure_allowances("reference", case)
