"""One pass (issue 14): the fastest-run kernel places the kink points itself, where its kink-aware
steps locate the kinks (``fastest_segment(..., kink_points=True)``), instead of ``insert_kink_points``
finding them a second time on the finished trace. The independent computation here is that second
search: the points must be the same, in number, regime and place (to rounding: the kernel's offset
into an interval is not recomputed from the trace's position)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model.scenario import RunSettings
from trainsim.sim import _kernel_c, codes
from trainsim.sim.fastest import run_fastest
from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_route

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


class Segments:
    """The kernel's inputs for every segment of a run, as ``run_fastest`` builds them."""

    def __init__(self, train, route, settings, traction_share=1.0):
        train = train.at_gravity(route.gravity_mps2)
        stops = [s.position_m for s in route.stops]
        self.track = compile_route(route, train, stops, settings.max_step_m).track
        self.P, traction, brake = kernel_parameters(train, settings)
        self.tk = kink_speeds(*traction)
        self.bk = kink_speeds(*brake)
        self.curves = (*traction, *brake, *regenerative_arrays(train))
        self.tscale = self.track.traction_scale * traction_share
        self.segments = [
            (int(a), int(b))
            for a, b in zip(self.track.stop_index[:-1], self.track.stop_index[1:], strict=True)
        ]

    def run(self, n_max, **kw):
        """(s, v, t, m, statuses) of every segment in turn, each from its stop's standstill."""
        tr = self.track
        out = [np.zeros(n_max), np.zeros(n_max), np.zeros(n_max), np.zeros(n_max, np.int8)]
        n, statuses = 0, []
        for i0, i1 in self.segments:
            t0 = float(out[2][n - 1]) + 10.0 if n else 0.0
            while True:
                n_next, status, _ = _kernel_c.fastest_segment(
                    tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, self.tscale, i0, i1, t0, self.P.copy(),
                    self.curves, self.tk, self.bk, *out, n, grow=True, **kw,
                )  # fmt: skip
                if status != codes.STATUS_FULL:
                    break
                out = [np.concatenate([a, np.zeros_like(a)]) for a in out]
            n = n_next
            statuses.append(status)
        return (*(a[:n] for a in out), statuses)

    def inserted(self, s, v, t, m):
        tr = self.track
        return _kernel_c.insert_kink_points(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, self.tscale, self.P.copy(), self.curves, self.tk, self.bk,
            s, v, t, m,
        )  # fmt: skip


def _scenario(name):
    sc = trainsim.load_scenario(ROOT / "examples" / name / "scenario.yaml")
    return sc.train, sc.route, sc.settings


def _trainruns():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the data's defaults are announced by a warning
        train = load_train(TRAINRUNS / "trains" / "freight.yaml")
    return train, load_route(TRAINRUNS / "paths" / "realworld.yaml"), RunSettings()


CASES = {
    "metro_b": lambda: Segments(*_scenario("metro_b")),
    "freight_000": lambda: Segments(*_scenario("freight_000")),
    "trainruns freight realworld": lambda: Segments(*_trainruns()),
    # a weak train stalls: the stall's stretch gets its kink points too
    "metro_b at 20 % traction": lambda: Segments(*_scenario("metro_b"), traction_share=0.2),
}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    seg = CASES[request.param]()
    n_max = 4 * len(seg.track.x) + 8 * len(seg.segments) + 32
    return request.param, seg, seg.run(n_max), seg.run(n_max, kink_points=True)


