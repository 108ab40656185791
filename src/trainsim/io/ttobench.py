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

import json
import math
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path
from typing import Any

from trainsim.constants import KMH, KN, KW
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
from trainsim.physics.resistance import davis_kn_kmh

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
}


@dataclass(frozen=True)
class TTOBenchTrain:
    """A TTOBench train: the trainsim Train, its tunnel drag per cross-section [m^2 -> N s^2/m^2]
    and the notes of what was assumed."""

    train: Train
    tunnel_drag: dict[float, float]
    notes: tuple[str, ...]


@dataclass(frozen=True)
class TimingPoint:
    """A TTOBench timing point: position [m], time window [s] and speed window [m/s]; None where
    unconstrained."""

    position_m: float
    earliest_s: float | None
    latest_s: float | None
    min_speed_mps: float | None
    max_speed_mps: float | None

    @property
    def is_stop(self) -> bool:
        """Both speed bounds 0: a stopping point."""
        return self.min_speed_mps == 0.0 and self.max_speed_mps == 0.0


@dataclass(frozen=True)
class Journey:
    """A TTOBench journey: ordered timing points on a track."""

    name: str
    track_id: str
    points: tuple[TimingPoint, ...]
    notes: tuple[str, ...] = field(default=())


def _read(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise InputError("file not found", file=str(path))
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", file=str(path), line=exc.lineno) from None
    if not isinstance(data, dict):
        raise InputError("a TTOBench file is a JSON object", file=str(path))
    return data


def _quantity(data: dict[str, Any], key: str, file: str, *, required: bool = True) -> float | None:
    item = data.get(key)
    if item is None:
        if required:
            raise InputError("missing field", file=file, field=key)
        return None
    if not isinstance(item, dict) or "value" not in item or "unit" not in item:
        raise InputError("expected {'unit': ..., 'value': ...}", file=file, field=key, value=item)
    unit, value = item["unit"], item["value"]
    if unit in ("kN/(km/h)", "kN/(km/h)^2"):
        factor = KN / KMH if unit == "kN/(km/h)" else KN / KMH**2
    elif unit in _UNITS:
        factor = _UNITS[unit]
    else:
        raise InputError(
            "unknown unit", file=file, field=f"{key}.unit", value=unit, allowed=", ".join(_UNITS)
        )
    if not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError("expected a finite number", file=file, field=f"{key}.value", value=value)
    return float(value) * factor


def read_ttobench_train(path: str | Path) -> TTOBenchTrain:
    """Read a TTOBench train file."""
    file = str(path)
    data = _read(path)
    notes: list[str] = []
    name = str(data.get("metadata", {}).get("id", Path(path).stem))
    mass = _quantity(data, "mass", file)
    rho = 1.0 + (_quantity(data, "rho", file, required=False) or 0.0)
    p_trac = _quantity(data, "max traction power", file)
    f_trac = _quantity(data, "max traction force", file)
    p_reg = _quantity(data, "max reg braking power", file)
    f_reg = _quantity(data, "max reg braking force", file)
    f_pn = _quantity(data, "max pn braking force", file, required=False) or 0.0
    a_acc = _quantity(data, "max acceleration", file, required=False)
    a_dec = _quantity(data, "max deceleration", file, required=False)
    v_max = _quantity(data, "max speed", file)
    # r0 [N], r1 [N/(m/s)], r2 [N/(m/s)^2] after conversion; Davis law in SI
    r0 = _quantity(data, "rolling resistance r0", file)
    r1 = _quantity(data, "rolling resistance r1", file)
    r2 = _quantity(data, "rolling resistance r2", file)
    eta_t = _quantity(data, "efficiency traction", file, required=False)
    eta_r = _quantity(data, "efficiency reg brake", file, required=False)
    length = _quantity(data, "length", file, required=False)
    for key, value in (("mass", mass), ("max traction power", p_trac), ("max traction force", f_trac)):
        if not value > 0:
            raise InputError("must be > 0", file=file, field=key, value=value)
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
    drag: dict[float, float] = {}
    tunnel = data.get("tunnel resistance")
    if tunnel is not None:
        if tunnel.get("units", {}).get("coefficient") != "kN/(km/h)^2":
            raise InputError(
                "unknown unit",
                file=file,
                field="tunnel resistance.units.coefficient",
                value=tunnel.get("units"),
                allowed="kN/(km/h)^2",
            )
        for cross_section, coefficient in tunnel["values"]:
            drag[float(cross_section)] = float(coefficient) * KN / KMH**2
    return TTOBenchTrain(train=train, tunnel_drag=drag, notes=tuple(notes))


def _pairs(data: dict[str, Any], key: str, file: str, width: int) -> list[list[Any]]:
    item = data.get(key)
    if item is None:
        return []
    values = item.get("values") if isinstance(item, dict) else None
    if not isinstance(values, list) or any(not isinstance(v, list) or len(v) != width for v in values):
        raise InputError(f"expected a list of {width}-element lists under 'values'", file=file, field=key)
    positions = [float(v[0]) for v in values]
    if any(b <= a for a, b in pairwise(positions)):
        raise InputError("positions must increase strictly", file=file, field=key, value=positions[:10])
    return values


def _radius(value: Any) -> float:
    return math.inf if value in ("infinity", "inf", None) else abs(float(value))


def read_ttobench_track(path: str | Path, train: TTOBenchTrain | None = None) -> Route:
    """Read a TTOBench track file as a Route (stations at its stops)."""
    file = str(path)
    data = _read(path)
    name = str(data.get("metadata", {}).get("id", Path(path).stem))
    stops_item = data.get("stops")
    if not isinstance(stops_item, dict) or not isinstance(stops_item.get("values"), list):
        raise InputError("missing stops", file=file, field="stops")
    stops = [float(x) for x in stops_item["values"]]
    if len(stops) < 2 or stops[0] != 0.0 or any(b <= a for a, b in pairwise(stops)):
        raise InputError(
            "stops must start at 0 and increase",
            file=file,
            field="stops",
            value=stops,
            allowed="0 < s1 < ...",
        )
    length = stops[-1]
    limits = _pairs(data, "speed limits", file, 2)
    if not limits or float(limits[0][0]) != 0.0:
        raise InputError("speed limits must start at position 0", file=file, field="speed limits")
    speed_limits = [
        SpeedLimit(float(p), float(limits[k + 1][0]) if k + 1 < len(limits) else length, float(v) * KMH)
        for k, (p, v) in enumerate(limits)
    ]
    grads = _pairs(data, "gradients", file, 2)
    gradients = [
        GradientSection(float(p), float(grads[k + 1][0]) if k + 1 < len(grads) else length, float(g))
        for k, (p, g) in enumerate(grads)
        if g != 0
    ]
    curves = []
    rows = _pairs(data, "curvatures", file, 3)
    for k, (p, r_start, r_end) in enumerate(rows):
        end = float(rows[k + 1][0]) if k + 1 < len(rows) else length
        mean_curvature = 0.5 * (1.0 / _radius(r_start) + 1.0 / _radius(r_end))
        if mean_curvature > 0.0 and end > float(p):
            curves.append(Curve(float(p), end, 1.0 / mean_curvature))
    tunnels = []
    for p, tunnel_length, cross_section in _pairs(data, "tunnels", file, 3):
        drag = 0.0
        if train is not None and train.tunnel_drag:
            nearest = min(train.tunnel_drag, key=lambda a, cs=float(cross_section): abs(a - cs))
            drag = train.tunnel_drag[nearest]
        tunnels.append(Tunnel(float(p), float(p) + float(tunnel_length), extra_drag_n_s2_per_m2=drag))
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
            curve_formula="roeckl", tunnel_formula="none", gradient_formula="small_angle", apply_over="head"
        ),
    )


