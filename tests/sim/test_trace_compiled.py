"""The compiled trace (``sim/_trace_c.pyx``, Cython) on its own: ``run_arrays`` gives the same bits
as the numpy reference ``result._trace_and_peaks_numpy`` (which evaluates the model's own
``EffortCurve`` and ``PiecewiseLinear`` calls and the electrical formulas with numpy) on the fastest
run of every example and of the TrainRuns freight train on ``realworld``, with every regime and driver
level; a small run and the per-interval laws checked by hand; bad input refused with a message naming
the argument. ``test_trace_kernel.py`` compares the same through ``result`` and ``profile``."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.model import Electrical, ElectrificationSection, Quadratic
from trainsim.model.scenario import RunSettings
from trainsim.sim import _trace_c
from trainsim.sim import result as res
from trainsim.sim.fastest import run_fastest, stops_of
from trainsim.sim.profile import (
    PiecewiseLinear,
    _law_arrays,
    compile_route,
    line_voltage,
    traction_availability,
)

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


def _cases():
    for path in sorted((ROOT / "examples").rglob("scenario*.yaml")):
        sc = trainsim.load_scenario(path)
        yield str(path.relative_to(ROOT / "examples")), sc.train, sc.route, sc.settings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        freight = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml")
    route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="homogeneous_strip")
    yield "trainruns_freight_strip", freight, route, RunSettings()
    electric = dataclasses.replace(
        make_train(resistance=Quadratic(3000.0, 20.0, 5.0)),
        electrical=Electrical(line_voltage_v=1500.0, traction_efficiency=0.9, power_factor=0.95),
    )
    gap = dataclasses.replace(
        make_route(length_m=10_000.0, limit_kmh=160.0, gradient_permille=4.0, apply_over="train_length"),
        electrification=(
            ElectrificationSection(0.0, 4000.0, 1500.0),
            ElectrificationSection(4000.0, 4500.0, 0.0),
            ElectrificationSection(4500.0, 10_000.0, 1500.0),
        ),
    )
    yield "electrification_gap", electric, gap, RunSettings()


@pytest.fixture(scope="module")
def runs():
    """Per case, on the run's own regimes and on random ones with random driver levels (the forces
    are evaluated whatever the motion, so every branch is reached): the arguments of ``run_arrays``
    (but ``with_trace``) and those of the numpy reference (but ``with_trace``)."""
    out = {}
    rng = np.random.default_rng(14)
    for name, train, route, settings in _cases():
        tr = run_fastest(train, route, settings).trace
        s, v, t = tr.position_m, tr.speed_mps, tr.time_s
        train = train.at_gravity(route.gravity_mps2)
        compiled = compile_route(route, train, stops_of(route), settings.max_step_m)
        availability, voltage = traction_availability(route, train), line_voltage(route, train)
        elec = train.electrical
        eta_t = elec.traction_efficiency if elec else 1.0
        eta_r = elec.regenerative_efficiency * elec.receptivity if elec else 0.0
        aux = elec.auxiliary_power_w if elec else 0.0
        s_right = np.minimum(s + 1e-7, route.end_m)
        works = rng.uniform(0.0, 1e6, (4, len(s) - 1))
        variants = []
        for regime, level in (
            (tr.regime.astype(np.int64), np.ones(len(s))),
            (rng.integers(0, 7, len(s)), rng.uniform(0.0, 1.0, len(s))),
        ):
            laws = (compiled.profile, compiled.ceiling, availability, voltage)
            inputs = res.TraceInputs(
                train, settings, route, *laws, s, v, t, regime, level, s_right, *works, eta_t, eta_r, aux
            )
            variants.append((res._run_arrays_args(inputs), inputs))
        out[name] = variants
    return out


def test_run_arrays_equal_the_numpy_reference_bit_for_bit(runs):
    for name, variants in runs.items():
        for k, (args, ref_args) in enumerate(variants):
            for with_trace in (True, False):
                rows, peak, paper = _trace_c.run_arrays(*args, with_trace)
                trace, ref_peak, ref_paper = res._trace_and_peaks_numpy(ref_args, with_trace)
                what = f"{name} variant {k} trace {with_trace}"
                assert rows.shape == ((15, len(peak)) if with_trace else (15, 0)), what
                np.testing.assert_array_equal(peak, ref_peak, err_msg=f"{what}: peak")
                np.testing.assert_array_equal(paper, ref_paper, err_msg=f"{what}: paper peak")
                if with_trace:
                    for row, field in zip(rows, _trace_c.TRACE_ROWS, strict=True):
                        np.testing.assert_array_equal(row, getattr(trace, field), err_msg=f"{what}: {field}")


def test_trace_rows_are_trace_fields():
    assert set(_trace_c.TRACE_ROWS) <= set(res.Trace.__dataclass_fields__)
    assert len(set(_trace_c.TRACE_ROWS)) == len(_trace_c.TRACE_ROWS) == 15


def test_the_comparison_reaches_every_branch(runs):
    """Not NaN against NaN, and every regime, brake kind and law kind met."""
    regimes, finite_peaks, decel, service, regen, sloped = set(), 0, False, False, False, False
    for variants in runs.values():
        for args, _ in variants:
            regimes |= set(np.unique(args[2]).tolist())
            mech = args[8]
            decel |= mech[3]
            service |= mech[4] and not mech[3]
            regen |= mech[5]
            sloped |= any(not law[3] for law in args[5])
        finite_peaks += int(np.isfinite(_trace_c.run_arrays(*variants[0][0], False)[1]).sum())
    assert regimes == set(range(7))
    assert decel and service and regen and sloped
    assert finite_peaks > 1000


def _small_args():
    law = (np.array([0.0, 100.0]), np.array([1.0]), np.array([1.0]), True)
    curve = (np.zeros(1), np.array([[1e5, 0.0, 0.0, 0.0]]), 1e5, 1e6)
    s = np.array([0.0, 50.0, 100.0])
    return [
        s,
        np.array([0.0, 5.0, 0.0]),
        np.array([0, 3, 4]),
        np.ones(3),
        s,
        (law,) * 7,
        (1000.0, 10.0, 1.0),
        9.81e5,
        (1e5, 0.5, 1.0, True, False, False),
        (True, 0.9, 0.8, 1e4, 1.0),
        curve,
        curve,
        curve,
        True,
    ]


@pytest.mark.parametrize(
    "index,value,message",
    [
        (1, np.ones(2), "v: length 2, need the length of s"),
        (0, np.ones((3, 1)), "s: need a 1-D array of real numbers"),
        (2, np.array([0.0, 3.0, 4.0]), "regime: need a 1-D array of integers"),
        (3, np.array(["a", "b", "c"]), "level: need a 1-D array of real numbers"),
        (5, ((np.array([0.0, 1.0]),) * 3 + (True,),) * 6, "laws: need 7 laws"),
        (6, (1.0, 2.0), "resist (c0, c1, c2): need a tuple of 3 values"),
        (8, (1e5, 0.5, 1.0), "mech: need a tuple of 6 values"),
        (9, (True, 0.9), "electric: need a tuple of 5 values"),
        (11, (np.zeros(2), np.zeros((1, 4)), 1.0, 1.0), "service braking curve: effort curve arrays"),
    ],
)
def test_run_arrays_refuses_bad_input_naming_it(index, value, message):
    args = _small_args()
    args[index] = value
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        _trace_c.run_arrays(*args)


def test_law_with_inconsistent_arrays_is_refused_by_name():
    args = _small_args()
    bad = (np.array([0.0, 100.0, 200.0]), np.array([1.0]), np.array([1.0]), True)
    args[5] = (*args[5][:5], bad, args[5][6])
    with pytest.raises(
        ValueError, match=r"law voltage: arrays of shapes \(3,\), \(1,\), \(1,\): need n \+ 1 breakpoints"
    ):
        _trace_c.run_arrays(*args)
    ints = (np.array([0, 100]), np.array([1.0]), np.array([1.0]), True)
    with pytest.raises(
        ValueError, match="law available: x: need a C-contiguous float64 array, got items of format 'l'"
    ):
        _trace_c.interval_laws(np.array([0.0, 1.0]), *args[5][:5], ints, 9.81)
    strided = (np.arange(4.0)[::2], np.array([1.0]), np.array([1.0]), True)
    with pytest.raises(ValueError, match="law ceiling: x: need a C-contiguous float64 array"):
        _trace_c.interval_laws(np.array([0.0, 1.0]), *args[5][:4], strided, args[5][5], 9.81)
    flat = (np.zeros((2, 1)), np.array([1.0]), np.array([1.0]), True)
    with pytest.raises(ValueError, match=r"law gradient: arrays of shapes \(2, 1\)"):
        _trace_c.interval_laws(np.array([0.0, 1.0]), flat, *args[5][1:6], 9.81)
    with pytest.raises(ValueError, match="x: need at least one grid point"):
        _trace_c.interval_laws(np.array([]), *args[5][:6], 9.81)


def test_small_run_by_hand():
    """Three points on the level, one law everywhere: the traction point's force is the curve's, the
    braking point's the constant deceleration's, the dwell's acceleration 0 (computed by hand)."""
    rows, peak, paper = _trace_c.run_arrays(*_small_args())
    r = dict(zip(_trace_c.TRACE_ROWS, rows, strict=True))
    assert r["traction_force_n"][0] == 1e5  # TRACTION at 0 m/s: the law, under both caps
    running = (1000.0 + 10.0 * 5.0 + 1.0 * 25.0) * 1.0
    line = 9.81e5 * 1.0
    assert r["running_resistance_n"][1] == running
    assert r["braking_force_n"][1] == max(1e5 * 0.5 - running - line, 0.0)  # BRAKE, level 1
    assert r["acceleration_mps2"][2] == 0.0  # DWELL
    assert r["line_current_a"][0] == (0.0 / 0.9 + 1e4 - 0.0) / (1.0 * 1.0)  # 0 m/s: the auxiliaries only
    assert np.isfinite(peak).all() and np.isfinite(paper).all()
    diesel = _small_args()
    diesel[9] = (False, 0.9, 0.8, 1e4, 1.0)
    assert np.isnan(_trace_c.run_arrays(*diesel)[1]).all()
    empty = _small_args()
    empty[0:5] = [np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)]
    rows, peak, paper = _trace_c.run_arrays(*empty)
    assert rows.shape == (15, 0) and peak.shape == (0,) and paper.shape == (0,)


