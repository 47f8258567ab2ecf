"""The one parameter source of rsmcheck.

Tables 1–4 of De Bonis et al. (2021), the beam data that follow from Table 2 (docs/physics.md §2),
and every value the paper leaves open, each with the reason it was chosen.  Every
engine builds its model from a `Params` object and from nothing else.

Units are SI throughout (kg, m, s, rad, N, N·m).  Vectors in the base frame carry the
suffix `_B` (relative to the base COM), in the target frame `_T` (relative to the target
COM).

A `Params` is validated on construction: an unknown key, a wrong type, a non-finite
number or a non-positive mass/length/stiffness raises `InputError` naming the field.
Overrides come as a nested mapping (a case file's `[params]` table):
``Params.from_overrides({"link": {"damping_ratio": 0.0}}, where="cases/x.toml")``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

from rsmcheck.core.errors import InputError

# ---------------------------------------------------------------------------------------
# Sections.  Each field's metadata["why"] is the sentence that justifies an open value;
# metadata["check"] says which validation applies.
# ---------------------------------------------------------------------------------------

POSITIVE = "positive"
NON_NEGATIVE = "non-negative"
ANY = "any"


def _p(default: Any, why: str, check: str = POSITIVE) -> Any:
    return field(default=default, metadata={"why": why, "check": check})


@dataclass(frozen=True)
class RigidBodyParams:
    """A rigid square body (Table 1): base or target."""

    mass: float = _p(300.0, "Table 1.")
    inertia_z: float = _p(200.0, "Table 1, about the COM.")
    side: float = _p(2.0, "Table 1, side of the square.")


@dataclass(frozen=True)
class LinkParams:
    """One of the six identical links (Tables 1, 2): a hollow square Euler–Bernoulli beam."""

    mass: float = _p(36.49, "Table 1.")
    inertia_z: float = _p(7.23, "Table 1, about the link COM.")
    length: float = _p(1.5, "Table 1, pin to pin.")
    f1_pp_hz: float = _p(
        30.16,
        "Table 2, first pinned-pinned frequency; the bending stiffness EI is derived from it "
        "(docs/physics.md §2), every other Table 2 value is then a check.",
    )
    damping_ratio: float = _p(
        0.01,
        "Open in the paper (Fig. 15: vibrations 'dampened very quickly').  Kelvin–Voigt "
        "material damping, stress = EI·(κ + η κ̇), with η chosen so that the first PP mode "
        "has this ratio; higher modes get ζ_j = ζ_1 ω_j/ω_1 (stiffness-proportional).  It is "
        "the one damping law both a modal and a finite-element beam can share exactly.",
        NON_NEGATIVE,
    )
    axial_to_bending: float = _p(
        1.0e5,
        "EA/EI in 1/m² for engines with axial flexibility (Exudyn).  The reference is "
        "axially rigid (EA → ∞), so this is a penalty: the stiffer, the closer to the "
        "reference, until round-off stops Newton.  At 1e4 the coupled arm frequencies of "
        "the two engines differ by up to 1.3e-3, the axial compliance being most of it "
        "(docs/exudyn.md §5.1); 1e5 (first axial mode 2.3–4.6 kHz, damped by the "
        "integrator) cuts that tenfold; 1e6 needs a Newton tolerance of 1e-2 N (the axial "
        "force's round-off EA·ε·|q|/le), which then shows in the momentum.  Below ~1e3 an "
        "axial mode enters the band of interest (docs/exudyn.md).",
    )

    @property
    def rho_a(self) -> float:
        """Mass per unit length ρA = m/L [kg/m] (docs/physics.md §2: 24.327 kg/m)."""
        return self.mass / self.length

    @property
    def ei(self) -> float:
        """Bending stiffness EI [N·m²] from Table 2's PP f1 = (π/L)² sqrt(EI/ρA) / 2π."""
        c = 2.0 * self.f1_pp_hz * self.length**2 / math.pi  # sqrt(EI/ρA) [m²/s]
        return self.rho_a * c * c

    @property
    def kelvin_voigt_eta(self) -> float:
        """η [s] of stress = EI(κ + η κ̇): ζ_1 = η ω_1/2 for the first PP mode."""
        return 2.0 * self.damping_ratio / (2.0 * math.pi * self.f1_pp_hz)

    @property
    def inertia_extra(self) -> float:
        """Rotary inertia beyond the slender beam's mL²/12 [kg·m²] (docs/physics.md §2.3: 0.388).

        Placed on the rotation of the link frame only (docs/physics.md §2.3).
        """
        return self.inertia_z - self.mass * self.length**2 / 12.0


@dataclass(frozen=True)
class MotorParams:
    """Joint gear-motors (Table 4), identical at all six joints."""

    torque_max: float = _p(80.0, "Table 4.")
    inertia: float = _p(0.12, "Table 4, B_m seen from the output shaft.")
    stiffness: float = _p(40000.0, "Table 4, K_m.")
    damping: float = _p(0.002, "Table 4, C_m.", NON_NEGATIVE)


