"""Many metro trains on a 750 V line over time: invariants, energy balance, rectifiers, outputs."""

from __future__ import annotations

import numpy as np
import pytest
from powercases import metro_loads, metro_network

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.power import simulate


@pytest.fixture(scope="module")
def results():
    loads = metro_loads(n_per_direction=3)
    return {rev: simulate(metro_network(rev), loads, dt_s=1.0) for rev in (False, True)}


@pytest.mark.parametrize("reversible", [False, True])
def test_invariants_and_energy_balance(results, reversible):
    res = results[reversible]
    s = res.summary()
    assert s["status"] == "ok", s["warnings"]
    assert res.converged.all()
    assert s["energy_balance_error"] < 1e-6
    # substations (at their busbars) = trains at the pantograph + line losses, in kWh
    assert s["substations_energy_kwh"] == pytest.approx(
        s["trains_energy_kwh"] + s["line_losses_kwh"], rel=1e-6
    )
    v = res.train_voltage_v[np.isfinite(res.train_voltage_v)]
    assert np.all(v > 0) and np.all(np.isfinite(res.substation_power_w))
    # regen split adds up
    r = s["regen_kwh"]
    assert r["used_by_trains"] + r["returned"] + r["dissipated"] == pytest.approx(r["offered"], rel=1e-12)
    assert r["dissipated"] >= 0 and r["returned"] >= 0
    # the train's own figures: demand from the run's trace (F v / eta), delivered <= demand
    for t in s["trains"]:
        assert t["traction_delivered_kwh"] <= t["traction_demand_kwh"] + 1e-12


def test_non_reversible_substations_never_take_power(results):
    res = results[False]
    assert np.min(res.substation_power_w) >= -1e-6
    assert res.summary()["regen_kwh"]["returned"] == pytest.approx(0.0, abs=1e-9)
    # without a sink, regenerated energy is curtailed: more is dissipated than with inverters
    assert res.summary()["regen_kwh"]["dissipated"] > results[True].summary()["regen_kwh"]["dissipated"]


def test_reversible_substations_take_power_back_and_save_energy(results):
    rev, diode = results[True].summary(), results[False].summary()
    assert rev["regen_kwh"]["returned"] > 0
    assert rev["substations_energy_kwh"] < diode["substations_energy_kwh"]


def test_demand_matches_the_run_energy():
    """The traction energy the network is asked for equals the run's traction work / eta within the
    1 s sampling error (an independent integral of the run's trace)."""
    from powercases import metro_run

    run, _ = metro_run()
    loads = metro_loads(n_per_direction=1)
    res = simulate(metro_network(True), loads[:1], dt_s=0.5)
    demand_kwh = res.summary()["trains"][0]["traction_demand_kwh"]
    assert demand_kwh == pytest.approx(run.energy_kwh.traction / 0.98, rel=0.01)


def test_rms_windows_and_overloads(results):
    res = results[True]
    i = res.substation_current_a
    # the 60 s moving RMS is at least the whole-run RMS of some window and at most the peak
    rms60 = res.rms_current_a(60.0)
    assert np.all(rms60 <= np.max(np.abs(i), axis=0) + 1e-9)
    assert np.all(rms60 >= np.sqrt(np.mean(i**2, axis=0)) - 1e-9)
    assert np.all(np.isnan(res.rms_current_a(3600.0)))  # the run is shorter than an hour
    events = res.overload_events(0)
    for e in events:
        assert e["peak_power_kw"] > 3000.0 and e["duration_s"] >= res.dt_s


def test_train_off_the_wire_is_an_input_error():
    loads = metro_loads(n_per_direction=1)
    bad = loads[0].__class__(**{**loads[0].__dict__, "position_m": loads[0].position_m + 1000.0})
    with pytest.raises(InputError, match="runs off the wire"):
        simulate(metro_network(True), [bad])


def test_energy_units():
    assert KWH == 3.6e6


def test_wayside_storage_takes_regenerated_energy_and_keeps_its_books():
    """A 20 kWh / 2 MW storage beside the middle diode substation: it charges only above 870 V and
    discharges below 830 V, never beyond its power or capacity; its stored energy follows
    E_end = E_0 + sqrt(eta) charged - discharged / sqrt(eta); the balance includes it; less
    regenerated energy is burnt and the substations deliver less."""
    import dataclasses

    from trainsim.power import Storage

    net = metro_network(False)
    storage = Storage("ESS", 2295.0, ("up", "down"), 20 * KWH, 2e6, 0.9, 870.0, 830.0)
    loads = metro_loads(n_per_direction=3)
    without = simulate(net, loads).summary()
    res = simulate(dataclasses.replace(net, storages=(storage,)), loads)
    s = res.summary()
    assert s["status"] == "ok" and s["energy_balance_error"] < 1e-6
    p = res.storage_power_w[:, 0]
    e = res.storage_energy_j[:, 0]
    assert np.max(np.abs(p)) <= 2e6 * (1 + 1e-12)
    assert np.all((e >= -1e-6) & (e <= 20 * KWH + 1e-6))
    eta = np.sqrt(0.9)
    books = 10 * KWH + (np.sum(np.maximum(p, 0)) * eta - np.sum(np.maximum(-p, 0)) / eta) * res.dt_s
    assert e[-1] == pytest.approx(books, rel=1e-12)
    assert s["regen_kwh"]["stored"] > 0
    assert s["regen_kwh"]["dissipated"] < without["regen_kwh"]["dissipated"]
    assert s["substations_energy_kwh"] < without["substations_energy_kwh"]
    assert s["substations_energy_kwh"] == pytest.approx(
        s["trains_energy_kwh"] + s["line_losses_kwh"] + s["storages_energy_kwh"], rel=1e-6
    )
