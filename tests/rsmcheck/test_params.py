"""The one parameter source: the paper's tables, the derived beam data, the open values
with their reasons, and `Params.from_overrides` refusing every kind of bad input with an
`InputError` that names the source and the field."""

from __future__ import annotations

import dataclasses
import math

import pytest

from rsmcheck.core.errors import InputError
from rsmcheck.core.params import TABLE2_HZ, Params

WHERE = "cases/some_case.toml"


def test_paper_tables():
    p = Params()
    assert (p.base.mass, p.base.inertia_z, p.base.side) == (300.0, 200.0, 2.0)  # Table 1
    assert (p.target.mass, p.target.inertia_z, p.target.side) == (400.0, 600.0, 3.0)
    assert (p.link.mass, p.link.inertia_z, p.link.length) == (36.49, 7.23, 1.5)
    assert TABLE2_HZ == {"PP": (30.16, 120.64), "PF": (47.12, 152.68)}  # Table 2
    assert p.link.f1_pp_hz == 30.16
    assert (p.actuators.torque_max, p.actuators.thrust, p.actuators.isp) == (12.0, 180.0, 270.0)  # Table 3
    m = p.motor  # Table 4
    assert (m.torque_max, m.inertia, m.stiffness, m.damping) == (80.0, 0.12, 40000.0, 0.002)
    assert p.orbit.mu == 3.986004418e14 and p.orbit.earth_radius == 6378137.0
    assert (p.orbit.altitude_initial, p.orbit.altitude_final) == (700e3, 300e3)


def test_derived_beam_data():
    lk = Params().link
    assert lk.rho_a == pytest.approx(36.49 / 1.5, rel=1e-15)
    # PP f1 = (π/L)² sqrt(EI/ρA) / 2π reproduces the Table 2 value it was derived from
    f1 = (math.pi / lk.length) ** 2 * math.sqrt(lk.ei / lk.rho_a) / (2 * math.pi)
    assert f1 == pytest.approx(30.16, rel=1e-14)
    # Kelvin–Voigt η = 2ζ/ω1 (docs/physics.md §2.2: 1.0554e-4 s at ζ = 1 %)
    assert lk.kelvin_voigt_eta == pytest.approx(2 * 0.01 / (2 * math.pi * 30.16), rel=1e-14)
    assert abs(lk.kelvin_voigt_eta - 1.0554e-4) <= 0.5e-8
    assert lk.inertia_extra == pytest.approx(7.23 - 36.49 * 1.5**2 / 12, rel=1e-14)


def test_geometry_helpers():
    g = Params().geometry
    c1, o = g.grasp1_centre_T, g.target_com_offset_T
    assert g.grasp_T(1) == (c1[0] - o[0], c1[1] - o[1])
    assert g.mount_B(1) == g.mount_arm1_B and g.mount_B(2) == g.mount_arm2_B
    assert o != (0.0, 0.0)  # docs/cases.md §2: the target COM is offset from the centre


def test_every_value_has_its_reason():
    """docs/physics.md (introduction): each value is set once, in the parameter source, with a
    sentence on why."""
    p = Params()
    for section in dataclasses.fields(p):
        for f in dataclasses.fields(getattr(p, section.name)):
            why = f.metadata.get("why", "")
            assert why.strip().endswith("."), f"{section.name}.{f.name} has no reason"


def test_overrides_apply_and_keep_the_rest():
    p = Params.from_overrides({"link": {"damping_ratio": 0, "mass": 37}, "motor": {"damping": 0.0},
                               "geometry": {"mount_arm1_B": [1.0, 0.5]}}, WHERE)
    d = Params()
    assert p.link.damping_ratio == 0.0 and isinstance(p.link.damping_ratio, float)
    assert p.link.mass == 37.0 and isinstance(p.link.mass, float)
    assert p.link.length == d.link.length and p.base == d.base and p.target == d.target
    assert p.motor.damping == 0.0 and p.motor.stiffness == d.motor.stiffness
    assert p.geometry.mount_arm1_B == (1.0, 0.5)
    assert Params.from_overrides(None, WHERE) == d
    assert Params.from_overrides({}, WHERE) == d


