"""``trainsim optimize`` options for allowances and driving constraints (issue 16), through typer's
CliRunner: each option changes the run as the library call with the same arguments does."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import trainsim
from trainsim.cli import app
from trainsim.errors import InputError
from trainsim.optimize.allowances import Allowance, allowance_timetable, parse_allowance

ROOT = Path(__file__).resolve().parents[2]
METRO = ROOT / "examples" / "metro_b" / "scenario.yaml"


def _json(*args: str) -> dict:
    r = CliRunner().invoke(app, ["optimize", str(METRO), "--json", *args])
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


def test_parse_allowance_forms() -> None:
    assert parse_allowance("5%") == Allowance("percent", 5.0, label="--allowance 5%")
    a = parse_allowance("1.5min/100km:distance")
    assert (a.kind, a.value, a.distribution) == ("min_per_100km", 1.5, "distance")
    a = parse_allowance("30s@1200-3400")
    assert (a.kind, a.value, a.start_m, a.end_m) == ("seconds", 30.0, 1200.0, 3400.0)
    for bad in ("5", "x%", "30s@12", "5%:fast", "nan%", "-3s", "30s@3400-1200"):
        with pytest.raises(InputError):
            parse_allowance(bad)


def test_cli_allowances_give_the_library_timetable() -> None:
    scenario = trainsim.load_scenario(METRO)
    stops = [s.position_m for s in scenario.route.stops]
    margin = f"20s@{stops[1] + 100:.0f}-{stops[1] + 600:.0f}"
    data = _json("--allowance", "5%:optimal", "--allowance", margin)
    expected, _ = allowance_timetable(
        scenario.train,
        scenario.route,
        [Allowance("percent", 5.0, distribution="optimal"), parse_allowance(margin)],
        scenario.settings,
    )
    assert data["status"] == "ok"
    assert data["scheduled_running_time_s"] == pytest.approx([s.running_time_s for s in expected.sections])
    fastest = data["fastest"]["running_time_s"]
    # 5 % of the fastest run plus the 20 s margin
    assert sum(data["scheduled_running_time_s"]) == pytest.approx(1.05 * fastest + 20.0, rel=1e-6)
    assert all(abs(d) <= 0.5 for d in data["schedule_deviation_s"])


def test_cli_constraints_bind() -> None:
    free = _json("--supplement", "10%")
    held = _json("--supplement", "10%", "--speed-margin", "5", "--max-acceleration", "0.5")
    assert held["status"] == "ok"
    assert held["max_speed_kmh"] < free["max_speed_kmh"]
    # the margin lowers every limit by 5 km/h; the metro's line limit is 80 km/h
    assert held["max_speed_kmh"] <= 80.0 - 5.0 + 1e-6
    assert held["fastest"]["running_time_s"] > free["fastest"]["running_time_s"]


def test_cli_option_errors_are_clear() -> None:
    runner = CliRunner()
    for args, text in (
        (["--allowance", "5"], "not an allowance"),
        (["--allowance", "5%", "--supplement", "5%"], "exactly one of"),
        (["--supplement", "5%", "--max-deceleration", "-1"], "--max-deceleration"),
        (["--supplement", "5%", "--speed-margin", "inf"], "--speed-margin"),
    ):
        r = runner.invoke(app, ["optimize", str(METRO), *args])
        assert r.exit_code == 2, (args, r.output)
        assert text in r.output and "Traceback" not in r.output


def test_help_documents_the_options() -> None:
    r = CliRunner().invoke(app, ["optimize", "--help"], terminal_width=200)
    for option in ("--allowance", "--max-acceleration", "--max-deceleration", "--max-jerk", "--speed-margin"):
        assert option in r.output
