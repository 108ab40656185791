"""Supply-voltage limits of traction systems and the trains' voltage-dependent behaviour.

The limits are those of EN 50163:2004 + A1:2007, Table 1 (nominal voltages and their permissible
limits in values and duration), identical to IEC 60850:2014 Table 1: ``Umin2`` lowest
non-permanent voltage, ``Umin1`` lowest permanent voltage, ``Un`` nominal voltage, ``Umax1``
highest permanent voltage, ``Umax2`` highest non-permanent voltage, ``Umax3`` highest long-term
overvoltage (20 ms, added by A1:2007), all at the pantograph [V]. They are data (:data:`EN50163`), never hard-coded in a formula: a network
file may give its own.

The train's behaviour follows the principle of EN 50388 (train current limitation as the line
voltage falls): full traction power above ``traction_full_v``, a linear reduction down to zero at
``Umin1``, no traction below ``Umin1``; regenerated power is accepted in full up to
``regen_full_v`` and curtailed linearly to zero at ``regen_zero_v`` (the rest goes to the on-board
resistors or the friction brakes).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike

from trainsim.errors import InputError

__all__ = [
    "EN50163",
    "VoltageLimits",
    "regen_acceptance",
    "regen_acceptance_slope",
    "traction_availability",
    "traction_availability_slope",
]

#: Where the traction limitation starts when a file does not say, as a share of the way from Umin1
#: to Un (0.5: half way, 625 V on a 750 V line, 1250 V on 1500 V, 22 kV on 25 kV). A trainsim
#: default, not a value of the standard: EN 50388 asks for a limitation between a voltage U and
#: Umin1 that the rolling stock sets within its limits; give ``traction_full_v`` when it is known.
DEFAULT_TRACTION_FULL_SHARE = 0.5


@dataclass(frozen=True)
class VoltageLimits:
    """Voltage limits of one supply system and the trains' limitation thresholds [V].

    Attributes:
        nominal_v: Un.
        min2_v: Umin2, lowest non-permanent voltage.
        min1_v: Umin1, lowest permanent voltage; no traction below it.
        max1_v: Umax1, highest permanent voltage; regenerated power is accepted in full up to it
            unless ``regen_full_v`` says otherwise.
        max2_v: Umax2, highest non-permanent voltage; no regeneration above it unless
            ``regen_zero_v`` says otherwise.
        traction_full_v: full traction above this voltage (default half way from Umin1 to Un, see
            DEFAULT_TRACTION_FULL_SHARE).
        regen_full_v: full regeneration below this voltage (default Umax1).
        regen_zero_v: no regeneration above this voltage (default Umax2).
        max3_v: Umax3, highest long-term overvoltage (20 ms) [V], or None; informative (a
            simulation at 1 s steps does not resolve 20 ms events), checked >= Umax2.
    """

    nominal_v: float
    min2_v: float
    min1_v: float
    max1_v: float
    max2_v: float
    traction_full_v: float | None = None
    regen_full_v: float | None = None
    regen_zero_v: float | None = None
    max3_v: float | None = None

    def __post_init__(self) -> None:
        if self.traction_full_v is None:
            object.__setattr__(
                self,
                "traction_full_v",
                self.min1_v + DEFAULT_TRACTION_FULL_SHARE * (self.nominal_v - self.min1_v),
            )
        if self.regen_full_v is None:
            object.__setattr__(self, "regen_full_v", self.max1_v)
        if self.regen_zero_v is None:
            object.__setattr__(self, "regen_zero_v", self.max2_v)
        order = [
            ("min2_v", self.min2_v),
            ("min1_v", self.min1_v),
            ("nominal_v", self.nominal_v),
            ("max1_v", self.max1_v),
            ("max2_v", self.max2_v),
        ]
        if not self.min2_v > 0:
            raise InputError(
                "voltage limits must be > 0", field="limits.min2_v", value=self.min2_v, allowed="> 0 V"
            )
        for (name_a, a), (name_b, b) in pairwise(order):
            if not a <= b:
                raise InputError(
                    f"voltage limits out of order: {name_a} > {name_b}",
                    field=f"limits.{name_b}",
                    value=b,
                    allowed=f">= {name_a} = {a} V (Umin2 <= Umin1 <= Un <= Umax1 <= Umax2)",
                )
        if self.max3_v is not None and not self.max3_v >= self.max2_v:
            raise InputError(
                "voltage limits out of order: max2_v > max3_v",
                field="limits.max3_v",
                value=self.max3_v,
                allowed=f">= max2_v = {self.max2_v} V",
            )
        if not self.min1_v < self.traction_full_v:
            raise InputError(
                "traction must be full above a voltage higher than Umin1",
                field="limits.traction_full_v",
                value=self.traction_full_v,
                allowed=f"> Umin1 = {self.min1_v} V",
            )
        if not self.regen_full_v < self.regen_zero_v:
            raise InputError(
                "regeneration must stop at a voltage higher than where it is curtailed",
                field="limits.regen_zero_v",
                value=self.regen_zero_v,
                allowed=f"> regen_full_v = {self.regen_full_v} V",
            )

    def with_overrides(self, **values: float | None) -> VoltageLimits:
        """The same limits with the given fields replaced (None leaves a field as it is)."""
        fields = {
            "nominal_v": self.nominal_v,
            "min2_v": self.min2_v,
            "min1_v": self.min1_v,
            "max1_v": self.max1_v,
            "max2_v": self.max2_v,
            "traction_full_v": self.traction_full_v,
            "regen_full_v": self.regen_full_v,
            "regen_zero_v": self.regen_zero_v,
            "max3_v": self.max3_v,
        }
        fields.update({k: v for k, v in values.items() if v is not None})
        return VoltageLimits(**fields)


#: EN 50163:2004 + A1:2007 Table 1 (= IEC 60850:2014 Table 1): (Umin2, Umin1, Un, Umax1, Umax2,
#: Umax3) [V] per system name; DC values are mean values, AC values r.m.s. Umin2 = Umin1 for DC;
#: Umax3 is the 20 ms long-term overvoltage. Public sources found (issue 18, search of public pages
#: and repositories; the standards themselves are not public):
#:
#: - Umin2, Umin1, Un, Umax1 and Umax2 of all six systems: the table "Supply voltages of railway
#:   systems" of a public GitHub-hosted blog post (2025-02-25, Jekyll site, category "Rolling
#:   stock"), which attributes it to EN 50163 and IEC 60850 and cites EN 50163 (2007): every value
#:   below agrees, including 1.5 kV's Umax1 1800 V and Umax2 1950 V.
#: - Umin1, Un, Umax1: the traction-system table of IEC 60038 as reproduced by S. McFadyen,
#:   "Voltage Levels to IEC 60038", https://myelectrical.com/notes/entryid/203/voltage-levels-to-iec-60038,
#:   agrees for 600 V, 750 V, 3 kV, 15 kV and 25 kV; for 1.5 kV it prints 1600 V as the highest
#:   voltage, a misprint of 1800 V by the source above (and every other DC system's Umax1 is 1.2 Un).
#: - Umax3 (A1:2007): no public source found; the values are as read from EN 50163 + A1 and are
#:   informative only here (a 1 s step does not resolve 20 ms events; only Umax3 >= Umax2 is checked).
EN50163: dict[str, tuple[float, float, float, float, float, float]] = {
    "dc_600": (400.0, 400.0, 600.0, 720.0, 800.0, 1015.0),
    "dc_750": (500.0, 500.0, 750.0, 900.0, 1000.0, 1270.0),
    "dc_1500": (1000.0, 1000.0, 1500.0, 1800.0, 1950.0, 2540.0),
    "dc_3000": (2000.0, 2000.0, 3000.0, 3600.0, 3900.0, 5075.0),
    "ac_15000": (11000.0, 12000.0, 15000.0, 17250.0, 18000.0, 24300.0),
    "ac_25000": (17500.0, 19000.0, 25000.0, 27500.0, 29000.0, 38750.0),
}


def standard_limits(system: str) -> VoltageLimits:
    """The EN 50163 limits of a named system (``dc_750``, ``dc_1500``, ``dc_3000``, ``ac_15000``,
    ``ac_25000``, ``dc_600``) with trainsim's default limitation thresholds."""
    if system not in EN50163:
        raise InputError(
            "unknown supply system", field="system", value=system, allowed=", ".join(sorted(EN50163))
        )
    u_min2, u_min1, u_n, u_max1, u_max2, u_max3 = EN50163[system]
    return VoltageLimits(
        nominal_v=u_n, min2_v=u_min2, min1_v=u_min1, max1_v=u_max1, max2_v=u_max2, max3_v=u_max3
    )


