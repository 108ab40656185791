"""The compiled Newton (dense LAPACK LU, trainsim.power.solver._newton_dc_dense) against the sparse
one (SuperLU, the same iteration in numpy) on whole simulations: diode rectifiers that block, curtailed
regeneration (the continuation fallbacks), reversible substations, leaking rails, a weak line."""

from __future__ import annotations

import numpy as np
import pytest
from powercases import metro_loads, metro_network

import trainsim.power.solver as solver
from trainsim.power import simulate, standard_limits
from trainsim.power.network import Network, Substation, Track

FIELDS = (
    "train_voltage_v",
    "train_power_w",
    "substation_power_w",
    "substation_current_a",
    "line_loss_w",
    "traction_delivered_w",
    "regen_accepted_w",
)


def _both(monkeypatch, net, loads):
    dense = simulate(net, loads, dt_s=2.0)
    with monkeypatch.context() as m:
        m.setattr(solver, "DENSE_NEWTON_MAX_NODES", 0)
        sparse = simulate(net, loads, dt_s=2.0)
    return dense, sparse


def _agree(dense, sparse):
    assert dense.converged.all() and sparse.converged.all()
    for name in FIELDS:
        a, b = getattr(dense, name), getattr(sparse, name)
        assert np.array_equal(np.isfinite(a), np.isfinite(b)), name
        scale = max(float(np.nanmax(np.abs(b))), 1.0)
        assert float(np.nanmax(np.abs(a - b))) <= 1e-9 * scale, name
    # what the two paths compute the same way, step by step (not a round-off figure)
    assert np.sum(dense.iterations) == pytest.approx(np.sum(sparse.iterations), rel=0.02)


@pytest.mark.parametrize("reversible", [False, True])
def test_dense_and_sparse_newton_agree_on_the_metro(monkeypatch, reversible):
    net = metro_network(reversible)
    loads = metro_loads(2, 150.0)
    dense, sparse = _both(monkeypatch, net, loads)
    _agree(dense, sparse)
    if not reversible:
        # the case that needs the rectifier continuation: some regenerated energy burnt
        assert dense.regen_kwh()["dissipated"] > 0


def test_dense_and_sparse_newton_agree_on_a_weak_one_end_feed(monkeypatch):
    """One diode substation at one end of thin conductors: traction limited on the EN 50388 ramp
    (the fallback that starts on the ramp) and regeneration curtailed."""
    base = metro_network(False)
    length = base.tracks[0].end_m
    tracks = tuple(Track(t, 0.0, length, 0.08e-3, 0.015e-3, 0.1e-6) for t in ("up", "down"))
    net = Network(
        "weak",
        "dc",
        standard_limits("dc_750"),
        tracks,
        (Substation("S", 0.0, ("up", "down"), 850.0, 0.03, reversible=False),),
    )
    dense, sparse = _both(monkeypatch, net, metro_loads(1, 150.0))
    _agree(dense, sparse)
    assert np.nanmin(dense.train_voltage_v) < net.limits.traction_full_v  # the ramp was reached


def test_larger_networks_take_the_sparse_path(monkeypatch):
    """Above DENSE_NEWTON_MAX_NODES unknowns the dense kernel is not called."""
    calls = []
    real = solver._newton_dc_dense

    def spy(*args):
        calls.append(len(args[0]))
        return real(*args)

    monkeypatch.setattr(solver, "_newton_dc_dense", spy)
    net = metro_network(True)
    loads = metro_loads(1, 150.0)
    simulate(net, loads, dt_s=20.0)
    assert calls and max(calls) <= solver.DENSE_NEWTON_MAX_NODES
    small = max(calls) - 1
    before = len(calls)
    calls.clear()
    monkeypatch.setattr(solver, "DENSE_NEWTON_MAX_NODES", small)
    simulate(net, loads, dt_s=20.0)
    assert len(calls) < before and all(n <= small for n in calls)


def test_band_solver_against_lapack():
    """_band_solve against numpy's LAPACK solve on random banded matrices, some with small or zero
    diagonals (row exchanges needed), and a singular one reported, not raised."""
    rng = np.random.default_rng(18)
    for n, w in ((1, 0), (5, 1), (40, 3), (86, 6), (120, 15)):
        mat = np.zeros((n, n))
        for i in range(n):
            for j in range(max(0, i - w), min(n, i + w + 1)):
                mat[i, j] = rng.normal()
        if w:  # zero pivots: Gaussian elimination without row exchanges would fail
            mat[np.arange(0, n, 3), np.arange(0, n, 3)] = 0.0
        rhs = rng.normal(size=n)
        ref = np.linalg.solve(mat, rhs)
        x, singular = solver._band_solve(mat.copy(), rhs.copy(), w)
        assert not singular
        np.testing.assert_allclose(x, ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
    mat = np.diag([1.0, 2.0, 0.0, 3.0])
    _, singular = solver._band_solve(mat, np.ones(4), 0)
    assert singular
