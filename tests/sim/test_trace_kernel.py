"""The compiled point arrays (``sim/_trace_c.pyx`` through ``result``) are the same bits as the numpy
computation they replaced (``result._trace_and_peaks_numpy``), in every regime, with driver levels,
constant-deceleration and force-law brakes, regenerative braking, gaps in the electrification and
averaged line laws; so are the kernel grid's per-interval laws (``profile.compile_route``) and the
compiled law and curve values (the model's own ``PiecewiseLinear`` and ``EffortCurve`` calls)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.model import EffortCurve, Electrical, ElectrificationSection, Quadratic
from trainsim.model.scenario import RunSettings
from trainsim.sim import _trace_c
from trainsim.sim import result as res
from trainsim.sim.fastest import run_fastest, stops_of
from trainsim.sim.profile import (
    PiecewiseLinear,
    compile_route,
    compile_track,
    line_voltage,
    traction_availability,
)

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


def _gap_case():
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
    return train, route, RunSettings()


def _cases():
    metro = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")
    yield "metro_b", (metro.train, metro.route, metro.settings)
    freight = trainsim.load_scenario(ROOT / "examples" / "freight_000" / "scenario.yaml")
    yield "freight_000", (freight.train, freight.route, freight.settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tr = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml")  # constant deceleration
    route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="homogeneous_strip")
    yield "trainruns_strip", (tr, route, RunSettings())
    yield "electrification_gap", _gap_case()


def _both(train, route, settings, scramble: bool, with_trace: bool):
    """The compiled and the numpy arrays of a run's points; ``scramble`` gives every point a random
    regime and driver level (the forces are evaluated whatever the motion), so that every branch is
    compared."""
    run = run_fastest(train, route, settings)
    tr = run.trace
    s, v, t, regime = tr.position_m, tr.speed_mps, tr.time_s, tr.regime.astype(np.int64)
    rng = np.random.default_rng(14)
    level = np.ones(len(s))
    if scramble:
        regime = rng.integers(0, 7, len(s))
        level = rng.uniform(0.0, 1.0, len(s))
    train = train.at_gravity(route.gravity_mps2)
    _, profile, ceiling = compile_track(route, train, stops_of(route), settings.max_step_m)
    availability, voltage = traction_availability(route, train), line_voltage(route, train)
    elec = train.electrical
    eta_t = elec.traction_efficiency if elec else 1.0
    eta_r = elec.regenerative_efficiency * elec.receptivity if elec else 0.0
    aux = elec.auxiliary_power_w if elec else 0.0
    w = rng.uniform(0.0, 1e6, (4, len(s) - 1))
    s_right = np.minimum(s + 1e-7, route.end_m)
    args = (
        train,
        settings,
        route,
        profile,
        ceiling,
        availability,
        voltage,
        s,
        v,
        t,
        regime,
        level,
        s_right,
        *w,
    )
    inputs = res.TraceInputs(*args, eta_t, eta_r, aux)
    return (
        res._trace_and_peaks(inputs, with_trace),
        res._trace_and_peaks_numpy(inputs, with_trace),
    )


@pytest.mark.parametrize("scramble", [False, True], ids=["run", "every_regime"])
@pytest.mark.parametrize("name,case", list(_cases()), ids=[n for n, _ in _cases()])
def test_compiled_arrays_equal_numpy(name, case, scramble):
    (trace, peak, paper), (ref, ref_peak, ref_paper) = _both(*case, scramble=scramble, with_trace=True)
    for field in ref.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(trace, field), getattr(ref, field), err_msg=f"{name}: {field}")
    np.testing.assert_array_equal(peak, ref_peak)
    np.testing.assert_array_equal(paper, ref_paper)
    if scramble:
        assert len(np.unique(trace.regime)) == 7
    if name in ("metro_b", "electrification_gap"):
        assert np.isfinite(peak).all()  # the peaks are really compared, not NaN against NaN


def test_peaks_without_trace_are_the_same():
    (trace, peak, paper), (_, ref_peak, ref_paper) = _both(*_gap_case(), scramble=True, with_trace=False)
    assert trace is None
    np.testing.assert_array_equal(peak, ref_peak)
    np.testing.assert_array_equal(paper, ref_paper)


def test_curve_value_is_effort_curve_call():
    speeds = np.concatenate([[0.0, 1e-4, 1e-3], np.linspace(0.0, 60.0, 2001)])
    curves = [
        EffortCurve.power_limited(4e6, 300e3),
        EffortCurve(
            np.array([0.0, 5.0, 10.0]),
            np.array([[3e5, -2e3, 0.0, 0.0], [0.0, 0.0, 0.0, 2e6], [1e5, 0.0, 10.0, 1e6]]),
        ),
        EffortCurve(
            np.array([0.0, 8.0]), np.array([[2e5, 0.0, 0.0, -5e4], [9e4, 1e3, -3.0, 0.0]]), force_cap_n=1.8e5
        ),
    ]
    for curve in curves:
        arrays = curve.as_arrays()
        got = np.array([_trace_c.curve_value_at(x, arrays) for x in speeds])
        np.testing.assert_array_equal(got, curve(speeds))


def test_piecewise_value_is_piecewise_linear_call():
    x = np.array([0.0, 100.0, 250.0, 1000.0])
    step = PiecewiseLinear(x, np.array([1.0, -2.0, 0.5]), np.array([1.0, -2.0, 0.5]))
    ramp = PiecewiseLinear(x, np.array([1.0, -2.0, 0.5]), np.array([3.0, 0.25, -7.0]))
    s = np.concatenate([[-5.0, 0.0, 100.0, 250.0, 1000.0, 2000.0, np.nan], np.linspace(-10.0, 1010.0, 997)])
    for f in (step, ramp):
        got = np.array([_trace_c.piecewise_value_at(res._law_arrays(f), q) for q in s])
        np.testing.assert_array_equal(got, f(s))


def test_sequential_lookup_is_the_bisection_in_any_order():
    """The loops look laws up with a hint from the last position (issue 14): whatever the order of the
    positions (increasing with repeats, decreasing, jumping far, NaN, beyond the ends) every value is
    the bisection's and PiecewiseLinear's; a law whose breakpoints are not ordered (a NaN among them)
    is never walked."""
    rng = np.random.default_rng(14)
    x = np.unique(np.concatenate([[0.0, 5000.0], rng.uniform(0.0, 5000.0, 300)]))
    left, right = rng.normal(size=len(x) - 1), rng.normal(size=len(x) - 1)
    ramp = PiecewiseLinear(x, left, right)
    step = PiecewiseLinear(x, left, left.copy())
    fine = np.sort(rng.uniform(-100.0, 5100.0, 3000))
    orders = {
        "increasing, the grid's and the breakpoints themselves": np.sort(
            np.concatenate([fine, x, x, x + 1e-9])
        ),
        "decreasing": fine[::-1],
        "random": rng.permutation(fine),
        "jumps and NaN": np.array([10.0, 4999.0, 1.0, np.nan, 2500.0, 2500.0, -1.0, 6000.0, 0.0, 5000.0]),
    }
    for f in (ramp, step):
        arrays = res._law_arrays(f)
        for name, s in orders.items():
            got = _trace_c.piecewise_values_seq(arrays, s)
            bisection = np.array([_trace_c.piecewise_value_at(arrays, q) for q in s])
            np.testing.assert_array_equal(got, bisection, err_msg=name)
            np.testing.assert_array_equal(got, f(s), err_msg=name)
    unordered = (
        np.array([0.0, np.nan, 10.0, 20.0]),
        np.array([1.0, 2.0, 3.0]),
        np.array([1.0, 2.0, 3.0]),
        True,
    )
    s = np.linspace(-1.0, 21.0, 45)
    np.testing.assert_array_equal(
        _trace_c.piecewise_values_seq(unordered, s),
        np.array([_trace_c.piecewise_value_at(unordered, q) for q in s]),
    )


def _numpy_laws(route, train, x, profile, ceiling, available):
    """The per-interval laws as compile_track computed them with numpy before they were compiled."""
    left, right = x[:-1], x[1:]
    width = right - left
    eps = 1e-9 * np.maximum(1.0, np.abs(left))

    def law(f):
        v0 = f(left + eps)
        v1 = f(right - eps)
        slope = (v1 - v0) / np.maximum(width - 2 * eps, 1e-12)
        return v0 - slope * eps, slope

    g0, g1 = law(profile.gradient)
    c0, c1 = law(profile.curve)
    t0, t1 = law(profile.tunnel)
    g = route.gravity_mps2
    b0, b1 = law(profile.tunnel_v2)
    mid = 0.5 * (left + right)
    return g * (g0 + c0 + t0), g * (g1 + c1 + t1), g * b0, g * b1, ceiling(mid), available(mid)


@pytest.mark.parametrize("name,case", list(_cases()), ids=[n for n, _ in _cases()])
def test_compiled_track_laws_equal_numpy(name, case):
    train, route, settings = case
    train = train.at_gravity(route.gravity_mps2)
    stops = stops_of(route)
    compiled = compile_route(route, train, stops, settings.max_step_m)
    track = compiled.track
    # every breakpoint of every law lies on the grid (merged only with a point closer than 1e-6 m)
    pr = compiled.profile
    for f in (pr.gradient, pr.curve, pr.tunnel, pr.tunnel_v2, compiled.ceiling, compiled.available):
        inside = f.x[(f.x > stops[0]) & (f.x < stops[-1])]
        assert all(np.min(np.abs(track.x - b)) <= 1e-6 for b in inside.tolist())
    ref = _numpy_laws(route, train, track.x, compiled.profile, compiled.ceiling, compiled.available)
    got = (track.a0, track.a1, track.b0, track.b1, track.vlim, track.traction_scale)
    for label, a, b in zip(("a0", "a1", "b0", "b1", "vlim", "traction_scale"), got, ref, strict=True):
        np.testing.assert_array_equal(a, b, err_msg=f"{name}: {label}")
    if name in ("trainruns_strip", "electrification_gap"):
        assert np.any(track.a1 != 0.0)  # averaged over the length: the interpolating branch is compared
