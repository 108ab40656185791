"""TTOBench JSON files (Kouzoupis, Pendharkar, Corman 2023, TTOBench v1.5): trains, tracks, journeys.

Every value carries its unit (``{"unit": "kN", "value": 213.9}``); units are converted to SI here.
Conventions and choices (reported in the ``notes`` of what is read, never applied silently):

* Train: traction ``min(F_max, P_max / v)``, further capped by ``rho m a_max`` when a comfort
  acceleration is given; braking ``min(B_reg, P_reg / v) + B_pn`` capped by ``rho m d_max``; the
  regenerative part is the electric brake; Davis r0, r1, r2 given in kN with v in km/h.
* TTOBench gives no line voltage: currents assume ``ASSUMED_LINE_VOLTAGE_V``; energies do not depend
  on it. A train without a length is a mass point (1 m long).
* Track: stops become stations (dwell 0); clothoids get the radius of their mean curvature; curve
  resistance uses Roeckl's formula (TTOBench does not prescribe one); tunnels get the train's measured
  tunnel drag for their cross-section when the train gives one.
* Journey: timing points with time and speed windows; stopping points delimit journey sections.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

from trainsim.constants import KMH, KN, KW, TTOBENCH_GRAVITY
from trainsim.errors import InputError
from trainsim.model import (
    Braking,
    Curve,
    EffortCurve,
    Electrical,
    GradientSection,
    LineResistanceSettings,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
    Tunnel,
)
from trainsim.model.timetable import Journey, TimingPoint
from trainsim.physics.resistance import davis_kn_kmh

__all__ = [
    "ETCSBraking",
    "Journey",
    "TTOBenchTrain",
    "TimingPoint",
    "read_ttobench_journey",
    "read_ttobench_track",
    "read_ttobench_train",
]

#: Line voltage assumed for line currents: TTOBench does not give one [V].
ASSUMED_LINE_VOLTAGE_V = 1500.0

_UNITS = {
    "kg": 1.0,
    "t": 1000.0,
    "kW": KW,
    "W": 1.0,
    "MW": 1e6,
    "kN": KN,
    "N": 1.0,
    "km/h": KMH,
    "m/s": 1.0,
    "m/s^2": 1.0,
    "%": 0.01,
    "-": 1.0,
    "m": 1.0,
    "m^2": 1.0,
    "permil": 1.0,
    "s": 1.0,
}


@dataclass(frozen=True)
class ETCSBraking:
    """TTOBench's optional ETCS braking data, read and kept (trainsim does not compute ETCS curves).

    Attributes:
        values: every scalar field in SI or as given when dimensionless (e.g. ``T_be`` [s],
            ``K_dry_rst`` [-], ``v_uncertainty`` [-] as a fraction, ``Kt_int`` [-]).
        curves: every curve field as (speed [m/s], deceleration [m/s^2]) pairs
            (``A_brake_emergency``, ``A_brake_service``).
    """

    values: dict[str, float]
    curves: dict[str, tuple[tuple[float, float], ...]]


@dataclass(frozen=True)
class TTOBenchTrain:
    """A TTOBench train: the trainsim Train, its tunnel drag per cross-section [m^2 -> N s^2/m^2],
    its ETCS braking data (None when the file has none) and the notes of what was assumed."""

    train: Train
    tunnel_drag: dict[float, float]
    notes: tuple[str, ...]
    etcs: ETCSBraking | None = None


def _read(path: str | Path) -> dict[str, Any]:
    from trainsim.io.documents import read_json

    data = read_json(path)  # bounded size and depth; NaN, Infinity and duplicate keys refused
    if not isinstance(data, dict):
        raise InputError("a TTOBench file is a JSON object", file=str(path), value=type(data).__name__)
    return data


def _metadata(data: dict[str, Any], file: str) -> dict[str, Any]:
    """The ``metadata`` block (a mapping; missing means empty)."""
    meta = data.get("metadata", {})
    if not isinstance(meta, dict):
        raise InputError(
            "the metadata block must be a mapping", file=file, field="metadata", value=meta, allowed="{...}"
        )
    return meta


def _name(meta: dict[str, Any], key: str, file: str, default: str) -> str:
    value = meta.get(key, default)
    if not isinstance(value, str) or not value:
        raise InputError(
            "expected a non-empty text",
            file=file,
            field=f"metadata.{key}",
            value=value,
            allowed="a non-empty text",
        )
    return value


def _number(
    value: Any,
    file: str,
    field: str,
    *,
    minimum: float | None = None,
    positive: bool = False,
    allowed: str = "a finite number",
) -> float:
    """A finite JSON number (never a bool, text, null, list or mapping), optionally >= minimum or > 0."""
    try:  # an integer beyond the range of a float is not a finite number either
        finite = not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value)
    except OverflowError:
        finite = False
    if not finite:
        raise InputError("expected a finite number", file=file, field=field, value=value, allowed=allowed)
    x = float(value)
    if positive and not x > 0.0:
        raise InputError("must be > 0", file=file, field=field, value=value, allowed=allowed)
    if minimum is not None and x < minimum:
        raise InputError(f"must be >= {minimum:g}", file=file, field=field, value=value, allowed=allowed)
    return x


def _factor(unit: Any, file: str, field: str, allowed_units: tuple[str, ...] | None = None) -> float:
    if unit in ("kN/(km/h)", "kN/(km/h)^2"):
        factor = KN / KMH if unit == "kN/(km/h)" else KN / KMH**2
    elif isinstance(unit, str) and unit in _UNITS:
        factor = _UNITS[unit]
    else:
        raise InputError(
            "unknown unit",
            file=file,
            field=field,
            value=unit,
            allowed=", ".join(allowed_units or tuple(_UNITS)),
        )
    if allowed_units is not None and unit not in allowed_units:
        raise InputError("wrong unit", file=file, field=field, value=unit, allowed=", ".join(allowed_units))
    return factor


def _quantity(
    data: dict[str, Any],
    key: str,
    file: str,
    *,
    required: bool = True,
    minimum: float | None = None,
    positive: bool = False,
    prefix: str = "",
) -> float | None:
    """``{"unit": ..., "value": ...}`` in SI."""
    field = prefix + key
    item = data.get(key)
    if item is None:
        if key in data:
            raise InputError(
                "null where a quantity belongs", file=file, field=field, allowed="{'unit': ..., 'value': ...}"
            )
        if required:
            raise InputError("missing field", file=file, field=field, allowed="{'unit': ..., 'value': ...}")
        return None
    if not isinstance(item, dict) or "value" not in item or "unit" not in item:
        raise InputError(
            "expected {'unit': ..., 'value': ...}",
            file=file,
            field=field,
            value=item,
            allowed="{'unit', 'value'}",
        )
    factor = _factor(item["unit"], file, f"{field}.unit")
    value = _number(item["value"], file, f"{field}.value", minimum=minimum, positive=positive)
    return value * factor


def _etcs(
    data: dict[str, Any], file: str, scalars: tuple[str, ...], curves: tuple[str, ...]
) -> ETCSBraking | None:
    """The optional ``ETCS braking data`` block: every listed field must be there (TTOBench's rule)."""
    if "ETCS braking data" not in data:
        return None
    block = data["ETCS braking data"]
    field = "ETCS braking data"
    if not isinstance(block, dict):
        raise InputError("expected a mapping", file=file, field=field, value=block, allowed="{...}")
    missing = [k for k in (*scalars, *curves) if k not in block]
    if missing:
        raise InputError(
            "ETCS braking data must give all of its fields",
            file=file,
            field=f"{field}.{missing[0]}",
            allowed=", ".join((*scalars, *curves)),
        )
    values = {k: _quantity(block, k, file, prefix=field + ".", minimum=0.0) for k in scalars}
    out: dict[str, tuple[tuple[float, float], ...]] = {}
    for k in curves:
        item = block[k]
        where = f"{field}.{k}"
        if not isinstance(item, dict):
            raise InputError(
                "expected a mapping", file=file, field=where, value=item, allowed="{units, values}"
            )
        units = item.get("units", {})
        if not isinstance(units, dict):
            raise InputError("expected a mapping", file=file, field=f"{where}.units", value=units)
        fv = _factor(units.get("velocity", "m/s"), file, f"{where}.units.velocity", ("m/s", "km/h"))
        fd = _factor(units.get("deceleration", "m/s^2"), file, f"{where}.units.deceleration", ("m/s^2",))
        rows = _rows(item, file, where, 2, column_names=("velocity", "deceleration"))
        out[k] = tuple((r[0] * fv, r[1] * fd) for r in rows)
    return ETCSBraking(values={k: float(v) for k, v in values.items() if v is not None}, curves=out)


def read_ttobench_train(path: str | Path) -> TTOBenchTrain:
    """Read a TTOBench train file.

    Raises:
        InputError: naming the file, the field, the value and what is allowed, for anything that is
            not a TTOBench train (missing, null, text, non-finite or out-of-range numbers, unknown units).
    """
    file = str(path)
    data = _read(path)
    notes: list[str] = []
    name = _name(_metadata(data, file), "id", file, Path(path).stem)
    mass = _quantity(data, "mass", file, positive=True)
    rho = 1.0 + (_quantity(data, "rho", file, required=False, minimum=0.0) or 0.0)
    p_trac = _quantity(data, "max traction power", file, positive=True)
    f_trac = _quantity(data, "max traction force", file, positive=True)
    p_reg = _quantity(data, "max reg braking power", file, positive=True)
    f_reg = _quantity(data, "max reg braking force", file, positive=True)
    f_pn = _quantity(data, "max pn braking force", file, required=False, minimum=0.0) or 0.0
    a_acc = _quantity(data, "max acceleration", file, required=False, positive=True)
    a_dec = _quantity(data, "max deceleration", file, required=False, positive=True)
    v_max = _quantity(data, "max speed", file, positive=True)
    # r0 [N], r1 [N/(m/s)], r2 [N/(m/s)^2] after conversion; Davis law in SI
    r0 = _quantity(data, "rolling resistance r0", file, minimum=0.0)
    r1 = _quantity(data, "rolling resistance r1", file, minimum=0.0)
    r2 = _quantity(data, "rolling resistance r2", file, minimum=0.0)
    eta_t = _quantity(data, "efficiency traction", file, required=False, positive=True)
    eta_r = _quantity(data, "efficiency reg brake", file, required=False, minimum=0.0)
    length = _quantity(data, "length", file, required=False, positive=True)
    for key, eta in (("efficiency traction", eta_t), ("efficiency reg brake", eta_r)):
        if eta is not None and eta > 1.0:
            raise InputError(
                "an efficiency is at most 100 %", file=file, field=key, value=eta, allowed="<= 100 %"
            )
    assert mass is not None and p_trac is not None and f_trac is not None  # required above
    assert p_reg is not None and f_reg is not None and v_max is not None
    assert r0 is not None and r1 is not None and r2 is not None
    inertial = rho * mass
    trac_cap = f_trac if a_acc is None else min(f_trac, inertial * a_acc)
    traction = EffortCurve.power_limited(p_trac, force_cap_n=trac_cap, label="TTOBench min(F, P/v)")
    regen = EffortCurve.power_limited(p_reg, force_cap_n=f_reg, label="TTOBench regenerative")
    knee = p_reg / f_reg
    service = EffortCurve.piecewise(
        [0.0, knee],
        [[f_reg + f_pn, 0.0, 0.0, 0.0], [f_pn, 0.0, 0.0, p_reg]],
        force_cap_n=inertial * a_dec if a_dec is not None else float("inf"),
        label="TTOBench regenerative + pneumatic",
    )
    if a_dec is None:
        notes.append("no max deceleration: braking limited by the braking forces only")
    if eta_t is None or eta_r is None:
        notes.append("efficiencies missing: 1.0 assumed where absent")
    if length is None:
        notes.append("no train length: mass point (1 m)")
    notes.append(f"no line voltage in TTOBench: currents assume {ASSUMED_LINE_VOLTAGE_V:g} V")
    try:
        train = Train(
            name=name,
            mass_kg=mass,
            rotating_mass_factor=rho,
            length_m=length if length else 1.0,
            max_speed_mps=v_max,
            traction=traction,
            braking=Braking(service_force=service, regenerative=regen),
            resistance=(
                ResistanceTerm(
                    "TTOBench Davis r0 + r1 v + r2 v^2",
                    davis_kn_kmh(r0 / KN, r1 / (KN / KMH), r2 / (KN / KMH**2)),
                ),
            ),
            electrical=Electrical(
                line_voltage_v=ASSUMED_LINE_VOLTAGE_V,
                traction_efficiency=eta_t if eta_t is not None else 1.0,
                regenerative_efficiency=eta_r if eta_r is not None else 1.0,
            ),
        )
    except InputError as exc:
        raise exc.located(file) from None
    drag: dict[float, float] = {}
    if "tunnel resistance" in data:
        tunnel = data["tunnel resistance"]
        where = "tunnel resistance"
        if not isinstance(tunnel, dict):
            raise InputError(
                "expected a mapping", file=file, field=where, value=tunnel, allowed="{units, values}"
            )
        units = tunnel.get("units", {})
        if not isinstance(units, dict):
            raise InputError("expected a mapping", file=file, field=f"{where}.units", value=units)
        f_cs = _factor(units.get("cross section", "m^2"), file, f"{where}.units.cross section", ("m^2",))
        f_co = _factor(units.get("coefficient"), file, f"{where}.units.coefficient", ("kN/(km/h)^2",))
        rows = _rows(tunnel, file, where, 2, column_names=("cross section", "coefficient"), increasing=False)
        for k, (cross_section, coefficient) in enumerate(rows):
            if not cross_section > 0.0:
                raise InputError(
                    "a tunnel cross-section must be > 0",
                    file=file,
                    field=f"{where}.values[{k}][0]",
                    value=cross_section,
                    allowed="> 0 m^2",
                )
            drag[cross_section * f_cs] = coefficient * f_co
    etcs = _etcs(
        data,
        file,
        ("K_dry_rst", "K_wet_rst", "T_traction", "T_be", "T_bs", "v_uncertainty"),
        ("A_brake_emergency", "A_brake_service"),
    )
    if etcs is not None:
        notes.append("ETCS braking data read and kept; trainsim does not compute ETCS braking curves")
    return TTOBenchTrain(train=train, tunnel_drag=drag, notes=tuple(notes), etcs=etcs)


def _rows(
    item: dict[str, Any],
    file: str,
    field: str,
    width: int,
    *,
    column_names: tuple[str, ...],
    increasing: bool = True,
) -> list[list[float]]:
    """``item["values"]``: a list of ``width``-element lists of finite numbers, the first column
    strictly increasing (when ``increasing``)."""
    values = item.get("values")
    if not isinstance(values, list):
        raise InputError(
            f"expected a list of [{', '.join(column_names)}] under 'values'",
            file=file,
            field=f"{field}.values",
            value=values,
        )
    rows = []
    for k, row in enumerate(values):
        if not isinstance(row, list) or len(row) != width:
            raise InputError(
                f"expected [{', '.join(column_names)}]",
                file=file,
                field=f"{field}.values[{k}]",
                value=row,
                allowed=f"a list of {width} numbers",
            )
        rows.append(
            [_number(x, file, f"{field}.values[{k}][{j}] ({column_names[j]})") for j, x in enumerate(row)]
        )
    if increasing:
        for k, (a, b) in enumerate(pairwise(r[0] for r in rows)):
            if not b > a:
                raise InputError(
                    "positions must increase strictly",
                    file=file,
                    field=f"{field}.values[{k + 1}][0]",
                    value=b,
                    allowed=f"> {a:g}",
                )
    return rows


def _list_units(
    item: dict[str, Any], file: str, field: str, expected: dict[str, tuple[str, ...]]
) -> dict[str, float]:
    """The conversion factor of every column from the list's ``units`` (TTOBench's defaults where absent)."""
    units = item.get("units", {})
    if units is None:
        units = {}
    if not isinstance(units, dict):
        raise InputError("expected a mapping", file=file, field=f"{field}.units", value=units)
    return {
        col: _factor(units.get(col, allowed[0]), file, f"{field}.units.{col}", allowed)
        for col, allowed in expected.items()
    }


def _optional_list(data: dict[str, Any], key: str, file: str) -> dict[str, Any] | None:
    if key not in data:
        return None
    item = data[key]
    if not isinstance(item, dict):
        raise InputError(
            "expected a mapping with 'values'", file=file, field=key, value=item, allowed="{units, values}"
        )
    return item


def _radius(value: Any, file: str, field: str) -> float:
    """A curve radius [m]: "infinity" for straight track, else a non-zero finite number (the sign is
    the direction of the turn)."""
    if isinstance(value, str) and value.strip().lower() in (
        "infinity",
        "inf",
        "+infinity",
        "-infinity",
        "-inf",
    ):
        return math.inf
    r = _number(value, file, field, allowed='a non-zero number [m] or "infinity"')
    if r == 0.0:
        raise InputError(
            "a curve radius of 0 is not a curve",
            file=file,
            field=field,
            value=value,
            allowed='!= 0 m or "infinity"',
        )
    return abs(r)


def read_ttobench_track(path: str | Path, train: TTOBenchTrain | None = None) -> Route:
    """Read a TTOBench track file as a Route (stations at its stops, gravity 9.81 m/s^2 as TTOBench).

    Raises:
        InputError: naming the file, the field, the value and what is allowed.
    """
    file = str(path)
    data = _read(path)
    name = _name(_metadata(data, file), "id", file, Path(path).stem)
    stops_item = data.get("stops")
    if not isinstance(stops_item, dict) or not isinstance(stops_item.get("values"), list):
        raise InputError(
            "missing stops", file=file, field="stops", value=stops_item, allowed="{'values': [0, s1, ...]}"
        )
    f_stop = _list_units(stops_item, file, "stops", {"position": ("m",)})["position"]
    stops = [
        _number(x, file, f"stops.values[{k}]", minimum=0.0) * f_stop
        for k, x in enumerate(stops_item["values"])
    ]
    if len(stops) < 2 or stops[0] != 0.0 or any(b <= a for a, b in pairwise(stops)):
        raise InputError(
            "stops must start at 0 and increase strictly",
            file=file,
            field="stops.values",
            value=stops,
            allowed="0 < s1 < ... (at least two stops)",
        )
    length = stops[-1]

    def section_list(key: str, width: int, columns: dict[str, tuple[str, ...]], required: bool = False):
        item = _optional_list(data, key, file)
        if item is None:
            if required:
                raise InputError("missing field", file=file, field=key, allowed="{units, values}")
            return [], {}
        factors = _list_units(item, file, key, columns)
        rows = _rows(item, file, key, width, column_names=tuple(columns))
        for k, row in enumerate(rows):
            if not 0.0 <= row[0] * factors["position"] < length:
                raise InputError(
                    "a position must lie on the track",
                    file=file,
                    field=f"{key}.values[{k}][0]",
                    value=row[0],
                    allowed=f"0 <= position < {length:g} m (the last stop)",
                )
        return rows, factors

    limits, f_lim = section_list("speed limits", 2, {"position": ("m",), "velocity": ("km/h", "m/s")}, True)
    if not limits or limits[0][0] != 0.0:
        raise InputError(
            "speed limits must start at position 0",
            file=file,
            field="speed limits.values[0][0]",
            value=limits[0][0] if limits else None,
            allowed="0",
        )
    for k, (_, v) in enumerate(limits):
        if not v > 0.0:
            raise InputError(
                "a speed limit must be > 0",
                file=file,
                field=f"speed limits.values[{k}][1]",
                value=v,
                allowed="> 0",
            )
    speed_limits = [
        SpeedLimit(p, limits[k + 1][0] if k + 1 < len(limits) else length, v * f_lim["velocity"])
        for k, (p, v) in enumerate(limits)
    ]
    grads, f_grad = section_list("gradients", 2, {"position": ("m",), "slope": ("permil",)})
    for k, (_, g) in enumerate(grads):
        if abs(g) > 1000.0:
            raise InputError(
                "implausible gradient",
                file=file,
                field=f"gradients.values[{k}][1]",
                value=g,
                allowed="-1000 .. 1000 permil",
            )
    gradients = [
        GradientSection(p, grads[k + 1][0] if k + 1 < len(grads) else length, g * f_grad.get("slope", 1.0))
        for k, (p, g) in enumerate(grads)
        if g != 0
    ]
    curves = []
    item = _optional_list(data, "curvatures", file)
    if item is not None:
        _list_units(
            item, file, "curvatures", {"position": ("m",), "radius at start": ("m",), "radius at end": ("m",)}
        )
        rows = item.get("values")
        if not isinstance(rows, list):
            raise InputError(
                "expected a list of [position, radius at start, radius at end] under 'values'",
                file=file,
                field="curvatures.values",
                value=rows,
            )
        parsed = []
        for k, row in enumerate(rows):
            where = f"curvatures.values[{k}]"
            if not isinstance(row, list) or len(row) != 3:
                raise InputError(
                    "expected [position, radius at start, radius at end]", file=file, field=where, value=row
                )
            p = _number(row[0], file, f"{where}[0] (position)", minimum=0.0)
            if parsed and not p > parsed[-1][0]:
                raise InputError(
                    "positions must increase strictly",
                    file=file,
                    field=f"{where}[0]",
                    value=p,
                    allowed=f"> {parsed[-1][0]:g}",
                )
            if not p < length:
                raise InputError(
                    "a position must lie on the track",
                    file=file,
                    field=f"{where}[0]",
                    value=p,
                    allowed=f"< {length:g} m",
                )
            parsed.append((p, _radius(row[1], file, f"{where}[1]"), _radius(row[2], file, f"{where}[2]")))
        for k, (p, r_start, r_end) in enumerate(parsed):
            end = parsed[k + 1][0] if k + 1 < len(parsed) else length
            mean_curvature = 0.5 * (1.0 / r_start + 1.0 / r_end)
            if mean_curvature > 0.0 and end > p:
                curves.append(Curve(p, end, 1.0 / mean_curvature))
    tunnels = []
    rows, _ = section_list("tunnels", 3, {"position": ("m",), "length": ("m",), "cross section": ("m^2",)})
    for k, (p, tunnel_length, cross_section) in enumerate(rows):
        if not tunnel_length >= 0.0 or not p + tunnel_length <= length:
            raise InputError(
                "a tunnel must lie on the track",
                file=file,
                field=f"tunnels.values[{k}][1]",
                value=tunnel_length,
                allowed=f"0 <= length <= {length - p:g} m",
            )
        if not cross_section > 0.0:
            raise InputError(
                "a tunnel cross-section must be > 0",
                file=file,
                field=f"tunnels.values[{k}][2]",
                value=cross_section,
            )
        if tunnel_length == 0.0:
            continue
        drag = 0.0
        if train is not None and train.tunnel_drag:
            nearest = min(train.tunnel_drag, key=lambda a, cs=cross_section: abs(a - cs))
            drag = train.tunnel_drag[nearest]
        tunnels.append(Tunnel(p, p + tunnel_length, extra_drag_n_s2_per_m2=drag))
    _etcs(data, file, ("M_NVAVADH", "Kt_int"), ())
    try:
        return Route(
            name=name,
            start_m=0.0,
            end_m=length,
            stations=tuple(Station(f"stop {k} ({s:.0f} m)", s, 0.0) for k, s in enumerate(stops)),
            speed_limits=tuple(speed_limits),
            gradients=tuple(gradients),
            curves=tuple(curves),
            tunnels=tuple(tunnels),
            line_resistance=LineResistanceSettings(
                curve_formula="roeckl",
                tunnel_formula="none",
                gradient_formula="small_angle",
                apply_over="head",
            ),
            gravity_mps2=TTOBENCH_GRAVITY,
        )
    except InputError as exc:
        raise exc.located(file) from None


def read_ttobench_journey(path: str | Path) -> Journey:
    """Read a TTOBench journey file: timing points [position, earliest, latest, min speed, max speed]
    with ``null`` for no constraint (TTOBench's journey rules are checked).

    Raises:
        InputError: naming the file, the field, the value and what is allowed.
    """
    file = str(path)
    data = _read(path)
    meta = _metadata(data, file)
    item = data.get("timing points")
    if not isinstance(item, dict) or not isinstance(item.get("values"), list) or len(item["values"]) < 2:
        raise InputError(
            "at least two timing points are required",
            file=file,
            field="timing points.values",
            value=item.get("values") if isinstance(item, dict) else item,
            allowed="a list of [position, earliest, latest, min speed, max speed]",
        )
    columns = {
        "position": ("m",),
        "lower time constraint": ("s",),
        "upper time constraint": ("s",),
        "lower speed constraint": ("km/h", "m/s"),
        "upper speed constraint": ("km/h", "m/s"),
    }
    factors = _list_units(item, file, "timing points", columns)
    f_speed_lo, f_speed_hi = factors["lower speed constraint"], factors["upper speed constraint"]
    points: list[TimingPoint] = []
    for k, row in enumerate(item["values"]):
        where = f"timing points.values[{k}]"
        if not isinstance(row, list) or len(row) != 5:
            raise InputError(
                "a timing point is [position, earliest, latest, min speed, max speed]",
                file=file,
                field=where,
                value=row,
            )
        pos = _number(row[0], file, f"{where}[0] (position)", minimum=0.0)

        def opt(j: int, what: str, row=row, where=where) -> float | None:
            x = row[j]
            return (
                None
                if x is None
                else _number(x, file, f"{where}[{j}] ({what})", minimum=0.0, allowed=">= 0 or null")
            )

        lo, hi = opt(1, "lower time constraint"), opt(2, "upper time constraint")
        vmin, vmax = opt(3, "lower speed constraint"), opt(4, "upper speed constraint")
        if lo is not None and hi is not None and lo > hi:
            raise InputError(
                "the lower time constraint is above the upper one",
                file=file,
                field=where,
                value=row,
                allowed="lower <= upper",
            )
        if vmin is not None and vmax is not None and vmin > vmax:
            raise InputError(
                "the lower speed constraint is above the upper one",
                file=file,
                field=where,
                value=row,
                allowed="lower <= upper",
            )
        point = TimingPoint(
            pos,
            lo,
            hi,
            None if vmin is None else vmin * f_speed_lo,
            None if vmax is None else vmax * f_speed_hi,
            name=f"timing point {k} ({pos:.0f} m)",
        )
        if points and pos < points[-1].position_m:
            raise InputError(
                "timing points must be ordered by position",
                file=file,
                field=f"{where}[0]",
                value=pos,
                allowed=f">= {points[-1].position_m:g}",
            )
        if points and pos == points[-1].position_m and not (point.is_stop and points[-1].is_stop):
            raise InputError(
                "equal positions are only allowed for the arrival and departure stopping points of a station",
                file=file,
                field=f"{where}[0]",
                value=pos,
            )
        points.append(point)
    if not (points[0].is_stop and points[-1].is_stop):
        raise InputError(
            "the first and last timing points must be stopping points (both speed constraints 0)",
            file=file,
            field="timing points.values",
        )
    return Journey(
        name=_name(meta, "id", file, Path(path).stem),
        track_id=_name(meta, "associated track", file, "") if "associated track" in meta else "",
        points=tuple(points),
    )
