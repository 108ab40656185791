"""The compiled fastest-run kernel (``sim/_kernel_c.pyx``, Cython) gives the same bits as the numba
kernel (``sim/kernel.py``) on real cases: every output array, status and stall position."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model.scenario import RunSettings
from trainsim.sim import _kernel_c, codes, kernel
from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_route

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS_DIRS = (ROOT.parent / "shared" / "data" / "trainruns", ROOT / "tests" / "data" / "trainruns")
EXAMPLES = (
    "metro_b/scenario.yaml",
    "heavy_haul/scenario_head.yaml",
    "loco_001/scenario.yaml",
    "freight_000/scenario.yaml",
)


def _trainruns_freight():
    data = next((d for d in TRAINRUNS_DIRS if (d / "paths" / "realworld.yaml").exists()), None)
    if data is None:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = load_train(data / "trains" / "freight.yaml")
    return train, load_route(data / "paths" / "realworld.yaml"), RunSettings()


class Case:
    """The kernel inputs of a run, as ``run_fastest`` builds them."""

    def __init__(self, train, route, settings):
        train = train.at_gravity(route.gravity_mps2)
        stops = [s.position_m for s in route.stops]
        self.track = compile_route(route, train, stops, settings.max_step_m).track
        self.P, traction, brake = kernel_parameters(train, settings)
        self.tk = kink_speeds(*traction)
        self.bk = kink_speeds(*brake)
        self.curves = (*traction, *brake, *regenerative_arrays(train))
        self.n_max = 4 * len(self.track.x) + 8 * len(stops) + 16
        self.segments = list(zip(self.track.stop_index[:-1], self.track.stop_index[1:], strict=True))

    def run(self, segment_fn, traction_share=1.0):
        """Every segment from its stop's standstill, and the P left; ``traction_share`` scales the
        traction (a weak train stalls on the way)."""
        tr = self.track
        tscale = tr.traction_scale * traction_share
        P = self.P.copy()
        out = [
            np.zeros(self.n_max),
            np.zeros(self.n_max),
            np.zeros(self.n_max),
            np.zeros(self.n_max, np.int8),
        ]
        n, results = 0, []
        for i0, i1 in self.segments:
            t0 = float(out[2][n - 1]) + 10.0 if n else 0.0
            res = segment_fn(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tscale,
                int(i0), int(i1), t0, P, self.curves, self.tk, self.bk, *out, n,
            )  # fmt: skip
            results.append(res)
            n = res[0]
        return results, out, P

    def kinks(self, fn, s, v, t, m, P):
        tr = self.track
        return fn(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, P, self.curves, self.tk, self.bk, s, v, t, m
        )


@pytest.fixture(
    scope="module",
    params=[*EXAMPLES, "metro_b/scenario.yaml @ 40 m", "trainruns freight realworld", "trainruns @ 2.5 m"],
)
def case(request):
    """A case at its own step, or at another (``@ h m``: other grids, other paths through the kernel)."""
    name, _, step = request.param.partition(" @ ")
    if name.startswith("trainruns"):
        found = _trainruns_freight()
        if found is None:
            pytest.skip("TrainRuns.jl data not found")
        train, route, settings = found
    else:
        sc = trainsim.load_scenario(ROOT / "examples" / name)
        train, route, settings = sc.train, sc.route, sc.settings
    if step:
        settings = dataclasses.replace(settings, max_step_m=float(step.removesuffix(" m")))
    return Case(train, route, settings)


def _same(a, b):
    assert a.dtype == b.dtype
    assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("traction_share", [1.0, 0.05])
def test_fastest_segment_and_kink_points_equal_the_numba_kernel(case, traction_share):
    want, want_out, want_P = case.run(kernel.fastest_segment, traction_share)
    got, got_out, got_P = case.run(_kernel_c.fastest_segment, traction_share)
    assert [(int(n), int(st), float(x)) for n, st, x in got] == [
        (int(n), int(st), float(x)) for n, st, x in want
    ]
    assert all(type(a) is int and type(b) is int and type(c) is float for a, b, c in got)
    for a, b in zip(got_out, want_out, strict=True):
        _same(a, b)
    _same(got_P, want_P)  # the traction share written per interval, as numba writes it
    n = got[-1][0]
    trace = [a[:n] for a in want_out]
    P_numba, P_compiled = case.P.copy(), case.P.copy()
    want_k = case.kinks(kernel.insert_kink_points, *trace, P_numba)
    got_k = case.kinks(_kernel_c.insert_kink_points, *trace, P_compiled)
    for a, b in zip(got_k, want_k, strict=True):
        _same(a, b)
    _same(P_compiled, P_numba)
    assert len(got_k[0]) >= n


def test_braking_ceilings_equal_the_numba_kernel(case):
    tr = case.track
    args = (tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim)
    modes = np.where(np.arange(len(tr.a0)) % 3 == 0, codes.REGEN, codes.BRAKE).astype(np.int64)
    for i0, i1 in case.segments:
        for mode in (codes.BRAKE, codes.REGEN):
            want = kernel.braking_ceiling(*args, int(i0), int(i1), case.P, case.curves, case.bk, mode)
            got = _kernel_c.braking_ceiling(*args, int(i0), int(i1), case.P, case.curves, case.bk, mode)
            for a, b in zip(got, want, strict=True):
                _same(a, b)
        want = kernel.braking_ceiling_mixed(
            *args, int(i0), int(i1), case.P, case.curves, case.bk, case.tk, modes
        )
        got = _kernel_c.braking_ceiling_mixed(
            *args, int(i0), int(i1), case.P, case.curves, case.bk, case.tk, modes
        )
        for a, b in zip(got, want, strict=True):
            _same(a, b)


def test_the_step_functions_equal_the_numba_kernel(case):
    """From many states of the case's line, in every regime: the steps, crossings and distances."""
    tr = case.track
    rng = np.random.default_rng(3)
    vmax = float(np.max(tr.vlim))
    P = case.P
    for i in rng.choice(len(tr.a0), size=min(40, len(tr.a0)), replace=False):
        line = (float(tr.a0[i]), float(tr.a1[i]), float(tr.b0[i]), float(tr.b1[i]))
        w = float(tr.x[i + 1] - tr.x[i])
        for mode in (codes.TRACTION, codes.BRAKE, codes.REGEN, codes.COAST):
            kinks = case.tk if mode == codes.TRACTION else case.bk
            for v in (0.0, 1e-3, *rng.uniform(0.0, vmax, 3), *kinks[:2]):
                E, u, h = 0.5 * v * v, float(rng.uniform(0.0, w)), float(rng.uniform(-w, w))
                vref = float(rng.choice([-1.0, v]))
                assert _kernel_c.acceleration_of(
                    mode, E, u, line, P, case.curves, vref
                ) == kernel.acceleration(mode, E, u, line, P, case.curves, vref)
                assert _kernel_c.rk4_energy_of(
                    E, u, h, mode, line, P, case.curves, vref
                ) == kernel.rk4_energy(E, u, h, mode, line, P, case.curves, vref)
                assert _kernel_c.rk4_energy_time_of(E, u, abs(h), mode, line, P, case.curves, vref) == (
                    kernel.rk4_energy_time(E, u, abs(h), mode, line, P, case.curves, vref)
                )
                assert _kernel_c.step_energy_time(E, u, abs(h), mode, line, P, case.curves, kinks) == (
                    kernel.step_energy_time(E, u, abs(h), mode, line, P, case.curves, kinks)
                )
                assert _kernel_c.step_energy(
                    E, u, h, mode, line, P, case.curves, kinks
                ) == kernel.step_energy(E, u, h, mode, line, P, case.curves, kinks)
                Et = 0.5 * float(rng.uniform(0.0, vmax)) ** 2
                assert _kernel_c.distance_to_speed_of(E, u, Et, mode, line, P, case.curves) == (
                    kernel.distance_to_speed(E, u, Et, mode, line, P, case.curves)
                )
                assert _kernel_c.find_speed_crossing_split(
                    E, u, h, Et, mode, line, P, case.curves, kinks
                ) == (kernel.find_speed_crossing_split(E, u, h, Et, mode, line, P, case.curves, kinks))
                for v1 in (v, *kinks[:1], *rng.uniform(0.0, vmax, 2)):
                    assert _kernel_c.kinks_between_of(v, v1, kinks) == kernel._kinks_between(v, v1, kinks)
        Er = 0.5 * float(rng.uniform(0.0, vmax)) ** 2
        E = 0.5 * float(rng.uniform(0.0, vmax)) ** 2
        assert _kernel_c.find_curve_meeting_of(E, 0.0, Er, w, line, P, case.curves, case.tk, case.bk) == (
            kernel.find_curve_meeting(E, 0.0, Er, w, line, P, case.curves, case.tk, case.bk)
        )


