"""Feedback of voltage-limited traction into operated trains (issue 18): the file's method, per
stretch or constant, knock-on through the operation's signalling, settings that cannot apply refused,
and a train the line gives no traction reported, not raised."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.io.power_file import _stretch_cap_cache, run_power_file
from trainsim.power.operated import (
    NO_TRACTION_SHARE,
    OperatedTrain,
    greatest_wheel_power_w,
    lowered_caps,
    stretch_index,
)

ROOT = Path(__file__).resolve().parents[2]
OPERATION = ROOT / "examples" / "operations" / "metro_fixed_block.yaml"
EXAMPLE = ROOT / "examples" / "power" / "metro_750v_operated.yaml"


# ----------------------------------------------------------------------------- the cap update


def _train(**changes) -> OperatedTrain:
    base = OperatedTrain("t", np.array([0.0, 1000.0, 2500.0]), 0.0, 1, 0.9, 4.0e6, ("A", "B", "C"))
    return dataclasses.replace(base, **changes)


def test_stretch_index_and_running_positions():
    train = _train(zero_m=5000.0, sign=-1)
    # a down train: chainage 5000 - x
    np.testing.assert_allclose(train.running_m(np.array([5000.0, 4000.0, 2500.0])), [0.0, 1000.0, 2500.0])
    k = stretch_index(train.stops_m, np.array([0.0, 999.0, 1000.0, 2400.0, 2500.0]), 2)
    np.testing.assert_array_equal(k, [0, 0, 1, 1, 1])
    np.testing.assert_array_equal(stretch_index(train.stops_m, np.array([10.0, 2000.0]), 1), [0, 0])


def test_lowered_caps_per_stretch_are_the_least_delivered_power_at_the_wheel():
    """Steps on stretch 0 delivered 2.0 and 1.5 MW, on stretch 1 3.0 MW: caps 0.9 x 1.5 and
    0.9 x 3.0 MW; a cap only falls (stretch 1 already at 2 MW keeps it); constant: one cap, the
    least of all."""
    train = _train()
    x = np.array([100.0, 900.0, 1200.0])
    p = np.array([2.0e6, 1.5e6, 3.0e6])
    np.testing.assert_allclose(lowered_caps(np.full(2, np.inf), x, p, train), [1.35e6, 2.7e6])
    np.testing.assert_allclose(lowered_caps(np.array([np.inf, 2.0e6]), x, p, train), [1.35e6, 2.0e6])
    np.testing.assert_allclose(lowered_caps(np.full(1, np.inf), x, p, train), [1.35e6])


def test_a_cap_below_the_floor_is_no_traction():
    train = _train()
    floor_w = NO_TRACTION_SHARE * train.greatest_power_w  # 4 kW at the wheel
    delivered = np.array([0.99 * floor_w / 0.9, 1.01 * floor_w / 0.9])
    caps = lowered_caps(np.full(2, np.inf), np.array([10.0, 1100.0]), delivered, train)
    assert caps[0] == 0.0
    assert caps[1] == pytest.approx(1.01 * floor_w)


def test_greatest_wheel_power_of_the_metro_train():
    """Source 002's type B metro: 310 kN up to about 10.4 m/s and then constant power; sampled
    F(v) v peaks between 4.6 and 4.8 MW (an independent look at the curve: F(v) v at its knee)."""
    train = read_operation(OPERATION).services[0].train
    p = greatest_wheel_power_w(train)
    v = np.linspace(0.0, train.max_speed_mps, 20001)
    assert p == pytest.approx(float(np.max(np.asarray(train.traction(v)) * v)), rel=2e-3)


# ----------------------------------------------------------------------------- caps in the operation


@pytest.fixture(scope="module")
def op():
    return read_operation(OPERATION)


@pytest.fixture(scope="module")
def uncapped(op):
    return {o.id: o for o in run_operation(op).trains}


def _with_stretch_caps(op, caps: dict[str, list[float]]):
    """The operation run with caps per scheduled stretch (S1-S2, S2-S3, S3-S4) for some trains."""
    cache = _stretch_cap_cache(op.settings)
    services = []
    for svc in op.services:
        if svc.id in caps:
            at = op.line.paths[svc.direction].stop_m
            train = dataclasses.replace(svc.train)
            cache.set_caps(train, np.array([at["S1"], at["S2"], at["S3"], at["S4"]]), np.array(caps[svc.id]))
            svc = dataclasses.replace(svc, train=train)
        services.append(svc)
    return {o.id: o for o in run_operation(op, services, cache).trains}


@pytest.fixture(scope="module")
def late_capped_on_s2_s3(op):
    return _with_stretch_caps(op, {"late": [np.inf, 1.0e6, np.inf]})


def _wheel_power_w(run) -> float:
    tr = run.trace
    return float(np.max(tr.traction_force_n * tr.speed_mps))


def test_a_stretch_cap_holds_on_its_stretch_only(op, late_capped_on_s2_s3):
    """'late' capped at 1 MW at the wheel on S2-S3 only: its run there never asks more, its runs of
    S1-S2 and S3-S4 are the uncapped ones (more than 4 MW)."""
    late = late_capped_on_s2_s3["late"]
    at = op.line.paths["up"].stop_m
    inside = [at["S2"] - 1e-6 <= r.trace.position_m[0] < at["S3"] for r in late.runs]
    on_s2_s3 = [r for r, i in zip(late.runs, inside, strict=True) if i]
    elsewhere = [r for r, i in zip(late.runs, inside, strict=True) if not i]
    assert on_s2_s3 and elsewhere
    for run in on_s2_s3:
        assert _wheel_power_w(run) <= 1.0e6 * (1 + 1e-9)
    for run in elsewhere:
        assert _wheel_power_w(run) > 4.0e6


def test_a_slowed_leader_makes_its_follower_late_through_the_signals(uncapped, late_capped_on_s2_s3):
    """Knock-on: 'late' slowed on S2-S3 arrives later; 'after', not capped at all, runs behind it and
    is held longer at the signals: it arrives later, its delay grows, and its longer waits explain
    its loss (at least the wait; the rest is braking to the signal and starting again). The trains
    ahead of 'late' and the down trains are unchanged to the bit; the plan stays the uncapped one."""
    before, after = uncapped, late_capped_on_s2_s3
    assert after["late"].stops[-1].arrival_s > before["late"].stops[-1].arrival_s + 5.0
    np.testing.assert_array_equal(
        after["late"].planned_trajectory.time_s, before["late"].planned_trajectory.time_s
    )
    lost = after["after"].stops[-1].arrival_s - before["after"].stops[-1].arrival_s
    waited = sum(h.wait_s for h in after["after"].hindrances) - sum(
        h.wait_s for h in before["after"].hindrances
    )
    assert after["after"].delay_s > before["after"].delay_s + 1.0 and after["after"].delay_s > 0.0
    assert waited > 1.0
    assert lost >= waited - 1e-6
    assert any(h.kind == "signal" for h in after["after"].hindrances)
    for tid in before:
        if tid not in ("late", "after"):
            assert after[tid].stops[-1].arrival_s == before[tid].stops[-1].arrival_s, tid


def test_equal_caps_on_every_stretch_are_the_constant_cap(op):
    """An independent computation: the same 1 MW on the three stretches gives the operation of the
    train's own constant cap (``TrainService.traction_power_cap_w``), arrivals to round-off."""
    per_stretch = _with_stretch_caps(op, {"late": [1.0e6] * 3})
    services = [
        dataclasses.replace(s, traction_power_cap_w=1.0e6) if s.id == "late" else s for s in op.services
    ]
    constant = {o.id: o for o in run_operation(op, services).trains}
    for tid in ("late", "after"):
        assert per_stretch[tid].stops[-1].arrival_s == pytest.approx(
            constant[tid].stops[-1].arrival_s, abs=1e-9
        )


