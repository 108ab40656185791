"""Physically plausible ranges of the quantities trainsim reads: one table, one check.

Readers check every number they read against this table, so that an absurd magnitude (a dwell of
1e308 s, a position of 1e308 m, a count of 10^9 vehicles) is refused with the allowed range instead
of giving a run that says ``ok``, an overflow deep in numpy, or gigabytes of memory. The ranges are
wide on purpose: they bound what any railway vehicle or line can be (the heaviest trains run at about
100,000 t, the fastest at about 600 km/h, the steepest adhesion lines at about 100 per mille), not what
is usual. Where a quantity has a tighter rule (a mass > 0) the reader's own check says so; this table
catches the magnitudes.

Efficiencies and shares are told apart. A conversion efficiency (line -> wheel of a traction chain,
nominal power -> wheel, a storage's charge or discharge) and a power factor are at least 0.1: real
traction chains convert about 0.6-0.95 of the power (transformer, converters, motors, gears), power
factors of traction units are about 0.6-1, and the line energy and current scale with their inverse,
so 0.001 (a percentage written as a fraction twice) gave 80,000 kWh and 4.9 MA with status ``ok``,
and 1e-308 overflowed to an infinite energy. Shares (``traction_share``, ``braking_fraction``,
``service_fraction``) may legitimately be small and keep (0, 1]. Efficiencies between 0.1 and 0.5 are
read with a plausibility warning of the run (``trainsim.sim.result.plausibility_warnings``).

Every bound is in SI (the unit in :attr:`Bound.si_unit`); :func:`check` takes the value in the unit
it was written in, with the factor that turns it into SI, and names the range in that unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from trainsim.constants import GRAVITY_RANGE_MPS2
from trainsim.errors import InputError

__all__ = ["BOUNDS", "EFFICIENCY_NOTE", "MIN_EFFICIENCY", "Bound", "bound_for", "check", "check_count"]


@dataclass(frozen=True)
class Bound:
    """The plausible range of one quantity, in SI.

    Attributes:
        quantity: what is bounded (``mass``, ``speed``...).
        si_unit: the SI unit of ``low`` and ``high``.
        low, high: the range; a value outside it is refused.
        low_open: whether ``low`` itself is refused (shares: 0 is not a share).
        why: where the range comes from, for readers of the table.
        note: the reason for the range, shown with it in messages where the range is not obvious
            (an efficiency below 0.1 is refused: the user needs to know why).
    """

    quantity: str
    si_unit: str
    low: float
    high: float
    low_open: bool = False
    why: str = ""
    note: str = ""

    def contains(self, value_si: float) -> bool:
        """Whether a finite value [SI] is inside the range."""
        if not math.isfinite(value_si):
            return False
        above = value_si > self.low if self.low_open else value_si >= self.low
        return above and value_si <= self.high

    def allowed(self, unit: str | None = None, factor: float = 1.0) -> str:
        """The range in words, in ``unit`` (``factor``: SI value of one ``unit``)."""
        unit = unit if unit is not None else self.si_unit
        low, high = self.low / factor, self.high / factor
        left = ">" if self.low_open else ">="
        suffix = f" {unit}" if unit else ""
        text = f"{left} {low:g}{suffix} and <= {high:g}{suffix}"
        return f"{text} ({self.note})" if self.note else text


#: Lowest conversion efficiency or power factor read [-]: real traction chains convert about 0.6-0.95
#: of the power and power factors of traction units are about 0.6-1; below 0.1 the value is a unit
#: mistake (a percentage divided twice), and the line energy and current, which scale with its
#: inverse, would be absurd (0.001: 80,000 kWh on a 4.6 km metro line) or overflow (1e-308).
MIN_EFFICIENCY = 0.1

#: Why efficiencies are bounded below, in the messages that refuse one.
EFFICIENCY_NOTE = (
    "real traction chains convert about 0.6 to 0.95 of the power and power factors of traction units "
    "are about 0.6 to 1; the line energy and current scale with the inverse of an efficiency"
)

#: The table: quantity -> plausible range [SI]. Dimensions of :mod:`trainsim.io.units` map onto it.
BOUNDS: dict[str, Bound] = {
    b.quantity: b
    for b in (
        Bound("mass", "kg", 0.0, 1e8, why="the heaviest trains weigh about 1e8 kg (100,000 t)"),
        Bound("length", "m", -1e7, 1e7, why="positions and lengths on a line: 10,000 km"),
        Bound("speed", "m/s", 0.0, 200.0, why="720 km/h, above any railway's record"),
        Bound("signal_speed", "m/s", 0.0, 3e8, why="brake signals: air (about 250 m/s) to radio"),
        Bound("acceleration", "m/s^2", -20.0, 20.0, why="2 g: no vehicle brakes or pulls harder"),
        Bound("force", "N", -1e8, 1e8, why="100 MN: the weight of a 10,000 t train is about 98 MN"),
        Bound("power", "W", 0.0, 1e9, why="1 GW, about 50 times the most powerful locomotive"),
        Bound("voltage", "V", 0.0, 1e6, why="1 MV, above any traction supply"),
        Bound("current", "A", 0.0, 1e6, why="1 MA"),
        Bound("time", "s", -1e6, 1e6, why="about 11.6 days: dwell times, clock times of a week"),
        Bound("energy", "J", -1e13, 1e13, why="about 2,800 MWh"),
        Bound("ratio", "", -1.0, 1.0, why="gradients and specific resistances: 1000 per mille"),
        Bound("angle", "rad", -2 * math.pi, 2 * math.pi, why="one full turn"),
        Bound(
            "efficiency",
            "",
            MIN_EFFICIENCY,
            1.0,
            why="a conversion efficiency or power factor: [0.1, 1]",
            note=EFFICIENCY_NOTE,
        ),
        Bound("share", "", 0.0, 1.0, low_open=True, why="a share of a force or power: (0, 1]"),
        Bound("fraction", "", 0.0, 1.0, why="a share: [0, 1]"),
        Bound("count", "", 0.0, 100_000.0, why="vehicles, motors or axles of one train"),
        Bound("gravity", "m/s^2", *GRAVITY_RANGE_MPS2, why="g anywhere on the Earth's surface"),
        Bound("coefficient", "", -1e12, 1e12, why="coefficients of force laws in SI"),
    )
}

#: Plain field names (no unit suffix) and the quantity they are.
_BY_NAME: dict[str, str] = {
    "count": "count",
    "propagation_speed_mps": "signal_speed",
    "gravity_mps2": "gravity",
    "motors": "count",
    "axles": "count",
    "number": "count",
    "efficiency": "efficiency",
    "traction_efficiency": "efficiency",
    "regenerative_efficiency": "fraction",
    "power_factor": "efficiency",
    "fraction": "fraction",
    # shares may be small (a train drawing a tenth of its effort on a weak line): (0, 1]
    "braking_fraction": "share",
    "traction_share": "share",
    "service_fraction": "share",
}


def bound_for(name: str, dimension: str | None = None) -> Bound:
    """The bound of a field: by its plain name (``count``, ``efficiency``...), else by the dimension
    of its unit (``mass``, ``speed``...), else the generic coefficient bound."""
    quantity = _BY_NAME.get(name)
    if quantity is None and name.endswith("_count"):
        quantity = "count"
    if quantity is None and name.endswith("_efficiency"):
        quantity = "efficiency"
    if quantity is None:
        quantity = dimension if dimension in BOUNDS else "coefficient"
    return BOUNDS[quantity]


def check(
    value: float,
    quantity: str | Bound,
    *,
    field: str | None = None,
    file: str | None = None,
    line: int | None = None,
    unit: str | None = None,
    factor: float = 1.0,
) -> float:
    """``value`` (in ``unit``; ``factor`` is the SI value of one ``unit``) if it is finite and inside the
    plausible range of ``quantity``; otherwise an InputError naming the field and the range in ``unit``.

    Returns the value in SI.
    """
    bound = quantity if isinstance(quantity, Bound) else BOUNDS[quantity]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(
            "must be a number",
            file=file,
            line=line,
            field=field,
            value=value,
            allowed=bound.allowed(unit, factor),
        )
    try:
        si = float(value) * factor
    except OverflowError:
        si = math.inf
    if not bound.contains(si):
        finite = math.isfinite(value) if isinstance(value, float) else True
        reason = "out of range" if finite else "must be a finite number"
        raise InputError(
            reason, file=file, line=line, field=field, value=value, allowed=bound.allowed(unit, factor)
        )
    return si


def check_count(
    value: object, *, field: str | None = None, file: str | None = None, line: int | None = None, low: int = 0
) -> int:
    """``value`` as a count (a whole number from ``low`` to the count bound), or an InputError."""
    bound = BOUNDS["count"]
    allowed = f"a whole number from {low} to {bound.high:g}"
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(
            "must be a whole number", file=file, line=line, field=field, value=value, allowed=allowed
        )
    if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
        raise InputError(
            "must be a whole number", file=file, line=line, field=field, value=value, allowed=allowed
        )
    if not low <= value <= bound.high:
        raise InputError("out of range", file=file, line=line, field=field, value=value, allowed=allowed)
    return int(value)
