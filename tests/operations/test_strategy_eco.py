"""Driving strategies in operation (issue 17): ``optimal`` drives each stretch energy-efficiently in its
scheduled running time; ``signal_aware`` adds timing points from the blocking times of the trains
ahead so that a follower coasts instead of braking to a restrictive aspect."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import trainsim
from trainsim import Route, RunSettings, SpeedLimit
from trainsim.cli import app
from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.model.timetable import SectionSchedule, Timetable
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.runs import RunCache, auxiliary_power_w, service_route
from trainsim.operations.simulate import ScheduledStop, TrainService, simulate
from trainsim.optimize.api import optimize

SETTINGS = RunSettings(max_step_m=20)
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "operations" / "metro_eco.yaml"
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")
LENGTH_M = 6000.0
STATIONS_M = {"A": 500.0, "B": 3000.0, "C": LENGTH_M - 500.0}
#: the follower leaves A this long after the leader, which is scheduled 220 s for B-C: the follower
#: (150 s) catches up with it there
HEADWAY_S = 150.0


def _line():
    train = trainsim.load_train("examples/metro_b/train.yaml")
    geometry = Route("geo", 0, LENGTH_M, (), (SpeedLimit(0, LENGTH_M, 80 / 3.6),))
    stations = tuple(StationLayout(n, p) for n, p in STATIONS_M.items())
    line = build_line("metro", LENGTH_M, "double_track", stations, Signalling(), block_length_m=600)
    return train, geometry, line


def _service(
    train, name: str, dep: float, dwell_b: float, strategy: str, bc_s: float = 150.0
) -> TrainService:
    # fastest A-B 136.6 s, B-C 136.6 s: 150 s scheduled for A-B, bc_s for B-C
    stops = (
        ScheduledStop("B", dwell_b, arrival_s=dep + 150.0),
        ScheduledStop("C", 0.0, arrival_s=dep + 150.0 + dwell_b + bc_s),
    )
    return TrainService(name, train, "up", "A", "C", dep, stops, strategy=strategy)


@pytest.fixture(scope="module")
def runs():
    train, geometry, line = _line()
    out = {}
    cache = RunCache(SETTINGS)  # the leader's runs and the follower's plan are shared
    for strategy in ("fastest", "optimal", "signal_aware"):
        lead = _service(train, "lead", 0.0, 30.0, "optimal", bc_s=220.0)
        follow = _service(train, "follow", HEADWAY_S, 20.0, strategy)
        out[strategy] = simulate(line, geometry, [lead, follow], SETTINGS, headways=False, cache=cache)
        out[f"alone {strategy}"] = simulate(line, geometry, [follow], SETTINGS, headways=False, cache=cache)
    return train, geometry, line, out


def _follower(result):
    return next(t for t in result.trains if t.id == "follow")


def _reference_energy_kwh(train, geometry, outcome) -> float:
    """The operated energy of an energy-efficient train whose every stretch was driven optimal,
    from trainsim.optimize directly: each stretch's optimal run in the running time it was asked for,
    with its timing points, plus the auxiliaries while standing at the stops."""
    total = 0.0
    for d in outcome.stretches:
        assert d.driven in ("optimal", "signal_aware")
        route = service_route(geometry, [(d.start, STATIONS_M[d.start]), (d.end, STATIONS_M[d.end])])
        timetable = Timetable(
            sections=(SectionSchedule(running_time_s=d.asked_s),), timing_points=d.timing_points
        )
        total += optimize(train, route, timetable, "optimal", SETTINGS).run.energy_kwh.net
    stops = {s.station: s for s in outcome.stops}
    standing = sum(stops[d.end].departure_s - stops[d.end].arrival_s for d in outcome.stretches[:-1])
    return total + auxiliary_power_w(train) * standing / KWH


def test_an_optimal_train_on_an_empty_line_saves_energy_and_arrives_on_time(runs) -> None:
    train, geometry, _, out = runs
    fastest, optimal = _follower(out["alone fastest"]), _follower(out["alone optimal"])
    assert out["alone optimal"].status == "ok" and optimal.strategy == "optimal"
    assert [d.driven for d in optimal.stretches] == ["optimal", "optimal"]
    assert optimal.energy_kwh < 0.8 * fastest.energy_kwh
    for s in optimal.stops[1:]:
        assert s.arrival_s == pytest.approx(s.scheduled_arrival_s, abs=1.0)
    assert abs(optimal.delay_s) <= 1.0
    # on time the operated run is the plan (B-C asked from the actual departure, within the schedule
    # tolerance of the A-B run's arrival)
    assert optimal.energy_kwh == pytest.approx(optimal.planned_energy_kwh, rel=1e-6)
    assert optimal.energy_kwh == pytest.approx(_reference_energy_kwh(train, geometry, optimal), rel=1e-9)


def test_the_signal_aware_follower_coasts_instead_of_braking_for_a_signal(runs) -> None:
    out = runs[3]
    fastest, blind, aware = (_follower(out[k]) for k in ("fastest", "optimal", "signal_aware"))
    # the fastest follower catches up with the slow leader on B-C and is slowed by restrictive aspects;
    # so is the signal-blind optimal one, which then drives that stretch fastest
    assert any(h.kind in ("signal", "slowed") for h in fastest.hindrances)
    assert any(h.kind in ("signal", "slowed") for h in blind.hindrances)
    assert [(d.driven, d.reason) for d in blind.stretches] == [
        ("optimal", ""),
        ("optimal, fastest from the braking", "signal"),
    ]
    # up to where its driver starts braking it is on its energy-efficient run (as alone, leaving B on
    # time): the signal does not change its past
    alone = _follower(out["alone optimal"])
    assert blind.stops[1].departure_s == pytest.approx(alone.stops[1].departure_s, abs=1e-9)
    for x in np.linspace(STATIONS_M["B"] + 1.0, 3800.0, 40):
        assert blind.trajectory.first_time_s(x) == pytest.approx(alone.trajectory.first_time_s(x), abs=1e-6)
    assert blind.runs[1].energy_balance["relative_error"] == pytest.approx(0.0, abs=1e-6)
    # the aware one never meets a restrictive aspect: no stand and no slowdown at any signal, on
    # either stretch
    assert aware.hindrances == []
    assert [d.driven for d in aware.stretches] == ["signal_aware", "signal_aware"]
    assert all(d.timing_points for d in aware.stretches)
    assert out["signal_aware"].iterations >= 2
    assert aware.energy_kwh < blind.energy_kwh - 5.0
    # B-C: the timing points cannot be met in the scheduled 150 s; it is asked for more and arrives later
    assert aware.stretches[1].asked_s > 150.0 and aware.delay_s > blind.delay_s + 1.0
    # it passes every approach start no earlier than the route ahead is free (the timing point)
    stops = {s.station: s for s in aware.stops}
    tr = aware.trajectory
    for d in aware.stretches:
        for p in d.timing_points:
            t_pass = tr.first_time_s(p.position_m) - stops[d.start].departure_s
            assert t_pass >= p.earliest_s - 0.5
        # between its stops it keeps moving (coasting, not standing)
        inside = (tr.position_m > STATIONS_M[d.start] + 1) & (tr.position_m < STATIONS_M[d.end] - 1)
        assert tr.speed_mps[inside].min() > 1.0


def test_the_signal_aware_energy_is_that_of_the_optimize_api(runs) -> None:
    train, geometry, _, out = runs
    aware = _follower(out["signal_aware"])
    assert aware.energy_kwh == pytest.approx(_reference_energy_kwh(train, geometry, aware), rel=1e-9)
    for run, d in zip(aware.runs, aware.stretches, strict=True):
        assert run.running_time_s == pytest.approx(d.asked_s, abs=0.5)


def test_a_late_optimal_train_drives_fastest_to_recover(runs) -> None:
    train, geometry, line, _out = runs
    late = replace(_service(train, "late", 0.0, 30.0, "optimal"), entry_delay_s=10.0)
    res = simulate(line, geometry, [late], SETTINGS, headways=False)
    o = res.trains[0]
    assert o.stretches[0].driven == "fastest" and o.stretches[0].reason == "late"
    assert o.stretches[0].late_s == pytest.approx(10.0)
    # 10 s late at A, 13.4 s recovered on A-B: on time at B's departure, so B-C is optimal again
    assert o.stretches[1].driven == "optimal"
    assert o.delay_s == pytest.approx(0.0, abs=1.0)


def test_an_energy_efficient_train_needs_its_scheduled_arrivals() -> None:
    train, geometry, line = _line()
    svc = TrainService("x", train, "up", "A", "C", 0.0, (ScheduledStop("B", 30.0),), strategy="optimal")
    with pytest.raises(InputError, match="give the scheduled arrival at B") as e:
        simulate(line, geometry, [svc], SETTINGS)
    assert "trains[0].stops[0].arrival" in str(e.value)
    assert "give the scheduled arrival at C (a stop entry for the destination" in str(e.value)
    with pytest.raises(InputError, match="unknown driving strategy"):
        simulate(line, geometry, [replace(svc, strategy="lazy")], SETTINGS)


def test_the_eco_example_compares_the_strategies_on_the_command_line() -> None:
    result = CliRunner().invoke(
        app,
        ["operate", str(EXAMPLE), "--json", "--compare-strategies", "fastest,optimal,signal_aware"],
    )
    # the planned timetable conflicts at S2 on purpose (F closer than the minimum headway)
    assert result.exit_code == 3, result.output
    summary = json.loads(result.stdout)
    assert summary["status"] == "conflicts"
    assert {t["id"]: t["strategy"] for t in summary["trains"]} == {"L": "optimal", "F": "signal_aware"}
    f = next(t for t in summary["trains"] if t["id"] == "F")
    assert f["hindrances"] == [] and f["stretches"][0]["driven"] == "signal_aware"
    cmp = summary["strategies"]
    assert list(cmp) == ["fastest", "optimal", "signal_aware"]
    energy = {k: v["energy_kwh"]["operated"] for k, v in cmp.items()}
    assert energy["signal_aware"] < energy["optimal"] < energy["fastest"]
    per_train = {k: {t["id"]: t for t in v["trains"]} for k, v in cmp.items()}
    assert per_train["optimal"]["F"]["waits"] >= 1 and per_train["signal_aware"]["F"]["waits"] == 0
    assert per_train["signal_aware"]["F"]["energy_kwh"] < per_train["optimal"]["F"]["energy_kwh"]
    assert cmp["signal_aware"]["iterations"] >= 2 and cmp["fastest"]["iterations"] == 1
    # the file's own run is the signal_aware column (L optimal, F signal_aware)
    assert summary["energy_kwh"]["operated"] == pytest.approx(energy["signal_aware"], abs=1e-4)
    table = CliRunner().invoke(app, ["operate", str(EXAMPLE), "--compare-strategies", "optimal,fastest"])
    assert table.exit_code == 3 and "total delay s" in table.stdout and "optimal kWh" in table.stdout
    bad = CliRunner().invoke(app, ["operate", str(EXAMPLE), "--compare-strategies", "fastest,lazy"])
    assert bad.exit_code == 2 and "--compare-strategies" in bad.output


def test_an_unknown_strategy_in_the_file_names_its_field(tmp_path: Path) -> None:
    text = EXAMPLE.read_text().replace("strategy: signal_aware", "strategy: lazy")
    text = text.replace("../metro_b/", str(EXAMPLE.parents[1] / "metro_b") + "/")
    bad = tmp_path / "op.yaml"
    bad.write_text(text)
    result = CliRunner().invoke(app, ["operate", str(bad), "--json"])
    assert result.exit_code == 2
    assert "trains[1].strategy" in result.output and "signal_aware" in result.output
