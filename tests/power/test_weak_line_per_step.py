"""The shipped per_step example (examples/power/metro_750v_weak_per_step.yaml) through the CLI's entry
point: the weak line limits traction, the limitation is reported, and per_step loses less time than a
cap per stretch on the same line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from trainsim.cli import app

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "power" / "metro_750v_weak_per_step.yaml"
BALANCE_TOLERANCE = 1e-6  # docs/POWER.md: a balance worse than this is a warning


def _power(path: Path, out: Path) -> tuple[dict, str]:
    """The summary.json and the printed report of ``trainsim power <path> --out <out>``."""
    result = CliRunner().invoke(app, ["power", str(path), "--out", str(out), "--no-plots"])
    # the trains lose time to the voltage: ran, but not as asked (docs/POWER.md, "Status")
    assert result.exit_code == 3, result.output
    return json.loads((out / "summary.json").read_text()), result.output


@pytest.fixture(scope="module")
def per_step(tmp_path_factory) -> tuple[dict, str]:
    return _power(EXAMPLE, tmp_path_factory.mktemp("per_step"))


def _with_method(tmp_path: Path, method: str) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text())
    assert data["simulation"]["feedback"]["method"] == "per_step"
    data["simulation"]["feedback"]["method"] = method
    for train in data["trains"]:  # scenarios are relative to the power file
        train["scenario"] = str(EXAMPLE.parent / train["scenario"])
    path = tmp_path / f"weak_{method}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _time_lost_s(summary: dict) -> tuple[float, float]:
    lost = [t["time_lost_s"] for t in summary["trains"]]
    return sum(lost), max(lost)


def test_per_step_limits_traction_and_says_so(per_step):
    summary, printed = per_step
    assert "time_lost" in summary["statuses"] and summary["status"] == summary["statuses"][0]
    feedback = summary["feedback"]
    assert feedback["enabled"] and feedback["consistent"]
    assert feedback["iterations"] > 1, "the line must limit traction, else the example shows nothing"
    assert feedback["mismatch"] <= yaml.safe_load(EXAMPLE.read_text())["simulation"]["feedback"]["tolerance"]
    assert any("traction limited by the line voltage" in w for w in summary["warnings"]), summary["warnings"]
    assert "traction limited by the line voltage" in printed
    trains = summary["trains"]
    # every train is held down somewhere (the line is fed from one end), and it costs running time
    assert all(t["traction_share_min"] < 1.0 for t in trains)
    assert all(t["traction_limited_length_m"] > 0.0 for t in trains)
    assert all(t["time_lost_s"] > 0.0 for t in trains)
    for t in trains:
        assert t["running_time_s"] == pytest.approx(t["nominal_running_time_s"] + t["time_lost_s"], abs=1e-6)
        # the run used what the line delivered, within the feedback's tolerance
        assert t["traction_used_kwh"] == pytest.approx(t["traction_delivered_kwh"], rel=1e-3)
        assert t["traction_delivered_kwh"] < t["traction_demand_kwh"]
    assert summary["energy_balance_error"] < BALANCE_TOLERANCE


@pytest.mark.slow
def test_per_step_loses_less_time_than_per_stretch(per_step, tmp_path):
    step_summary, _ = per_step
    per_stretch, _ = _power(_with_method(tmp_path, "per_stretch"), tmp_path / "out")
    assert "time_lost" in per_stretch["statuses"] and per_stretch["feedback"]["consistent"]
    assert per_stretch["energy_balance_error"] < BALANCE_TOLERANCE
    step_total, step_worst = _time_lost_s(step_summary)
    stretch_total, stretch_worst = _time_lost_s(per_stretch)
    # a cap per stretch holds the whole stretch at its worst step; a share per step only where needed
    assert 0.0 < step_total < stretch_total, (step_total, stretch_total)
    assert step_worst < stretch_worst, (step_worst, stretch_worst)
