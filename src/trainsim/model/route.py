"""The line as the simulation core sees it: positions in metres from the route's origin."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Literal

import numpy as np

from trainsim.constants import GRAVITY_RANGE_MPS2, STANDARD_GRAVITY
from trainsim.errors import InputError
from trainsim.model import bounds

CurveFormula = Literal["roeckl", "wang", "tbt1407", "french800", "none"]
TunnelFormula = Literal["wang", "tbt1407", "none"]
ApplyOver = Literal["head", "train_length"]
GradientFormula = Literal["small_angle", "exact"]


#: Dwell times: a stop of up to the "time" bound (about 11.6 days), never negative.
_DWELL_BOUND = bounds.Bound("time", "s", 0.0, bounds.BOUNDS["time"].high, why="dwell times")


@dataclass(frozen=True)
class Station:
    """A station (or any stopping point) on the route.

    Attributes:
        name: station name.
        position_m: where the train's head stops [m].
        dwell_s: dwell time when the train stops there [s].
        stop: whether the train stops there.
    """

    name: str
    position_m: float
    dwell_s: float = 0.0
    stop: bool = True


@dataclass(frozen=True)
class SpeedLimit:
    """A line speed limit on ``[start_m, end_m)`` [m], ``limit_mps`` [m/s]."""

    start_m: float
    end_m: float
    limit_mps: float


@dataclass(frozen=True)
class GradientSection:
    """A constant gradient on ``[start_m, end_m)``: positive uphill, in per mille (m per km, N/kN)."""

    start_m: float
    end_m: float
    gradient_permille: float


@dataclass(frozen=True)
class Curve:
    """A curve of radius ``radius_m`` [m] on ``[start_m, end_m)`` [m]."""

    start_m: float
    end_m: float
    radius_m: float


@dataclass(frozen=True)
class Tunnel:
    """A tunnel on ``[start_m, end_m)`` [m].

    ``limiting_gradient`` selects source 000's law for tunnels on a limiting (ruling) gradient,
    whose resistance grows with speed squared. ``extra_drag_n_s2_per_m2``, when given, is a
    measured additional aerodynamic drag of the train in this tunnel, ``F = k v^2`` [N s^2/m^2]
    (TTOBench gives it per train and tunnel cross-section); it is added to the formula's value.
    """

    start_m: float
    end_m: float
    limiting_gradient: bool = False
    extra_drag_n_s2_per_m2: float = 0.0

    @property
    def length_m(self) -> float:
        """Tunnel length [m]."""
        return self.end_m - self.start_m


@dataclass(frozen=True)
class ElectrificationSection:
    """Electrification on ``[start_m, end_m)``: ``voltage_v`` [V], 0 for a non-electrified part.

    ``traction_share`` [-] is the share of its tractive effort an electric train (one with electrical
    data) may use on the section, in (0, 1]: what the power supply lets it draw there when the
    pantograph voltage falls (``trainsim.power.traction_share``, method ``per_step``). 1 (the
    default) is the train's full effort. Trains without electrical data are not fed by the line and
    ignore it (see ``trainsim.sim.profile.traction_availability``).
    """

    start_m: float
    end_m: float
    voltage_v: float
    traction_share: float = 1.0

    def __post_init__(self) -> None:
        share = self.traction_share
        # a share of 0 would be an unelectrified section: that is voltage_v 0, not a share
        number = isinstance(share, int | float) and not isinstance(share, bool)
        if not (number and math.isfinite(share) and 0.0 < share <= 1.0):
            raise InputError(
                "invalid share of tractive effort on an electrification section",
                field="electrification.traction_share",
                value=share,
                allowed="a number 0 < x <= 1 (1: the train's full tractive effort)",
            )


@dataclass(frozen=True)
class LineResistanceSettings:
    """Which line-resistance formulas apply and where on the train.

    Attributes:
        curve_formula: ``roeckl`` (Roeckl 650/(R-55), 500/(R-30) per mille), ``wang`` (source 000
            as printed), ``tbt1407`` (600/R, source 002 eq. 6), ``french800`` (800/R, source 001),
            or ``none``.
        tunnel_formula: ``wang`` (source 000, both tunnel kinds), ``tbt1407`` (0.00013 L_s N/kN,
            source 002 eq. 7) or ``none``.
        gradient_formula: ``small_angle`` (i per mille = i N/kN, source 002 eq. 5) or ``exact``
            (m g sin(atan(i/1000)), source 000).
        apply_over: ``head`` evaluates at the head; ``train_length`` averages over the train's
            length (homogeneous mass strip).
    """

    curve_formula: CurveFormula = "roeckl"
    tunnel_formula: TunnelFormula = "wang"
    gradient_formula: GradientFormula = "small_angle"
    apply_over: ApplyOver = "head"


@dataclass(frozen=True)
class Route:
    """A route: the path one train runs, with its stations and line data.

    Attributes:
        name: route name.
        start_m: position where the route starts [m].
        end_m: position where it ends [m].
        stations: stations in increasing position.
        speed_limits: line speed limits covering ``[start_m, end_m)`` without gaps or overlaps.
        gradients: gradient sections (positions not covered are level).
        curves: curves (positions not covered are straight).
        tunnels: tunnels.
        electrification: electrified sections (empty: electrified everywhere).
        line_resistance: formula choices.
        gravity_mps2: acceleration due to gravity g [m/s^2] for every weight force on this route
            (gradient, curve, tunnel, weight-based resistance, adhesion); default the standard
            9.80665. Readers set their source's convention (``trainsim.constants``:
            ``TRAINRUNS_GRAVITY`` 9.80665, ``TTOBENCH_GRAVITY`` 9.81, ``ALTRIOS_GRAVITY`` 9.80155).
    """

    name: str
    start_m: float
    end_m: float
    stations: tuple[Station, ...]
    speed_limits: tuple[SpeedLimit, ...]
    gradients: tuple[GradientSection, ...] = ()
    curves: tuple[Curve, ...] = ()
    tunnels: tuple[Tunnel, ...] = ()
    electrification: tuple[ElectrificationSection, ...] = ()
    line_resistance: LineResistanceSettings = field(default_factory=LineResistanceSettings)
    gravity_mps2: float = STANDARD_GRAVITY

    def __post_init__(self) -> None:
        lo, hi = GRAVITY_RANGE_MPS2
        if not lo <= self.gravity_mps2 <= hi:
            raise InputError(
                "gravity must be the acceleration due to gravity at the Earth's surface",
                field="gravity_mps2",
                value=self.gravity_mps2,
                allowed=f"{lo:g} .. {hi:g} m/s^2 (standard 9.80665)",
            )
        for name in ("stations", "speed_limits", "gradients", "curves", "tunnels", "electrification"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        bounds.check(self.start_m, "length", field="route start_m", unit="m")
        bounds.check(self.end_m, "length", field="route end_m", unit="m")
        if not (np.isfinite(self.start_m) and np.isfinite(self.end_m) and self.end_m > self.start_m):
            raise InputError(
                "the route must end after it starts",
                field="route length",
                value=(self.start_m, self.end_m),
            )
        positions = [s.position_m for s in self.stations]
        if any(b < a for a, b in pairwise(positions)):
            raise InputError("stations must be in increasing position", field="stations", value=positions)
        for s in self.stations:
            if not self.start_m - 1e-9 <= s.position_m <= self.end_m + 1e-9:
                raise InputError(
                    f"station '{s.name}' lies outside the route",
                    field="stations.position",
                    value=s.position_m,
                    allowed=f"{self.start_m:g} .. {self.end_m:g} m",
                )
            if not s.dwell_s >= 0:
                raise InputError(
                    f"station '{s.name}' has a negative dwell time",
                    field="stations.dwell",
                    value=s.dwell_s,
                    allowed=">= 0 s",
                )
            # a dwell of 1e308 s once gave a run of 0 s that said ok: bound it like every time
            bounds.check(s.dwell_s, _DWELL_BOUND, field=f"stations.dwell ('{s.name}')", unit="s")
        self._check_cover("speed_limits", [(x.start_m, x.end_m) for x in self.speed_limits], full=True)
        for x in self.speed_limits:
            if not 0 < x.limit_mps < 200:
                raise InputError(
                    "speed limits must be positive",
                    field="speed_limits",
                    value=x.limit_mps * 3.6,
                    allowed="0 < v < 720 km/h",
                )
        self._check_cover("gradients", [(x.start_m, x.end_m) for x in self.gradients])
        for g in self.gradients:
            if not abs(g.gradient_permille) < 200:
                raise InputError(
                    "gradient out of range",
                    field="gradients",
                    value=g.gradient_permille,
                    allowed="-200 .. 200 per mille",
                )
        self._check_cover("curves", [(x.start_m, x.end_m) for x in self.curves])
        for c in self.curves:
            if not c.radius_m > 0:
                raise InputError("curve radius must be > 0", field="curves.radius", value=c.radius_m)
        self._check_cover("tunnels", [(x.start_m, x.end_m) for x in self.tunnels])
        self._check_cover("electrification", [(x.start_m, x.end_m) for x in self.electrification])

    def _check_cover(self, name: str, spans: list[tuple[float, float]], full: bool = False) -> None:
        spans = sorted(spans)
        for a, b in spans:
            if not b > a:
                raise InputError(f"{name}: a section must end after it starts", field=name, value=(a, b))
        for (a0, b0), (a1, _b1) in pairwise(spans):
            if a1 < b0 - 1e-6:
                raise InputError(f"{name}: sections overlap", field=name, value=((a0, b0), (a1, _b1)))
            if full and a1 > b0 + 1e-6:
                raise InputError(f"{name}: gap between sections", field=name, value=(b0, a1))
        if full:
            if not spans:
                raise InputError(f"{name}: at least one section is required", field=name)
            if spans[0][0] > self.start_m + 1e-6 or spans[-1][1] < self.end_m - 1e-6:
                raise InputError(
                    f"{name} must cover the whole route",
                    field=name,
                    value=(spans[0][0], spans[-1][1]),
                    allowed=f"{self.start_m:g} .. {self.end_m:g} m",
                )

    @property
    def length_m(self) -> float:
        """Route length [m]."""
        return self.end_m - self.start_m

    @property
    def stops(self) -> tuple[Station, ...]:
        """Stations where the train stops."""
        return tuple(s for s in self.stations if s.stop)
