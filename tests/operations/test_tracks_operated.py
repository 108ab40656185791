"""Diverging-switch speeds in an operated line (issue 17): a train given a platform track over a
switch's diverging branch keeps to its speed from the blade tip until its rear has cleared the
clearance point, whether the track was asked for in the timetable or chosen by the dispatcher.
The example line is examples/operations/branch_line.railml (W1, W2: 40 km/h diverging)."""

from __future__ import annotations

from pathlib import Path

import pytest

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.model import SpeedLimit

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "operations"
EXAMPLE = EXAMPLES / "branch_line_railml.yaml"
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")  # TrainRuns.jl's documented defaults
V_DIV = 40 * KMH
# D1 (down, running coordinate 12000 - position) into Mittelfeld's loop over W2 (6400 m, clearance
# 6350 m) and out of it over W1 (clearance 5650 m, tip 5600 m)
DOWN_SPANS = ((5600.0, 5650.0), (6350.0, 6400.0))


def _max_speed(traj, lo: float, hi: float) -> float:
    """Highest speed of the head from ``lo`` until the rear has passed ``hi`` [m/s]."""
    return traj.max_speed_between(lo, hi + traj.length_m)


def test_the_railml_switch_speeds_reach_the_line() -> None:
    line = read_operation(EXAMPLE).line
    assert {w.name: w.diverging_speed_mps for w in line.tracks["both"].switches} == {
        "W1": pytest.approx(V_DIV),
        "W2": pytest.approx(V_DIV),
    }
    assert line.paths["up"].track_speed_limits("Mittelfeld", 2) == (
        SpeedLimit(5600.0, 5650.0, V_DIV),
        SpeedLimit(6350.0, 6400.0, V_DIV),
    )


def test_a_train_timetabled_on_the_loop_keeps_to_the_diverging_speed() -> None:
    res = run_operation(read_operation(EXAMPLE))
    trains = {t.id: t for t in res.trains}
    d1, u1 = trains["D1"], trains["U1"]
    for lo, hi in DOWN_SPANS:
        assert _max_speed(d1.trajectory, lo, hi) <= V_DIV + 1e-6
    # U1 runs straight through on track 1 at line speed there
    assert _max_speed(u1.trajectory, 5600.0, 5650.0) > 60 * KMH
    # the planned run is the same train on the same track: no delay
    assert d1.delay_s == pytest.approx(0.0, abs=1e-6)


def test_a_train_the_dispatcher_sends_into_the_loop_keeps_to_the_diverging_speed(tmp_path) -> None:
    # D1 asks for no track; U1 (one minute earlier, track 1) is given Mittelfeld first, so D1 gets the loop
    text = EXAMPLE.read_text()
    text = text.replace("{station: Mittelfeld, dwell_s: 60, track: 2}", "{station: Mittelfeld, dwell_s: 60}")
    text = text.replace(
        'departure: "06:00"\n    stops: [{station: Mittelfeld, dwell_s: 60, track: 1}]',
        'departure: "05:59"\n    stops: [{station: Mittelfeld, dwell_s: 60, track: 1}]',
    )
    text = text.replace("file: branch_line.railml", f"file: {EXAMPLES / 'branch_line.railml'}")
    text = text.replace("../../tests/", f"{EXAMPLES.parents[1] / 'tests'}/")
    path = tmp_path / "op.yaml"
    path.write_text(text)
    res = run_operation(read_operation(path))
    d1 = next(t for t in res.trains if t.id == "D1")
    assert next(s for s in d1.stops if s.station == "Mittelfeld").track == 2
    for lo, hi in DOWN_SPANS:
        assert _max_speed(d1.trajectory, lo, hi) <= V_DIV + 1e-6
    # planned without a track (straight through), so the loop's slow switches make it late
    planned = d1.planned_trajectory
    assert _max_speed(planned, *DOWN_SPANS[0]) > V_DIV + 1.0
    assert d1.delay_s > 5.0


def test_a_bad_diverging_speed_in_the_operation_file_names_its_field(tmp_path) -> None:
    text = f"""schema: trainsim/operation
version: 1
name: bad switch
line:
  route: {EXAMPLES / "single_track_route.yaml"}
  layout: single_track
  stations: [{{name: P, tracks: 2}}, {{name: Q, tracks: 2}}, {{name: R, tracks: 2}}, {{name: S, tracks: 2}}]
  tracks:
    both:
      switches: [{{name: Q1, position_m: 9550, clearance_m: 9600, diverging_speed_kmh: -40}}]
  signalling: {{system: fixed_block}}
trains: []
"""
    path = tmp_path / "op.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        read_operation(path)
    p = e.value.problems[0]
    assert p.field == "line.tracks.both.switches[0].diverging_speed_kmh" and p.value == -40
