"""The kernel grid built in one compiled call (``_trace_c.kernel_grid`` through ``profile.compile_route``)
is the grid the numpy code it replaced built, bit for bit: every example, the TrainRuns freight train on
``realworld`` (mass point and strip), an electrification gap and grids made to hit the edge cases
(breakpoints closer than the tolerance, a stop on a breakpoint, coarse intervals shorter than the
grading, steps longer than the line); the grading checked by hand; bad input refused by name."""

from __future__ import annotations

import dataclasses
import itertools
import warnings
from pathlib import Path

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.errors import InputError
from trainsim.model import Electrical, ElectrificationSection, GradientSection, Quadratic, Station
from trainsim.model.scenario import RunSettings
from trainsim.sim import _trace_c
from trainsim.sim import profile as prof
from trainsim.sim.fastest import stops_of

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


def _graded_numpy(a: float, b: float, max_step: float, grade_left: bool, grade_right: bool) -> list[float]:
    """``profile._graded`` as it was before the grid was compiled (the reference)."""
    pts: list[float] = []
    length = b - a
    left_edge, right_edge = a, b
    if grade_left or grade_right:
        h = prof.SMALLEST_STEP_M
        reach = min(max_step, length / (2 if grade_left and grade_right else 1))
        offsets = []
        while h < reach:
            offsets.append(h)
            h *= prof.GRADING_RATIO
        if grade_left:
            pts += [a + d for d in offsets]
            left_edge = a + (offsets[-1] if offsets else 0.0)
        if grade_right:
            pts += [b - d for d in offsets]
            right_edge = b - (offsets[-1] if offsets else 0.0)
    span = right_edge - left_edge
    if span > 0:
        n = int(np.ceil(span / max_step - 1e-9))
        pts += list(np.linspace(left_edge, right_edge, n + 1)[1:-1])
    return sorted(pts)


