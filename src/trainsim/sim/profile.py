"""Compile a route for one train into the arrays the simulation kernel walks.

The route's piecewise data (gradients, curves, tunnels, speed limits) become, on a grid of head
positions that contains every breakpoint, per-interval linear laws of the specific line resistance
and a constant speed ceiling. Averaging over the train length (a homogeneous mass strip) turns a
piecewise constant law into a continuous piecewise linear one with breakpoints at x and x + L, so
both ways of applying line resistance share one representation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.train import Train
from trainsim.physics import line_resistance as lr
from trainsim.sim._trace_c import ceiling_law, kernel_grid, step_law

#: Smallest interval kept when merging breakpoints [m]; closer points are the same point.
POSITION_TOLERANCE_M = 1e-6

#: Steps next to standstill are graded geometrically down to this length [m], because the time
#: spent in the last metres before a stop depends on the braking law at walking speed.
SMALLEST_STEP_M = 0.005

#: Ratio between successive graded steps next to a stop or a start.
GRADING_RATIO = 2.0


@dataclass(frozen=True)
class PiecewiseLinear:
    """A function of position, linear on each ``[x[k], x[k+1])``, given by values at both ends of
    each piece (so it may jump at a breakpoint). Beyond the ends it keeps the end values."""

    x: np.ndarray  # breakpoints, increasing [m]
    left: np.ndarray  # value at x[k] from the right (start of piece k)
    right: np.ndarray  # value at x[k+1] from the left (end of piece k)

    def __post_init__(self) -> None:
        # piecewise constant (left == right on every piece, e.g. a gradient step function): the
        # interpolation is left[k] + 0 x frac, so it is skipped (most calls of a run are of these)
        object.__setattr__(self, "_steps", bool(np.array_equal(self.left, self.right)))

    def __call__(self, s: np.ndarray | float) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        if self._steps and s.ndim == 1:
            k = np.searchsorted(self.x, s, side="right") - 1
            # not np.clip: with Python int bounds it looks up integer limits on every call
            np.maximum(k, 0, out=k)
            np.minimum(k, len(self.left) - 1, out=k)
            out = self.left[k] + 0.0  # + 0.0: -0.0 becomes 0.0, as left + 0 x frac does
            nan = np.isnan(s)
            if nan.any():
                out[nan] = np.nan
            return out
        k = np.searchsorted(self.x, s, side="right") - 1
        k = np.minimum(np.maximum(k, 0), len(self.left) - 1)
        x0 = self.x[k]
        frac = np.minimum(np.maximum((s - x0) / (self.x[k + 1] - x0), 0.0), 1.0)
        left = self.left[k]
        return left + (self.right[k] - left) * frac


def step_function(
    starts: list[float], ends: list[float], values: list[float], lo: float, hi: float
) -> PiecewiseLinear:
    """A piecewise constant function on [lo, hi] that is ``values[k]`` on ``[starts[k], ends[k])``
    and 0 elsewhere (the sections do not overlap)."""
    if not len(starts):
        # no section (a route without curves or tunnels): 0 on [lo, hi], without the look-ups (and
        # without np.unique's sort of two values, a tenth of compile_route on such a route)
        x = np.array([lo, hi], dtype=float)
        if not lo < hi:
            x = np.unique(np.clip(x, lo, hi))
        return PiecewiseLinear(x, np.zeros(len(x) - 1), np.zeros(len(x) - 1))
    a = np.asarray(starts, dtype=float)
    val_in = np.broadcast_to(np.asarray(values, dtype=float), a.shape)
    # compiled (one call instead of a dozen numpy calls: most of line_resistance_profile's time)
    law = step_law(a, np.asarray(ends, dtype=float), val_in, float(lo), float(hi))
    if law is None:
        raise InputError(
            "a section's start or end, or the route's start or end, is not a number",
            field="route",
            value=[lo, hi, *a.tolist(), *np.asarray(ends, dtype=float).tolist()][:8],
            allowed="finite positions [m]",
        )
    return PiecewiseLinear(*law)


def averaged_over_length(f: PiecewiseLinear, length_m: float) -> PiecewiseLinear:
    """The mean of a piecewise constant ``f`` over ``[s - L, s]`` as a function of the head
    position s (exact: the mean of a step function over a sliding window is piecewise linear)."""
    x = f.x
    lo, hi = x[0], x[-1]
    # integral F(s) of the step function, extended with the end values beyond the ends
    cum = np.concatenate([[0.0], np.cumsum(f.left * np.diff(x))])

    def integral(s: np.ndarray) -> np.ndarray:
        s_c = np.clip(s, lo, hi)
        k = np.clip(np.searchsorted(x, s_c, side="right") - 1, 0, len(f.left) - 1)
        inside = cum[k] + f.left[k] * (s_c - x[k])
        return (
            inside
            + np.where(s < lo, (s - lo) * f.left[0], 0.0)
            + np.where(s > hi, (s - hi) * f.left[-1], 0.0)
        )

    nodes = np.unique(np.clip(np.concatenate([x, x + length_m]), lo, hi))
    mean = (integral(nodes) - integral(nodes - length_m)) / length_m
    return PiecewiseLinear(nodes, mean[:-1].copy(), mean[1:].copy())


def speed_ceiling(route: Route, train: Train) -> PiecewiseLinear:
    """Most restrictive speed profile over head position [m/s]: the line limits, each held until
    the train's rear has cleared it, and the train's maximum speed."""
    limits = route.speed_limits
    # compiled: the breakpoints and each piece's lowest limit in one call (``_trace_c.ceiling_law``)
    law = ceiling_law(
        np.array([lim.start_m for lim in limits], dtype=float),
        np.array([lim.end_m for lim in limits], dtype=float),
        np.array([lim.limit_mps for lim in limits], dtype=float),
        float(train.length_m),
        float(route.start_m),
        float(route.end_m),
        float(train.max_speed_mps),
    )
    if law is None:
        raise InputError(
            "the route's start or end is not a number",
            field="route",
            value=[route.start_m, route.end_m],
            allowed="finite positions [m]",
        )
    return PiecewiseLinear(*law)


@dataclass(frozen=True)
class LineResistanceProfile:
    """Specific line resistances over head position, each a ratio of the train's weight
    (force = ratio x m g, g = ``gravity_mps2``, the route's); ``tunnel_v2`` multiplies v^2 [s^2/m^2]."""

    gradient: PiecewiseLinear
    curve: PiecewiseLinear
    tunnel: PiecewiseLinear
    tunnel_v2: PiecewiseLinear
    gravity_mps2: float

    def weight_n(self, mass_kg: float) -> float:
        """Weight m g of a mass [kg] with the route's gravity [N]."""
        return mass_kg * self.gravity_mps2


def line_resistance_profile(route: Route, train: Train) -> LineResistanceProfile:
    """Evaluate the route's gradient, curve and tunnel resistance laws once, at the head or
    averaged over the train's length as the route's settings say."""
    settings = route.line_resistance
    lo, hi = route.start_m, route.end_m
    grad = step_function(
        [g.start_m for g in route.gradients],
        [g.end_m for g in route.gradients],
        lr.gradient_ratio(
            np.array([g.gradient_permille for g in route.gradients]), settings.gradient_formula
        ),
        lo,
        hi,
    )
    curve = step_function(
        [c.start_m for c in route.curves],
        [c.end_m for c in route.curves],
        [
            lr.curve_ratio(c.radius_m, settings.curve_formula, gravity_mps2=route.gravity_mps2)
            for c in route.curves
        ],
        lo,
        hi,
    )
    weight = train.mass_kg * route.gravity_mps2
    # a measured train-specific tunnel drag (TTOBench) adds to the formula's v^2 term
    tunnel_terms = [
        (c, k + t.extra_drag_n_s2_per_m2 / weight)
        for t in route.tunnels
        for c, k in [lr.tunnel_ratio(t.length_m, settings.tunnel_formula, t.limiting_gradient)]
    ]
    tun0 = step_function(
        [t.start_m for t in route.tunnels],
        [t.end_m for t in route.tunnels],
        [c for c, _ in tunnel_terms],
        lo,
        hi,
    )
    tun2 = step_function(
        [t.start_m for t in route.tunnels],
        [t.end_m for t in route.tunnels],
        [k for _, k in tunnel_terms],
        lo,
        hi,
    )
    if settings.apply_over == "train_length":
        grad, curve, tun0, tun2 = (averaged_over_length(f, train.length_m) for f in (grad, curve, tun0, tun2))
    return LineResistanceProfile(grad, curve, tun0, tun2, route.gravity_mps2)


def line_voltage(route: Route, train: Train) -> PiecewiseLinear:
    """Line voltage over head position [V]: the route's electrification sections, the train's
    nominal voltage where the route says nothing (a route without electrification data is
    electrified throughout), 0 on parts electrified with 0 V (not electrified)."""
    nominal = train.electrical.line_voltage_v if train.electrical else 0.0
    lo, hi = route.start_m, route.end_m
    sections = route.electrification
    covered = step_function(
        [e.start_m for e in sections], [e.end_m for e in sections], [1.0] * len(sections), lo, hi
    )
    voltage = step_function(
        [e.start_m for e in sections], [e.end_m for e in sections], [e.voltage_v for e in sections], lo, hi
    )
    value = np.where(covered.left > 0, voltage.left, nominal)
    return PiecewiseLinear(voltage.x, value.copy(), value.copy())


def traction_availability(
    route: Route, train: Train, voltage: PiecewiseLinear | None = None
) -> PiecewiseLinear:
    """Share of the tractive effort available over head position [-]: an electric train (one with
    electrical data) has none where the line is not electrified and the section's
    ``traction_share`` where it is (1 where the route has no section); other trains are not fed by
    the line, so they have all of it everywhere, whatever the sections' shares.
    ``voltage``: ``line_voltage(route, train)`` when the caller has it already."""
    voltage = line_voltage(route, train) if voltage is None else voltage
    if train.electrical is None:
        ones = np.ones(len(voltage.left))
        return PiecewiseLinear(voltage.x, ones, ones.copy())
    on = (voltage.left > 0).astype(float)
    sections = route.electrification
    if any(e.traction_share != 1.0 for e in sections):
        # the share as a step function on the voltage's own breakpoints (both are cut at the same
        # section ends), 1 where no section covers the route
        starts, ends = [e.start_m for e in sections], [e.end_m for e in sections]
        lo, hi = voltage.x[0], voltage.x[-1]
        covered = step_function(starts, ends, [1.0] * len(sections), lo, hi)
        share = step_function(starts, ends, [e.traction_share for e in sections], lo, hi)
        mid = 0.5 * (voltage.x[:-1] + voltage.x[1:])
        k = np.clip(np.searchsorted(share.x, mid, side="right") - 1, 0, len(share.left) - 1)
        on = on * np.where(covered.left[k] > 0, share.left[k], 1.0)
    return PiecewiseLinear(voltage.x, on, on.copy())


@dataclass(frozen=True)
class KernelTrack:
    """The arrays the kernel walks: grid of head positions and per-interval laws."""

    x: np.ndarray  # grid [m], N + 1 points
    a0: np.ndarray  # specific line resistance (ratio x g) at the start of each interval [N/kg]
    a1: np.ndarray  # its slope [N/(kg m)]
    b0: np.ndarray  # v^2 coefficient (ratio x g) at the start of each interval [N s^2/(kg m^2)]
    b1: np.ndarray  # its slope [N s^2/(kg m^3)]
    vlim: np.ndarray  # speed ceiling on each interval [m/s]
    traction_scale: np.ndarray  # share of the tractive effort available on each interval [-]
    stop_index: np.ndarray  # grid index of each stop, increasing


@dataclass(frozen=True)
class CompiledRoute:
    """Everything a run derives from its route and train once: the kernel's arrays, the line
    resistance laws, the speed ceiling, the traction availability and the line voltage."""

    track: KernelTrack
    profile: LineResistanceProfile
    ceiling: PiecewiseLinear
    available: PiecewiseLinear
    voltage: PiecewiseLinear


def compile_route(route: Route, train: Train, stops_m: list[float], max_step_m: float) -> CompiledRoute:
    """Build the kernel grid for a run between the first and last of ``stops_m``, with the laws
    the result needs too (``compile_track`` returns its first three).

    The grid holds every stop and every breakpoint of the laws in between (points closer than
    ``POSITION_TOLERANCE_M`` merged), each interval split uniformly into steps of at most
    ``max_step_m``, graded from ``SMALLEST_STEP_M`` by ``GRADING_RATIO`` next to a stop; each interval's
    laws are read just inside it so that a jump at a breakpoint belongs to the interval on its right.
    Grid and laws are built in one compiled call (``_trace_c.kernel_grid``)."""
    profile = line_resistance_profile(route, train)
    ceiling = speed_ceiling(route, train)
    voltage = line_voltage(route, train)
    available = traction_availability(route, train, voltage)
    laws = (profile.gradient, profile.curve, profile.tunnel, profile.tunnel_v2, ceiling, available)
    x, a0, a1, b0, b1, vlim, traction_scale, stop_index = kernel_grid(
        tuple(_law_arrays(f) for f in laws),
        np.asarray(stops_m, dtype=float),
        float(max_step_m),
        float(route.gravity_mps2),
        POSITION_TOLERANCE_M,
        SMALLEST_STEP_M,
        GRADING_RATIO,
    )
    if x is None:
        raise InputError("internal: grid not increasing", field="route")
    track = KernelTrack(x, a0, a1, b0, b1, vlim, traction_scale, stop_index)
    return CompiledRoute(track, profile, ceiling, available, voltage)


def _law_arrays(f: PiecewiseLinear) -> tuple:
    """A ``PiecewiseLinear`` as the compiled kernels take it: ``(x, left, right, piecewise constant)``."""
    return (
        np.ascontiguousarray(f.x, dtype=float),
        np.ascontiguousarray(f.left, dtype=float),
        np.ascontiguousarray(f.right, dtype=float),
        bool(f._steps),
    )


def compile_track(
    route: Route, train: Train, stops_m: list[float], max_step_m: float
) -> tuple[KernelTrack, LineResistanceProfile, PiecewiseLinear]:
    """Build the kernel grid for a run between the first and last of ``stops_m``: the kernel's
    arrays, the line resistance laws and the speed ceiling (see ``compile_route``)."""
    compiled = compile_route(route, train, stops_m, max_step_m)
    return compiled.track, compiled.profile, compiled.ceiling
