"""The ``trainsim/train`` document: vehicles, traction, braking, running resistance, electrical data
(docs/FORMAT.md, "Train")."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import Discriminator, Field, Tag, model_validator

from trainsim.constants import GRAVITY_RANGE_MPS2, KMH, KN, KW, TONNE
from trainsim.errors import InputError
from trainsim.io.spec import (
    _UNION_FIELDS,
    Fraction,
    NonNegative,
    Positive,
    Spec,
    _check_increasing,
    _located,
    _validate,
    fail,
)
from trainsim.model import (
    Braking,
    EffortCurve,
    Electrical,
    Quadratic,
    ResistanceTerm,
    Train,
    Vehicle,
)
from trainsim.physics import resistance as res

if TYPE_CHECKING:  # trainsim.optimize is imported where a driving block is read, not by every reader
    pass


# ====================================================================== force tables
class _ForceTable(Spec):
    """A table of speeds [km/h] and forces [kN or N], interpolated linearly (source 002 eq. 1, 8)."""

    speed_kmh: list[float] = Field(min_length=1)
    force_kn: list[float] | None = None
    force_n: list[float] | None = None

    signed: ClassVar[bool] = False  # braking tables may be written negative (source 002)

    @model_validator(mode="after")
    def _check_table(self) -> _ForceTable:
        if (self.force_kn is None) == (self.force_n is None):
            fail("give the forces as exactly one of 'force_kn' or 'force_n'", field="force_kn")
        forces = self.forces_n_signed()
        name = "force_kn" if self.force_kn is not None else "force_n"
        if len(forces) != len(self.speed_kmh):
            fail(
                f"'speed_kmh' has {len(self.speed_kmh)} values but '{name}' has {len(forces)}",
                field=name,
                allowed="as many forces as speeds",
            )
        if self.speed_kmh[0] < 0:
            fail("speeds must be >= 0", field="speed_kmh[0]", value=self.speed_kmh[0], allowed=">= 0")
        _check_increasing(self.speed_kmh, "speed_kmh", what="table speeds")
        if self.signed:
            if any(f > 0 for f in forces) and any(f < 0 for f in forces):
                fail(
                    "braking forces must all have the same sign (positive magnitudes, or all negative "
                    "as in source 002)",
                    field=name,
                    value=[self._shown(f) for f in forces],
                )
        else:
            for i, f in enumerate(forces):
                if f < 0:
                    fail("forces must be >= 0", field=f"{name}[{i}]", value=self._shown(f), allowed=">= 0")
        return self

    def _shown(self, force_n: float) -> float:
        return force_n / KN if self.force_kn is not None else force_n

    def forces_n_signed(self) -> list[float]:
        """Forces as written, in N."""
        if self.force_kn is not None:
            return [f * KN for f in self.force_kn]
        return list(self.force_n or [])

    def curve(self, label: str) -> EffortCurve:
        """The table as an effort curve [N over m/s]; braking forces as magnitudes."""
        return EffortCurve.from_table(
            np.asarray(self.speed_kmh) * KMH, np.abs(self.forces_n_signed()), label=label
        )


# ====================================================================== traction
class _Caps(Spec):
    max_force_kn: Positive | None = None
    max_power_kw: Positive | None = None

    def _capped(self, curve: EffortCurve) -> EffortCurve:
        return curve.capped(
            force_cap_n=self.max_force_kn * KN if self.max_force_kn is not None else None,
            power_cap_w=self.max_power_kw * KW if self.max_power_kw is not None else None,
        )


class TableTraction(_ForceTable, _Caps):
    """``model: table``: maximum tractive effort by speed; ``per_motor`` tables times ``motors``
    (source 002 eq. 2: W_x = n_m w_x)."""

    model: Literal["table"]
    per_motor: bool = False
    motors: int | None = Field(default=None, ge=1)

    @model_validator(mode="after")
    def _check_motors(self) -> TableTraction:
        if self.per_motor and self.motors is None:
            fail("a per-motor table needs 'motors' (the number of motors or motor cars)", field="motors")
        if not self.per_motor and self.motors is not None:
            fail("'motors' only applies with 'per_motor: true'", field="motors", value=self.motors)
        return self

    def build(self, train: TrainSpec) -> EffortCurve:
        curve = self.curve("traction table")
        if self.per_motor:
            curve = curve.scaled(float(self.motors or 1), label=f"{self.motors} x traction table per motor")
        return self._capped(curve)


class PiecewiseInterval(Spec):
    """One interval of a piecewise law from ``from_kmh`` to the next interval's start (source 000):
    ``F = c0 + c1 V + c2 V^2 + ch / v`` with V in km/h and F in kN; ``ch_kw`` is the constant power
    P of a hyperbolic law ``F = P / v``."""

    from_kmh: float = Field(ge=0)
    c0_kn: float = 0.0
    c1_kn_per_kmh: float = 0.0
    c2_kn_per_kmh2: float = 0.0
    ch_kw: float = 0.0

    def row(self) -> tuple[float, float, float, float]:
        # V [km/h] = v [m/s] / KMH: the linear term scales by 1/KMH, the quadratic one by 1/KMH^2.
        return (
            self.c0_kn * KN,
            self.c1_kn_per_kmh * KN / KMH,
            self.c2_kn_per_kmh2 * KN / KMH**2,
            self.ch_kw * KW,
        )


class PiecewiseTraction(_Caps):
    """``model: piecewise``: quadratic or hyperbolic law per speed interval (source 000)."""

    model: Literal["piecewise"]
    intervals: list[PiecewiseInterval] = Field(min_length=1)

    @model_validator(mode="after")
    def _check_intervals(self) -> PiecewiseTraction:
        if self.intervals[0].from_kmh != 0:
            fail(
                "the first interval must start at 0 km/h",
                field="intervals[0].from_kmh",
                value=self.intervals[0].from_kmh,
                allowed="0",
            )
        starts = [i.from_kmh for i in self.intervals]
        for i in range(1, len(starts)):
            if starts[i] <= starts[i - 1]:
                fail(
                    "interval starts must increase strictly",
                    field=f"intervals[{i}].from_kmh",
                    value=starts[i],
                    allowed=f"> {starts[i - 1]:g}",
                )
        if self.intervals[0].ch_kw != 0 and self.max_force_kn is None:
            fail(
                "a hyperbolic law (ch_kw) from 0 km/h is infinite at standstill: give 'max_force_kn' "
                "(e.g. the adhesion limit) or start it at a speed above 0",
                field="max_force_kn",
            )
        return self

    def build(self, train: TrainSpec) -> EffortCurve:
        curve = EffortCurve.piecewise(
            np.array([i.from_kmh * KMH for i in self.intervals]),
            np.array([i.row() for i in self.intervals]),
            force_cap_n=self.max_force_kn * KN if self.max_force_kn is not None else float("inf"),
            label="piecewise traction law",
        )
        return self._capped(curve)


class PowerLimitedTraction(Spec):
    """``model: power_limited``: ``F = min(F_cap, eta P / v)`` (source 001: P_available = eta P_nom).

    The force cap is ``max_force_kn`` and/or the adhesion limit ``mu m_adh g`` (the smaller if both).
    ``efficiency`` is nominal power -> wheel, not the line-to-wheel efficiency of ``electrical``.
    """

    model: Literal["power_limited"]
    power_kw: Positive
    efficiency: Fraction
    max_force_kn: Positive | None = None
    adhesion_coefficient: Annotated[float, Field(gt=0, le=0.6)] | None = None
    adhesion_mass_t: Positive | None = None

    @model_validator(mode="after")
    def _check_cap(self) -> PowerLimitedTraction:
        if self.max_force_kn is None and self.adhesion_coefficient is None:
            fail(
                "power-limited traction needs a force limit at low speed: 'max_force_kn' and/or "
                "'adhesion_coefficient'",
                field="max_force_kn",
            )
        if self.adhesion_mass_t is not None and self.adhesion_coefficient is None:
            fail("'adhesion_mass_t' needs 'adhesion_coefficient'", field="adhesion_mass_t")
        return self

    def build(self, train: TrainSpec) -> EffortCurve:
        cap = math.inf
        if self.max_force_kn is not None:
            cap = self.max_force_kn * KN
        adhesion_kg = math.inf
        if self.adhesion_coefficient is not None:
            mass_kg = (
                self.adhesion_mass_t * TONNE if self.adhesion_mass_t is not None else train.adhesion_mass_kg()
            )
            if mass_kg is None:
                raise InputError(
                    "the adhesion limit needs the mass on driven axles: give 'adhesion_mass_t', or mark the "
                    "driving vehicles 'powered: true', or give the train's 'adhesion_mass_t'",
                    field="traction.adhesion_mass_t",
                )
            adhesion_kg = self.adhesion_coefficient * mass_kg
        # the law's constant bounds the force at the largest g a route may have; the adhesion limit
        # mu m_adh g itself is applied with the route's gravity when the run starts
        law_cap = min(cap, adhesion_kg * GRAVITY_RANGE_MPS2[1])
        curve = EffortCurve.power_limited(
            self.power_kw * KW, law_cap, self.efficiency, label=f"{self.power_kw:g} kW power-limited"
        )
        return dataclasses.replace(curve, force_cap_n=cap, adhesion_limit_kg=adhesion_kg)


TractionSpec = Annotated[
    TableTraction | PiecewiseTraction | PowerLimitedTraction,
    Field(discriminator="model"),
]


# ====================================================================== braking
class RegenerativeFraction(Spec):
    """``model: fraction_of_traction``: regenerative force = fraction x maximum traction
    (source 004: f_ru = 0.8 f_u(V))."""

    model: Literal["fraction_of_traction"]
    fraction: Fraction
    max_power_kw: Positive | None = None

    def build(self, traction: EffortCurve) -> EffortCurve:
        curve = traction.scaled(self.fraction, label=f"{self.fraction:g} x traction (regenerative)")
        return curve.capped(power_cap_w=self.max_power_kw * KW) if self.max_power_kw else curve


class RegenerativeTable(_ForceTable):
    """``model: table``: maximum regenerative braking force by speed (magnitudes; signs ignored)."""

    model: Literal["table"]
    max_power_kw: Positive | None = None
    signed: ClassVar[bool] = True

    def build(self, traction: EffortCurve) -> EffortCurve:
        curve = self.curve("regenerative braking table")
        return curve.capped(power_cap_w=self.max_power_kw * KW) if self.max_power_kw else curve


def _regen_tag(value: Any) -> str | None:
    if value is None or value == "none":
        return "none"
    if isinstance(value, dict):
        return value.get("model")
    return None


RegenerativeSpec = Annotated[
    Annotated[Literal["none"], Tag("none")]
    | Annotated[RegenerativeFraction, Tag("fraction_of_traction")]
    | Annotated[RegenerativeTable, Tag("table")],
    Discriminator(_regen_tag),
]


class _BrakingBase(Spec):
    regenerative: RegenerativeSpec | None = None

    def _regen(self, traction: EffortCurve) -> EffortCurve | None:
        if self.regenerative is None or self.regenerative == "none":
            return None
        return self.regenerative.build(traction)


class TableBraking(_ForceTable, _BrakingBase):
    """``model: table`` (``table_is`` required) or ``model: fraction_of_full`` (a table of the full
    braking force). Service force = ``service_fraction`` x table; ``service_fraction`` defaults to
    0.75 for a full-braking table (source 000: service braking is 0.75 x full braking, the rest is
    kept for emergencies) and to 1.0 for a service table. Negative forces (source 002 table 4) are
    read as magnitudes."""

    model: Literal["table", "fraction_of_full"]
    table_is: Literal["service", "full"] | None = None
    service_fraction: Fraction | None = None
    signed: ClassVar[bool] = True

    @model_validator(mode="after")
    def _check_kind(self) -> TableBraking:
        if self.model == "table" and self.table_is is None:
            fail(
                "say what the braking table is: 'table_is: service' (the force the train brakes with) or "
                "'table_is: full' (full/emergency force; service = 0.75 x full unless 'service_fraction')",
                field="table_is",
                allowed="service, full",
            )
        if self.model == "fraction_of_full" and self.table_is == "service":
            fail(
                "'fraction_of_full' scales a table of the full braking force",
                field="table_is",
                value=self.table_is,
                allowed="full",
            )
        return self

    @property
    def is_full(self) -> bool:
        return self.model == "fraction_of_full" or self.table_is == "full"

    @property
    def fraction(self) -> float:
        if self.service_fraction is not None:
            return self.service_fraction
        return 0.75 if self.is_full else 1.0

    def build(self, traction: EffortCurve) -> Braking:
        table = self.curve("braking table")
        if self.is_full:
            service = table.scaled(self.fraction, label=f"{self.fraction:g} x full braking table")
            return Braking(service_force=service, full_force=table, regenerative=self._regen(traction))
        service = table if self.fraction == 1.0 else table.scaled(self.fraction)
        return Braking(service_force=service, regenerative=self._regen(traction))


class DecelerationBraking(_BrakingBase):
    """``model: deceleration``: constant service deceleration [m/s^2], whatever resistance and grade
    (TrainRuns.jl convention); the sign is ignored because sources write it negative."""

    model: Literal["deceleration"]
    deceleration_mps2: float

    @model_validator(mode="after")
    def _check_value(self) -> DecelerationBraking:
        if not 0 < abs(self.deceleration_mps2) <= 5:
            fail(
                "the deceleration must be non-zero and realistic",
                field="deceleration_mps2",
                value=self.deceleration_mps2,
                allowed="0 < |a| <= 5 m/s^2",
            )
        return self

    def build(self, traction: EffortCurve) -> Braking:
        return Braking(deceleration_mps2=abs(self.deceleration_mps2), regenerative=self._regen(traction))


BrakingSpec = Annotated[TableBraking | DecelerationBraking, Field(discriminator="model")]


# ====================================================================== resistance
class _Term(Spec):
    """A running-resistance term; ``applies_to`` is ``train`` or the name of a vehicle of the
    formation (the term is then evaluated with that vehicle's mass, empty + load, and multiplied by
    its count)."""

    applies_to: str | None = None

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        raise NotImplementedError

    @staticmethod
    def _axles(own: int | None, fallback: int | None, family: str) -> int:
        axles = own if own is not None else fallback
        if axles is None:
            raise InputError(
                f"'{family}' needs the number of axles: give 'axles' in the term or in the vehicle",
                field="axles",
            )
        return axles


class DavisTerm(_Term):
    """``R = A + B v + C v^2`` in SI (N, v in m/s) (Davis 1926; source 002 eq. 4)."""

    family: Literal["davis"]
    a_n: NonNegative
    b_n_s_per_m: float
    c_n_s2_per_m2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.davis(self.a_n, self.b_n_s_per_m, self.c_n_s2_per_m2)


class DavisKnKmhTerm(_Term):
    """``R = A + B V + C V^2`` in kN with V in km/h (source 002 table 2 reading)."""

    family: Literal["davis_kn_kmh"]
    a_kn: NonNegative
    b_kn_per_kmh: float
    c_kn_per_kmh2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.davis_kn_kmh(self.a_kn, self.b_kn_per_kmh, self.c_kn_per_kmh2)


class PerMassTerm(_Term):
    """``R_b = m (a1 + a2 v^2)`` (source 000), a1 [N/kg], a2 [N s^2/(kg m^2)], v in m/s."""

    family: Literal["per_mass"]
    a1_n_per_kg: NonNegative
    a2_n_s2_per_kg_m2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.per_mass(mass_kg, self.a1_n_per_kg, self.a2_n_s2_per_kg_m2)


class SpecificTerm(_Term):
    """``w = a + b V + c V^2`` [N/kN] with V in km/h, force ``w m g / 1000`` (TB/T 1407, PTR)."""

    family: Literal["specific_n_per_kn"]
    a_n_per_kn: NonNegative
    b_n_per_kn_per_kmh: float
    c_n_per_kn_per_kmh2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.specific_n_per_kn(
            mass_kg, self.a_n_per_kn, self.b_n_per_kn_per_kmh, self.c_n_per_kn_per_kmh2
        )


class RavTerm(_Term):
    """French ``RAV = A + B V + C V^2`` in N with V in km/h (source 001)."""

    family: Literal["rav"]
    a_n: NonNegative
    b_n_per_kmh: float
    c_n_per_kmh2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.rav(self.a_n, self.b_n_per_kmh, self.c_n_per_kmh2)


class RavLocomotiveTerm(_Term):
    """BB 60000 locomotive RAV ``6.5 M + 130 N_e + 0.1 M V + 0.3 V^2`` (source 001)."""

    family: Literal["rav_locomotive_bb60000"]
    axles: int | None = Field(default=None, ge=1)

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.rav_locomotive_bb60000(mass_kg, self._axles(self.axles, axles, self.family))


class RavCarriageTerm(_Term):
    """Standard 4-axle carriage RAV ``12 M + 0.09 M V + 0.0044 M V^2`` (source 001)."""

    family: Literal["rav_carriage_4axle"]

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.rav_carriage_4axle(mass_kg)


class StrahlTerm(_Term):
    """Strahl (freight wagons): ``m g (f0 + f2 (v/v00)^2) / 1000`` (Wende 2003)."""

    family: Literal["strahl"]
    f0_permille: NonNegative
    f2_permille: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.strahl(mass_kg, self.f0_permille, self.f2_permille)


class SauthoffTerm(_Term):
    """Sauthoff (passenger coaches): ``m g (f0 + f1 v/v00 + f2 ((v+dv)/v00)^2) / 1000`` (Wende 2003)."""

    family: Literal["sauthoff"]
    f0_permille: NonNegative
    f1_permille: NonNegative
    f2_permille: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.sauthoff(mass_kg, self.f0_permille, self.f1_permille, self.f2_permille)


class WendeTerm(_Term):
    """Traction unit after Wende (2003) p. 151; ``driven_mass_t`` defaults to the whole mass."""

    family: Literal["wende"]
    f_driven_permille: NonNegative
    f_carrying_permille: NonNegative
    f_air_permille: NonNegative
    driven_mass_t: Positive | None = None

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        driven = self.driven_mass_t * TONNE if self.driven_mass_t is not None else mass_kg
        return res.wende_traction_unit(
            mass_kg, driven, self.f_driven_permille, self.f_carrying_permille, self.f_air_permille
        )


class AltriosTerm(_Term):
    """US freight style (ALTRIOS): bearing per axle + rolling ratio x W + davis_b v W + rho cd_area v^2."""

    family: Literal["altrios"]
    bearing_force_per_axle_n: NonNegative
    rolling_ratio: NonNegative
    davis_b_s_per_m: NonNegative
    cd_area_m2: NonNegative
    axles: int | None = Field(default=None, ge=1)

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.altrios(
            mass_kg,
            self._axles(self.axles, axles, self.family),
            self.bearing_force_per_axle_n,
            self.rolling_ratio,
            self.davis_b_s_per_m,
            self.cd_area_m2,
        )


_TERMS = (
    DavisTerm,
    DavisKnKmhTerm,
    PerMassTerm,
    SpecificTerm,
    RavTerm,
    RavLocomotiveTerm,
    RavCarriageTerm,
    StrahlTerm,
    SauthoffTerm,
    WendeTerm,
    AltriosTerm,
)
RESISTANCE_FAMILY_NAMES = tuple(t.model_fields["family"].annotation.__args__[0] for t in _TERMS)
_UNION_FIELDS["resistance"] = ("family", ", ".join(RESISTANCE_FAMILY_NAMES))

ResistanceSpec = Annotated[
    DavisTerm
    | DavisKnKmhTerm
    | PerMassTerm
    | SpecificTerm
    | RavTerm
    | RavLocomotiveTerm
    | RavCarriageTerm
    | StrahlTerm
    | SauthoffTerm
    | WendeTerm
    | AltriosTerm,
    Field(discriminator="family"),
]


# ====================================================================== train
class VehicleSpec(Spec):
    """One vehicle type of the formation, ``count`` times."""

    name: str = Field(min_length=1)
    count: int = Field(default=1, ge=1)
    mass_t: Annotated[float, Field(gt=0, le=1000)]
    load_t: NonNegative = 0.0
    length_m: Annotated[float, Field(gt=0, le=500)]
    axles: int | None = Field(default=None, ge=1, le=64)
    rotating_mass_factor: Annotated[float, Field(ge=1, le=2)] | None = None
    powered: bool = False
    max_speed_kmh: Positive | None = None
    resistance: list[ResistanceSpec] | None = None

    @model_validator(mode="after")
    def _check_terms(self) -> VehicleSpec:
        for i, term in enumerate(self.resistance or []):
            if term.applies_to not in (None, self.name):
                fail(
                    "a term inside a vehicle applies to that vehicle; leave 'applies_to' out",
                    field=f"resistance[{i}].applies_to",
                    value=term.applies_to,
                    allowed=self.name,
                )
        return self

    @property
    def total_mass_kg(self) -> float:
        return (self.mass_t + self.load_t) * TONNE


class ElectricalSpec(Spec):
    """Electrical data; ``regenerative_efficiency`` defaults to ``traction_efficiency``."""

    line_voltage_v: Positive
    traction_efficiency: Fraction
    regenerative_efficiency: Annotated[float, Field(ge=0, le=1)] | None = None
    power_factor: Fraction = 1.0
    auxiliary_power_kw: NonNegative = 0.0
    receptivity: Annotated[float, Field(ge=0, le=1)] = 1.0

    def build(self) -> Electrical:
        return Electrical(
            line_voltage_v=self.line_voltage_v,
            traction_efficiency=self.traction_efficiency,
            regenerative_efficiency=(
                self.regenerative_efficiency
                if self.regenerative_efficiency is not None
                else self.traction_efficiency
            ),
            power_factor=self.power_factor,
            auxiliary_power_w=self.auxiliary_power_kw * KW,
            receptivity=self.receptivity,
        )


class TrainSpec(Spec):
    """A ``trainsim/train`` file (see docs/FORMAT.md)."""

    schema_id: Literal["trainsim/train"] = Field(default="trainsim/train", alias="schema")
    version: Literal[1] = 1
    name: str = Field(min_length=1)
    description: str | None = None
    formation: list[VehicleSpec] | None = Field(default=None, min_length=1)
    mass_t: Annotated[float, Field(gt=0, le=50000)] | None = None
    load_t: NonNegative | None = None
    length_m: Annotated[float, Field(gt=0, le=5000)] | None = None
    adhesion_mass_t: Positive | None = None
    rotating_mass_factor: Annotated[float, Field(ge=1, le=2)] | None = None
    gamma: Annotated[float, Field(ge=0, le=1)] | None = None
    max_speed_kmh: Annotated[float, Field(gt=0, lt=720)] | None = None
    traction: TractionSpec
    braking: BrakingSpec
    resistance: list[ResistanceSpec] = Field(default_factory=list)
    electrical: ElectricalSpec | None = None

    @model_validator(mode="after")
    def _check_train(self) -> TrainSpec:
        if not self.resistance and not any(v.resistance for v in self.formation or []):
            fail(
                "the train needs running resistance: a 'resistance' list (or 'resistance' in its vehicles)",
                field="resistance",
                allowed=", ".join(RESISTANCE_FAMILY_NAMES),
            )
        if self.formation is None:
            if self.mass_t is None:
                fail("give the train's 'formation' (list of vehicles) or its 'mass_t'", field="formation")
            if self.length_m is None:
                fail("a train given by 'mass_t' needs 'length_m'", field="length_m")
            vehicles: list[VehicleSpec] = []
        else:
            for key in ("mass_t", "load_t", "length_m"):
                if getattr(self, key) is not None:
                    fail(
                        f"'{key}' comes from the formation; give it per vehicle, not for the train",
                        field=key,
                        value=getattr(self, key),
                    )
            vehicles = self.formation
            seen: dict[str, int] = {}
            for i, v in enumerate(vehicles):
                if v.name == "train":
                    fail(
                        "'train' is reserved ('applies_to: train' means the whole train)",
                        field=f"formation[{i}].name",
                        value=v.name,
                    )
                if v.name in seen:
                    fail(
                        f"vehicle name already used by formation[{seen[v.name]}]",
                        field=f"formation[{i}].name",
                        value=v.name,
                    )
                seen[v.name] = i
        if self.rotating_mass_factor is not None and self.gamma is not None:
            fail("give 'rotating_mass_factor' or 'gamma' (= factor - 1), not both", field="gamma")
        if self.rotating_mass_factor is None and self.gamma is None:
            missing = [f"formation[{i}]" for i, v in enumerate(vehicles) if v.rotating_mass_factor is None]
            if not vehicles or missing:
                fail(
                    "the rotating mass factor is needed: give the train's 'rotating_mass_factor' "
                    "(rho >= 1) or 'gamma' (= rho - 1, source 002), or 'rotating_mass_factor' for every "
                    "vehicle" + (f" (missing in {', '.join(missing)})" if vehicles else ""),
                    field="rotating_mass_factor",
                )
        if self.max_speed_kmh is None and (not vehicles or any(v.max_speed_kmh is None for v in vehicles)):
            fail(
                "give the train's 'max_speed_kmh' (or 'max_speed_kmh' for every vehicle)",
                field="max_speed_kmh",
            )
        names = [v.name for v in vehicles]
        for i, term in enumerate(self.resistance):
            if term.applies_to is None:
                fail(
                    "say what the term applies to: 'train' or a vehicle name",
                    field=f"resistance[{i}].applies_to",
                    allowed=", ".join(["train", *names]),
                )
            if term.applies_to != "train" and term.applies_to not in names:
                fail(
                    "no vehicle of that name in the formation",
                    field=f"resistance[{i}].applies_to",
                    value=term.applies_to,
                    allowed=", ".join(["train", *names]),
                )
        return self

    # ------------------------------------------------------------------ derived figures
    def vehicles(self) -> list[VehicleSpec]:
        """The vehicle types of the formation (empty for a train given by its mass)."""
        return list(self.formation or [])

    def mass_kg(self) -> float:
        """Train mass including load [kg]."""
        if self.formation is None:
            return ((self.mass_t or 0.0) + (self.load_t or 0.0)) * TONNE
        return sum(v.count * v.total_mass_kg for v in self.formation)

    def adhesion_mass_kg(self) -> float | None:
        """Mass on driven axles [kg]: the train's ``adhesion_mass_t``, else the powered vehicles'
        mass (empty + load), else None."""
        if self.adhesion_mass_t is not None:
            return self.adhesion_mass_t * TONNE
        powered = [v for v in self.vehicles() if v.powered]
        return sum(v.count * v.total_mass_kg for v in powered) if powered else None

    def rho(self) -> float:
        """Rotating mass factor of the train [-].

        From the vehicles: each vehicle's rotating parts add ``(xi - 1) x empty mass`` of inertia
        (they do not grow with the load), so ``rho = 1 + sum n (xi - 1) m_empty / m_total``.
        """
        if self.rotating_mass_factor is not None:
            return self.rotating_mass_factor
        if self.gamma is not None:
            return 1.0 + self.gamma
        extra = sum(
            v.count * ((v.rotating_mass_factor or 1.0) - 1.0) * v.mass_t * TONNE for v in self.vehicles()
        )
        return 1.0 + extra / self.mass_kg()

    def max_speed_mps(self) -> float:
        if self.max_speed_kmh is not None:
            return self.max_speed_kmh * KMH
        return min(v.max_speed_kmh or math.inf for v in self.vehicles()) * KMH

    def resistance_terms(self, file: str = "") -> list[ResistanceTerm]:
        """The running-resistance terms, vehicle terms evaluated per vehicle and times its count."""
        vehicles = {v.name: v for v in self.vehicles()}
        terms: list[tuple[str, _Term, VehicleSpec | None]] = []
        for i, term in enumerate(self.resistance):
            terms.append((f"resistance[{i}]", term, vehicles.get(term.applies_to or "train")))
        for j, v in enumerate(self.vehicles()):
            for i, term in enumerate(v.resistance or []):
                terms.append((f"formation[{j}].resistance[{i}]", term, v))
        out = []
        all_axles = [v.axles for v in self.vehicles()]
        train_axles = (
            sum((v.axles or 0) * v.count for v in self.vehicles())
            if all_axles and all(a is not None for a in all_axles)
            else None
        )
        for field, term, vehicle in terms:
            family = getattr(term, "family", "?")
            with _located(file, field):
                if vehicle is None:
                    law = term.law(self.mass_kg(), train_axles)
                    label = f"{family} (whole train)"
                else:
                    if isinstance(term, RavCarriageTerm) and vehicle.axles not in (None, 4):
                        raise InputError(
                            "'rav_carriage_4axle' is the law of 4-axle carriages",
                            field="axles",
                            value=vehicle.axles,
                            allowed="4",
                        )
                    law = term.law(vehicle.total_mass_kg, vehicle.axles).scaled(float(vehicle.count))
                    label = f"{family}: {vehicle.count} x {vehicle.name}"
            out.append(ResistanceTerm(label, law))
        return out

    def notes(self) -> list[str]:
        """Defaults applied and readings made when building the train, for ``trainsim check``."""
        notes: list[str] = []
        if self.formation is not None and self.rotating_mass_factor is None and self.gamma is None:
            notes.append(f"rotating mass factor {self.rho():.4f} combined from the vehicles' factors")
        t = self.traction
        if isinstance(t, PowerLimitedTraction) and t.adhesion_coefficient and t.adhesion_mass_t is None:
            mass = self.adhesion_mass_kg()
            if mass is not None:
                notes.append(
                    f"adhesion mass {mass / TONNE:g} t (powered vehicles or the train's adhesion_mass_t)"
                )
        b = self.braking
        if isinstance(b, TableBraking):
            if b.is_full and b.service_fraction is None:
                notes.append("service braking = 0.75 x the full braking table (source 000 default)")
            if any(f < 0 for f in b.forces_n_signed()):
                notes.append("braking table given as negative forces: read as magnitudes")
        if b.regenerative is None:
            notes.append("no regenerative braking (the 'regenerative' key is absent: friction brakes only)")
        if self.electrical is not None:
            if self.electrical.regenerative_efficiency is None:
                notes.append("regenerative efficiency = traction efficiency (not given)")
        else:
            notes.append("no electrical data: energy at the wheel only")
        return notes

    def warnings(self) -> list[str]:
        """Inconsistencies that are not errors, for ``trainsim check``."""
        out = []
        if self.max_speed_kmh is not None and self.formation:
            for v in self.formation:
                if v.max_speed_kmh is not None and v.max_speed_kmh < self.max_speed_kmh:
                    out.append(
                        f"train max speed {self.max_speed_kmh:g} km/h exceeds the limit of vehicle "
                        f"'{v.name}' ({v.max_speed_kmh:g} km/h)"
                    )
        return out

    # ------------------------------------------------------------------ the model object
    def to_train(self, file: str = "<train>") -> Train:
        """The :class:`~trainsim.model.Train` in SI units."""
        with _located(file, "traction"):
            traction = self.traction.build(self)
        with _located(file, "braking"):
            braking = self.braking.build(traction)
        resistance = self.resistance_terms(file)
        electrical = None
        if self.electrical is not None:
            with _located(file, "electrical"):
                electrical = self.electrical.build()
        vehicles: list[Vehicle] = []
        for v in self.vehicles():
            vehicles += [
                Vehicle(
                    name=v.name,
                    mass_kg=v.mass_t * TONNE,
                    length_m=v.length_m,
                    load_kg=v.load_t * TONNE,
                    axles=v.axles,
                    rotating_mass_factor=v.rotating_mass_factor or self.rho(),
                    powered=v.powered,
                )
            ] * v.count
        length = (
            self.length_m if self.formation is None else sum(v.count * v.length_m for v in self.vehicles())
        )
        with _located(file, "train"):
            return Train(
                name=self.name,
                mass_kg=self.mass_kg(),
                rotating_mass_factor=self.rho(),
                length_m=float(length or 0.0),
                max_speed_mps=self.max_speed_mps(),
                traction=traction,
                braking=braking,
                resistance=tuple(resistance),
                electrical=electrical,
                vehicles=tuple(vehicles),
                adhesion_mass_kg=self.adhesion_mass_kg(),
            )


def train_spec_from_dict(data: Any, source: str = "<train>", *, path: str | Path | None = None) -> TrainSpec:
    """Validate a ``trainsim/train`` mapping; InputError naming ``source`` and the field on failure."""
    return _validate(TrainSpec, data, "trainsim/train", source, path, header=True)
