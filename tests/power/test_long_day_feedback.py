"""Voltage-limited traction fed back on a compact (whole-day) run (issue 18): run_study's loop with
traces kept only while each train runs gives the full traces' caps, iterations, time lost and
substation energies, and a compact day through the power file is fed back like a full study."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from trainsim.io.power_file import load_power_file, run_power_file
from trainsim.power.day import run_day_study
from trainsim.power.simulation import CompactPowerResult
from trainsim.power.study import FeedbackSettings, run_study

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "power" / "metro_750v_weak_per_step.yaml"
RTOL = 1e-9  # the compact sums run over the train's own steps, without NaN padding: equal to rounding


def _close(a: Any, b: Any, where: str) -> None:
    """a and b equal, floats to RTOL (relative, or absolute near 0), recursively."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for key in a:
            _close(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for j, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{where}[{j}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert b == pytest.approx(a, rel=RTOL, abs=RTOL), where
    else:
        assert a == b, where


@pytest.fixture(scope="module")
def weak_line():
    _, network, services = load_power_file(EXAMPLE)
    return network, services


@pytest.mark.parametrize(
    "method, knock_on", [("per_step", False), ("per_stretch", False), ("constant", True)]
)
def test_compact_feedback_gives_the_full_traces_figures(weak_line, method, knock_on):
    network, services = weak_line
    fb = FeedbackSettings(max_iterations=30, tolerance=1e-3, method=method, knock_on=knock_on)
    full = run_study(network, services, dt_s=1.0, feedback=fb)
    compact = run_study(network, services, dt_s=1.0, feedback=fb, traces="on_network")
    assert isinstance(compact, CompactPowerResult) and not isinstance(full, CompactPowerResult)
    a, b = full.summary(), compact.summary()
    # the weak line limits traction, so the loop is exercised: caps made, runs made again, time lost
    assert a["feedback"]["iterations"] > 1 and a["feedback"]["consistent"]
    assert max(t["time_lost_s"] for t in a["trains"]) > 5.0
    if knock_on:
        assert max(t["departure_delay_s"] for t in a["trains"]) > 0.0
    assert b["feedback"]["iterations"] == a["feedback"]["iterations"]
    assert (b["status"], b["statuses"]) == (a["status"], a["statuses"])
    # every figure of the summary: feedback block, each train's caps and time lost, substation energies
    _close(a, b, "summary")


def test_compact_day_without_feedback_says_traction_limited(weak_line):
    """Feedback disabled: solved once, the limitation reported as a status, not hidden."""
    network, services = weak_line
    day = run_day_study(network, services, feedback=FeedbackSettings(enabled=False)).summary()
    assert "traction_limited" in day["statuses"] and day["status"] != "ok"
    assert not day["feedback"]["enabled"] and day["feedback"]["iterations"] == 1
    assert all(t["time_lost_s"] == 0.0 for t in day["trains"])
    assert any("enable simulation.feedback" in w for w in day["warnings"])


def test_power_file_feeds_a_compact_day_back_like_a_full_study(tmp_path):
    """simulation.traces: on_network (the day path) with the example's per_step feedback: the same
    iterations, consistency, time lost and substation energies as traces: full."""
    summaries = {}
    for mode in ("full", "on_network"):
        data = yaml.safe_load(EXAMPLE.read_text())
        data["simulation"]["traces"] = mode
        for train in data["trains"]:  # scenarios are relative to the power file
            train["scenario"] = str(EXAMPLE.parent / train["scenario"])
        path = tmp_path / f"weak_{mode}.yaml"
        path.write_text(yaml.safe_dump(data))
        summaries[mode], _ = run_power_file(path)
    a, b = summaries["full"], summaries["on_network"]
    assert b["traces"]["kept"] == "on_network" and b["traces"]["train_steps"] > 0
    assert b["feedback"]["enabled"] and b["feedback"]["iterations"] > 1 and b["feedback"]["consistent"]
    assert "traction_limited" not in b["statuses"] and "time_lost" in b["statuses"]
    assert b["status"] == a["status"]
    _close(
        {k: v for k, v in a.items() if k != "traces"},
        {k: v for k, v in b.items() if k != "traces"},
        "summary",
    )
