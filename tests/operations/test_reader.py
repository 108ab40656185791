"""The operation file: the metro example end to end, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation_file

ROOT = Path(__file__).resolve().parents[2]
METRO = ROOT / "examples" / "metro_b"


def _write(tmp_path: Path, **changes) -> Path:
    doc = {
        "schema": "trainsim/operation",
        "version": 1,
        "name": "t",
        "line": {
            "route": str(METRO / "route.yaml"),
            "layout": "double_track",
            "block_length_m": 500,
            "stations": [
                {"name": n, "entry_signal_distance_m": 200, "switch_zone_m": 60}
                for n in ("S1", "S2", "S3", "S4")
            ],
            "signalling": {"system": "fixed_block", "aspects": 3},
        },
        "trains": [
            {
                "id": "a",
                "train": str(METRO / "train.yaml"),
                "direction": "up",
                "origin": "S1",
                "destination": "S4",
                "departure": "07:00",
                "stops": [{"station": "S2", "dwell_s": 30}],
            }
        ],
    }
    for key, value in changes.items():
        target = doc
        *head, last = key.split("__")
        for h in head:
            target = target[int(h)] if h.isdigit() else target[h]
        target[last] = value
    p = tmp_path / "op.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_metro_example_runs_and_writes_its_outputs(tmp_path: Path) -> None:
    summary, status = run_operation_file(
        ROOT / "examples/operations/metro_fixed_block.yaml", out_dir=tmp_path
    )
    assert status == "ok"
    trains = {t["id"]: t for t in summary["trains"]}
    assert len(trains) == 14
    assert trains["late"]["delay_s"] == pytest.approx(100.0, abs=1e-6)
    assert trains["after"]["delay_s"] > 0 and trains["after"]["hindrances"]
    assert trains["after"]["energy_kwh"] > trains["after"]["planned_energy_kwh"]
    assert all(trains[f"U.{k}"]["delay_s"] == 0 for k in range(1, 7))
    first = trains["U.1"]["stops"]
    assert [s["station"] for s in first] == ["S1", "S2", "S3", "S4"]
    assert first[0]["scheduled_departure_s"] == 7 * 3600
    assert {"fixed_block", "etcs_l2", "moving_block"} == set(summary["separation"])
    for name in (
        "summary.json",
        "trains.csv",
        "blocking_times.csv",
        "traces.csv",
        "train_graph.png",
        "delays.png",
        "headways.png",
    ):
        assert (tmp_path / name).stat().st_size > 0
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "ok"


def test_unknown_fields_and_bad_values_are_named(tmp_path: Path) -> None:
    p = _write(tmp_path, line__signalling__aspect=3, trains__0__departure="7h", line__layout="triple_track")
    with pytest.raises(InputError) as e:
        read_operation(p)
    fields = {q.field for q in e.value.problems}
    assert "line.signalling.aspect" in fields and "line.layout" in fields
    assert all(q.file == str(p) for q in e.value.problems)
    assert all(q.line is not None and q.line > 1 for q in e.value.problems)


def test_signal_off_the_open_line_is_an_error(tmp_path: Path) -> None:
    p = _write(tmp_path, line__block_signals_m={"up": [900.0, 1590.0]})
    with pytest.raises(InputError, match="open line") as e:
        read_operation(p)
    assert e.value.problems[0].field == "line.block_signals_m.up" and e.value.file == str(p)
    # the one value off the open line, and the open-line ranges allowed (not the whole list)
    assert e.value.problems[0].value == 1590.0
    assert e.value.problems[0].allowed.startswith("between ")


def test_disconnected_route_and_bad_time_are_errors(tmp_path: Path) -> None:
    p = _write(tmp_path, trains__0__destination="S1", trains__0__origin="S3")
    with pytest.raises(InputError, match="not connected"):
        run_operation_file(p)
    p = _write(tmp_path, trains__0__departure="25:61")
    with pytest.raises(InputError, match="time of day"):
        read_operation(p)


def test_inconsistent_layout_and_missing_etcs_data_are_errors(tmp_path: Path) -> None:
    p = _write(tmp_path, line__stations=[{"name": "S1"}, {"name": "S2", "position_m": 300.0}])
    with pytest.raises(InputError, match="too close"):
        read_operation(p)
    p = _write(tmp_path, line__signalling={"system": "etcs_l2"})
    with pytest.raises(InputError, match="ETCS braking data"):
        read_operation(p)


def test_impossible_timetable_is_an_explained_result(tmp_path: Path) -> None:
    p = _write(tmp_path, trains__0__stops=[{"station": "S2", "dwell_s": 30, "arrival": "07:00:30"}])
    summary, status = run_operation_file(p)
    assert status == "ok"
    (train,) = summary["trains"]
    assert any("earlier than the train can make it" in w for w in train["warnings"])
    assert summary["warnings"]
    assert train["stops"][1]["delay_s"] is not None


def test_monte_carlo_samples_are_seeded_and_summarised(tmp_path: Path) -> None:
    from trainsim.io.operation_run import monte_carlo

    p = _write(tmp_path, delays={"seed": 3, "probability": 0.5, "mean_s": 90.0})
    doc = yaml.safe_load(p.read_text())
    doc["trains"][0]["repeat"] = {"count": 4, "every_s": 180}
    p.write_text(yaml.safe_dump(doc))
    op = read_operation(p)
    assert [s.entry_delay_s for s in op.given_services] == [0.0] * 4
    assert any(s.entry_delay_s > 0 for s in op.services)  # the file's own sample
    a, b = monte_carlo(op, 6), monte_carlo(op, 6)
    assert a == b and a["samples"] == 6 and sum(a["statuses"].values()) == 6
    first = a["trains"][0]["delay_s"]
    assert 0 <= first["p50"] <= first["p95"] <= first["max"]
    assert a["runs"]["computed"] < a["runs"]["reused"]
    assert monte_carlo(op, 6, seed=4) != a
    with pytest.raises(InputError, match="samples"):
        monte_carlo(op, 0)


def test_check_report_of_an_operation_file() -> None:
    from trainsim.io.operation_file import check_operation

    report = check_operation(ROOT / "examples/operations/metro_fixed_block.yaml")
    assert report.kind == "operation" and report.figures["trains"] == "14"
    assert "fixed_block, 3 aspects" in report.to_text()
