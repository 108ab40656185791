"""Tracks in operation files (issue 17): switches, clearance points and train detection points from
trainsim YAML and railML, used by the line model, and bad layouts as errors naming file and field."""

from __future__ import annotations

import json
import subprocess
import sys
from itertools import pairwise
from pathlib import Path

import pytest

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "operations" / "single_track_tracks.yaml"
RAILML = ROOT / "tests" / "io" / "railml_signalling"
TRAIN = ROOT / "tests" / "data" / "trainruns" / "trains" / "local.yaml"


def test_the_example_builds_its_loops_from_switches_and_detection_points() -> None:
    op = read_operation(EXAMPLE)
    up = op.line.paths["up"]
    # Q: the loop between the given clearance points; R: between the axle counters next to its switches
    assert up.platform_m["Q"] == pytest.approx((9600.0, 10400.0))
    assert up.platform_m["R"] == pytest.approx((19610.0, 20390.0))
    down = op.line.paths["down"]
    assert down.platform_m["R"] == pytest.approx((30000.0 - 20390.0, 30000.0 - 19610.0))
    # the up entry into R is released at the axle counter behind R1's clearance point
    entry = next(s for s in up.steps if s.station == "R" and s.kind == "entry").alternatives[0]
    assert entry.resources[0].end_m == pytest.approx(19610.0)
    # Q's exit switch Q2 is released at the axle counter behind its tip (10500)
    exit_q = next(s for s in up.steps if s.station == "Q" and s.kind == "exit").alternatives[0]
    assert exit_q.resources[0].end_m == pytest.approx(10500.0)
    assert [r.name for r in exit_q.resources[1:]] == ["Q-R/2", "Q-R/3"]  # up to R's entry signal (19500)


def test_the_example_runs_from_the_command_line() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "trainsim", "operate", str(EXAMPLE), "--json"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    summary = json.loads(out.stdout)
    # the planned timetable has meets that conflict; the simulation resolves them without a deadlock
    assert summary["status"] == "conflicts" and out.returncode == 3
    assert [t["id"] for t in summary["trains"]] == ["U1", "D1", "G1", "D2"]
    assert any(c["resource"].startswith("Q-R/") for c in summary["conflicts"])


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    text = EXAMPLE.read_text()
    assert old in text
    text = text.replace(old, new).replace(
        "single_track_route.yaml", str(EXAMPLE.parent / "single_track_route.yaml")
    )
    text = text.replace("../../tests/", str(ROOT / "tests") + "/")
    path = tmp_path / "op.yaml"
    path.write_text(text)
    return path


def _error(path: Path, file: Path | None = None) -> InputError:
    with pytest.raises(InputError) as err:
        read_operation(path)
    assert all(p.file == str(file or path) for p in err.value.problems)
    return err.value


def test_a_switch_off_the_line(tmp_path) -> None:
    e = _error(_edited(tmp_path, "{name: S1, position_m: 29050", "{name: S1, position_m: 31050"))
    p = e.problems[0]
    assert (
        p.field == "line.tracks.both.switches[5].position_m"
        and p.value == 31050
        and "0 .. 30000" in p.allowed
    )


def test_a_passing_loop_shorter_than_the_train(tmp_path) -> None:
    # Q1's clearance point 9900: 100 m to Q's stopping point, the 205 m freight train G1 does not fit
    e = _error(
        _edited(tmp_path, "position_m: 9550, clearance_m: 9600", "position_m: 9550, clearance_m: 9900")
    )
    p = e.problems[0]
    assert p.field == "trains[2].train" and "'Q'" in p.reason and "at most 100 m" in p.allowed
    assert p.value == pytest.approx(204.72)


def test_a_loop_that_is_not_connected(tmp_path) -> None:
    e = _error(
        _edited(
            tmp_path,
            "        - {name: Q2, position_m: 10450, clearance_m: 10400}   #   clearance points\n",
            "",
        )
    )
    assert "not connected at their exit end" in str(e) and e.problems[0].field == "line.tracks.both.switches"