def test_the_compiled_constants_are_the_python_ones():
    compiled = _kernel_c.compiled_constants()
    assert compiled == {
        name: getattr(codes, name) if hasattr(codes, name) else getattr(kernel, name) for name in compiled
    }


def test_bad_input_is_refused_naming_what_is_wrong():
    case = Case(*_small())
    tr = case.track
    out = [np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4, np.int8)]
    args = [tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tr.traction_scale, 0, len(tr.a0), 0.0]
    with pytest.raises(ValueError, match="too short"):
        _kernel_c.fastest_segment(*args, case.P.copy(), case.curves, case.tk, case.bk, *out, 0)
    with pytest.raises(ValueError, match="length 3: need 8"):
        _kernel_c.fastest_segment(*args, np.zeros(3), case.curves, case.tk, case.bk, *out, 0)
    with pytest.raises(ValueError, match="need one length n for the intervals"):
        _kernel_c.fastest_segment(tr.x[:-1], *args[1:], case.P.copy(), case.curves, case.tk, case.bk, *out, 0)
    with pytest.raises(ValueError, match="track a0: need a C-contiguous 1-D array of float64"):
        _kernel_c.fastest_segment(
            tr.x, tr.a0.astype(np.float32), *args[2:], case.P.copy(), case.curves, case.tk, case.bk, *out, 0
        )
    with pytest.raises(ValueError, match="track b1: need a C-contiguous 1-D array of float64, got ndarray"):
        _kernel_c.fastest_segment(
            *args[:4],
            np.repeat(tr.b1, 2)[::2],
            *args[5:],
            case.P.copy(),
            case.curves,
            case.tk,
            case.bk,
            *out,
            0,
        )
    with pytest.raises(ValueError, match="out_m: need a C-contiguous writable 1-D array of int8"):
        _kernel_c.fastest_segment(
            *args, case.P.copy(), case.curves, case.tk, case.bk, *out[:3], np.zeros(4), 0
        )
    with pytest.raises(ValueError, match=r"\(n,\) and \(n, 4\)"):
        bad = (*case.curves[:5], np.zeros((len(case.curves[4]), 3)), *case.curves[6:])
        _kernel_c.fastest_segment(*args, case.P.copy(), bad, case.tk, case.bk, *out, 0)
    with pytest.raises(ValueError, match="trace regimes m: need a C-contiguous 1-D array of int8"):
        case.kinks(
            _kernel_c.insert_kink_points, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2), case.P.copy()
        )


def _small():
    sc = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")
    return sc.train, sc.route, sc.settings