def traction_availability(voltage_v: ArrayLike, u_min1_v: float, u_full_v: float) -> np.ndarray:
    """Share of the demanded traction power a train may draw at pantograph voltage U [-].

    a(U) = 0 for U <= Umin1, (U - Umin1) / (U_full - Umin1) between, 1 for U >= U_full: the
    linear current/power limitation of EN 50388 (clause "train power or current limitation").

    Args:
        voltage_v: pantograph voltage U [V].
        u_min1_v: Umin1, no traction at or below it [V].
        u_full_v: full traction at or above it [V].
    """
    u = np.asarray(voltage_v, dtype=float)
    return np.clip((u - u_min1_v) / (u_full_v - u_min1_v), 0.0, 1.0)


def traction_availability_slope(voltage_v: ArrayLike, u_min1_v: float, u_full_v: float) -> np.ndarray:
    """Derivative of :func:`traction_availability` with respect to U [1/V] (0 outside the ramp)."""
    u = np.asarray(voltage_v, dtype=float)
    inside = (u > u_min1_v) & (u < u_full_v)
    return np.where(inside, 1.0 / (u_full_v - u_min1_v), 0.0)


def regen_acceptance(voltage_v: ArrayLike, u_full_v: float, u_zero_v: float) -> np.ndarray:
    """Share of the offered regenerated power a train may feed at pantograph voltage U [-].

    r(U) = 1 for U <= U_full, (U_zero - U) / (U_zero - U_full) between, 0 for U >= U_zero: the
    curtailment of regenerative braking as the voltage rises towards Umax (EN 50388 / EN 50163);
    the rest is dissipated on board or taken by the friction brakes.

    Args:
        voltage_v: pantograph voltage U [V].
        u_full_v: full regeneration at or below it [V] (default Umax1).
        u_zero_v: no regeneration at or above it [V] (default Umax2).
    """
    u = np.asarray(voltage_v, dtype=float)
    return np.clip((u_zero_v - u) / (u_zero_v - u_full_v), 0.0, 1.0)


def regen_acceptance_slope(voltage_v: ArrayLike, u_full_v: float, u_zero_v: float) -> np.ndarray:
    """Derivative of :func:`regen_acceptance` with respect to U [1/V] (0 outside the ramp)."""
    u = np.asarray(voltage_v, dtype=float)
    inside = (u > u_full_v) & (u < u_zero_v)
    return np.where(inside, -1.0 / (u_zero_v - u_full_v), 0.0)
