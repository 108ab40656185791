"""``trainsim operate``: JSON, exit codes, plots."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.cli import app

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "operations"
runner = CliRunner()
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def test_operate_json_prints_the_summary_and_exits_0() -> None:
    result = runner.invoke(app, ["operate", str(EXAMPLES / "metro_cbtc.yaml"), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["status"] == "ok"
    train = summary["trains"][0]
    assert {"id", "energy_kwh", "delay_s", "stops"} <= set(train)
    assert {"scheduled_arrival_s", "scheduled_departure_s", "arrival_s", "departure_s", "delay_s"} <= set(
        train["stops"][1]
    )
    assert {"leader", "follower", "min_headway_s", "critical_block"} <= set(summary["headways"][0])


def test_operate_exits_3_on_conflicts_and_writes_tables_and_plots(tmp_path: Path) -> None:
    result = runner.invoke(app, ["operate", str(EXAMPLES / "single_track.yaml"), "--out", str(tmp_path)])
    assert result.exit_code == 3, result.output
    assert "conflicts in the planned timetable" in result.stdout
    for name in ("summary.json", "trains.csv", "blocking_times.csv", "traces.csv", "train_graph.png"):
        assert (tmp_path / name).exists()


def test_operate_bad_file_exits_2(tmp_path: Path) -> None:
    bad = tmp_path / "op.yaml"
    bad.write_text("schema: trainsim/operation\nversion: 1\nname: x\nline: {}\ntrains: []\nextra: 1\n")
    result = runner.invoke(app, ["operate", str(bad)])
    assert result.exit_code == 2
    assert "error" in result.stderr and "extra" in result.stderr
    assert runner.invoke(app, ["operate", str(tmp_path / "missing.yaml")]).exit_code == 2