# ----------------------------------------------------------------------------- settings that cannot apply


def _power_file(tmp_path: Path, feedback: dict, name: str = "power") -> Path:
    doc = yaml.safe_load(EXAMPLE.read_text())
    doc["operation"]["file"] = OPERATION.as_posix()
    doc["simulation"]["feedback"] = feedback
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize(
    ("feedback", "field", "value", "allowed"),
    [
        ({"method": "per_step"}, "simulation.feedback.method", "per_step", "per_stretch, constant"),
        ({"knock_on": False}, "simulation.feedback.knock_on", False, "true"),
        ({"buffer_s": 30}, "simulation.feedback.buffer_s", 30, "0"),
    ],
)
def test_feedback_settings_that_cannot_apply_to_operated_trains_are_refused(
    tmp_path, feedback, field, value, allowed
):
    path = _power_file(tmp_path, feedback)
    with pytest.raises(InputError) as info:
        run_power_file(path, plots=False)
    problem = info.value.problems[0]
    assert problem.field == field and problem.value == value and allowed in problem.allowed
    assert problem.file == str(path)


# ----------------------------------------------------------------------------- a train the line cannot move


def _stall_case(tmp_path: Path, method: str) -> Path:
    """Two trains up a 40 permille climb between S2 and S3 on a contact line of 2 ohm/km fed from S1
    only: the line voltage gives the leader (next to) no traction beyond S2."""
    ex = ROOT / "examples"
    route = yaml.safe_load((ex / "metro_b" / "route.yaml").read_text())
    route["gradients"] = [{"from_m": 0, "gradient_permille": 0}, {"from_m": 1800, "gradient_permille": 40},
                          {"from_m": 2900, "gradient_permille": 0}]  # fmt: skip
    (tmp_path / "route.yaml").write_text(yaml.safe_dump(route))
    op = yaml.safe_load(OPERATION.read_text())
    op["line"]["route"] = "route.yaml"
    op.pop("compare_systems", None)
    op.pop("pattern_period_s", None)
    stops = [{"station": "S2", "dwell_s": 30}, {"station": "S3", "dwell_s": 30}]
    train = (ex / "metro_b" / "train.yaml").as_posix()
    op["trains"] = [
        {"id": tid, "train": train, "direction": "up", "origin": "S1", "destination": "S4", "departure": dep,
         "stops": stops}
        for tid, dep in (("lead", "07:00:00"), ("follow", "07:02:30"))
    ]  # fmt: skip
    (tmp_path / "operation.yaml").write_text(yaml.safe_dump(op, sort_keys=False))
    power = yaml.safe_load(EXAMPLE.read_text())
    power["network"]["tracks"] = [{"id": "up", "start_km": 0, "end_km": 4.59097, "contact_resistance_ohm_per_km": 2.0,
                                   "rail_resistance_ohm_per_km": 0.012, "rail_to_earth_conductance_s_per_km": 0.1}]  # fmt: skip
    power["network"]["substations"] = [{"id": "SS", "position_km": 0.0, "tracks": ["up"], "no_load_voltage_v": 850,
                                        "internal_resistance_ohm": 0.012, "rated_power_kw": 3000,
                                        "overload_power_kw": 4500, "reversible": False}]  # fmt: skip
    power["network"]["connections"] = []
    power["operation"] = {"file": "operation.yaml", "tracks": {"up": "up"}, "origin_km": 0}
    power["simulation"]["feedback"] = {"method": method}
    path = tmp_path / f"power_{method}.yaml"
    path.write_text(yaml.safe_dump(power, sort_keys=False))
    return path


