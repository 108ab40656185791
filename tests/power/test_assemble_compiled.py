"""The compiled DC assembly (trainsim.power.solver._assemble_dc) against the numpy form
(_assemble_numpy): the same nodes, branches and leaky segments, array by array, on networks that
exercise every branch of it (leaking and non-leaking rails, section insulator and dead section,
paralleling post and cross-bond, earthed negatives, an ideal return, trains sharing a node with a
fixed point or with each other)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from powercases import NO_LIMITS, metro_network

from trainsim.power import Connection, Gap, Network, Substation, Track
from trainsim.power.solver import _assemble_dc, _assemble_numpy


def _networks() -> dict[str, Network]:
    tracks = (Track("A", 0, 4000, 0.02e-3, 0.015e-3, 0.2e-6), Track("B", 0, 4000, 0.02e-3, 0.015e-3))
    subs = (
        Substation("S1", 0, ("A", "B"), 835, 0.03),
        Substation("S2", 4000, ("A", "B"), 825, 0.05, reversible=True),
    )
    conns = (Connection("PP", 1000, ("A", "B")), Connection("CB", 2000, ("A", "B"), kind="cross_bond"))
    gaps = (Gap("SI", "B", 2500, 2500), Gap("NS", "A", 3000, 3100))
    cut = Network("cut", "dc", NO_LIMITS, tracks, subs, conns, gaps, contact_leakage_s=1e-12)
    ideal_tracks = tuple(dataclasses.replace(t, rail_resistance_ohm_per_m=0.0) for t in tracks)
    return {
        "metro": metro_network(False),
        "cut": cut,
        "earthed": dataclasses.replace(cut, negative_earthed=True, _topology=None),
        "ideal": Network("ideal", "dc", NO_LIMITS, ideal_tracks, subs, conns, gaps),
    }


@pytest.mark.parametrize("name", ["metro", "cut", "earthed", "ideal"])
def test_compiled_assembly_is_the_numpy_one(name):
    net = _networks()[name]
    rng = np.random.default_rng(18)
    end = net.tracks[0].end_m
    for _ in range(20):
        m = int(rng.integers(1, 12))
        track = rng.integers(0, len(net.tracks), m)
        x = rng.uniform(0.0, end, m)
        # on a fixed point, two trains at one node, one 4 cm from another (rounded to one node)
        x[0] = net.substations[0].position_m
        if m > 2:
            x[1], track[1] = x[2] + 0.04, track[2]
        supplied = np.array([net.supplied(int(t), np.array([p]))[0] for t, p in zip(track, x, strict=True)])
        track, x = track[supplied], x[supplied]
        got, ref = _assemble_dc(net, track, x), _assemble_numpy(net, track, x)
        assert got.n == ref.n
        for field in ("a", "b", "train_c", "train_r", "rail_nodes", "fixed_index"):
            assert np.array_equal(getattr(got, field), getattr(ref, field)), field
        # the same formulas; the hyperbolic functions of numpy and of the C library may differ in
        # the last bit
        np.testing.assert_allclose(got.y, ref.y, rtol=4e-16, atol=0)
        assert (got.leaky_segments is None) == (ref.leaky_segments is None)
        if ref.leaky_segments is not None:
            for g, r in zip(got.leaky_segments, ref.leaky_segments, strict=True):
                assert np.array_equal(g, r)


def test_unknowns_along_the_line_make_a_narrow_band():
    """band_place numbers the unknowns by chainage: on the two-track metro with six trains each
    branch joins unknowns at most a few places apart (the nodes of both tracks between its ends),
    while the natural numbering (fixed nodes first) spreads them over the whole matrix."""
    from trainsim.power.solver import _half_bandwidth, _relabel

    net = metro_network(True)
    end = net.tracks[0].end_m
    track = np.array([0, 0, 0, 1, 1, 1])
    x = np.array([0.1, 0.45, 0.8, 0.2, 0.55, 0.9]) * end
    asm = _assemble_dc(net, track, x)
    place = asm.band_place
    assert sorted(place.tolist()) == list(range(asm.n))
    placed = _half_bandwidth(((_relabel(asm.a, place), _relabel(asm.b, place)),))
    natural = _half_bandwidth(((asm.a, asm.b),))
    assert placed <= 6 < natural