def test_a_clearance_point_on_the_wrong_side(tmp_path) -> None:
    e = _error(
        _edited(tmp_path, "position_m: 10450, clearance_m: 10400", "position_m: 10450, clearance_m: 10500")
    )
    p = e.problems[0]
    assert (
        p.field == "line.tracks.both.switches[2].clearance_m"
        and p.value == 10500
        and "10000 < x < 10450" in p.allowed
    )


ROUTE = """schema: trainsim/route
version: 1
name: t
length_m: 6000
stations: [{name: A, position_m: 500}, {name: B, position_m: 5500}]
speed_limits: [{from_m: 0, limit_kmh: 80}]
gradients: [{from_m: 0, gradient_permille: 0}]
line_resistance: {curve_formula: none, tunnel_formula: none}
"""


def _double(tmp_path: Path, tracks: str) -> Path:
    (tmp_path / "route.yaml").write_text(ROUTE)
    path = tmp_path / "op.yaml"
    path.write_text(
        f"""schema: trainsim/operation
version: 1
name: d
line:
  route: route.yaml
  layout: double_track
  stations: [{{name: A}}, {{name: B}}]
  tracks:
{tracks}
  signalling: {{system: fixed_block}}
trains:
  - {{id: U, train: {TRAIN}, direction: up, origin: A, destination: B, departure: "06:00"}}
"""
    )
    return path


def test_a_clearance_point_beyond_the_next_signal(tmp_path) -> None:
    # the detection point behind A's exit switch lies beyond the first automatic block signal (2046.7 m)
    e = _error(
        _double(
            tmp_path,
            "    up: {switches: [{name: A2, position_m: 600, clearance_m: 560}], detection_points_m: [2100]}",
        )
    )
    assert "beyond the next signal" in str(e) and e.problems[0].value == pytest.approx(2100.0)


def test_a_down_track_of_its_own(tmp_path) -> None:
    op = read_operation(
        _double(
            tmp_path,
            "    down: {station_signals_m: {B: [5800, 5450]}, detection_points_m: [3000], block_signals_m: [2000]}",
        )
    )
    down = op.line.paths["down"]
    assert op.line.line_position("down", down.steps[0].start_m) == pytest.approx(5800.0)
    assert any(abs(op.line.line_position("down", s.start_m) - 2000.0) < 1e-9 for s in down.steps)
    names = {r.name for s in down.steps for a in s.alternatives for r in a.resources}
    assert "D:B-A block 1/1" in names and "D:B-A block 1/2" in names


@pytest.mark.parametrize("xml", ["line_railml2.xml", "line_railml3.xml"])
def test_railml_switches_and_detection_points(tmp_path, xml) -> None:
    def write(extra: str) -> Path:
        path = tmp_path / "op.yaml"
        path.write_text(
            f"""schema: trainsim/operation
version: 1
name: r
line:
  railml:
    file: {RAILML / xml}
    ocps: [A, B, C]
    line_resistance: {{curve_formula: none, tunnel_formula: none}}
    tracks: true
{extra}
  layout: single_track
  signalling: {{system: fixed_block, aspects: 3}}
trains:
  - {{id: U1, train: {TRAIN}, direction: up, origin: A, destination: C, departure: "06:00"}}
"""
        )
        return path

    # the file's switches W1 (2600) and W2 (3400) around B (3000) have no detection point towards B
    e = _error(write(""))
    assert "needs its clearance point" in str(e)
    op = read_operation(write("    clearance_distance_m: 50"))
    up = op.line.paths["up"]
    assert up.platform_m["B"] == pytest.approx((2650.0, 3350.0))
    exit_b = next(s for s in up.steps if s.station == "B" and s.kind == "exit").alternatives[0]
    assert exit_b.resources[0].end_m == pytest.approx(4000.0)  # the track-circuit border behind W2


SHEETS = ROOT / "examples" / "operations" / "sheets_double_track"


def _sheets(tmp_path: Path, switches: str) -> Path:
    import shutil

    shutil.copytree(SHEETS / "line", tmp_path / "line")
    (tmp_path / "line" / "switches.csv").write_text(switches)
    text = (SHEETS / "operation.yaml").read_text()
    text = text.replace("spreadsheet: {file: line}", "spreadsheet: {file: line, tracks: true}")
    text = text.replace("../../metro_b/", str(ROOT / "examples" / "metro_b") + "/")
    path = tmp_path / "op.yaml"
    path.write_text(text)
    return path


