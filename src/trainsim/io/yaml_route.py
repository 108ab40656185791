"""The ``trainsim/route`` document: stations, speed limits, gradients or elevation, curves, tunnels,
electrification, line resistance and gravity (docs/FORMAT.md, "Route")."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, WrapSerializer, model_validator

from trainsim.constants import KMH, STANDARD_GRAVITY
from trainsim.io.spec import (
    Fraction,
    NonNegative,
    Positive,
    Spec,
    SpecTable,
    _check_increasing,
    _located,
    _validate,
    column,
    fail,
    table_as_list,
    table_or_models,
)
from trainsim.model import (
    Curve,
    ElectrificationSection,
    GradientSection,
    LineResistanceSettings,
    Route,
    SpeedLimit,
    Station,
    Tunnel,
)
from trainsim.model.route import ApplyOver, CurveFormula, GradientFormula, TunnelFormula
from trainsim.physics import line_resistance

if TYPE_CHECKING:  # trainsim.optimize is imported where a driving block is read, not by every reader
    pass


# ====================================================================== route
class StationSpec(Spec):
    name: str = Field(min_length=1)
    position_m: float
    dwell_s: NonNegative = 0.0
    stop: bool = True


class _Section(Spec):
    """A section from ``from_m`` to ``to_m`` (or ``from_m + length_m``)."""

    from_m: float
    to_m: float | None = None

    def stop(self) -> float:
        """End of a section that must have one (curves, tunnels) [m]."""
        end = self.end()
        return self.from_m if end is None else end

    def end(self) -> float | None:
        """End [m] from ``to_m`` or ``from_m + length_m``; None if neither is given."""
        length = self.__dict__.get("length_m")
        if self.to_m is not None:
            return self.to_m
        return self.from_m + length if length is not None else None

    @model_validator(mode="after")
    def _check_extent(self) -> _Section:
        length = self.__dict__.get("length_m")
        if self.to_m is not None and length is not None:
            fail("give 'to_m' or 'length_m', not both", field="length_m")
        end = self.end()
        if end is not None and not end > self.from_m:
            fail("a section must end after it starts", field="to_m", value=end, allowed=f"> {self.from_m:g}")
        return self


def _extent_ok(columns: dict[str, np.ndarray]) -> bool:
    """:meth:`_Section._check_extent` on whole columns of a section list without ``length_m``."""
    to, start = columns["to_m"], columns["from_m"]
    given = ~np.isnan(to)
    return bool((to[given] > start[given]).all())


class SpeedLimitSpec(_Section):
    limit_kmh: Annotated[float, Field(gt=0, lt=720)]

    _table_ok = staticmethod(_extent_ok)


class GradientSpec(_Section):
    gradient_permille: Annotated[float, Field(gt=-200, lt=200)]

    _table_ok = staticmethod(_extent_ok)


class ElevationPointSpec(Spec):
    position_m: float
    elevation_m: float

    @staticmethod
    def _table_ok(columns: dict[str, np.ndarray]) -> bool:
        return True  # no rule across fields


# Long lists (200,000 gradient entries) are read as columns when every entry is plainly valid: see
# spec.spec_table; otherwise one model per entry says which entry is wrong and why.
_Table = WrapSerializer(table_as_list)


class CurveSpec(_Section):
    """A curve: extent by ``to_m`` or ``length_m``; ``radius_m`` or ``central_angle_deg`` (source 002:
    R = (360 / 2 pi) L_r / alpha)."""

    length_m: Positive | None = None
    radius_m: Positive | None = None
    central_angle_deg: Annotated[float, Field(gt=0, lt=360)] | None = None

    @model_validator(mode="after")
    def _check_curve(self) -> CurveSpec:
        if self.end() is None:
            fail("a curve needs 'to_m' or 'length_m'", field="to_m")
        if (self.radius_m is None) == (self.central_angle_deg is None):
            fail("give exactly one of 'radius_m' or 'central_angle_deg'", field="radius_m")
        return self

    def radius(self) -> float:
        if self.radius_m is not None:
            return self.radius_m
        return line_resistance.curve_radius_from_angle(
            self.stop() - self.from_m, self.central_angle_deg or 0.0
        )


class TunnelSpec(_Section):
    length_m: Positive | None = None
    limiting_gradient: bool = False

    @model_validator(mode="after")
    def _check_tunnel(self) -> TunnelSpec:
        if self.end() is None:
            fail("a tunnel needs 'to_m' or 'length_m'", field="length_m")
        return self


class ElectrificationSpec(_Section):
    """An electrification entry: ``voltage_v`` (0: not electrified) and ``traction_share``, the share of
    its tractive effort an electric train may use there (0 < share <= 1, default 1: full effort)."""

    voltage_v: NonNegative
    traction_share: Fraction = 1.0


class LineResistanceSpec(Spec):
    """Formula choices; ``curve_formula`` and ``tunnel_formula`` are required (they change the result
    and no choice is neutral); ``gradient_formula`` defaults to ``small_angle`` (differs from ``exact``
    by < 0.01 % below 10 per mille) and ``apply_over`` to ``head`` (mass-point train)."""

    curve_formula: CurveFormula
    tunnel_formula: TunnelFormula
    gradient_formula: GradientFormula = "small_angle"
    apply_over: ApplyOver = "head"

    def build(self) -> LineResistanceSettings:
        return LineResistanceSettings(
            curve_formula=self.curve_formula,
            tunnel_formula=self.tunnel_formula,
            gradient_formula=self.gradient_formula,
            apply_over=self.apply_over,
        )


class RouteSpec(Spec):
    """A ``trainsim/route`` file (see docs/FORMAT.md)."""

    schema_id: Literal["trainsim/route"] = Field(default="trainsim/route", alias="schema")
    version: Literal[1] = 1
    name: str = Field(min_length=1)
    description: str | None = None
    start_m: float = 0.0
    length_m: Positive | None = None
    end_m: float | None = None
    stations: list[StationSpec] = Field(min_length=2)
    speed_limits: Annotated[list[SpeedLimitSpec], table_or_models(SpeedLimitSpec), _Table] = Field(
        min_length=1
    )
    gradients: Annotated[list[GradientSpec] | None, table_or_models(GradientSpec), _Table] = None
    elevation: Annotated[list[ElevationPointSpec] | None, table_or_models(ElevationPointSpec), _Table] = None
    curves: list[CurveSpec] = Field(default_factory=list)
    tunnels: list[TunnelSpec] = Field(default_factory=list)
    electrification: list[ElectrificationSpec] = Field(default_factory=list)
    line_resistance: LineResistanceSpec
    #: g for every weight force on the route [m/s^2]; default the standard 9.80665 (sources differ:
    #: TTOBench 9.81, ALTRIOS 9.80155; see trainsim.constants)
    gravity_mps2: float = STANDARD_GRAVITY

    @model_validator(mode="after")
    def _check_route(self) -> RouteSpec:
        if (self.length_m is None) == (self.end_m is None):
            fail("give exactly one of 'length_m' or 'end_m'", field="length_m")
        end = self.end()
        if not end > self.start_m:
            fail(
                "the route must end after it starts", field="end_m", value=end, allowed=f"> {self.start_m:g}"
            )
        if self.gradients is not None and self.elevation is not None:
            fail("give 'gradients' or 'elevation', not both", field="elevation")
        self._check_stations(end)
        self._check_changes("speed_limits", self.speed_limits, end, cover=True)
        self._check_changes("gradients", self.gradients or [], end, cover=False)
        self._check_changes("electrification", self.electrification, end, cover=False)
        self._check_spans("curves", self.curves, end)
        self._check_spans("tunnels", self.tunnels, end)
        if self.elevation is not None:
            if len(self.elevation) < 2:
                fail("an elevation profile needs at least 2 points", field="elevation")
            _check_increasing(column(self.elevation, "position_m"), "elevation", what="positions")
        return self

    def end(self) -> float:
        return self.end_m if self.end_m is not None else self.start_m + (self.length_m or 0.0)

    def _check_stations(self, end: float) -> None:
        names: dict[str, int] = {}
        for i, s in enumerate(self.stations):
            if not self.start_m <= s.position_m <= end:
                fail(
                    "station outside the route",
                    field=f"stations[{i}].position_m",
                    value=s.position_m,
                    allowed=f"{self.start_m:g} .. {end:g} m",
                )
            if s.name in names:
                fail(
                    f"station name already used by stations[{names[s.name]}]",
                    field=f"stations[{i}].name",
                    value=s.name,
                )
            names[s.name] = i
        _check_increasing([s.position_m for s in self.stations], "stations", what="station positions")

    def _check_changes(self, name: str, items: Sequence[_Section], end: float, *, cover: bool) -> None:
        """Lists of changes: each entry runs to its own ``to_m`` or to the next entry's start.

        Checked on whole columns (a list may hold 200,000 entries); each rule reports its first
        offending entry, as a loop over the entries would."""
        if not len(items):
            return
        starts, stops = column(items, "from_m"), column(items, "to_m")
        outside = np.flatnonzero(~((self.start_m <= starts) & (starts < end)))
        if outside.size:
            i = int(outside[0])
            fail(
                "section starts outside the route",
                field=f"{name}[{i}].from_m",
                value=float(starts[i]),
                allowed=f"{self.start_m:g} <= from_m < {end:g} m",
            )
        _check_increasing(starts, name, what="'from_m' positions")
        if cover and starts[0] != self.start_m:
            fail(
                f"{name} must start at the route start",
                field=f"{name}[0].from_m",
                value=float(starts[0]),
                allowed=f"{self.start_m:g}",
            )
        nxt = np.append(starts[1:], end)
        given = ~np.isnan(stops)
        over = given & (stops > nxt + 1e-9)
        gap = given & (stops < nxt - 1e-9) if cover else np.zeros_like(given)
        bad = np.flatnonzero(over | gap)
        if bad.size:
            i = int(bad[0])
            if over[i]:
                fail(
                    "section runs into the next one"
                    if i + 1 < len(items)
                    else "section runs past the route end",
                    field=f"{name}[{i}].to_m",
                    value=float(stops[i]),
                    allowed=f"<= {nxt[i]:g}",
                )
            fail(
                f"gap in {name}: every position needs a value (leave 'to_m' out to run to the next one)",
                field=f"{name}[{i}].to_m",
                value=float(stops[i]),
                allowed=f"{nxt[i]:g}",
            )

    def _check_spans(self, name: str, items: Sequence[_Section], end: float) -> None:
        for i, item in enumerate(items):
            stop = item.stop()
            if item.from_m < self.start_m or stop > end + 1e-9:
                fail(
                    "section outside the route",
                    field=f"{name}[{i}]",
                    value=(item.from_m, stop),
                    allowed=f"{self.start_m:g} .. {end:g} m",
                )
            if i > 0:
                prev_end = items[i - 1].stop()
                if item.from_m < prev_end - 1e-9:
                    fail(
                        f"{name} must be listed in order and must not overlap",
                        field=f"{name}[{i}].from_m",
                        value=item.from_m,
                        allowed=f">= {prev_end:g}",
                    )

    @staticmethod
    def _ends(items: Sequence[_Section], end: float) -> list[tuple[float, float]]:
        if isinstance(items, SpecTable):  # whole columns: a list may hold 200,000 entries
            starts, stops = items.column("from_m"), items.column("to_m")
            ends = np.where(np.isnan(stops), np.append(starts[1:], end), stops)
            return list(zip(starts.tolist(), ends.tolist(), strict=True))
        return [
            (x.from_m, x.to_m if x.to_m is not None else (items[i + 1].from_m if i + 1 < len(items) else end))
            for i, x in enumerate(items)
        ]

    def notes(self) -> list[str]:
        notes = []
        fields_set = self.line_resistance.model_fields_set
        if "gradient_formula" not in fields_set:
            notes.append("line_resistance.gradient_formula not given: small_angle")
        if "apply_over" not in fields_set:
            notes.append("line_resistance.apply_over not given: head (mass-point train)")
        if not self.gradients and not self.elevation:
            notes.append("no gradients: level line")
        return notes

    def to_route(self, file: str = "<route>") -> Route:
        """The :class:`~trainsim.model.Route` in SI units."""
        end = self.end()
        limits = [
            SpeedLimit(a, b, v * KMH)
            for (a, b), v in zip(
                self._ends(self.speed_limits, end),
                column(self.speed_limits, "limit_kmh").tolist(),
                strict=True,
            )
        ]
        gradients: list[GradientSection] = []
        if self.gradients:
            gradients = [
                GradientSection(a, b, g)
                for (a, b), g in zip(
                    self._ends(self.gradients, end),
                    column(self.gradients, "gradient_permille").tolist(),
                    strict=True,
                )
                if g != 0
            ]
        elif self.elevation:
            positions = column(self.elevation, "position_m").tolist()
            heights = column(self.elevation, "elevation_m").tolist()
            for (p, hp), (q, hq) in itertools.pairwise(zip(positions, heights, strict=True)):
                a, b = max(p, self.start_m), min(q, end)
                grade = (hq - hp) / (q - p) * 1000.0
                if b > a and grade != 0:
                    gradients.append(GradientSection(a, b, grade))
        with _located(file, "curves"):
            curves = [Curve(c.from_m, c.stop(), c.radius()) for c in self.curves]
        tunnels = [Tunnel(t.from_m, t.stop(), t.limiting_gradient) for t in self.tunnels]
        electrification = [
            ElectrificationSection(a, b, x.voltage_v, x.traction_share)
            for (a, b), x in zip(self._ends(self.electrification, end), self.electrification, strict=True)
        ]
        stations = [Station(s.name, s.position_m, s.dwell_s, s.stop) for s in self.stations]
        with _located(file, "route"):
            return Route(
                name=self.name,
                start_m=self.start_m,
                end_m=end,
                stations=tuple(stations),
                speed_limits=tuple(limits),
                gradients=tuple(gradients),
                curves=tuple(curves),
                tunnels=tuple(tunnels),
                electrification=tuple(electrification),
                line_resistance=self.line_resistance.build(),
                gravity_mps2=self.gravity_mps2,
            )


def route_spec_from_dict(data: Any, source: str = "<route>", *, path: str | Path | None = None) -> RouteSpec:
    """Validate a ``trainsim/route`` mapping."""
    return _validate(RouteSpec, data, "trainsim/route", source, path, header=True)
