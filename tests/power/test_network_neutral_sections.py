"""Neutral sections given in the power network only are applied to the trains' runs (issue 18)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from trainsim.io.power_file import load_power_file
from trainsim.model.route import ElectrificationSection
from trainsim.power import Connection, Gap
from trainsim.power.study import route_with_neutral_sections, run_study, with_status

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"
#: Long enough for the first trains of both directions to cross the neutral section (about 25 km out).
END_S = 1500.0


def _study(name: str):
    spec, network, services = load_power_file(EXAMPLES / f"{name}.yaml")
    return services, run_study(network, services, dt_s=spec.simulation.step_s, end_s=END_S)


@pytest.fixture(scope="module")
def both():
    return _study("main_line_25kv"), _study("main_line_25kv_network_neutral")


def test_gap_in_the_network_only_gives_the_figures_of_the_gap_in_the_route(both):
    (_, in_route), (_, in_network) = both
    a, b = in_route.summary(), in_network.summary()
    assert a["status"] == b["status"] == "ok"
    for key in ("substations_energy_kwh", "trains_energy_kwh", "losses_kwh"):
        assert b[key] == pytest.approx(a[key], rel=1e-9, abs=1e-9)
    for sa, sb in zip(a["substations"], b["substations"], strict=True):
        for key in ("energy_kwh", "peak_power_kw", "peak_current_a", "rms_current_a"):
            assert sb[key] == pytest.approx(sa[key], rel=1e-9, abs=1e-9)
    assert len(a["trains"]) == len(b["trains"]) > 2
    for ta, tb in zip(a["trains"], b["trains"], strict=True):
        for key in ("energy_kwh", "traction_demand_kwh", "regen_offered_kwh", "running_time_s"):
            assert tb[key] == pytest.approx(ta[key], rel=1e-9, abs=1e-9)
    np.testing.assert_allclose(in_network.train_voltage_v, in_route.train_voltage_v, rtol=1e-9)
    # the trains coast through the neutral section: no traction asked there
    x = in_network.train_position_m
    inside = (x > 24800.0 + 1.0) & (x < 25200.0 - 1.0)
    assert inside.sum() > 10
    assert np.all(in_network.traction_demand_w[inside] == 0.0)


def test_the_records_and_no_warning_when_the_route_has_no_section_of_its_own(both):
    (_, in_route), (_, in_network) = both
    records = in_network.summary()["neutral_sections"]
    assert {(r["train"], r["gap"]) for r in records} == {("up", "NS-up"), ("down", "NS-down")}
    assert all(r["in_network"] and not r["in_route"] and not r["route_has_own"] for r in records)
    assert all(r["start_km"] == pytest.approx(24.8) and r["end_km"] == pytest.approx(25.2) for r in records)
    assert not any("neutral section" in w for w in in_network.summary()["warnings"])
    agreeing = in_route.summary()["neutral_sections"]
    assert all(r["in_network"] and r["in_route"] for r in agreeing)


def test_disagreement_between_route_and_network_is_a_warning(both):
    (_, _), (services, result) = both
    up = services[0]
    network = result.network
    # the route's own section without traction 1 km before the network's one, and 100 m of it shifted
    own = (
        ElectrificationSection(0.0, 20000.0, 25000.0),
        ElectrificationSection(20000.0, 20300.0, 0.0),
        ElectrificationSection(20300.0, 24900.0, 25000.0),
        ElectrificationSection(24900.0, 25200.0, 0.0),
        ElectrificationSection(25200.0, 50000.0, 25000.0),
    )
    route = dataclasses.replace(up.scenario.route, electrification=own)
    out, records = route_with_neutral_sections(route, up.scenario.train, network, "up", 0.0, 1)
    by_gap = {r["gap"]: r for r in records}
    assert not by_gap["NS-up"]["in_route"] and by_gap["NS-up"]["route_has_own"]
    assert by_gap[None]["start_km"] == pytest.approx(20.0) and by_gap[None]["end_km"] == pytest.approx(20.3)
    # the union: both the route's own sections and the network's are without traction
    dead = [(e.start_m, e.end_m) for e in out.electrification if e.voltage_v == 0]
    assert dead == [(20000.0, 20300.0), (24800.0, 24900.0), (24900.0, 25200.0)]
    extra = {**result.extra, "neutral_sections": [{"train": "up", **r} for r in records]}
    warnings = with_status(dataclasses.replace(result, extra=extra)).extra["warnings"]
    assert any("neutral section NS-up (24.8 .. 25.2 km of track up) is not a section without traction" in w
               for w in warnings)  # fmt: skip
    assert any("its route has no traction at 20 .. 20.3 km of track up" in w for w in warnings)


def test_direction_down_section_insulators_and_a_route_that_already_agrees(both):
    (services, result), _ = both
    down = services[1]
    network = dataclasses.replace(
        result.network,
        connections=(Connection("PP", 12000.0, ("up", "down")),),
        gaps=(*result.network.gaps, Gap("SI", "down", 10000.0, 10000.0)),
        _topology=None,
    )
    route = down.scenario.route
    # the down train runs the route mirrored from chainage 50 km: the neutral section is in its route,
    # and a section insulator (length 0) changes nothing
    out, records = route_with_neutral_sections(route, down.scenario.train, network, "down", 50000.0, -1)
    assert out is route
    assert [r["gap"] for r in records] == ["NS-down"] and records[0]["in_route"]
    # placed 1 km further on, the network's section is at route positions 23.8 .. 24.2 km (mirrored)
    out, records = route_with_neutral_sections(route, down.scenario.train, network, "down", 49000.0, -1)
    dead = [(e.start_m, e.end_m) for e in out.electrification if e.voltage_v == 0]
    assert dead == [(23800.0, 24200.0), (24800.0, 25200.0)]
    assert {r["gap"] for r in records} == {"NS-down", None}


def test_a_whole_day_run_coasts_through_the_network_neutral_sections_too(both):
    """The compact (whole-day) path makes its runs itself: with the gap in the network only it must
    give the figures of the full study, whose runs coast through the section."""
    from trainsim.power.day import run_day_study

    spec, network, services = load_power_file(EXAMPLES / "main_line_25kv_network_neutral.yaml")
    (_, in_route), _ = both
    day = run_day_study(network, services, dt_s=spec.simulation.step_s, end_s=END_S).summary()
    full = in_route.summary()
    assert day["substations_energy_kwh"] == pytest.approx(full["substations_energy_kwh"], rel=1e-9)
    for sa, sb in zip(full["substations"], day["substations"], strict=True):
        assert sb["peak_power_kw"] == pytest.approx(sa["peak_power_kw"], rel=1e-9)
    assert {r["gap"] for r in day["neutral_sections"]} == {"NS-up", "NS-down"}
