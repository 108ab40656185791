"""Cutting a route's spans (speed limits, gradients, curves, tunnels, electrification) to a stretch.

Several layers run a train over part of a route: the power supply's per-stretch runs between two
stops (``trainsim.power.stretches``), the operated runs of a line in operation
(``trainsim.operations.runs.service_route``), the voltage feedback that lays a share of tractive
effort over the electrification. They all cut the same way, here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from itertools import pairwise
from typing import TypeVar

import numpy as np

from trainsim.model.route import ElectrificationSection, Route, Station

__all__ = ["MIN_SPAN_M", "SPAN_FIELDS", "cut_spans", "electrification_cover", "route_between", "split_spans"]

#: A cut piece shorter than this is dropped [m]: it would only add a grid point of no length
#: (the core's stops and sections are placed to far coarser tolerances).
MIN_SPAN_M = 1e-9

#: The fields of a :class:`~trainsim.model.route.Route` that are spans ``[start_m, end_m)``.
SPAN_FIELDS = ("speed_limits", "gradients", "curves", "tunnels", "electrification")

S = TypeVar("S")


def cut_spans(items: Sequence[S], start_m: float, end_m: float) -> tuple[S, ...]:
    """The spans of ``items`` (objects with ``start_m`` and ``end_m`` [m]) that overlap
    ``[start_m, end_m]`` by more than :data:`MIN_SPAN_M`, cut to it, in their order."""
    out = []
    for x in items:
        lo, hi = max(x.start_m, start_m), min(x.end_m, end_m)  # type: ignore[attr-defined]
        if hi > lo + MIN_SPAN_M:
            out.append(dataclasses.replace(x, start_m=lo, end_m=hi))  # type: ignore[type-var]
    return tuple(out)


def route_between(route: Route, start_m: float, end_m: float, stations: Sequence[Station]) -> Route:
    """``route`` from ``start_m`` to ``end_m`` [m] with ``stations`` (inside it, in increasing
    position) instead of its own, every span cut to the stretch; name, line-resistance settings
    and gravity kept."""
    cut = {name: cut_spans(getattr(route, name), start_m, end_m) for name in SPAN_FIELDS}
    return dataclasses.replace(route, start_m=start_m, end_m=end_m, stations=tuple(stations), **cut)


def split_spans(items: Sequence[S], at_m: np.ndarray) -> tuple[S, ...]:
    """Each span of ``items`` split at every position of ``at_m`` strictly inside it (pieces
    shorter than :data:`MIN_SPAN_M` are not made), every other field kept."""
    at = np.unique(np.asarray(at_m, dtype=float))
    out = []
    for x in items:
        a, b = x.start_m, x.end_m  # type: ignore[attr-defined]
        inner = at[(at > a + MIN_SPAN_M) & (at < b - MIN_SPAN_M)]
        edges = [a, *inner.tolist(), b]
        out.extend(dataclasses.replace(x, start_m=lo, end_m=hi) for lo, hi in pairwise(edges))  # type: ignore[type-var]
    return tuple(out)


def electrification_cover(route: Route, voltage_v: float) -> tuple[ElectrificationSection, ...]:
    """The route's electrification with every part it does not cover given as a section at
    ``voltage_v`` [V] (what the core assumes there: the train's nominal line voltage), so that the
    sections cover ``[start_m, end_m)`` without a gap."""
    out: list[ElectrificationSection] = []
    pos = route.start_m
    for e in sorted(cut_spans(route.electrification, route.start_m, route.end_m), key=lambda e: e.start_m):
        if e.start_m > pos + MIN_SPAN_M:
            out.append(ElectrificationSection(pos, e.start_m, voltage_v))
        out.append(e)
        pos = max(pos, e.end_m)
    if route.end_m > pos + MIN_SPAN_M:
        out.append(ElectrificationSection(pos, route.end_m, voltage_v))
    return tuple(out)
