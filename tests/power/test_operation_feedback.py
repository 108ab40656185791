"""Voltage-limited traction of operated trains fed back into the operation (issue 18).

A power file with ``operation:`` on a weak network (examples/power/metro_750v_operated_weak.yaml: the
operated example's contact line 5 times as resistive): each train the line limits gets a cap on its
traction power per stretch between its stops (the file's ``per_stretch``), the operation is simulated
again with the caps, so that a slowed train holds the trains behind it at signals, until the network
gives every train the traction its run asks.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.io.power_file import _stretch_cap_cache, run_power_file

ROOT = Path(__file__).resolve().parents[2]
OPERATION = ROOT / "examples" / "operations" / "metro_fixed_block.yaml"
WEAK_EXAMPLE = ROOT / "examples" / "power" / "metro_750v_operated_weak.yaml"
#: the example's contact line is 0.018 ohm/km; five times that limits the traction of every train
WEAK_OHM_PER_KM = 0.09


def _arrivals(result) -> dict[str, float]:
    return {o.id: o.stops[-1].arrival_s for o in result.trains}


def _power_file(tmp_path: Path, name: str, *, weak: bool, enabled: bool | None) -> Path:
    doc = yaml.safe_load((ROOT / "examples" / "power" / "metro_750v_operated.yaml").read_text())
    if weak:
        doc = yaml.safe_load(WEAK_EXAMPLE.read_text())
        assert all(t["contact_resistance_ohm_per_km"] == WEAK_OHM_PER_KM for t in doc["network"]["tracks"])
    doc["operation"]["file"] = OPERATION.as_posix()
    if enabled is not None:
        doc["simulation"]["feedback"] = {**doc["simulation"].get("feedback", {}), "enabled": enabled}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture(scope="module")
def op():
    return read_operation(OPERATION)


@pytest.fixture(scope="module")
def uncapped(op):
    return run_operation(op)


def test_a_traction_cap_slows_the_operated_train_and_the_one_behind_it(op, uncapped):
    """'late' capped at 1 MW at the wheel (of some 4 MW) arrives later; its plan is the uncapped
    one (the cap is a disturbance, not the timetable); 'after', uncapped and held behind it at a
    signal, arrives later too (knock-on through the signalling); the trains ahead of 'late' and the
    down trains are unchanged to the bit."""
    services = [
        dataclasses.replace(s, traction_power_cap_w=1.0e6) if s.id == "late" else s for s in op.services
    ]
    capped = run_operation(op, services)
    before, after = _arrivals(uncapped), _arrivals(capped)
    assert after["late"] > before["late"] + 5.0
    assert after["after"] > before["after"] + 1.0
    for tid in before:
        if tid not in ("late", "after"):
            assert after[tid] == before[tid], tid
    plan = {o.id: o.planned_trajectory for o in uncapped.trains}["late"]
    capped_plan = {o.id: o.planned_trajectory for o in capped.trains}["late"]
    np.testing.assert_array_equal(capped_plan.time_s, plan.time_s)
    delays = {o.id: o.delay_s for o in capped.trains}
    assert delays["late"] > {o.id: o.delay_s for o in uncapped.trains}["late"] + 5.0


@pytest.mark.parametrize("cap_w", [0.0, -1.0e6])
def test_a_traction_cap_must_be_positive(op, cap_w):
    services = [
        dataclasses.replace(s, traction_power_cap_w=cap_w) if s.id == "late" else s for s in op.services
    ]
    with pytest.raises(InputError, match="traction power cap"):
        run_operation(op, services)


@pytest.fixture(scope="module")
def weak(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("weak")
    on = run_power_file(_power_file(tmp, "on", weak=True, enabled=True), plots=False)[0]
    off = run_power_file(_power_file(tmp, "off", weak=True, enabled=False), plots=False)[0]
    return on, off


@pytest.mark.slow
def test_without_feedback_the_weak_network_is_traction_limited(weak):
    _, off = weak
    assert "traction_limited" in off["statuses"]
    assert off["feedback"] == {
        "enabled": False,
        "iterations": 1,
        "consistent": True,
        "method": "none",
        "note": "operated trains are solved once: their delays come from the operation",
    }
    assert off["energy_balance_error"] < 1e-6


@pytest.mark.slow
def test_feedback_converges_and_reports_time_lost_instead(weak):
    on, _ = weak
    fb = on["feedback"]
    assert fb["enabled"] and fb["consistent"] and fb["method"] == "per_stretch"
    assert fb["knock_on"] is True and fb["buffer_s"] == 0.0 and fb["unfinished"] == []
    assert 1 < fb["iterations"] <= 10
    assert fb["mismatch"] <= 1e-3
    assert "traction_limited" not in on["statuses"] and "feedback_not_converged" not in on["statuses"]
    assert "time_lost" in on["statuses"]
    assert on["energy_balance_error"] < 1e-6
    # a cap per stretch between stops: some trains are limited on some stretches only
    caps = [t["traction_power_caps_kw"] for t in on["trains"]]
    assert all(c is not None and len(c) == 3 for c in caps)
    assert any(None in c and any(x is not None for x in c) for c in caps)
    for t in on["trains"]:
        finite = [x for x in t["traction_power_caps_kw"] if x is not None]
        assert t["traction_power_cap_kw"] == (min(finite) if finite else None)
    # consistent: every train gets at least 1 - tolerance of the traction energy its (capped) run asks
    for t in on["trains"]:
        assert t["traction_delivered_kwh"] >= (1 - 1e-3) * t["traction_demand_kwh"] - 1e-9, t["id"]


@pytest.mark.slow
def test_capped_trains_are_later_than_without_feedback(weak):
    on, off = weak
    capped = [t for t in on["trains"] if t["traction_power_cap_kw"] is not None]
    assert capped
    for t in capped:
        assert t["time_lost_s"] > 0.5 and t["status"] == "time_lost", t
        assert math.isclose(
            t["arrival_s"] - t["nominal_arrival_s"], t["time_lost_s"], rel_tol=0, abs_tol=1e-9
        )
    # the operation block is the capped operation's: its delays grew
    delay_on = {t["id"]: t["delay_s"] for t in on["operation"]["trains"]}
    delay_off = {t["id"]: t["delay_s"] for t in off["operation"]["trains"]}
    for t in capped:
        assert delay_on[t["id"]] > delay_off[t["id"]] + 0.5


@pytest.mark.slow
def test_the_train_behind_a_slowed_train_is_held_longer(weak, op):
    """Knock-on between services: 'after' runs behind 'late' and is held at a signal. With feedback
    it arrives later than it would under its own caps alone (every other train uncapped): the rest of
    its loss is the slowed 'late' ahead of it, passed on by the signalling, and shows as a longer
    wait (``wait_s`` against ``nominal_wait_s``)."""
    on, _ = weak
    by_id = {t["id"]: t for t in on["trains"]}
    assert by_id["late"]["traction_power_cap_kw"] is not None
    own_caps_w = np.array(
        [np.inf if c is None else c * 1e3 for c in by_id["after"]["traction_power_caps_kw"]]
    )
    cache = _stretch_cap_cache(op.settings)
    at = op.line.paths["up"].stop_m
    services = []
    for s in op.services:
        if s.id == "after":
            train = dataclasses.replace(s.train)
            cache.set_caps(train, np.array([at[n] for n in ("S1", "S2", "S3", "S4")]), own_caps_w)
            s = dataclasses.replace(s, train=train)
        services.append(s)
    arrival_alone = _arrivals(run_operation(op, services, cache))["after"]
    assert by_id["after"]["arrival_s"] > arrival_alone + 1.0
    assert by_id["after"]["wait_s"] > by_id["after"]["nominal_wait_s"] + 1.0
    assert by_id["after"]["time_lost_s"] > 0.5


@pytest.mark.slow
def test_feedback_changes_nothing_where_the_line_limits_no_train(tmp_path):
    """On the example's own network no train is limited: one iteration, no cap, and every figure
    the same to the bit as with feedback disabled (only the feedback block and the per-train
    feedback fields are added)."""
    on = run_power_file(_power_file(tmp_path, "on", weak=False, enabled=True), plots=False)[0]
    off = run_power_file(_power_file(tmp_path, "off", weak=False, enabled=False), plots=False)[0]
    assert on["feedback"]["iterations"] == 1 and on["feedback"]["consistent"]
    assert "traction_limited" not in off["statuses"]
    added = {"arrival_s", "nominal_arrival_s", "time_lost_s", "traction_power_cap_kw", "traction_power_caps_kw",
             "status", "operated_status", "wait_s", "nominal_wait_s"}  # fmt: skip
    for a, b in zip(on["trains"], off["trains"], strict=True):
        assert a["time_lost_s"] == 0.0 and a["traction_power_cap_kw"] is None
        assert {k: v for k, v in a.items() if k not in added} == {
            k: v for k, v in b.items() if k not in added
        }
    for key in set(on) | set(off):
        if key not in ("feedback", "trains"):
            assert on[key] == off[key], key


@pytest.mark.slow
def test_constant_method_gives_one_cap_per_operated_train(tmp_path):
    """``method: constant``: one cap per limited train for its whole run (the feedback before per
    stretch was done), converged, reported as such."""
    doc = yaml.safe_load(WEAK_EXAMPLE.read_text())
    doc["operation"]["file"] = OPERATION.as_posix()
    doc["simulation"]["feedback"]["method"] = "constant"
    path = tmp_path / "constant.yaml"
    path.write_text(yaml.safe_dump(doc))
    summary = run_power_file(path, plots=False)[0]
    fb = summary["feedback"]
    assert fb["method"] == "constant" and fb["consistent"] and 1 < fb["iterations"] <= 10
    capped = [t for t in summary["trains"] if t["traction_power_cap_kw"] is not None]
    assert capped
    for t in summary["trains"]:
        assert t["traction_power_caps_kw"] is None
    for t in capped:
        assert t["time_lost_s"] > 0.5 and t["status"] == "time_lost"
        assert t["traction_delivered_kwh"] >= (1 - 1e-3) * t["traction_demand_kwh"] - 1e-9, t["id"]
