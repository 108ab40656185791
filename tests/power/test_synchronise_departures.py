"""Per-departure timetable synchronisation (issue 18): the search against a brute force over the
same grid, the saving against two independent network solutions, headways and windows kept, and
bad settings refused with the field named."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.power import Network, Substation, Track, TrainLoad, simulate, standard_limits
from trainsim.power.synchronise import SyncSettings, substation_energy_kwh, synchronise_departures

LENGTH_M = 3000.0


def _diode_line() -> Network:
    """Two tracks fed by diode rectifiers at both ends: regenerated energy is only worth something
    when a train nearby draws it at the same time."""
    tracks = tuple(Track(t, 0.0, LENGTH_M, 0.02e-3, 0.015e-3) for t in ("up", "down"))
    subs = tuple(
        Substation(f"S{k}", x, ("up", "down"), 850.0, 0.03, reversible=False)
        for k, x in enumerate((0.0, LENGTH_M))
    )
    return Network("diode line", "dc", standard_limits("dc_750"), tracks, subs)


def _load(name: str, track: str, departure_s: float, start_s: float, kind: str) -> TrainLoad:
    """A train near the middle of the line, ``departure_s`` its first point, drawing 1.5 MW
    (``traction``) or offering 1.5 MW (``regen``) from ``departure_s + start_s`` for 30 s."""
    t = departure_s + np.array([0.0, start_s, start_s + 1, start_s + 29, start_s + 30, start_s + 60])
    p = np.array([0.0, 0.0, 1.5e6, 1.5e6, 0.0, 0.0])
    zero = np.zeros_like(p)
    x = np.linspace(1400.0, 1600.0, len(t))
    trac, regen = (p, zero) if kind == "traction" else (zero, p)
    return TrainLoad(name, track, t, x, trac, regen, auxiliary_power_w=20e3)


def _energy(net: Network, loads: list[TrainLoad], offsets, span) -> float:
    shifted = [
        TrainLoad(ld.id, ld.track, ld.time_s + x, ld.position_m, ld.traction_power_w, ld.regen_power_w,
                  ld.auxiliary_power_w)
        for ld, x in zip(loads, offsets, strict=True)
    ]  # fmt: skip
    return substation_energy_kwh(simulate(net, shifted, dt_s=1.0, start_s=span[0], end_s=span[1]))


@pytest.fixture(scope="module")
def two_trains():
    """The braking train (up) offers from t = 100 s, the accelerating one (down) draws from
    t = 118 s: 12 s of overlap as given, 30 s when the down train starts 18 s earlier."""
    net = _diode_line()
    loads = [_load("brake", "up", 0.0, 100.0, "regen"), _load("start", "down", 100.0, 18.0, "traction")]
    settings = SyncSettings(window_s=20.0, step_s=10.0, rounds=3, refinements=0, min_headway_s=60.0)
    out = synchronise_departures(net, loads, ["up", "down"], settings)
    return net, loads, settings, out


def test_search_finds_the_brute_force_optimum_of_the_grid(two_trains):
    net, loads, _, out = two_trains
    grid = np.arange(-20.0, 20.0 + 1e-9, 10.0)
    brute = {xy: _energy(net, loads, xy, out.span_s) for xy in itertools.product(grid, grid)}
    best = min(brute.values())
    assert out.status == "ok" and out.evaluation == "local"
    assert out.synchronised_kwh == pytest.approx(best, rel=1e-9, abs=1e-9)
    # the optimum makes the two powers overlap the most: the down train 18 s earlier relative to the up
    # one (20 s on a 10 s grid: 28 s of overlap instead of 12)
    assert out.offsets_s[1] - out.offsets_s[0] == -20.0
    assert brute[(0.0, 0.0)] - best > 0.05  # a real saving, in kWh


def test_saving_is_the_difference_of_two_independent_solutions(two_trains):
    net, loads, _, out = two_trains
    before = _energy(net, loads, (0.0, 0.0), out.span_s)
    after = _energy(net, loads, out.offsets_s, out.span_s)
    assert out.baseline_kwh == pytest.approx(before, rel=1e-12)
    assert out.synchronised_kwh == pytest.approx(after, rel=1e-12)
    assert out.saving_kwh == pytest.approx(before - after, rel=1e-9)
    assert out.saving_percent == pytest.approx(100 * (before - after) / before, rel=1e-9)


def test_headway_and_windows_are_kept_on_one_track():
    """Two departures of one track 100 s apart: the energy wants them 82 s apart (the second's
    traction on the first's braking), the headway allows 90 s at least."""
    net = _diode_line()
    loads = [_load("first", "up", 0.0, 100.0, "regen"), _load("second", "up", 100.0, 18.0, "traction")]
    settings = SyncSettings(window_s=20.0, step_s=5.0, rounds=2, refinements=1, min_headway_s=90.0)
    out = synchronise_departures(net, loads, ["up", "up"], settings)
    gap = 100.0 + out.offsets_s[1] - out.offsets_s[0]
    assert out.status == "ok"
    assert all(abs(x) <= 20.0 + 1e-9 for x in out.offsets_s)
    assert gap >= 90.0 - 1e-9
    assert gap == pytest.approx(90.0)  # as close to 82 s as the headway allows
    assert out.saving_kwh > 0


def test_a_headway_the_windows_cannot_give_is_a_status():
    net = _diode_line()
    loads = [_load("first", "up", 0.0, 100.0, "regen"), _load("second", "up", 100.0, 18.0, "traction")]
    out = synchronise_departures(net, loads, ["up", "up"], SyncSettings(window_s=20.0, min_headway_s=150.0))
    assert out.status == "headway_not_met" and "150" in out.message
    assert out.offsets_s == (0.0, 0.0) and out.saving_kwh == 0.0


@pytest.mark.parametrize(
    ("field", "value"),
    [("window_s", -5.0), ("step_s", 0.0), ("rounds", 0), ("refinements", -1), ("min_headway_s", np.nan),
     ("per", "week")],
)  # fmt: skip
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(InputError) as err:
        SyncSettings(**{field: value})
    assert f"synchronisation.{field}" in str(err.value)


def test_overload_excess_is_the_energy_above_the_overload_power(two_trains):
    """Against a sum written out step by step: 0.4 MW of overload power on each substation."""
    import dataclasses

    from trainsim.power.synchronise import overload_excess_kwh

    net, loads, _, _ = two_trains
    subs = tuple(dataclasses.replace(s, rated_power_w=0.3e6, overload_power_w=0.4e6) for s in net.substations)
    res = simulate(dataclasses.replace(net, substations=subs), loads, dt_s=1.0)
    by_hand = 0.0
    for row in res.substation_power_w:
        for p in row:
            by_hand += max(p - 0.4e6, 0.0) * 1.0
    assert by_hand > 0
    assert overload_excess_kwh(res) == pytest.approx(by_hand / 3.6e6, rel=1e-12)
    assert overload_excess_kwh(simulate(net, loads, dt_s=1.0)) == 0.0  # no overload power given