def test_interval_laws_by_hand():
    """Gradient ramp 0 -> 10 per mille over 0-1000 m, curve 1 per mille with a jump to 3 at 250 m
    (a grid point: the jump belongs to the interval on its right), tunnel v^2 term 1e-5 s^2/m^2:
    per interval a0 = g (gradient at its start + curve), a1 = g x ramp slope, b0 = g 1e-5, b1 = 0,
    and the ceiling and availability at its middle."""
    x = np.array([0.0, 250.0, 1000.0])
    ramp = PiecewiseLinear(np.array([0.0, 1000.0]), np.array([0.0]), np.array([0.01]))
    curve = PiecewiseLinear(x, np.array([0.001, 0.003]), np.array([0.001, 0.003]))
    zero = PiecewiseLinear(np.array([0.0, 1000.0]), np.zeros(1), np.zeros(1))
    v2 = PiecewiseLinear(np.array([0.0, 1000.0]), np.full(1, 1e-5), np.full(1, 1e-5))
    ceiling = PiecewiseLinear(np.array([0.0, 500.0, 1000.0]), np.array([20.0, 30.0]), np.array([20.0, 30.0]))
    avail = PiecewiseLinear(np.array([0.0, 1000.0]), np.array([1.0]), np.array([0.5]))
    g = 9.81
    laws = [_law_arrays(f) for f in (ramp, curve, zero, v2, ceiling, avail)]
    a0, a1, b0, b1, vlim, scale = _trace_c.interval_laws(x, *laws, g)
    np.testing.assert_allclose(a0, [g * 0.001, g * (0.0025 + 0.003)], rtol=1e-9)
    np.testing.assert_allclose(a1, [g * 1e-5, g * 1e-5], rtol=1e-6)
    np.testing.assert_allclose(b0, [g * 1e-5, g * 1e-5], rtol=1e-12)
    np.testing.assert_array_equal(b1, [0.0, 0.0])
    np.testing.assert_array_equal(vlim, [20.0, 30.0])  # middles 125 m and 625 m
    np.testing.assert_allclose(scale, [1.0 - 0.5 * 0.125, 1.0 - 0.5 * 0.625], rtol=1e-15)
