"""The result pass (``result._trace_and_peaks``, compiled) and its numpy reference take one container,
``result.TraceInputs``; a whole ``build_result`` through the compiled pass gives the trace and summary
the numpy reference gives, bit for bit; the compiled running totals (``_trace_c.cumulative_rows``) are
``np.cumsum``'s, and refuse arrays of different lengths by name."""

from __future__ import annotations

import dataclasses
import inspect
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
from trainsim.sim.profile import compile_route

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


def _cases():
    metro = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")
    yield "metro_b", metro.train, metro.route, metro.settings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        freight = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml")
    route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="mass_point")
    yield "trainruns_freight_realworld", freight, route, RunSettings()
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


def test_both_forms_take_the_one_container():
    for fn in (res._trace_and_peaks, res._trace_and_peaks_numpy):
        assert list(inspect.signature(fn).parameters) == ["inp", "with_trace"], fn.__name__
    assert list(inspect.signature(res._run_arrays_args).parameters) == ["inp"]
    assert res.TraceInputs._fields[-3:] == ("eta_t", "eta_r", "aux_w")


@pytest.fixture(scope="module")
def both_runs():
    """Per case, the run through the compiled pass and through the numpy reference (the same
    points: the reference is swapped in for ``build_result`` only)."""
    out = []
    for name, train, route, settings in _cases():
        compiled = (run_fastest(train, route, settings), run_fastest(train, route, settings, trace=False))
        original = res._trace_and_peaks
        res._trace_and_peaks = res._trace_and_peaks_numpy
        try:
            reference = (
                run_fastest(train, route, settings),
                run_fastest(train, route, settings, trace=False),
            )
        finally:
            res._trace_and_peaks = original
        out.append((name, compiled, reference))
    return out


def test_a_run_through_the_compiled_pass_is_the_numpy_run_bit_for_bit(both_runs):
    for name, (full, bare), (ref_full, ref_bare) in both_runs:
        for field in res.Trace.__dataclass_fields__:
            np.testing.assert_array_equal(
                getattr(full.trace, field), getattr(ref_full.trace, field), err_msg=f"{name}: {field}"
            )
        assert full.summary() == ref_full.summary(), name
        assert bare.summary() == ref_bare.summary() == ref_full.summary(), name
        assert bare.trace is None
    peaks = {name: full.peak_current_a for name, (full, _), _ in both_runs}
    assert peaks["electrification_gap"] > 0.0  # an electric train: the peaks are really compared


def test_cumulative_rows_are_cumsum():
    rng = np.random.default_rng(26)
    arrays = (
        rng.normal(size=5000) * 1e6,
        np.concatenate([[-0.0], rng.uniform(size=4999)]),
        np.full(5000, 0.1),
    )
    out = _trace_c.cumulative_rows(arrays)
    assert out.shape == (3, 5001)
    for row, a in zip(out, arrays, strict=True):
        np.testing.assert_array_equal(row, np.concatenate([[0.0], np.cumsum(a)]))
    assert np.signbit(out[1, 1])  # the first value itself, as cumsum: -0.0, not 0.0 + -0.0
    strided = rng.normal(size=(100, 6))[:, 2]
    np.testing.assert_array_equal(
        _trace_c.cumulative_rows((strided,))[0], np.concatenate([[0.0], np.cumsum(strided)])
    )


def test_cumulative_rows_by_hand_and_edges():
    out = _trace_c.cumulative_rows((np.array([1.0, 2.0, 3.0]), np.array([0.5, -0.5, 0.25])))
    assert out.tolist() == [[0.0, 1.0, 3.0, 6.0], [0.0, 0.5, 0.0, 0.25]]
    assert _trace_c.cumulative_rows((np.zeros(0),)).tolist() == [[0.0]]  # one point, no stretch
    assert _trace_c.cumulative_rows(()).shape == (0, 0)
    with pytest.raises(
        ValueError, match=r"stretches\[1\]: length 2, need the length of stretches\[0\] \(3\)"
    ):
        _trace_c.cumulative_rows((np.zeros(3), np.zeros(2)))
    with pytest.raises(ValueError, match=r"stretches\[0\]: need a 1-D array of real numbers"):
        _trace_c.cumulative_rows((np.zeros((2, 2)),))


def _peak_args(name: str):
    """``run_arrays``'s arguments for a case's run, every regime and random driver levels."""
    train, route, settings = next((t, r, st) for n, t, r, st in _cases() if n == name)
    run = run_fastest(train, route, settings)
    train = train.at_gravity(route.gravity_mps2)
    compiled = compile_route(route, train, stops_of(route), settings.max_step_m)
    tr = run.trace
    rng = np.random.default_rng(7)
    n = len(tr)
    regime = rng.integers(0, 7, n)
    elec = train.electrical
    inputs = res.TraceInputs(
        train, settings, route, compiled.profile, compiled.ceiling, compiled.available, compiled.voltage,
        tr.position_m, tr.speed_mps, tr.time_s, regime, rng.uniform(0.0, 1.0, n),
        np.minimum(tr.position_m + 1e-7, route.end_m), *np.zeros((4, n - 1)),
        elec.traction_efficiency, elec.regenerative_efficiency * elec.receptivity, elec.auxiliary_power_w,
    )  # fmt: skip
    return inputs, list(res._run_arrays_args(inputs))