@pytest.mark.parametrize("method", ["per_stretch", "constant"])
def test_a_train_the_line_gives_no_traction_is_reported_by_name(tmp_path, method):
    """Not a traceback nor a hang: the leader's cap falls to no traction, it stalls, the follower is
    stuck behind it; the status is not ok and says which trains did not arrive and why."""
    summary, status = run_power_file(_stall_case(tmp_path, method), plots=False)
    assert status != "ok" and "time_lost" in summary["statuses"]
    fb = summary["feedback"]
    assert fb["method"] == method and fb["iterations"] <= 10
    lead = next(t for t in summary["trains"] if t["id"] == "lead")
    assert lead["time_lost_s"] is None and lead["status"] == "time_lost"
    assert lead["operated_status"] == "stalled"
    caps = lead["traction_power_caps_kw"] if method == "per_stretch" else [lead["traction_power_cap_kw"]]
    assert 0.0 in caps
    unfinished = {u["id"]: u for u in fb["unfinished"]}
    assert set(unfinished) == {"lead", "follow"}
    assert unfinished["lead"]["explanation"].startswith("lead is stalled: no traction on ")
    assert "behind lead" in unfinished["follow"]["explanation"]
    assert any("lead" in w and "follow" in w and "did not reach" in w for w in summary["warnings"])
    assert summary["operation"]["status"] != "ok"


