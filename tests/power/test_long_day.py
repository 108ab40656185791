"""A whole day on the power network (issue 18): traces kept only while each train runs give the
same figures as the full time x train arrays, memory grows with the running time and not with the
span, the cap says how to proceed, and the power file picks the compact traces for a day."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from trainsim.errors import InputError
from trainsim.power import (
    Network,
    OnboardStorage,
    Storage,
    Substation,
    Track,
    TrainLoad,
    simulate,
    standard_limits,
)
from trainsim.power.simulation import MAX_FULL_TRAIN_STEPS, RMS_WINDOWS_S, CompactPowerResult

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"


def _line(storage: bool = False) -> Network:
    tracks = tuple(Track(t, 0.0, 4000.0, 0.02e-3, 0.015e-3, 0.1e-6) for t in ("up", "down"))
    subs = tuple(
        Substation(f"S{k}", x, ("up", "down"), 850.0, 0.03, rated_power_w=1.5e6, reversible=False)
        for k, x in enumerate((0.0, 2000.0, 4000.0))
    )
    net = Network("day line", "dc", standard_limits("dc_750"), tracks, subs)
    if storage:
        net = dataclasses.replace(
            net, storages=(Storage("W", 1000.0, ("up", "down"), 3.6e6, 5e5, 0.9, 870.0, 820.0),)
        )
    return net


def _trip(name: str, k: int, departure_s: float, onboard: bool = False) -> TrainLoad:
    """A 4 km trip in 200 s: 40 s drawing 2 MW, coasting, 30 s offering 1.5 MW."""
    up = k % 2 == 0
    t = departure_s + np.array([0.0, 40.0, 41.0, 160.0, 161.0, 190.0, 191.0, 200.0])
    s = np.array([0.0, 300.0, 310.0, 3200.0, 3210.0, 3900.0, 3905.0, 4000.0])
    trac = np.array([2e6, 2e6, 0, 0, 0, 0, 0, 0])
    regen = np.array([0, 0, 0, 0, 1.5e6, 1.5e6, 0, 0])
    store = OnboardStorage(7.2e6, 4e5, 0.95, 0.95, 0.2, 0.9, 0.5, 1e6) if onboard else None
    return TrainLoad(name, "up" if up else "down", t, s if up else 4000.0 - s, trac, regen, 30e3,
                     onboard_storage=store)  # fmt: skip


def _timetable(hours: float, headway_s: float, onboard: bool = False) -> list[TrainLoad]:
    n = int(hours * 3600 / headway_s)
    return [_trip(f"t{k}", k, (k // 2) * headway_s + (k % 2) * headway_s / 2, onboard) for k in range(2 * n)]


@pytest.mark.parametrize(("storage", "onboard"), [(False, False), (True, True)])
def test_compact_traces_solve_the_same_steps_bit_for_bit(storage, onboard):
    """An hour and a half (longer than the 1 h RMS window), with and without storage whose state of
    charge carries from step to step."""
    net, loads = _line(storage), _timetable(1.5, 300.0, onboard)
    full = simulate(net, loads, dt_s=10.0)
    compact = simulate(net, loads, dt_s=10.0, traces="on_network")
    assert isinstance(compact, CompactPowerResult)
    dense = compact.full()
    for f in dataclasses.fields(full):
        a = getattr(full, f.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(getattr(dense, f.name), a, err_msg=f.name)
    for w in RMS_WINDOWS_S:
        np.testing.assert_array_equal(compact.rms_current_a(w), full.rms_current_a(w))
    a, b = full.summary(), compact.summary()
    assert a["status"] == b["status"] and a["warnings"] == b["warnings"]
    for x, y in zip(a["trains"], b["trains"], strict=True):
        assert x.keys() == y.keys()
        for key, value in x.items():
            assert y[key] == (
                pytest.approx(value, rel=1e-13, abs=1e-12) if isinstance(value, float) else value
            )
    assert b["substations"] == a["substations"]  # the series are whole: the same sums bit for bit
    assert b["substations_energy_kwh"] == a["substations_energy_kwh"]
    assert b["trains_energy_kwh"] == pytest.approx(a["trains_energy_kwh"], rel=1e-13)
    if onboard:
        assert b["regen_kwh"]["stored_onboard"] == pytest.approx(a["regen_kwh"]["stored_onboard"], rel=1e-13)
        assert b["regen_kwh"]["stored_onboard"] > 0 and a["storages"] == b["storages"]


def test_a_day_is_refused_with_full_traces_and_runs_compact_in_bounded_memory():
    """18 h at a 3-minute headway each way (720 trips): at 1 s steps 64,800 steps x 720 trains is over
    the cap of full traces (refused before anything is solved); compact at 10 s steps keeps each
    trip's 20 steps."""
    net, loads = _line(), _timetable(18.0, 180.0)
    assert len(loads) == 720
    with pytest.raises(InputError) as err:
        simulate(net, loads, dt_s=1.0)
    text = str(err.value)
    assert "simulation.traces" in text and "on_network" in text and f"{MAX_FULL_TRAIN_STEPS:.0e}" in text
    day = simulate(net, loads, dt_s=10.0, traces="on_network")
    steps_on = int(day.train_offset[-1])
    assert steps_on == pytest.approx(720 * 20, abs=720)
    per_train_step = (day.memory_bytes() - len(day.time_s) * (8 * 3 * 3 + 8 * 6 + 1)) / steps_on
    assert per_train_step < 80  # bytes, against 8 bytes x 8 fields x 6,480 steps of a full trace
    s = day.summary()
    assert len(s["trains"]) == 720 and s["solver"]["not_converged_steps"] == 0
    assert s["energy_balance_error"] < 1e-6
    # every 1 h window of the day solved: the largest hourly RMS is the same as in any hour's own run
    assert all(v is not None for v in s["substations"][1]["rms_current_max_a"].values())