def test_spreadsheet_switches_per_track(tmp_path) -> None:
    table = "Name,Position (m),Clearance (m),Track\nU1,2700,2750,up\nU2,3300,3250,up\nD1,3300,3250,down\nD2,2700,2750,down\n"
    op = read_operation(_sheets(tmp_path, table))
    assert op.line.paths["up"].platform_m["B"] == pytest.approx((2750.0, 3250.0))
    assert op.line.paths["down"].platform_m["B"] == pytest.approx((6000.0 - 3250.0, 6000.0 - 2750.0))
    assert set(op.line.tracks) == {"up", "down"}
    # the down track's own station signals, from the table's down signals (B home down 3350, exit 2970)
    assert op.line.tracks["down"].station_signals_m["B"] == pytest.approx((3350.0, 2970.0))


def test_a_bad_spreadsheet_switch_names_its_cell(tmp_path) -> None:
    e = _error(
        _sheets(tmp_path, "Name,Position (m),Track\nU1,2700,sideways\n"), tmp_path / "line" / "switches.csv"
    )
    assert "switches" in str(e) and "sideways" in str(e) and "up, down" in str(e)


def test_railml_double_track_gives_the_down_track_its_own_switches_and_signals(tmp_path) -> None:
    path = tmp_path / "op.yaml"
    path.write_text(
        f"""schema: trainsim/operation
version: 1
name: r
line:
  railml:
    file: {RAILML / "double_track_railml2.xml"}
    ocps: [A, B, C]
    line_resistance: {{curve_formula: none, tunnel_formula: none}}
    double_track: true
    tracks: true
    clearance_distance_m: 50
  layout: double_track
  signalling: {{system: fixed_block, aspects: 3}}
trains:
  - {{id: D1, train: {TRAIN}, direction: down, origin: C, destination: A, departure: "06:00"}}
"""
    )
    op = read_operation(path)
    down = op.line.tracks["down"]
    # the down path's switches and axle counters, at their route positions (railml_signalling mapping)
    assert [w.name for w in down.switches] == ["W D2", "W D1"]
    assert down.detection_points_m == pytest.approx((400.0, 4250.0))
    # B's down home signal at 3500 and down exit signal at 2975 (3030 / 2970 would be the up track's)
    assert down.station_signals_m["B"] == pytest.approx((3500.0, 2975.0))
    assert op.line.tracks["up"].switches == ()
    lo, hi = op.line.paths["down"].platform_m["B"]
    assert (lo, hi) == pytest.approx((6000.0 - 3350.0, 6000.0 - (2615.384615385 + 50.0)))


def test_check_shows_the_tracks_and_loops() -> None:
    from trainsim.io.operation_file import check_operation

    figures = check_operation(EXAMPLE).figures
    assert figures["tracks"] == "both: 6 switches, 11 detection points"
    assert figures["loops (up, clearance to clearance)"] == "Q 800 m, R 780 m"


def test_operated_example_releases_at_the_clearance_points_and_never_shares_a_section() -> None:
    from trainsim.io.operation_run import run_operation

    result = run_operation(read_operation(EXAMPLE))
    assert not result.deadlock
    by = {(b.train, b.resource): b for b in result.blocking}
    # U1 enters R over R1: released at the axle counter 19610 behind the switch; D1 leaves R over R1:
    # at the axle counter 19500 beyond its blade tip (19550)
    assert by[("U1", "R/switchW")].to_m == pytest.approx(19610.0)
    assert by[("D1", "R/switchW")].to_m == pytest.approx(19500.0)
    # in operation no two trains ever hold one resource at the same time
    held: dict[str, list] = {}
    for b in result.blocking:
        held.setdefault(b.resource, []).append(b)
    for resource, times in held.items():
        times.sort(key=lambda b: b.start_s)
        for a, b in pairwise(times):
            if a.train != b.train:
                assert b.start_s >= a.end_s - 1e-6, (resource, a.train, b.train)