def read_ttobench_journey(path: str | Path) -> Journey:
    """Read a TTOBench journey file (timing points with time and speed windows)."""
    file = str(path)
    data = _read(path)
    meta = data.get("metadata", {})
    item = data.get("timing points")
    if not isinstance(item, dict) or not isinstance(item.get("values"), list) or len(item["values"]) < 2:
        raise InputError("at least two timing points are required", file=file, field="timing points")
    points = []
    for k, row in enumerate(item["values"]):
        if not isinstance(row, list) or len(row) != 5:
            raise InputError(
                "a timing point is [position, earliest, latest, min speed, max speed]",
                file=file,
                field=f"timing points.values[{k}]",
                value=row,
            )
        pos, lo, hi, vmin, vmax = row
        points.append(
            TimingPoint(
                float(pos),
                None if lo is None else float(lo),
                None if hi is None else float(hi),
                None if vmin is None else float(vmin) * KMH,
                None if vmax is None else float(vmax) * KMH,
            )
        )
    if not (points[0].is_stop and points[-1].is_stop):
        raise InputError(
            "the first and last timing points must be stopping points", file=file, field="timing points"
        )
    return Journey(
        name=str(meta.get("id", Path(path).stem)),
        track_id=str(meta.get("associated track", "")),
        points=tuple(points),
    )
