"""Quantities with units at the edge of trainsim.

Inside trainsim everything is SI; this module is where the units of input files are read. Two
conventions, both meant to be written by hand without ambiguity:

* a field named with its unit suffix takes a plain number in that unit: ``speed_kmh: 80``,
  ``mass_t: 49.8``, ``length_m: 19``, ``force_kn: 93.25``, ``power_kw: 1000``,
  ``gradient_permille: 4.5`` (see :data:`SUFFIX_UNITS`);
* a generic field (the same name without the suffix) takes a string with its unit, which is
  converted into the suffixed field: ``speed: "80 km/h"``, ``mass: "49.8 t"``, ``power: "1 MW"``,
  ``gradient: "4.5 ‰"`` or ``"4.5 permille"``. A bare number in a generic field is an error,
  because the unit is exactly what such a field is there to say.

Every unknown unit raises an :class:`~trainsim.errors.InputError` naming the units allowed for
that quantity.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from trainsim.constants import KMH, KN, KW, KWH, MINUTE, MW, PERMILLE, TONNE
from trainsim.errors import InputError

__all__ = [
    "SUFFIX_UNITS",
    "UNITS",
    "Unit",
    "format_units",
    "from_si",
    "parse_quantity",
    "split_suffix",
    "to_si",
    "to_unit",
]


@dataclass(frozen=True)
class Unit:
    """A unit: the quantity it measures and the factor that turns a value in it into SI.

    Attributes:
        symbol: the canonical spelling, e.g. ``"km/h"``.
        dimension: quantity measured, e.g. ``"speed"``.
        factor: SI value of one unit, e.g. 1/3.6 for km/h [SI unit of the dimension].
    """

    symbol: str
    dimension: str
    factor: float


def _units(dimension: str, *entries: tuple[str, float]) -> list[Unit]:
    return [Unit(symbol, dimension, factor) for symbol, factor in entries]


# Canonical units, SI factors from trainsim.constants (the only place factors are defined).
_CANONICAL: list[Unit] = [
    *_units("speed", ("km/h", KMH), ("m/s", 1.0)),
    *_units("mass", ("t", TONNE), ("kg", 1.0)),
    *_units("length", ("m", 1.0), ("km", 1000.0)),
    *_units("force", ("N", 1.0), ("kN", KN)),
    *_units("power", ("W", 1.0), ("kW", KW), ("MW", MW)),
    *_units("voltage", ("V", 1.0), ("kV", 1000.0)),
    *_units("time", ("s", 1.0), ("min", MINUTE), ("h", 3600.0)),
    # Gradients and specific resistances: the SI value is the dimensionless ratio.
    *_units("ratio", ("‰", PERMILLE), ("%", 0.01)),
    *_units("acceleration", ("m/s^2", 1.0)),
    *_units("energy", ("J", 1.0), ("kWh", KWH), ("MJ", 1.0e6)),
    *_units("angle", ("deg", math.pi / 180.0), ("rad", 1.0)),
]

#: Other accepted spellings -> canonical symbol. Matching is case-sensitive on purpose: "MW"
#: (megawatt) and "mW" (milliwatt), "t" and "T" (tesla) are different units.
_SPELLINGS: dict[str, str] = {
    "kmh": "km/h",
    "kph": "km/h",
    "km/hr": "km/h",
    "mps": "m/s",
    "tonne": "t",
    "tonnes": "t",
    "kn": "kN",
    "KN": "kN",
    "kw": "kW",
    "KW": "kW",
    "kv": "kV",
    "sec": "s",
    "minutes": "min",
    "permille": "‰",
    "per mille": "‰",
    "per mil": "‰",
    "permil": "‰",
    "o/oo": "‰",
    "N/kN": "‰",
    "m/km": "‰",
    "percent": "%",
    "m/s2": "m/s^2",
    "m/s²": "m/s^2",
    "m/s**2": "m/s^2",
    "°": "deg",
    "degree": "deg",
    "degrees": "deg",
    "kwh": "kWh",
    "KWh": "kWh",
}

#: Every accepted unit spelling -> :class:`Unit`.
UNITS: dict[str, Unit] = {u.symbol: u for u in _CANONICAL}
UNITS.update({alias: UNITS[canonical] for alias, canonical in _SPELLINGS.items()})

#: Field-name suffixes -> unit of the plain number such a field holds.
SUFFIX_UNITS: dict[str, str] = {
    "kmh": "km/h",
    "mps": "m/s",
    "mps2": "m/s^2",
    "t": "t",
    "kg": "kg",
    "m": "m",
    "km": "km",
    "n": "N",
    "kn": "kN",
    "w": "W",
    "kw": "kW",
    "mw": "MW",
    "v": "V",
    "kv": "kV",
    "s": "s",
    "min": "min",
    "permille": "‰",
    "percent": "%",
    "deg": "deg",
    "kwh": "kWh",
}

_NUMBER_WITH_UNIT = re.compile(r"^\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def format_units(dimension: str) -> str:
    """The canonical units of a dimension, for error messages, e.g. ``"km/h, m/s"``."""
    symbols = [u.symbol for u in _CANONICAL if u.dimension == dimension]
    spellings = [a for a, c in _SPELLINGS.items() if UNITS[c].dimension == dimension and a not in symbols]
    text = ", ".join(symbols)
    if spellings:
        text += " (also written " + ", ".join(spellings) + ")"
    return text


def _unit(symbol: str, *, field: str | None, file: str | None, dimension: str | None = None) -> Unit:
    unit = UNITS.get(symbol.strip())
    if unit is None:
        dimensions = [dimension] if dimension else list(dict.fromkeys(u.dimension for u in _CANONICAL))
        raise InputError(
            f"unknown unit '{symbol}'",
            file=file,
            field=field,
            value=symbol,
            allowed="; ".join(f"{d}: {format_units(d)}" for d in dimensions),
        )
    return unit


def split_suffix(field_name: str) -> tuple[str, str] | None:
    """``"max_speed_kmh"`` -> ``("max_speed", "km/h")``; None if the name has no unit suffix."""
    if "_per_" in field_name:  # compound units (b_kn_per_kmh) have no generic form
        return None
    base, sep, suffix = field_name.rpartition("_")
    if not sep or not base or suffix not in SUFFIX_UNITS:
        return None
    return base, SUFFIX_UNITS[suffix]


def parse_quantity(
    value: object,
    dimension: str,
    *,
    bare_unit: str | None = None,
    field: str | None = None,
    file: str | None = None,
) -> float:
    """A quantity as SI value.

    Args:
        value: a number (only if ``bare_unit`` is given: it is then read in that unit) or a string
            ``"<number> <unit>"`` such as ``"80 km/h"``, ``"1 MW"``, ``"4.5 ‰"``.
        dimension: the quantity expected (``"speed"``, ``"mass"``, ``"length"``, ``"force"``,
            ``"power"``, ``"voltage"``, ``"time"``, ``"ratio"``, ``"acceleration"``, ``"energy"``,
            ``"angle"``); a unit of another dimension is an error.
        bare_unit: the unit of a plain number, or None to require a unit.
        field, file: where the value comes from, for error messages.

    Returns:
        The value in SI units (m/s, kg, m, N, W, V, s, ratio, m/s^2, J, rad).
    """
    if isinstance(value, bool):
        raise InputError("expected a quantity, not true/false", file=file, field=field, value=value)
    if isinstance(value, int | float):
        if bare_unit is None:
            raise InputError(
                "a number without unit; write the unit, e.g. '80 km/h', or use the field named with its unit",
                file=file,
                field=field,
                value=value,
                allowed=format_units(dimension),
            )
        number, symbol = float(value), bare_unit
    elif isinstance(value, str):
        match = _NUMBER_WITH_UNIT.match(value)
        if match is None:
            raise InputError(
                "expected '<number> <unit>'",
                file=file,
                field=field,
                value=value,
                allowed=format_units(dimension),
            )
        number = float(match.group(1))
        symbol = match.group(2) or bare_unit or ""
        if not symbol:
            raise InputError(
                "a number without unit", file=file, field=field, value=value, allowed=format_units(dimension)
            )
    else:
        raise InputError(
            "expected a number or '<number> <unit>'",
            file=file,
            field=field,
            value=value,
            allowed=format_units(dimension),
        )
    unit = _unit(symbol, field=field, file=file, dimension=dimension)
    if unit.dimension != dimension:
        raise InputError(
            f"'{symbol}' is a unit of {unit.dimension}, this field is a {dimension}",
            file=file,
            field=field,
            value=value,
            allowed=format_units(dimension),
        )
    if not math.isfinite(number):
        raise InputError("the value must be finite", file=file, field=field, value=value)
    return number * unit.factor


def to_si(value: float, unit: str) -> float:
    """``value`` [unit] in SI, e.g. ``to_si(80, "km/h")`` = 22.2 m/s."""
    return float(value) * _unit(unit, field=None, file=None).factor


def from_si(value_si: float, unit: str) -> float:
    """An SI value expressed in ``unit``, e.g. ``from_si(22.2, "km/h")`` = 80."""
    return float(value_si) / _unit(unit, field=None, file=None).factor


def to_unit(
    value: object,
    unit: str,
    *,
    require_unit: bool = False,
    field: str | None = None,
    file: str | None = None,
) -> float:
    """A number in ``unit`` (unless ``require_unit``) or a string with any unit of the same
    dimension, expressed in ``unit``.

    ``to_unit("1 MW", "kW")`` = 1000.0; ``to_unit(49.8, "t")`` = 49.8.
    """
    target = _unit(unit, field=field, file=file)
    bare = None if require_unit else unit
    return parse_quantity(value, target.dimension, bare_unit=bare, field=field, file=file) / target.factor
