"""The shipped railML operation example (issue 17): examples/operations/branch_line.railml (railML 2.5:
tracks, switches with their diverging speed, signals, axle counters) read by branch_line_railml.yaml
with ``tracks: true`` and operated by ``trainsim operate FILE --json``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.constants import KMH
from trainsim.io.operation_file import read_operation
from trainsim.io.railml_signalling import read_signalling

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "operations" / "branch_line_railml.yaml"
RAILML = EXAMPLE.with_name("branch_line.railml")
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")  # TrainRuns.jl's documented defaults


@pytest.fixture(scope="module")
def summary() -> dict:
    result = CliRunner().invoke(app, ["operate", str(EXAMPLE), "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_operate_json_is_ok_with_headways(summary) -> None:
    assert summary["status"] == "ok" and not summary["deadlock"] and not summary["conflicts"]
    assert all(t["status"] == "ok" for t in summary["trains"])
    (h,) = summary["headways"]
    assert (h["leader"], h["follower"]) == ("U1", "U2")
    assert 0 < h["min_headway_s"] < h["planned_headway_s"] == 1800.0


def test_the_trains_meet_at_mittelfeld_on_its_two_tracks(summary) -> None:
    trains = {t["id"]: t for t in summary["trains"]}
    u1 = next(s for s in trains["U1"]["stops"] if s["station"] == "Mittelfeld")
    d1 = next(s for s in trains["D1"]["stops"] if s["station"] == "Mittelfeld")
    assert (u1["track"], d1["track"]) == (1, 2)
    # both stand there at once
    assert u1["arrival_s"] < d1["departure_s"] and d1["arrival_s"] < u1["departure_s"]


def test_the_railml_file_gives_the_switches_diverging_speed() -> None:
    read = read_signalling(RAILML, ocps=["Ostbach", "Mittelfeld", "Westheim"])
    assert {w.name: w.diverging_speed_mps for w in read.switches} == {
        "W1": pytest.approx(40 * KMH),
        "W2": pytest.approx(40 * KMH),
    }


def test_the_line_is_built_from_the_railml_tracks() -> None:
    line = read_operation(EXAMPLE).line
    assert [s.name for s in line.stations] == ["Ostbach", "Mittelfeld", "Westheim"]
    assert [s.tracks for s in line.stations] == [1, 2, 1]
    track = line.tracks["both"]
    assert [w.name for w in track.switches] == ["W1", "W2"]
    assert len(track.detection_points_m) == 8
    up = line.paths["up"]
    # the loop between the clearance points, the axle counters beside the switches
    assert up.platform_m["Mittelfeld"] == pytest.approx((5650.0, 6350.0))
    # Ostbach's exit route ends at Mittelfeld's home signal (5400 m): its overlap runs to the axle
    # counter at 5550 m, the first one 50 m or more beyond the signal
    exit_route = next(s for s in up.steps if s.kind == "exit" and s.station == "Ostbach").alternatives[0]
    assert exit_route.end_m == pytest.approx(5400.0)
    assert exit_route.overlap_m == pytest.approx(150.0)
