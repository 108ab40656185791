"""The solver's fast gathers and scatters equal the masked forms they replace, bit for bit."""

from __future__ import annotations

import numpy as np
from powercases import metro_network

from trainsim.power.limits import regen_acceptance, traction_availability
from trainsim.power.rail import segment_leakage_a
from trainsim.power.solver import (
    _bins,
    _dc_load_residual,
    _injection,
    _injection_into,
    _Pattern,
    _potential,
    _with_earth,
    assemble,
)


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


def test_compiled_dc_residual_equals_the_numpy_form():
    """The residual kernel against the numpy operations it replaces (gathers, EN 50388 / EN 50163
    ramps, bincounts): the same doubles, on a metro network with trains on the ramps and beyond."""
    net = metro_network(reversible=True)
    lim = net.limits
    rng = np.random.default_rng(5)
    m = 40
    track = rng.integers(0, 2, size=m)
    position = rng.uniform(0.0, net.tracks[0].end_m, size=m)
    asm = assemble(net, track, position)
    n = asm.n
    sub_p = np.array([net.topology.substation_nodes[i][0] for i in range(len(net.substations))])
    sub_n = np.array([net.topology.substation_nodes[i][1] for i in range(len(net.substations))])
    ys = np.full(len(sub_p), 1 / 0.03)
    pattern = _Pattern(n, [(asm.a, asm.b), (sub_p, sub_n), (asm.train_c, asm.train_r)])
    j_src = rng.normal(size=n) * 1e4
    tw, aux, rw = rng.uniform(0, 3e6, m), np.full(m, 5e4), rng.uniform(0, 2e6, m)
    tc, tr = asm.train_c, asm.train_r
    # contact potentials spread over the traction ramp, the curtailment ramp and beyond both
    v = np.where(np.isin(np.arange(n), asm.rail_nodes), rng.normal(size=n) * 5.0, rng.uniform(400, 1100, n))
    u_floor = 1e-3 * lim.nominal_v
    f, uu, p = _dc_load_residual(
        v, tc, tr, np.where(tc < 0, n, tc), np.where(tr < 0, n, tr), *pattern.weights(0, asm.y),
        *pattern.weights(1, ys), j_src, tw, aux, rw, u_floor, lim.min1_v, lim.traction_full_v,
        lim.regen_full_v, lim.regen_zero_v,
    )  # fmt: skip
    u = _potential(v, tc) - _potential(v, tr)
    uu_ref = np.maximum(u, u_floor)
    a_s = traction_availability(uu_ref, lim.min1_v, lim.traction_full_v)
    r_s = regen_acceptance(uu_ref, lim.regen_full_v, lim.regen_zero_v)
    p_ref = tw * a_s + aux - rw * r_s
    i_t = p_ref / uu_ref
    f_ref = (
        pattern.matvec(0, asm.y, v) + pattern.matvec(1, ys, v) - j_src
        + _injection(n, tc, i_t, float) - _injection(n, tr, i_t, float)
    )  # fmt: skip
    assert np.sum((a_s > 0) & (a_s < 1)) > 0 or np.sum((r_s > 0) & (r_s < 1)) > 0
    np.testing.assert_array_equal(uu, uu_ref)
    np.testing.assert_array_equal(p, p_ref)
    np.testing.assert_array_equal(f, f_ref)


def _pattern_reference(n, pairs):
    """The numpy form the compiled stamping replaced."""
    parts, rows_all, cols_all = [], [], []
    for a, b in pairs:
        ma, mb = a >= 0, b >= 0
        both = ma & mb
        ia, ib, iboth = np.flatnonzero(ma), np.flatnonzero(mb), np.flatnonzero(both)
        rows = np.concatenate([a[ia], b[ib], a[iboth], b[iboth]])
        cols = np.concatenate([a[ia], b[ib], b[iboth], a[iboth]])
        take = np.concatenate([ia, ib, iboth, iboth])
        sign = np.concatenate([np.ones(len(ia) + len(ib)), -np.ones(2 * len(iboth))])
        parts.append((rows, cols, take, sign))
        rows_all.append(rows)
        cols_all.append(cols)
    key = np.concatenate(cols_all).astype(np.int64) * n + np.concatenate(rows_all)
    uniq, inv = np.unique(key, return_inverse=True)
    return parts, uniq, inv


def test_compiled_pattern_equals_the_numpy_stamping():
    rng = np.random.default_rng(13)
    n = 60
    pairs = [
        (rng.integers(-1, n, 200), rng.integers(-1, n, 200)),  # branches, some to earth
        (np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)),  # an empty part
        (rng.integers(0, n, 25), np.full(25, -1)),  # all to earth
        (rng.integers(0, n, 9), rng.integers(0, n, 9)),
    ]
    pattern = _Pattern(n, pairs)
    parts, uniq, inv = _pattern_reference(n, pairs)
    assert pattern.nnz == len(uniq)
    bounds = np.cumsum([0] + [len(p[0]) for p in parts])
    for k, ref in enumerate(parts):
        for got, want in zip(pattern.parts[k], ref, strict=True):
            np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(pattern.slots[k], inv[bounds[k] : bounds[k + 1]])
    np.testing.assert_array_equal(pattern.matrix.indices, (uniq % n).astype(np.int32))
    # the matrix it builds is the sum of the stamps
    y = [rng.uniform(1.0, 2.0, len(a)) for a, _ in pairs]
    pattern.matrix.data[:] = sum(pattern.values(k, y[k]) for k in range(len(pairs)))
    dense = np.zeros((n, n))
    for (a, b), yk in zip(pairs, y, strict=True):
        for i, j, g in zip(a, b, yk, strict=True):
            for p, q, s in ((i, i, 1), (j, j, 1), (i, j, -1), (j, i, -1)):
                if p >= 0 and q >= 0:
                    dense[p, q] += s * g
    np.testing.assert_allclose(pattern.matrix.toarray(), dense, rtol=1e-13, atol=1e-12)
