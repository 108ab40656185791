"""On-board storage: its books close, it respects its limits, it takes only what the line cannot."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from powercases import metro_loads, metro_network

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.power import simulate
from trainsim.power.onboard import OnboardStorage

STORAGE = OnboardStorage(
    capacity_j=8 * KWH, max_power_w=1.2e6, charge_efficiency=0.95, discharge_efficiency=0.93,
    min_soc=0.2, max_soc=0.9, initial_soc=0.3, assist_above_w=1.5e6,
)  # fmt: skip


@pytest.fixture(scope="module")
def runs():
    loads = metro_loads(n_per_direction=2)
    with_storage = [dataclasses.replace(load, onboard_storage=STORAGE) for load in loads]
    net = metro_network(False)  # diode rectifiers: regeneration is curtailed when no train takes it
    return simulate(net, loads, dt_s=1.0), simulate(net, with_storage, dt_s=1.0)


def test_storage_books_close_per_train(runs):
    """E_end - E_start = eta_c sum(P_c dt) - sum(P_d dt) / eta_d for every train, to 1e-9."""
    _, res = runs
    dt = res.dt_s
    for k in range(len(res.train_ids)):
        e = res.onboard_energy_j[:, k]
        on = np.isfinite(e)
        assert on.any()
        charged = np.nansum(res.onboard_charge_w[:, k]) * dt
        given = np.nansum(res.onboard_discharge_w[:, k]) * dt
        e_end = e[on][-1]
        e_start = STORAGE.initial_soc * STORAGE.capacity_j
        assert e_end - e_start == pytest.approx(
            STORAGE.charge_efficiency * charged - given / STORAGE.discharge_efficiency, rel=1e-9, abs=1e-6
        )
        soc = e[on] / STORAGE.capacity_j
        assert soc.min() >= STORAGE.min_soc - 1e-12 and soc.max() <= STORAGE.max_soc + 1e-12
        assert np.nanmax(res.onboard_charge_w[:, k]) <= STORAGE.max_power_w + 1e-6
        assert np.nanmax(res.onboard_discharge_w[:, k]) <= STORAGE.max_power_w + 1e-6
        assert charged > 0 and given > 0


def test_storage_takes_only_curtailed_regen_and_assists_only_above_threshold(runs):
    _, res = runs
    curtailed = res.regen_offered_w - res.regen_accepted_w
    assert np.all(np.nan_to_num(res.onboard_charge_w) <= np.nan_to_num(curtailed) + 1e-6)
    demand = np.nan_to_num(res.traction_demand_w)
    assist = np.nan_to_num(res.onboard_discharge_w)
    assert np.all(assist <= np.maximum(demand - STORAGE.assist_above_w, 0.0) + 1e-6)
    # the line is asked only for the rest: the train draws at most demand - assist (+ aux)
    drawn = np.nan_to_num(res.train_power_w)
    assert np.all(drawn <= demand - assist + 50e3 + 1e-3)


def test_energy_balance_and_the_substations_save(runs):
    plain, res = runs
    s0, s1 = plain.summary(), res.summary()
    assert s1["status"] == "ok", s1["warnings"]
    assert s1["energy_balance_error"] < 1e-6
    r = s1["regen_kwh"]
    assert r["used_by_trains"] + r["returned"] + r["dissipated"] + r["stored_onboard"] == pytest.approx(
        r["offered"], rel=1e-12
    )
    assert r["dissipated"] < s0["regen_kwh"]["dissipated"]
    assert r["dissipated"] >= -1e-9
    assert s1["substations_energy_kwh"] < s0["substations_energy_kwh"]
    # the traction delivered is the same work (the storage gives what the line no longer does)
    for t0, t1 in zip(s0["trains"], s1["trains"], strict=True):
        assert t1["traction_delivered_kwh"] == pytest.approx(t0["traction_delivered_kwh"], rel=1e-3)
        assert "onboard_charged_kwh" in t1 and "onboard_charged_kwh" not in t0


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"capacity_j": 0.0}, "capacity_kwh"),
        ({"charge_efficiency": 1.2}, "charge_efficiency"),
        ({"min_soc": 0.95}, "min_soc"),
        ({"initial_soc": 0.1}, "initial_soc"),
        ({"assist_above_w": -1.0}, "assist_above_kw"),
    ],
)
def test_bad_storage_is_an_input_error(change, field):
    load = metro_loads(n_per_direction=1)[0]
    bad = dataclasses.replace(load, onboard_storage=dataclasses.replace(STORAGE, **change))
    with pytest.raises(InputError) as info:
        simulate(metro_network(False), [bad], dt_s=1.0)
    assert info.value.problems[0].field == f"trains[0].onboard_storage.{field}"