# ----------------------------------------------------------------------------- neutral sections


@pytest.fixture(scope="module")
def with_neutral_section(tmp_path_factory):
    """The operated example with a 100 m neutral section on each track at 2.0 .. 2.1 km; a stronger
    contact line (0.005 ohm/km) and full traction down to 520 V, so that the line, cut by the
    sections, limits the trains little."""
    doc = yaml.safe_load(EXAMPLE.read_text())
    doc["operation"]["file"] = OPERATION.as_posix()
    doc["network"]["limits"] = {"traction_full_v": 520}
    for track in doc["network"]["tracks"]:
        track["contact_resistance_ohm_per_km"] = 0.005
    doc["network"]["gaps"] = [
        {"id": f"NS-{t}", "track": t, "start_km": 2.0, "end_km": 2.1} for t in ("up", "down")
    ]
    path = tmp_path_factory.mktemp("neutral") / "power.yaml"
    path.write_text(yaml.safe_dump(doc))
    from trainsim.io.power_file import _run_operated, load_power_file

    spec, network, _ = load_power_file(path)
    return _run_operated(path, spec, network)


def test_operated_trains_coast_through_the_network_neutral_sections(with_neutral_section):
    """The operation's runs are made on the line with the network's neutral sections: no traction is
    asked inside them (up and down trains alike; only a step within one step's run of the section's
    end, 25 m at 80 km/h, sees the traction the run takes up there), the line gives nothing there and
    the feedback does not take that for a voltage limitation (every train arrives, consistent);
    every train has its record, and the balance holds."""
    result = with_neutral_section
    x = result.train_position_m
    up = np.array([tid.startswith(("U", "late", "after")) for tid in result.train_ids])
    inside = (x > 2000.0 + 1.0) & (x < 2100.0 - 1.0)
    assert inside[:, up].any() and inside[:, ~up].any()
    assert np.all(result.traction_delivered_w[inside] == 0.0)
    assert np.all(np.isnan(result.train_voltage_v[inside]))
    # the end of the section in running direction: 2100 m up, 2000 m down
    clear = inside & np.where(up[None, :], x < 2100.0 - 25.0, x > 2000.0 + 25.0)
    assert np.all(result.traction_demand_w[clear] == 0.0)
    fb = result.extra["feedback"]
    # without leaving the steps off the wire out, the step at the end of a section (the line gives 0)
    # would cap its stretch at no traction and stall the train
    assert fb["consistent"] and fb["iterations"] <= 3 and fb["unfinished"] == []
    assert all(t["operated_status"] == "ok" for t in result.extra["trains"])
    records = result.extra["neutral_sections"]
    assert {r["train"] for r in records} == set(result.train_ids)
    assert all(r["in_network"] for r in records)
    assert {r["gap"] for r in records if r["train"] == "U.1"} == {"NS-up"}
    assert {r["gap"] for r in records if r["train"] == "D.1"} == {"NS-down"}
    summary = result.summary()
    assert summary["energy_balance_error"] < 1e-6
    assert summary["neutral_sections"] == records
