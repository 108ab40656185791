"""The shared span-cutting helper (trainsim.model.spans)."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.model import ElectrificationSection, GradientSection, Route, SpeedLimit, Station
from trainsim.model.spans import (
    MIN_SPAN_M,
    cut_spans,
    electrification_cover,
    route_between,
    split_spans,
)


def _route() -> Route:
    return Route(
        "line",
        0.0,
        1000.0,
        (Station("A", 0.0, 0.0, True), Station("P", 400.0, 0.0, False), Station("B", 1000.0, 0.0, True)),
        (SpeedLimit(0.0, 300.0, 20.0), SpeedLimit(300.0, 1000.0, 30.0)),
        gradients=(GradientSection(100.0, 600.0, 5.0),),
        electrification=(ElectrificationSection(200.0, 700.0, 750.0),),
        gravity_mps2=9.81,
    )


def test_cut_spans_keeps_overlaps_only_and_cuts_them():
    limits = _route().speed_limits
    cut = cut_spans(limits, 250.0, 500.0)
    assert [(x.start_m, x.end_m, x.limit_mps) for x in cut] == [(250.0, 300.0, 20.0), (300.0, 500.0, 30.0)]
    # a span touching the stretch only at its end, or by less than MIN_SPAN_M, is not kept
    assert cut_spans(limits, 300.0, 300.0 + 0.5 * MIN_SPAN_M) == ()
    assert cut_spans(limits, 1000.0, 1200.0) == ()


def test_route_between_cuts_every_span_and_keeps_the_rest():
    r = _route()
    stations = (Station("from", 150.0, 0.0, True), Station("to", 650.0, 0.0, True))
    part = route_between(r, 150.0, 650.0, stations)
    assert (part.start_m, part.end_m, part.stations) == (150.0, 650.0, stations)
    assert [(x.start_m, x.end_m) for x in part.speed_limits] == [(150.0, 300.0), (300.0, 650.0)]
    assert [(x.start_m, x.end_m) for x in part.gradients] == [(150.0, 600.0)]
    assert [(x.start_m, x.end_m) for x in part.electrification] == [(200.0, 650.0)]
    assert (part.name, part.gravity_mps2, part.line_resistance) == (r.name, 9.81, r.line_resistance)


def test_split_spans_makes_a_cover_of_the_same_spans():
    limits = _route().speed_limits
    pieces = split_spans(limits, np.array([100.0, 300.0, 300.0, 650.0, 2000.0]))
    assert [(x.start_m, x.end_m, x.limit_mps) for x in pieces] == [
        (0.0, 100.0, 20.0),
        (100.0, 300.0, 20.0),
        (300.0, 650.0, 30.0),
        (650.0, 1000.0, 30.0),
    ]


@pytest.mark.parametrize("voltage", [750.0, 1500.0])
def test_electrification_cover_fills_the_gaps_at_the_given_voltage(voltage):
    cover = electrification_cover(_route(), voltage)
    assert [(x.start_m, x.end_m, x.voltage_v) for x in cover] == [
        (0.0, 200.0, voltage),
        (200.0, 700.0, 750.0),
        (700.0, 1000.0, voltage),
    ]
