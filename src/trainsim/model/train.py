"""The train as the simulation core sees it: masses, length, effort curves, resistance, electrics."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from trainsim.errors import InputError
from trainsim.model import bounds
from trainsim.model.effort import EffortCurve
from trainsim.model.laws import Quadratic


@dataclass(frozen=True)
class Vehicle:
    """One vehicle of a formation.

    Attributes:
        name: vehicle name or type.
        mass_kg: empty (tare) mass [kg].
        length_m: length over buffers [m].
        load_kg: payload carried [kg].
        axles: number of axles (needed by per-axle resistance laws), or None.
        rotating_mass_factor: ratio of inertial to static mass, >= 1 [-].
        powered: True for locomotives and motor cars.
    """

    name: str
    mass_kg: float
    length_m: float
    load_kg: float = 0.0
    axles: int | None = None
    rotating_mass_factor: float = 1.0
    powered: bool = False

    @property
    def total_mass_kg(self) -> float:
        """Mass including load [kg]."""
        return self.mass_kg + self.load_kg


@dataclass(frozen=True)
class ResistanceTerm:
    """One running-resistance contribution (a vehicle, a group of vehicles, or the whole train).

    Attributes:
        label: what the term is, e.g. ``"Davis (whole train)"`` or ``"Strahl: 10 x Facs 124"``.
        law: the resistance force over speed [N].
    """

    label: str
    law: Quadratic


@dataclass(frozen=True)
class Braking:
    """How the train brakes.

    Exactly one of ``service_force`` (a force law) or ``deceleration_mps2`` (a constant net
    deceleration whatever the resistance and grade, the TrainRuns.jl convention) is given.

    Attributes:
        service_force: maximum service braking force at the wheel over speed, positive [N].
            Source 000: service braking is 0.75 x full braking; readers apply that factor.
        deceleration_mps2: constant service deceleration, positive [m/s^2].
        regenerative: maximum electric (regenerative) braking force over speed [N]; the demand is
            met by it first and by friction brakes for the rest (blending). None: friction only.
        full_force: full (emergency) braking force, for reference [N].
    """

    service_force: EffortCurve | None = None
    deceleration_mps2: float | None = None
    regenerative: EffortCurve | None = None
    full_force: EffortCurve | None = None

    def __post_init__(self) -> None:
        if (self.service_force is None) == (self.deceleration_mps2 is None):
            raise InputError(
                "braking needs either a braking force law or a constant deceleration, not both",
                field="braking",
            )
        if self.deceleration_mps2 is not None and not self.deceleration_mps2 > 0:
            raise InputError(
                "the braking deceleration must be > 0 (give its magnitude)",
                field="braking.deceleration",
                value=self.deceleration_mps2,
                allowed="> 0 m/s^2",
            )


@dataclass(frozen=True)
class Electrical:
    """Electrical data for energy and line current.

    Attributes:
        line_voltage_v: nominal line voltage [V].
        traction_efficiency: line-to-wheel efficiency in traction (product of the chain) [-].
        regenerative_efficiency: wheel-to-line efficiency in regenerative braking [-].
        power_factor: cos(phi) used in ``I = P / (U cos phi)`` (source 002 eq. 15) [-].
        auxiliary_power_w: auxiliaries (HVAC, lighting, compressors) drawn all the time [W].
        receptivity: share of regenerated power the line accepts (other trains, storage) [-].
    """

    line_voltage_v: float
    traction_efficiency: float = 1.0
    regenerative_efficiency: float = 1.0
    power_factor: float = 1.0
    auxiliary_power_w: float = 0.0
    receptivity: float = 1.0

    def __post_init__(self) -> None:
        checks = {
            "line_voltage_v": (self.line_voltage_v, self.line_voltage_v > 0, "> 0 V"),
            "traction_efficiency": (
                self.traction_efficiency,
                0 < self.traction_efficiency <= 1,
                "0 < x <= 1",
            ),
            "regenerative_efficiency": (
                self.regenerative_efficiency,
                0 <= self.regenerative_efficiency <= 1,
                "0 <= x <= 1",
            ),
            "power_factor": (self.power_factor, 0 < self.power_factor <= 1, "0 < x <= 1"),
            "auxiliary_power_w": (self.auxiliary_power_w, self.auxiliary_power_w >= 0, ">= 0 W"),
            "receptivity": (self.receptivity, 0 <= self.receptivity <= 1, "0 <= x <= 1"),
        }
        for name, (value, ok, allowed) in checks.items():
            if not ok:
                raise InputError(
                    "invalid electrical data", field=f"electrical.{name}", value=value, allowed=allowed
                )


@dataclass(frozen=True)
class Train:
    """A train reduced to what the single-point model needs, plus its formation.

    Attributes:
        name: train name.
        mass_kg: static mass including load [kg].
        rotating_mass_factor: rho >= 1; the inertial mass is rho x mass (source 000 eq. 1;
            source 002 writes it 1 + gamma) [-].
        length_m: train length [m].
        max_speed_mps: maximum speed of the train [m/s].
        traction: maximum tractive effort at the wheel over speed, whole train [N].
        braking: braking capability.
        resistance: running-resistance terms; their sum is the train's running resistance.
        electrical: electrical data, or None for a train without (diesel, or unknown).
        vehicles: the formation, head first (informative for the single-point model).
        adhesion_mass_kg: mass on driven axles, for adhesion limits [kg], or None.
    """

    name: str
    mass_kg: float
    rotating_mass_factor: float
    length_m: float
    max_speed_mps: float
    traction: EffortCurve
    braking: Braking
    resistance: tuple[ResistanceTerm, ...]
    electrical: Electrical | None = None
    vehicles: tuple[Vehicle, ...] = field(default=())
    adhesion_mass_kg: float | None = None

    def __post_init__(self) -> None:
        checks = {
            "mass": (self.mass_kg, self.mass_kg > 0, "> 0 kg"),
            "rotating_mass_factor": (
                self.rotating_mass_factor,
                1.0 <= self.rotating_mass_factor <= 2.0,
                "1 <= rho <= 2 (give 1 + gamma if your source uses gamma)",
            ),
            "length": (self.length_m, self.length_m > 0, "> 0 m"),
            "max_speed": (self.max_speed_mps, 0 < self.max_speed_mps < 200, "0 < v < 720 km/h"),
        }
        for name, (value, ok, allowed) in checks.items():
            if not (ok and np.isfinite(value)):
                raise InputError("invalid train data", field=name, value=value, allowed=allowed)
        bounds.check(self.mass_kg, "mass", field="mass", unit="kg")
        bounds.check(self.length_m, "length", field="length", unit="m")
        object.__setattr__(self, "resistance", tuple(self.resistance))
        object.__setattr__(self, "vehicles", tuple(self.vehicles))

    def at_gravity(self, gravity_mps2: float) -> Train:
        """The train with every adhesion limit of its effort curves resolved for gravity g [m/s^2]
        (a run calls this with its route's gravity; itself when nothing depends on g)."""
        b = self.braking
        curves = (self.traction, b.service_force, b.regenerative, b.full_force)
        if all(c is None or not np.isfinite(c.adhesion_limit_kg) for c in curves):
            return self
        g = gravity_mps2

        def res(c: EffortCurve | None) -> EffortCurve | None:
            return c.at_gravity(g) if c is not None else None

        braking = replace(
            b,
            service_force=res(b.service_force),
            regenerative=res(b.regenerative),
            full_force=res(b.full_force),
        )
        return replace(self, traction=self.traction.at_gravity(g), braking=braking)

    @property
    def inertial_mass_kg(self) -> float:
        """rho x m: the mass that resists acceleration [kg]."""
        return self.mass_kg * self.rotating_mass_factor

    @property
    def resistance_law(self) -> Quadratic:
        """The sum of all running-resistance terms [N over m/s]."""
        total = Quadratic(0.0)
        for term in self.resistance:
            total = total + term.law
        return total

    def running_resistance_n(self, speed_mps: ArrayLike) -> np.ndarray | float:
        """Running resistance [N] at speed [m/s]."""
        return self.resistance_law(speed_mps)

    def max_traction_n(self, speed_mps: ArrayLike) -> np.ndarray | float:
        """Maximum tractive effort [N] at speed [m/s]."""
        return self.traction(speed_mps)

    def max_braking_n(self, speed_mps: ArrayLike) -> np.ndarray | float:
        """Maximum service braking force [N] at speed [m/s] (force-law braking only)."""
        if self.braking.service_force is None:
            raise InputError(
                "this train brakes at a constant deceleration; it has no braking force law",
                field="braking",
            )
        return self.braking.service_force(speed_mps)