@dataclass(frozen=True)
class BaseActuatorParams:
    """Base actuators (Table 3).  The thrust acts along +x of the base frame through the
    base COM (the paper fixes the direction to the platform but not which axis)."""

    torque_max: float = _p(12.0, "Table 3, momentum-exchange devices.")
    thrust: float = _p(180.0, "Table 3, apogee motor.")
    isp: float = _p(270.0, "Table 3.")
    g0: float = _p(9.80665, "Standard gravity, defines Isp.")


@dataclass(frozen=True)
class OrbitParams:
    """Equatorial circular orbits of Sect. 4.1."""

    mu: float = _p(3.986004418e14, "Earth GM, WGS 84 (docs/physics.md §5).")
    earth_radius: float = _p(6378137.0, "Equatorial radius, WGS 84 (docs/physics.md §5).")
    altitude_initial: float = _p(700.0e3, "Sect. 4.1.")
    altitude_final: float = _p(300.0e3, "Sect. 4.1.")


@dataclass(frozen=True)
class GeometryParams:
    """Where the arms sit on the base and where they hold the target (open in the paper)."""

    mount_arm1_B: tuple[float, float] = _p(
        (1.0, 0.6),
        "Arm 1 root on the base's +x face (the face towards the target), 0.6 m left of the "
        "thrust axis; symmetric to arm 2 so that COM alignment is a question of the target.",
        ANY,
    )
    mount_arm2_B: tuple[float, float] = _p(
        (1.0, -0.6), "Arm 2 root, mirror image of arm 1 about the thrust axis.", ANY
    )
    target_com_offset_T: tuple[float, float] = _p(
        (0.15, 0.10),
        "Target COM relative to its geometric centre (Sect. 4: 'does not coincide').  "
        "5 % and 3 % of the side: the size of an asymmetric payload, and non-zero across the "
        "thrust axis so that the COM alignment of Sect. 5.3 has work to do.",
        ANY,
    )
    grasp1_centre_T: tuple[float, float] = _p(
        (-1.5, 0.6),
        "Designated grasp point of arm 1 relative to the target's geometric centre: on the "
        "face towards the base, 0.6 m off the centre line, opposite arm 1's root.",
        ANY,
    )
    grasp2_centre_T: tuple[float, float] = _p(
        (-1.5, -0.6), "Designated grasp point of arm 2, mirror image of grasp 1.", ANY
    )

    def grasp_T(self, arm: int) -> tuple[float, float]:
        """Grasp point of `arm` (1 or 2) relative to the target COM, target frame [m]."""
        c = self.grasp1_centre_T if arm == 1 else self.grasp2_centre_T
        o = self.target_com_offset_T
        return (c[0] - o[0], c[1] - o[1])

    def mount_B(self, arm: int) -> tuple[float, float]:
        """Root of `arm` (1 or 2) relative to the base COM, base frame [m]."""
        return self.mount_arm1_B if arm == 1 else self.mount_arm2_B


@dataclass(frozen=True)
class WristParams:
    """Revolute wrist with a bistop between the terminal link frame and the target."""

    limit: float = _p(
        0.5,
        "Half-range of the wrist rotation [rad] (≈ 29°): a typical mechanical range of a "
        "grapple fixture, wide enough that manipulation does not touch it, small enough "
        "that the target's free rotation of Fig. 9 reaches it.",
    )
    stiffness: float = _p(
        5000.0,
        "Bistop stiffness [N·m/rad]: with the target's 600 kg·m² the contact frequency is "
        "0.46 Hz, so the stop reverses the target (Fig. 9) without an impulsive spike.",
    )
    damping: float = _p(
        500.0,
        "Damping c of the paper's linear stop, τ = −k δ − c ψ̇ [N·m·s/rad]: ζ = c / (2 sqrt(k J_T)) "
        "= 0.14, a lossy stop.  No engine applies it any more: the damper pulled the target back "
        "during the rebound and switched on with a step c ψ̇ at contact; it sets contact_damping.",
        NON_NEGATIVE,
    )
    contact_damping: float = _p(
        1.2e5,
        "Hunt–Crossley damping λ of the bistop [N·m·s/rad²], τ = −sgn ψ max(0, k δ + λ δ δ̇), "
        "δ = |ψ| − ψ_lim, δ̇ = sgn ψ ψ̇ (docs/physics.md §4.3): the contact's damping λ δ grows "
        "with the penetration from 0 at first touch (no step) and the clamp keeps it from pulling.  "
        "λ = c / δ_max = 500 / 4.19e-3 = 1.19e5: the damping equals the linear stop's c at the "
        "peak penetration δ_max = 4.19e-3 rad that stop reaches in wrist_bistop (both engines), "
        "so the stop loses energy at the same scale (wrist_bistop's contact: 0.036 J, the linear "
        "stop's damper 0.055 J).",
        NON_NEGATIVE,
    )