def _grid_numpy(laws, stops_m: list[float], max_step_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The grid and stop indices as ``compile_route`` computed them with numpy (the reference)."""
    lo, hi = stops_m[0], stops_m[-1]
    inside = [f.x[(f.x > lo) & (f.x < hi)] for f in laws]
    coarse = np.unique(np.concatenate([[lo, hi], np.asarray(stops_m, dtype=float), *inside]))
    coarse = coarse[np.concatenate([[True], np.diff(coarse) > prof.POSITION_TOLERANCE_M])]
    stop_set = set(stops_m)
    widths = np.diff(coarse)
    counts = np.maximum(np.ceil(widths / max_step_m - 1e-9).astype(np.int64), 1)
    at_stop = np.isin(coarse, np.asarray(stops_m, dtype=float))
    graded = at_stop[:-1] | at_stop[1:]
    counts[graded] = 1
    starts = np.repeat(coarse[:-1], counts)
    within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    uniform = starts + within * np.repeat(widths / counts, counts)
    extra: list[float] = []
    for k in np.flatnonzero(graded):
        a, b = float(coarse[k]), float(coarse[k + 1])
        extra += _graded_numpy(a, b, max_step_m, a in stop_set, b in stop_set)
    x = np.unique(np.concatenate([uniform, coarse[-1:], np.array(extra)]))
    return x, np.searchsorted(x, np.array(stops_m) - prof.POSITION_TOLERANCE_M)


def _electric_gap():
    train = dataclasses.replace(
        make_train(resistance=Quadratic(3000.0, 20.0, 5.0)),
        electrical=Electrical(line_voltage_v=1500.0, traction_efficiency=0.9, power_factor=0.95),
    )
    route = dataclasses.replace(
        make_route(length_m=10_000.0, limit_kmh=160.0, gradient_permille=4.0, apply_over="train_length"),
        electrification=(
            ElectrificationSection(0.0, 4000.0, 1500.0),
            ElectrificationSection(4000.0, 4500.0, 0.0),
            ElectrificationSection(4500.0, 10_000.0, 1500.0),
        ),
    )
    return train, route


def _awkward():
    """Breakpoints 0.4 um apart (merged), stops on gradient breakpoints, breakpoints 20 mm and 3 mm
    after a stop (coarse intervals shorter than the grading), two stops 1.5 m apart."""
    train = make_train()
    base = make_route(length_m=3000.0, limit_kmh=100.0)
    grads = (
        GradientSection(0.0, 1000.0, 2.0),
        GradientSection(1000.0, 1000.0000004, -1.0),
        GradientSection(1000.0000004, 1500.0, 5.0),
        GradientSection(1500.0, 1500.02, 4.0),
        GradientSection(1500.02, 2000.003, -3.0),
        GradientSection(2000.003, 3000.0, 1.0),
    )
    stations = (
        Station("A", 0.0),
        Station("B", 1500.0, dwell_s=10.0),
        Station("C", 1501.5, dwell_s=10.0),
        Station("D", 2000.0, dwell_s=10.0),
        Station("E", 3000.0),
    )
    return train, dataclasses.replace(base, gradients=grads, stations=stations)


def _cases():
    for path in sorted((ROOT / "examples").rglob("scenario*.yaml")):
        sc = trainsim.load_scenario(path)
        yield str(path.relative_to(ROOT / "examples")), sc.train, sc.route, sc.settings.max_step_m
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        freight = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml")
    for mass_model in ("mass_point", "homogeneous_strip"):
        route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model=mass_model)
        yield f"trainruns_freight_{mass_model}", freight, route, RunSettings().max_step_m
    yield "electrification_gap", *_electric_gap(), 40.0
    train, route = _awkward()
    for step in (0.05, 0.7, 20.0, 1e7):
        yield f"awkward_step_{step}", train, route, step


@pytest.fixture(scope="module")
def compiled_cases():
    out = []
    for name, train, route, max_step in _cases():
        train = train.at_gravity(route.gravity_mps2)
        stops = stops_of(route)
        out.append((name, route, stops, max_step, prof.compile_route(route, train, stops, max_step)))
    return out


def test_grid_equals_the_numpy_grid_bit_for_bit(compiled_cases):
    for name, route, stops, max_step, compiled in compiled_cases:
        p = compiled.profile
        laws = (p.gradient, p.curve, p.tunnel, p.tunnel_v2, compiled.ceiling, compiled.available)
        x, stop_index = _grid_numpy(laws, stops, max_step)
        track = compiled.track
        np.testing.assert_array_equal(track.x, x, err_msg=name)
        np.testing.assert_array_equal(track.stop_index, stop_index, err_msg=name)
        assert track.stop_index.dtype == np.int64
        # the per-interval laws are interval_laws' (tested against numpy in test_trace_kernel.py)
        ref = _trace_c.interval_laws(x, *(prof._law_arrays(f) for f in laws), float(route.gravity_mps2))
        got = (track.a0, track.a1, track.b0, track.b1, track.vlim, track.traction_scale)
        for label, a, b in zip(("a0", "a1", "b0", "b1", "vlim", "scale"), got, ref, strict=True):
            np.testing.assert_array_equal(a, b, err_msg=f"{name}: {label}")


def test_the_cases_reach_the_edge_cases(compiled_cases):
    """Merged breakpoints, graded intervals on both sides and on one, uniform ones."""
    by_name = {name: (stops, c) for name, _, stops, _, c in compiled_cases}
    stops, c = by_name["awkward_step_20.0"]
    x = c.track.x
    assert 1000.0 in x and 1000.0000004 not in x  # merged: closer than POSITION_TOLERANCE_M
    assert 1500.02 in x and 2000.003 in x
    assert len(c.track.a0) == len(x) - 1 and np.all(np.diff(x) > 0)
    assert np.array_equal(x[c.track.stop_index], stops)


def test_grading_by_hand():
    """Two stops 100 m apart, no breakpoint between, steps of at most 20 m: 5, 10, 20, 40 mm, ...
    10.24 m from each stop (offsets doubling while below half the interval and the step), then the
    rest split uniformly into steps of at most 20 m (numpy's linspace: i x step + start)."""
    zero = prof._law_arrays(prof.PiecewiseLinear(np.array([0.0, 100.0]), np.zeros(1), np.zeros(1)))
    x, *laws, stop_index = _trace_c.kernel_grid(
        (zero,) * 6, np.array([0.0, 100.0]), 20.0, 9.81, 1e-6, 0.005, 2.0
    )
    offsets = [0.005 * 2.0**k for k in range(12)]  # 0.005 ... 10.24 < 20, the next 20.48 is not
    left, right = offsets[-1], 100.0 - offsets[-1]
    n = int(np.ceil((right - left) / 20.0 - 1e-9))  # 80 m: 4 steps
    inner = [i * ((right - left) / n) + left for i in range(1, n)]
    expected = [0.0, *offsets, *inner, *[100.0 - d for d in reversed(offsets)], 100.0]
    assert x.tolist() == expected
    assert stop_index.tolist() == [0, len(x) - 1]
    assert all(len(a) == len(x) - 1 for a in laws)


@pytest.mark.parametrize(
    "args,message",
    [
        (((None,) * 6, [0.0], 20.0), "stops: need at least two stops"),
        (((None,) * 5, [0.0, 1.0], 20.0), "laws: need 6 laws"),
        ((None, [0.0, 1.0], 0.0), "grading: need max_step > 0"),
    ],
)
def test_kernel_grid_refuses_bad_input_by_name(args, message):
    zero = prof._law_arrays(prof.PiecewiseLinear(np.array([0.0, 100.0]), np.zeros(1), np.zeros(1)))
    laws, stops, step = args
    laws = (zero,) * 6 if laws is None else laws
    with pytest.raises(ValueError, match=message):
        _trace_c.kernel_grid(laws, np.array(stops), step, 9.81, 1e-6, 0.005, 2.0)
    bad = (*(zero,) * 4, (np.array([0.0, 1.0]), np.zeros(2), np.zeros(2), True), zero)
    with pytest.raises(ValueError, match="law ceiling: arrays of shapes"):
        _trace_c.kernel_grid(bad, np.array([0.0, 1.0]), 20.0, 9.81, 1e-6, 0.005, 2.0)


def test_nan_stop_is_an_input_error_not_a_hang():
    train, route = _electric_gap()
    with pytest.raises(InputError, match="grid not increasing"):
        prof.compile_route(route, train.at_gravity(route.gravity_mps2), [0.0, float("nan"), 10_000.0], 40.0)


def _step_function_numpy(starts, ends, values, lo: float, hi: float) -> prof.PiecewiseLinear:
    """``profile.step_function`` as it was before it was compiled (the reference)."""
    a = np.asarray(starts, dtype=float)
    b = np.asarray(ends, dtype=float)
    val_in = np.broadcast_to(np.asarray(values, dtype=float), a.shape)
    x = np.unique(np.clip(np.concatenate([[lo, hi], a, b]), lo, hi))
    mid = 0.5 * (x[:-1] + x[1:])
    val = np.zeros(len(mid))
    order = np.argsort(a)
    a, b, val_in = a[order], b[order], val_in[order]
    k = np.searchsorted(a, mid, side="right") - 1
    inside = (k >= 0) & (mid < b[np.maximum(k, 0)])
    val[inside] = val_in[k[inside]]
    return prof.PiecewiseLinear(x, val.copy(), val.copy())


def _random_sections(rng, count: int, lo: float, hi: float):
    """Non-overlapping sections in random order, some touching, some with gaps, some reaching
    beyond [lo, hi]."""
    cuts = np.sort(rng.uniform(lo - 500.0, hi + 500.0, 2 * count))
    starts, ends = cuts[0::2].copy(), cuts[1::2].copy()
    touch = rng.random(count - 1) < 0.5
    ends[:-1][touch] = starts[1:][touch]
    order = rng.permutation(count)
    return starts[order], ends[order], rng.normal(size=count)


def test_step_function_equals_the_numpy_form_bit_for_bit():
    rng = np.random.default_rng(406)
    cases = [_random_sections(rng, count, 0.0, 20_000.0) for count in (1, 2, 7, 40, 300)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml")
    g = route.gradients
    cases.append(([s.start_m for s in g], [s.end_m for s in g], [s.gradient_permille for s in g]))
    cases.append(([0.0, 100.0], [100.0, 200.0], 1.0))  # one value for every section
    for k, (a, b, val) in enumerate(cases):
        for lo, hi in ((0.0, 20_000.0), (150.0, 5_000.0), (route.start_m, route.end_m), (10.0, 10.0)):
            got = prof.step_function(a, b, val, lo, hi)
            ref = _step_function_numpy(a, b, val, lo, hi)
            for name in ("x", "left", "right"):
                np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=f"{k} {name}")
            assert got.left is not got.right and got._steps == ref._steps


def test_step_function_by_hand_and_bad_positions():
    f = prof.step_function([300.0, 0.0], [400.0, 100.0], [2.0, 1.0], 50.0, 500.0)
    assert f.x.tolist() == [50.0, 100.0, 300.0, 400.0, 500.0]
    assert f.left.tolist() == [1.0, 0.0, 2.0, 0.0]
    with pytest.raises(InputError, match="is not a number"):
        prof.step_function([0.0, float("nan")], [1.0, 2.0], [1.0, 1.0], 0.0, 10.0)


def _speed_ceiling_numpy(route, train) -> prof.PiecewiseLinear:
    """``profile.speed_ceiling`` as it was before it was compiled (the reference)."""
    lo, hi = route.start_m, route.end_m
    limits = route.speed_limits
    starts = np.array([lim.start_m for lim in limits], dtype=float)
    ends = np.array([lim.end_m for lim in limits], dtype=float)
    cleared = ends + train.length_m
    inner = np.concatenate([starts, ends, cleared])
    x = np.unique(np.concatenate([[lo, hi], inner[(inner > lo) & (inner < hi)]]))
    mid = 0.5 * (x[:-1] + x[1:])
    ceiling = np.full(len(mid), train.max_speed_mps)
    j0 = np.searchsorted(mid, starts, side="left")
    j1 = np.searchsorted(mid, cleared, side="left")
    counts = np.maximum(j1 - j0, 0)
    within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    values = np.array([lim.limit_mps for lim in limits], dtype=float)
    np.minimum.at(ceiling, np.repeat(j0, counts) + within, np.repeat(values, counts))
    return prof.PiecewiseLinear(x, ceiling.copy(), ceiling.copy())


def test_speed_ceiling_equals_the_numpy_form_bit_for_bit():
    from trainsim.model import SpeedLimit

    rng = np.random.default_rng(26)
    checked = 0
    for name, train, route, _ in _cases():
        routes = [route]
        if name == "electrification_gap":
            # 25 limits tiling the line, some a few millimetres long, in random values
            cuts = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 10_000.0, 24)), [10_000.0]])
            cuts[5] = cuts[4] + 0.003
            limits = [SpeedLimit(a, b, rng.uniform(5.0, 40.0)) for a, b in itertools.pairwise(cuts)]
            routes.append(dataclasses.replace(route, speed_limits=tuple(limits)))
        for r in routes:
            for t in (
                train,
                dataclasses.replace(train, length_m=0.5),
                dataclasses.replace(train, length_m=750.0),
            ):
                got, ref = prof.speed_ceiling(r, t), _speed_ceiling_numpy(r, t)
                for field in ("x", "left", "right"):
                    np.testing.assert_array_equal(
                        getattr(got, field), getattr(ref, field), err_msg=f"{name} {field}"
                    )
                assert got.left is not got.right
                checked += 1
    assert checked >= 40


def test_speed_ceiling_by_hand():
    """A 100 km/h line with a 40 km/h limit on 1000-1200 m: a 300 m train is held at 40 km/h from 1000 m
    until its rear clears 1200 m, at 1500 m."""
    from trainsim.constants import KMH

    route = make_route(
        length_m=3000.0, limits=[(0.0, 1000.0, 100.0), (1000.0, 1200.0, 40.0), (1200.0, 3000.0, 100.0)]
    )
    f = prof.speed_ceiling(route, make_train(length_m=300.0, vmax_kmh=90.0))
    assert f.x.tolist() == [0.0, 1000.0, 1200.0, 1300.0, 1500.0, 3000.0]  # 1300: the first limit cleared
    np.testing.assert_array_equal(f.left, [90.0 * KMH, 40.0 * KMH, 40.0 * KMH, 40.0 * KMH, 90.0 * KMH])
