"""Speed ceilings handed to the core as line limits: staircases, merging, and the driver's curve."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from trainsim import Route, SpeedLimit
from trainsim.errors import InputError
from trainsim.operations.ceiling import (
    driver_braking_steps,
    merge_limits,
    release_steps,
    staircase,
    uniform_braking_curve,
    with_limits,
)


def _value(limits, x: float) -> float:
    return next(s.limit_mps for s in limits if s.start_m <= x < s.end_m)


def test_merge_keeps_a_cover_with_the_lowest_value_everywhere() -> None:
    base = (SpeedLimit(0, 1000, 30.0), SpeedLimit(1000, 2000, 20.0))
    extra = (SpeedLimit(500, 1500, 25.0), SpeedLimit(1800, 1900, 5.0))
    merged = merge_limits(base, extra)
    assert merged[0].start_m == 0 and merged[-1].end_m == 2000
    assert all(a.end_m == b.start_m for a, b in pairwise(merged))
    for x, v in [(100, 30), (600, 25), (1200, 20), (1850, 5), (1950, 20)]:
        assert _value(merged, x) == v
    # a valid route: no gaps, no overlaps
    Route("r", 0, 2000, (), merged)


def test_a_staircase_never_exceeds_its_ceiling_and_converges_to_it() -> None:
    curve = uniform_braking_curve(30.0, 0.0, 1000.0)
    x = np.linspace(0, 999.9, 20001)
    gaps = []
    for n in (10, 100, 1000):
        steps = staircase(curve, 0.0, 1000.0, n)
        inside = x[x < steps[-1].end_m]
        v = np.array([_value(steps, p) for p in inside])
        assert np.all(v <= curve(inside) + 1e-12)
        gaps.append(float(np.mean(curve(inside) - v)))
    assert gaps[0] > gaps[1] > gaps[2]


def test_uniform_braking_curve_is_constant_deceleration() -> None:
    # v^2 = v0^2 - 2 a x with a = v0^2 / (2 d): 30 m/s stopping in 900 m is 0.5 m/s^2
    curve = uniform_braking_curve(30.0, 100.0, 1000.0)
    assert curve(np.array([100.0]))[0] == pytest.approx(30.0)
    assert curve(np.array([550.0]))[0] == pytest.approx(np.sqrt(900 - 2 * 0.5 * 450))
    assert curve(np.array([1000.0]))[0] == 0.0


def test_driver_steps_start_at_the_aspect_and_a_release_cuts_them() -> None:
    steps = driver_braking_steps(20.0, 1000.0, 2000.0)
    assert steps[0].start_m == 1000.0 and steps[0].limit_mps == pytest.approx(20.0)
    assert all(a.limit_mps > b.limit_mps for a, b in pairwise(steps))
    assert driver_braking_steps(0.1, 1000.0, 2000.0) == ()
    released = release_steps(steps, 1510.0, 13.0, slowed=True)
    assert all(s.start_m < 1510.0 for s in released[:-1]) and released[-2].end_m == 1510.0
    assert released[-1].start_m == 1510.0 and released[-1].limit_mps == 13.0
    assert release_steps(steps, 1000.0, 20.0, slowed=False) is None


def test_bad_ceilings_are_input_errors() -> None:
    with pytest.raises(InputError):
        staircase(lambda x: x, 10.0, 5.0, 4)
    with pytest.raises(InputError):
        staircase(lambda x: x, 0.0, 5.0, 0)
    with pytest.raises(InputError):
        uniform_braking_curve(10.0, 5.0, 5.0)
    route = Route("r", 0, 100, (), (SpeedLimit(0, 100, 10.0),))
    assert with_limits(route, (SpeedLimit(200, 300, 1.0),)) is route