@dataclass(frozen=True)
class GraspParams:
    """Closed-chain constraint stabilisation (eq. 12) and capture thresholds."""

    baumgarte_alpha: float = _p(
        10.0,
        "α of eq. (12) [1/s].  α = β gives a critically damped residual, φ ∝ (1 + βt)e^(−βt), "
        "time constant 0.1 s, slower than every structural mode (Flores et al. 2011).",
        NON_NEGATIVE,
    )
    baumgarte_beta: float = _p(10.0, "β of eq. (12) [1/s], equal to α.", NON_NEGATIVE)
    capture_distance: float = _p(
        0.002,
        "First IF condition: |end effector − capture point| below this [m].  2 mm: a "
        "grapple fixture's capture envelope is of this order, and the point held is then "
        "within 2 mm of the designated one.",
    )
    capture_speed: float = _p(
        0.002,
        "Second IF condition: relative speed below this [m/s]; the plastic grasp then "
        "dissipates at most ½·m·v² ≈ 1e-3 J.",
    )


@dataclass(frozen=True)
class Params:
    """Everything the engines need to build the model of the paper."""

    base: RigidBodyParams = field(default_factory=RigidBodyParams)
    target: RigidBodyParams = field(
        default_factory=lambda: RigidBodyParams(mass=400.0, inertia_z=600.0, side=3.0)
    )
    link: LinkParams = field(default_factory=LinkParams)
    motor: MotorParams = field(default_factory=MotorParams)
    actuators: BaseActuatorParams = field(default_factory=BaseActuatorParams)
    orbit: OrbitParams = field(default_factory=OrbitParams)
    geometry: GeometryParams = field(default_factory=GeometryParams)
    wrist: WristParams = field(default_factory=WristParams)
    grasp: GraspParams = field(default_factory=GraspParams)

    def __post_init__(self) -> None:
        for section in fields(self):
            _validate_section(getattr(self, section.name), section.name, "<params>")

    # ---- construction from overrides ------------------------------------------------
    @classmethod
    def from_overrides(cls, overrides: Mapping[str, Any] | None, where: str) -> "Params":
        """Defaults with `overrides` (nested mapping) applied; errors name `where`."""
        overrides = overrides or {}
        if not isinstance(overrides, Mapping):
            raise InputError(where, "params", "must be a table")
        default = cls()
        sections: dict[str, Any] = {}
        known = {f.name for f in fields(cls)}
        for name, values in overrides.items():
            if name not in known:
                raise InputError(where, f"params.{name}", f"unknown section (known: {', '.join(sorted(known))})")
            if not isinstance(values, Mapping):
                raise InputError(where, f"params.{name}", "must be a table")
            sections[name] = _override_section(getattr(default, name), values, f"params.{name}", where)
        merged = {f.name: sections.get(f.name, getattr(default, f.name)) for f in fields(cls)}
        return cls(**merged)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def digest(self) -> str:
        """SHA-256 of the canonical JSON of all values (the HDF5 'parameter hash')."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def _override_section(section: Any, values: Mapping[str, Any], prefix: str, where: str) -> Any:
    known = {f.name: f for f in fields(section)}
    changes: dict[str, Any] = {}
    for key, value in values.items():
        if key not in known:
            raise InputError(where, f"{prefix}.{key}", f"unknown key (known: {', '.join(sorted(known))})")
        default = getattr(section, key)
        changes[key] = _coerce(value, default, f"{prefix}.{key}", where)
    new = dataclasses.replace(section, **changes)
    _validate_section(new, prefix.removeprefix("params."), where)
    return new


def _coerce(value: Any, default: Any, name: str, where: str) -> Any:
    if isinstance(default, tuple):
        if not isinstance(value, (list, tuple)) or len(value) != len(default):
            raise InputError(where, name, f"must be a list of {len(default)} numbers")
        return tuple(_coerce(v, default[0], name, where) for v in value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(where, name, f"must be a number, got {type(value).__name__}")
    return float(value)


def _validate_section(section: Any, name: str, where: str) -> None:
    for f in fields(section):
        value = getattr(section, f.name)
        check = f.metadata.get("check", ANY)
        items = value if isinstance(value, tuple) else (value,)
        for v in items:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise InputError(where, f"params.{name}.{f.name}", "must be a number")
            if not math.isfinite(v):
                raise InputError(where, f"params.{name}.{f.name}", f"must be finite, got {v}")
            if check == POSITIVE and v <= 0.0:
                raise InputError(where, f"params.{name}.{f.name}", f"must be positive, got {v}")
            if check == NON_NEGATIVE and v < 0.0:
                raise InputError(where, f"params.{name}.{f.name}", f"must be non-negative, got {v}")
    if isinstance(section, LinkParams) and section.inertia_extra < 0.0:
        raise InputError(
            where,
            f"params.{name}.inertia_z",
            f"{section.inertia_z} kg·m² is below the slender beam's mL²/12 = "
            f"{section.mass * section.length**2 / 12:.4f} kg·m²",
        )


# ---------------------------------------------------------------------------------------
# Table 2 as printed: the values the analytic and numerical link modes are checked against.
# ---------------------------------------------------------------------------------------
TABLE2_HZ = {"PP": (30.16, 120.64), "PF": (47.12, 152.68)}