def test_digest_identifies_the_values():
    a = Params()
    assert a.digest() == Params().digest() and len(a.digest()) == 64
    b = Params.from_overrides({"wrist": {"limit": 0.6}}, WHERE)
    assert b.digest() != a.digest()
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.link.mass = 1.0  # type: ignore[misc]


BAD_OVERRIDES = [
    ("unknown_section", {"gearbox": {"ratio": 100.0}}, "params.gearbox"),
    ("unknown_key", {"link": {"colour": 1.0}}, "params.link.colour"),
    ("section_not_table", {"link": 3.0}, "params.link"),
    ("string_value", {"base": {"mass": "heavy"}}, "params.base.mass"),
    ("bool_value", {"motor": {"stiffness": True}}, "params.motor.stiffness"),
    ("list_for_scalar", {"motor": {"inertia": [0.1, 0.2]}}, "params.motor.inertia"),
    ("scalar_for_pair", {"geometry": {"mount_arm1_B": 1.0}}, "params.geometry.mount_arm1_B"),
    ("pair_wrong_length", {"geometry": {"grasp2_centre_T": [1.0, 2.0, 3.0]}}, "params.geometry.grasp2_centre_T"),
    ("string_in_pair", {"geometry": {"target_com_offset_T": [0.1, "x"]}}, "params.geometry.target_com_offset_T"),
    ("negative_mass", {"base": {"mass": -300.0}}, "params.base.mass"),
    ("zero_mass", {"target": {"mass": 0.0}}, "params.target.mass"),
    ("negative_stiffness", {"motor": {"stiffness": -1.0}}, "params.motor.stiffness"),
    ("negative_damping_ratio", {"link": {"damping_ratio": -0.01}}, "params.link.damping_ratio"),
    ("negative_baumgarte", {"grasp": {"baumgarte_alpha": -1.0}}, "params.grasp.baumgarte_alpha"),
    ("nan", {"link": {"f1_pp_hz": float("nan")}}, "params.link.f1_pp_hz"),
    ("inf", {"orbit": {"mu": float("inf")}}, "params.orbit.mu"),
    ("minus_inf", {"wrist": {"limit": float("-inf")}}, "params.wrist.limit"),
    ("nan_in_pair", {"geometry": {"mount_arm2_B": [1.0, float("nan")]}}, "params.geometry.mount_arm2_B"),
    ("inertia_below_slender_beam", {"link": {"inertia_z": 6.0}}, "params.link.inertia_z"),
    ("mass_makes_inertia_inconsistent", {"link": {"mass": 50.0}}, "params.link.inertia_z"),
]


@pytest.mark.parametrize("overrides, field", [(o, f) for _, o, f in BAD_OVERRIDES],
                         ids=[i for i, _, _ in BAD_OVERRIDES])
def test_bad_override_names_source_and_field(overrides, field):
    with pytest.raises(InputError) as info:
        Params.from_overrides(overrides, WHERE)
    err = info.value
    assert err.where == WHERE
    assert err.field == field, (err.field, field)
    assert str(err).startswith(f"{WHERE}: {field}: ") and "\n" not in str(err)
    assert err.reason.strip()


def test_overrides_must_be_a_table():
    with pytest.raises(InputError) as info:
        Params.from_overrides([("link", {})], WHERE)  # type: ignore[arg-type]
    assert info.value.where == WHERE and info.value.field == "params"


def test_direct_construction_is_validated_too():
    from rsmcheck.core.params import LinkParams, RigidBodyParams

    with pytest.raises(InputError) as info:
        Params(base=RigidBodyParams(mass=-1.0))
    assert info.value.field == "params.base.mass"
    with pytest.raises(InputError):
        Params(link=LinkParams(length=float("nan")))
