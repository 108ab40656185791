"""The compiled stray-current sum (trainsim.power.rail.segment_leakage_total_a) against the numpy
form segment by segment (itself checked against quadrature in test_rail_potential.py)."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.power.rail import segment_leakage_a, segment_leakage_total_a


def test_compiled_leakage_sum_is_the_numpy_sum():
    rng = np.random.default_rng(18)
    m = 400
    va, vb = rng.normal(size=m) * 20.0, rng.normal(size=m) * 20.0
    length = rng.uniform(0.05, 3000.0, size=m)
    # some segments nearly without leakage (the linear branch), most with
    r, g = np.full(m, 0.012e-3), np.where(rng.random(m) < 0.2, 1e-12, 0.1e-6)
    each = segment_leakage_a(va, vb, length, r, g)
    assert np.any(va * vb < 0) and np.any(np.sqrt(r * g) * length < 1e-4)
    # every branch, one segment at a time (numpy's and the C library's sinh, tanh and arctanh may
    # differ in the last bits; a sign change close to a segment's end leaves a small positive part,
    # 1e-12 off in either form against quadrature)
    for k in range(m):
        got = segment_leakage_total_a(
            va[k : k + 1], vb[k : k + 1], length[k : k + 1], r[k : k + 1], g[k : k + 1]
        )
        assert got == pytest.approx(each[k], rel=5e-12, abs=1e-300)
    assert segment_leakage_total_a(va, vb, length, r, g) == pytest.approx(float(np.sum(each)), rel=1e-12)
    assert segment_leakage_total_a(va[:0], vb[:0], length[:0], r[:0], g[:0]) == 0.0
