"""The compiled fastest-run kernel (``sim/_kernel_c.pyx``, Cython): its settings and its checks of the
arrays it is given. It replaced the numba kernel ``sim/kernel.py`` bit for bit (every output array,
status and stall position compared on the examples and the TrainRuns.jl freight train at several steps,
commits 204d4fa to 188d243); its figures are tested by the run tests (analytic cases, published values)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.sim import _kernel_c, codes
from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_route

ROOT = Path(__file__).resolve().parents[2]


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


def test_a_train_too_weak_for_the_line_stalls_and_says_where():
    # source 000's freight train at a fifth of its traction stalls on the climb of the first section
    sc = trainsim.load_scenario(ROOT / "examples" / "freight_000" / "scenario.yaml")
    case = Case(sc.train, sc.route, sc.settings)
    results, (s, v, _t, _m), _ = case.run(_kernel_c.fastest_segment, traction_share=0.2)
    assert [status for _, status, _ in results] == [codes.STATUS_STALLED, codes.STATUS_OK]
    n, _, stall_at = results[0]
    (i0, i1) = case.segments[0]
    assert case.track.x[i0] < stall_at < case.track.x[i1]
    assert np.all(np.isfinite(s[:n])) and np.all(v[:n] >= 0.0) and np.all(np.diff(s[:n]) >= 0.0)
    full, _, _ = case.run(_kernel_c.fastest_segment)
    assert all(status == codes.STATUS_OK for _, status, _ in full)


def test_the_compiled_constants_are_the_python_ones():
    compiled = _kernel_c.compiled_constants()
    assert compiled == {name: getattr(codes, name) for name in compiled}


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