def _small_file(tmp_path: Path, **changes) -> Path:
    data = yaml.safe_load((EXAMPLES / "metro_750v_diode.yaml").read_text())
    for t in data["trains"]:
        t["scenario"] = str(EXAMPLES / t["scenario"])
        t["headway"]["count"] = 2
    data["simulation"].update(changes)
    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def small_runs(tmp_path_factory):
    """The metro example (2 departures each way) run with full and with compact traces."""
    from trainsim.io.power_file import run_power_file

    out = {}
    for mode in ("full", "on_network"):
        tmp = tmp_path_factory.mktemp(mode)
        summary, status = run_power_file(_small_file(tmp, traces=mode), tmp / "out", plots=False)
        out[mode] = (summary, status, tmp / "out")
    return out


def test_power_file_compact_traces_give_the_full_figures(small_runs):
    (full, s1, _), (compact, s2, _) = small_runs["full"], small_runs["on_network"]
    assert s1 == s2 == full["status"]
    assert compact["substations"] == full["substations"]
    assert compact["traces"]["kept"] == "on_network" and compact["traces"]["train_steps"] > 0
    assert compact["feedback"]["iterations"] == 1 and compact["feedback"]["consistent"]
    for a, b in zip(full["trains"], compact["trains"], strict=True):
        assert b["min_voltage_v"] == a["min_voltage_v"]
        assert b["energy_kwh"] == pytest.approx(a["energy_kwh"], rel=1e-13)
        assert b["time_lost_s"] == a["time_lost_s"] == 0.0


def test_power_file_compact_outputs_are_the_full_tables(small_runs):
    """A compact run that fits time x train arrays writes the same tables."""
    import pandas as pd

    full, compact = small_runs["full"][2], small_runs["on_network"][2]
    for name in ("substations.csv", "trains.csv", "network.csv"):
        pd.testing.assert_frame_equal(pd.read_csv(compact / name), pd.read_csv(full / name))
    assert json.loads((compact / "summary.json").read_text())["traces"]["kept"] == "on_network"


def test_limited_traction_on_a_compact_day_is_a_status_not_hidden(tmp_path):
    """A weak line (0.25 ohm/km) limits traction: with feedback disabled the compact day does not feed
    it back and says so (with feedback, tests/power/test_long_day_feedback.py)."""
    from trainsim.io.power_file import run_power_file

    path = _small_file(tmp_path, traces="on_network", feedback={"enabled": False})
    data = yaml.safe_load(path.read_text())
    for t in data["network"]["tracks"]:
        t["contact_resistance_ohm_per_km"] = 0.25
    data["network"]["substations"] = data["network"]["substations"][:1]
    data["network"]["connections"] = []
    path.write_text(yaml.safe_dump(data))
    summary, status = run_power_file(path)
    assert status != "ok" and "traction_limited" in summary["statuses"]
    assert not summary["feedback"]["requested"] and not summary["feedback"]["enabled"]
    assert any("enable simulation.feedback" in w for w in summary["warnings"])


def test_auto_traces_fall_back_to_compact_beyond_the_cap(tmp_path, monkeypatch):
    """With the cap lowered below the small file's steps x trains, ``auto`` runs it compact and writes
    the CSV tables without plots; ``full`` is refused naming the file and the field."""
    from trainsim.io.power_file import run_power_file
    from trainsim.power import simulation

    monkeypatch.setattr(simulation, "MAX_FULL_TRAIN_STEPS", 1000)
    summary, _ = run_power_file(_small_file(tmp_path), tmp_path / "out")
    assert summary["traces"]["kept"] == "on_network" and "plots" in summary["traces"]["outputs"]
    written = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert written == ["network.csv", "substations.csv", "summary.json", "trains.csv"]
    with pytest.raises(InputError) as err:
        run_power_file(_small_file(tmp_path, traces="full"))
    problem = err.value.problems[0]
    assert problem.field == "simulation.traces" and problem.file.endswith("small.yaml")


def test_the_day_example_is_a_whole_day_beyond_full_traces():
    """examples/power/metro_750v_diode_day.yaml: 720 departures from 05:00 to 23:00, over the cap
    of full traces at its 1 s step (so `trainsim power` runs it compact)."""
    from trainsim.io.power_file import load_power_file

    spec, _, services = load_power_file(EXAMPLES / "metro_750v_diode_day.yaml")
    deps = [d for s in services for d in s.departures_s]
    assert len(deps) == 720 and min(deps) == 5 * 3600 and max(deps) < 23 * 3600
    assert spec.simulation.traces == "auto"
    assert (max(deps) - min(deps)) / spec.simulation.step_s * len(deps) > MAX_FULL_TRAIN_STEPS
