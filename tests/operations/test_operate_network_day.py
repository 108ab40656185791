"""``trainsim operate`` as a network-day: several lines, sampled days, locally or on a local Dask cluster."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from trainsim.batch import network_day as nd
from trainsim.cli import app

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "operations"
CBTC = EXAMPLES / "metro_cbtc.yaml"
SINGLE = EXAMPLES / "single_track.yaml"
runner = CliRunner()
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _disturbed(tmp_path: Path) -> Path:
    text = (EXAMPLES / "metro_fixed_block.yaml").read_text()
    text = text.replace("../metro_b/", f"{EXAMPLES.parent / 'metro_b'}/")
    block = "disturbances: {seed: 2, entry: {kind: exponential, mean_s: 90, probability: 0.5}, "
    block += "running: {kind: uniform, low_s: 0, high_s: 20}}"
    path = tmp_path / "metro_disturbed.yaml"
    path.write_text(text + "\n" + block + "\n")
    return path


def test_two_lines_one_day_json_per_line_and_train(tmp_path: Path) -> None:
    result = runner.invoke(app, ["operate", str(CBTC), str(SINGLE), "--json", "--out", str(tmp_path)])
    # the single-track example's planned timetable has conflicts: status conflicts, exit 3
    assert result.exit_code == 3, result.output
    summary = json.loads(result.stdout)
    assert summary["status"] == "conflicts"
    assert json.loads((tmp_path / "network_day.json").read_text()) == summary
    lines = {x["file"]: x for x in summary["lines"]}
    assert lines[str(CBTC)]["statuses"] == {"ok": 1} and lines[str(CBTC)]["conflicts"] == 0
    assert lines[str(SINGLE)]["conflicts"] > 0
    # unsampled days are checked: each line-day has its own count, the per-line figure their sum
    for day in summary["line_days"]:
        assert day["conflicts"] == lines[day["file"]]["conflicts"]
    # one day: every statistic of a train is its delay of that day
    for day in summary["line_days"]:
        stats = {t["id"]: t["delay_s"] for t in lines[day["file"]]["trains"]}
        for t in day["trains"]:
            d = round(t["delay_s"], 3)
            assert stats[t["id"]] == {"mean": d, "p50": d, "p95": d, "max": d}


def test_sampled_days_statistics_and_the_local_cluster_agree(tmp_path: Path) -> None:
    path = _disturbed(tmp_path)
    local = runner.invoke(app, ["operate", str(path), "--days", "4", "--seed", "5", "--json"])
    assert local.exit_code == 0, local.output
    summary = json.loads(local.stdout)
    assert summary["samples"] == 4 and summary["seed"] == 5 and len(summary["line_days"]) == 4
    (line,) = summary["lines"]
    assert line["days"] == 4 and line["conflicts"] is None  # sampled days do not check the plan
    assert [d["conflicts"] for d in summary["line_days"]] == [None] * 4
    again = runner.invoke(app, ["operate", str(path), "--days", "4", "--seed", "5", "--json"])
    assert again.stdout == local.stdout  # the same seed, the same JSON
    # the statistics against numpy over the line-days
    for train in line["trains"]:
        x = np.array(
            [t["delay_s"] for d in summary["line_days"] for t in d["trains"] if t["id"] == train["id"]]
        )
        assert train["delay_s"]["mean"] == pytest.approx(x.mean(), abs=1e-3)
        assert train["delay_s"]["p95"] == pytest.approx(np.percentile(x, 95), abs=1e-3)
        assert train["delay_s"]["max"] == pytest.approx(x.max(), abs=1e-3)
    assert len({d["total_delay_s"] for d in summary["line_days"]}) > 1
    pytest.importorskip("distributed")
    remote = runner.invoke(
        app, ["operate", str(path), "--days", "4", "--seed", "5", "--local-workers", "2", "--json"]
    )
    assert remote.exit_code == 0, remote.output
    assert json.loads(remote.stdout) == summary


def test_the_table_is_printed_without_json(tmp_path: Path) -> None:
    result = runner.invoke(app, ["operate", str(CBTC), "--days", "0", "--local-workers", "1", "--no-json"])
    assert result.exit_code == 0, result.output
    assert "network-day" in result.stdout and "mean delay s" in result.stdout


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--days", "-1"], ["--days", "-1", "0 .. 10000"]),
        (["--days", "2"], ["disturbances", "delays", "metro_cbtc.yaml"]),  # nothing to sample
        (["--local-workers", "0"], ["--local-workers", "1 .. 256"]),
        (["--local-workers", "2", "--scheduler", "tcp://127.0.0.1:1"], ["not both"]),
        (["--days", "1", "--samples", "3"], ["--samples", "--days"]),
        (["--parquet", "--days", "1"], ["--parquet"]),
        (["--local-workers", "1", "--seed", "-1"], ["--seed", "-1", "0 .. 2**63 - 1"]),
    ],
)
def test_bad_network_day_options_exit_2_with_the_option_named(args: list[str], words: list[str]) -> None:
    result = runner.invoke(app, ["operate", str(CBTC), *args])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    for w in words:
        assert w in result.stderr


def test_a_missing_file_among_several_exits_2(tmp_path: Path) -> None:
    result = runner.invoke(app, ["operate", str(CBTC), str(tmp_path / "nope.yaml")])
    assert result.exit_code == 2 and "nope.yaml" in result.stderr


def test_an_unreachable_scheduler_exits_4(monkeypatch) -> None:
    pytest.importorskip("distributed")
    monkeypatch.setattr(nd, "CONNECT_TIMEOUT_S", 1)
    result = runner.invoke(app, ["operate", str(CBTC), "--scheduler", "tcp://127.0.0.1:9"])
    assert result.exit_code == 4, result.output
    assert "cannot connect to the Dask scheduler at tcp://127.0.0.1:9" in result.stderr