@pytest.mark.parametrize("name", ["metro_b", "electrification_gap"])
def test_run_peaks_are_the_nanmax_of_the_point_peaks(name):
    inputs, args = _peak_args(name)
    args[3][5::40] = np.nan  # a NaN driver level: NaN forces and currents there, ignored as by nanmax
    _, peak, paper = _trace_c.run_arrays(*args, False)
    n = len(peak)
    assert np.isnan(peak).any() and np.isfinite(peak).any()
    cuts = np.sort(np.random.default_rng(3).choice(np.arange(1, n - 1), 9, replace=False))
    # sections sharing an end point (no dwell), apart (points of no section: a dwell), a single point
    sections = [(0, cuts[0]), (cuts[0], cuts[1]), (cuts[2], cuts[3]), (cuts[4], cuts[4]), (cuts[5], n - 1)]
    # without s_right: run_peaks reads the laws at min(s + 1e-7, end), as run_arrays' s_right here
    section, section_paper, top, top_paper = _trace_c.run_peaks(
        *args[:4], float(inputs.route.end_m), *args[5:], np.array(sections)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a single NaN point: nanmax says so
        ref = [np.nanmax(peak[a : b + 1]) for a, b in sections]
        ref_paper = [np.nanmax(paper[a : b + 1]) for a, b in sections]
    np.testing.assert_array_equal(section, ref)
    np.testing.assert_array_equal(section_paper, ref_paper)
    assert top == np.nanmax(peak) and top_paper == np.nanmax(paper)
    assert np.isfinite(section).sum() >= 4 and top > 0.0


def test_run_peaks_without_electrics_or_points_and_bad_sections():
    inputs, args = _peak_args("electrification_gap")
    end = float(inputs.route.end_m)
    diesel = list(args)
    diesel[9] = (False, *args[9][1:])
    section, paper, top, top_paper = _trace_c.run_peaks(*diesel[:4], end, *diesel[5:], np.array([[0, 5]]))
    assert np.isnan(section).all() and np.isnan(paper).all() and np.isnan(top) and np.isnan(top_paper)
    empty = [np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0)]
    out = _trace_c.run_peaks(*empty, end, *args[5:], np.zeros((0, 2), dtype=np.int64))
    assert out[0].shape == (0,) and np.isnan(out[2])
    n = len(args[0])
    for bad in ([[0, n]], [[5, 2]], [[-1, 3]]):
        with pytest.raises(ValueError, match=r"sections: need increasing point indices in 0 \.\. "):
            _trace_c.run_peaks(*args[:4], end, *args[5:], np.array(bad))
    with pytest.raises(ValueError, match=r"sections: need an array of shape \(k, 2\)"):
        _trace_c.run_peaks(*args[:4], end, *args[5:], np.array([0, 3]))


def _violations_numpy(s, v, t) -> list[str]:
    """``result._invariant_violations`` as it was before it was compiled (the reference)."""
    problems = []
    if not (np.all(np.isfinite(s)) and np.all(np.isfinite(v)) and np.all(np.isfinite(t))):
        problems.append("non-finite position, speed or time")
    if np.any(v < 0.0):
        problems.append("negative speed")
    if np.any(np.diff(s) < -1e-9):
        problems.append("position decreasing")
    if np.any(np.diff(t) < -1e-9):
        problems.append("time decreasing")
    return problems


def test_point_problems_are_the_numpy_checks():
    rng = np.random.default_rng(50388)
    base = np.cumsum(rng.uniform(0.0, 10.0, (3, 200)), axis=1)
    seen = set()
    for trial in range(400):
        s, v, t = (x.copy() for x in base)
        for _ in range(rng.integers(0, 3)):
            arr = (s, v, t)[rng.integers(0, 3)]
            k = rng.integers(0, 200)
            arr[k] = rng.choice([np.nan, np.inf, -np.inf, -1e-3, arr[k] - 2e-9, arr[k] - 5e-10, -0.0])
        got = res._invariant_violations(s, v, t)
        assert got == _violations_numpy(s, v, t), trial
        seen |= set(got)
    assert len(seen) == 4  # every problem met
    assert res._invariant_violations(np.zeros(0), np.zeros(0), np.zeros(0)) == []
    assert res._invariant_violations(np.array([0.0, 1.0]), np.array([0.0, -0.0]), np.array([0.0, 1.0])) == []
    with pytest.raises(ValueError, match=r"t: length 1, need the length of s \(2\)"):
        _trace_c.point_problems(np.zeros(2), np.zeros(2), np.zeros(1), 1e-9)


def test_curve_values_looked_up_from_the_last_piece_are_the_curve_call():
    """The effort curve's piece found from the last one (speeds in a run change slowly): the force of
    ``EffortCurve.__call__`` in increasing, decreasing, random and jumping orders, with NaN and
    speeds beyond the table, for a tabulated curve of 81 pieces and a constant one."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tabulated = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml").traction
    rng = np.random.default_rng(26)
    up = np.linspace(0.0, 40.0, 3001)
    orders = [
        up,
        up[::-1],
        rng.permutation(up),
        np.concatenate([up[::97], up[::-53], [np.nan, 1e9, -1.0, 3.0]]),
    ]
    for curve in (tabulated, make_train().traction):
        assert curve.as_arrays()[0].shape[0] >= 1
        for speeds in orders:
            np.testing.assert_array_equal(_trace_c.curve_values_seq(curve.as_arrays(), speeds), curve(speeds))
    assert len(tabulated.as_arrays()[0]) > 50  # the walk is really exercised over many pieces