def test_the_kernel_places_the_kink_points_the_second_search_finds(case):
    name, seg, (s, v, t, m, st), (s1, v1, t1, m1, st1) = case
    s2, v2, t2, m2 = seg.inserted(s, v, t, m)
    assert st1 == st
    assert len(s1) == len(s2), name
    assert len(s1) > len(s) or name == "freight_000", "the case must cross kinks to test anything"
    np.testing.assert_array_equal(m1, m2)
    np.testing.assert_allclose(s1, s2, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(v1, v2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(t1, t2, rtol=1e-13, atol=1e-12)
    # every point the kernel put without kink points is still there, bit for bit
    keep = np.isin(s1, s)
    np.testing.assert_array_equal(s1[keep], s)
    np.testing.assert_array_equal(t1[keep], t)


def test_kink_points_sit_on_kinks_inside_their_stretch(case):
    name, seg, (s0, *_), (s, v, t, m, _) = case
    added = np.flatnonzero(~np.isin(s, s0))
    assert len(added) == len(s) - len(s0), name
    for k in added:
        kinks = seg.tk if m[k] == codes.TRACTION else seg.bk
        assert m[k] in (codes.TRACTION, codes.BRAKE) and m[k - 1] == m[k], (name, k)
        assert v[k] in kinks, (name, k, v[k])
        assert s[k - 1] < s[k] < s[k + 1] and t[k - 1] < t[k] < t[k + 1], (name, k)
        assert min(v[k - 1], v[k + 1]) < v[k] < max(v[k - 1], v[k + 1]), (name, k)


def test_full_out_arrays_grow_instead_of_failing():
    seg = CASES["metro_b"]()
    s, v, t, m, _ = seg.run(10_000, kink_points=True)
    tr = seg.track
    i0, i1 = seg.segments[0]
    out = [np.zeros(5), np.zeros(5), np.zeros(5), np.zeros(5, np.int8)]
    args = (tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, seg.tscale, i0, i1, 0.0, seg.P.copy(), seg.curves)
    n, status, stall = _kernel_c.fastest_segment(*args, seg.tk, seg.bk, *out, 2, kink_points=True, grow=True)
    assert (n, status) == (2, codes.STATUS_FULL) and np.isnan(stall)
    with pytest.raises(ValueError, match="too short"):
        _kernel_c.fastest_segment(*args, seg.tk, seg.bk, *out, 2, kink_points=True)
    # from a start of 5 points, doubled until the run fits: the same run as with long arrays at once
    small = seg.run(5, kink_points=True)
    for a, b in zip(small[:4], (s, v, t, m), strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_run_has_its_kink_points_and_is_deterministic():
    train, route, settings = _trainruns()
    a = run_fastest(train, route, settings)
    b = run_fastest(train, route, settings)
    np.testing.assert_array_equal(a.trace.position_m, b.trace.position_m)
    np.testing.assert_array_equal(a.trace.time_s, b.trace.time_s)
    seg = Segments(train, route, settings)
    kinks = np.concatenate([seg.tk, seg.bk])
    v = np.asarray(a.trace.speed_mps)
    assert np.isin(v, kinks).sum() >= 10


@pytest.mark.parametrize("name", ["metro_b", "trainruns freight realworld"])
def test_with_speed_domain_steps_too(name):
    # as run_fastest calls the kernel: the kink points are those of the second search on the same run
    # (their times by the distance domain there, so to 1e-9 rather than to rounding)
    seg = CASES[name]()
    n_max = 4 * len(seg.track.x) + 64
    s, v, t, m, _ = seg.run(n_max, slow_steps=True)
    s1, v1, t1, m1, _ = seg.run(n_max, kink_points=True, slow_steps=True)
    s2, v2, t2, m2 = seg.inserted(s, v, t, m)
    assert len(s1) == len(s2) > len(s)
    np.testing.assert_array_equal(m1, m2)
    np.testing.assert_allclose(s1, s2, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(v1, v2, rtol=1e-12, atol=1e-12)
    # near standstill the distance domain's time over a piece is off by up to 6e-7 of it (see
    # test_onepass_slow_steps): 2e-6 s measured at a kink point 1,045 s into the freight run
    slow = v1 < 5.0
    np.testing.assert_allclose(t1[~slow], t2[~slow], rtol=1e-9)
    np.testing.assert_allclose(t1[slow], t2[slow], rtol=1e-9, atol=1e-5)
