"""The solver's fast gathers and scatters equal the masked forms they replace, bit for bit."""

from __future__ import annotations

import numpy as np

from trainsim.power.rail import segment_leakage_a
from trainsim.power.solver import _bins, _injection, _injection_into, _potential, _with_earth


def test_potentials_with_the_earth_appended_equal_the_masked_gather():
    rng = np.random.default_rng(7)
    n = 40
    nodes = rng.integers(-1, n, size=200)  # -1: earth
    for v in (rng.normal(size=n) * 800.0, rng.normal(size=n) + 1j * rng.normal(size=n)):
        got = _with_earth(v)[nodes]
        np.testing.assert_array_equal(got, _potential(v, nodes))
        assert got.dtype == v.dtype
        assert np.all(got[nodes < 0] == 0)


def test_injection_into_a_spare_bin_equals_the_masked_scatter():
    rng = np.random.default_rng(11)
    n = 30
    nodes = rng.integers(-1, n, size=500)
    values = rng.normal(size=500) * 1e3
    got = _injection_into(n, _bins(nodes, n), values)
    np.testing.assert_array_equal(got, _injection(n, nodes, values, float))
    assert got.shape == (n,)
    # what goes to earth is dropped: the sum over nodes is the sum of the non-earth values
    assert np.isclose(got.sum(), values[nodes >= 0].sum(), rtol=1e-12)


def test_rail_leakage_is_elementwise():
    """Computed over many segments at once (the sign-change branch only where V changes sign) each
    segment's leakage is the one computed alone."""
    rng = np.random.default_rng(3)
    m = 50
    va, vb = rng.normal(size=m) * 20.0, rng.normal(size=m) * 20.0
    length = rng.uniform(1.0, 3000.0, size=m)
    r, g = np.full(m, 0.012e-3), np.where(rng.random(m) < 0.2, 1e-12, 0.1e-6)  # some nearly without leakage
    together = segment_leakage_a(va, vb, length, r, g)
    alone = np.array([segment_leakage_a(va[k], vb[k], length[k], r[k], g[k]) for k in range(m)])
    np.testing.assert_array_equal(together, alone)
    assert np.any(va * vb < 0) and np.all(together >= 0)
    assert np.ndim(segment_leakage_a(1.0, 2.0, 100.0, 1e-5, 1e-7)) == 0
