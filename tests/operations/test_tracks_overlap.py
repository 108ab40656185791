"""Overlaps that end at train detection points (issue 17): with detection points given, a signal's
overlap runs to the first detection point at least ``overlap_m`` beyond the signal, within the first
track section of the next route, and is released when the rear of the train has cleared it. Checked
against blocking times worked out by hand for a train at constant speed (Pachl, *Railway Operation
and Control*, 4th ed. 2018, 4.2: clearing ends when the rear has passed the release point)."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.operations.blocking import Trajectory, blocking_times
from trainsim.operations.line import (
    Signalling,
    StationLayout,
    SwitchLayout,
    TrackLayout,
    build_line,
    overlap_end_m,
)

V = 20.0  # m/s
L = 100.0  # train length, m
SIG = Signalling(aspects=3, overlap_m=50.0, setup_s=6.0, reaction_s=6.0, release_s=3.0)
STATIONS = (StationLayout("A", 500.0), StationLayout("B", 5500.0, tracks=2))
# up: A's exit signal 520, block signals 2000 and 3500, B's entry signal 5100, B's exit signal 5520
BLOCKS = {"up": [2000.0, 3500.0]}
# B's entry switch at 5200, its clearance point 5260: released at the detection point 5450 behind it
SWITCHES = (SwitchLayout("B1", 5200.0, 5260.0), SwitchLayout("B2", 5800.0, 5750.0))


def _line(detection: tuple[float, ...], signalling: Signalling = SIG):
    up = TrackLayout(detection, SWITCHES)
    return build_line(
        "t", 6000.0, "double_track", STATIONS, signalling, block_signals_m=BLOCKS, tracks={"up": up}
    )


def _times(line, signalling: Signalling = SIG) -> dict[str, object]:
    """Blocking times of a train at constant speed V, head at 0 at t = 0, by resource."""
    path = line.paths["up"]
    s = np.linspace(0.0, line.length_m, 3001)
    traj = Trajectory(s / V, s, np.full_like(s, V), L)
    steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
    return {b.resource: b for b in blocking_times("x", traj, path, steps, [], signalling)}


def test_the_overlap_end_is_the_first_detection_point_far_enough() -> None:
    dets = [2030.0, 2100.0, 2300.0]
    assert overlap_end_m(2000.0, 50.0, dets) == 2100.0  # 2030 is too close to the signal
    assert overlap_end_m(2000.0, 100.0, dets) == 2100.0  # exactly the overlap length
    assert overlap_end_m(2300.0, 50.0, dets) == 2350.0  # none beyond: the plain overlap
    assert overlap_end_m(2000.0, 0.0, dets) == 2000.0  # no overlap


@pytest.fixture(scope="module")
def times():
    return _times(_line((2100.0, 2300.0, 3600.0, 5450.0)))


def test_a_block_is_held_until_the_rear_clears_the_detection_point_ending_its_overlap(times) -> None:
    # block 1 (520 -> 2000): its overlap runs to the detection point 2100, not to 2050
    b = times["U:A-B block 1"]
    assert b.clear_s == pytest.approx((2100.0 + L) / V, abs=1e-6)
    assert b.end_s == pytest.approx((2100.0 + L) / V + SIG.release_s, abs=1e-6)
    # block 2 (2000 -> 3500) in three sections; its last one is held to the detection point 3600
    assert times["U:A-B block 2/1"].clear_s == pytest.approx((2100.0 + L) / V, abs=1e-6)
    assert times["U:A-B block 2/3"].clear_s == pytest.approx((3600.0 + L) / V, abs=1e-6)


def test_the_overlap_of_the_entry_signal_runs_over_the_switch_to_its_detection_point(times) -> None:
    # block 3 (3500 -> B's entry signal 5100): the first detection point 50 m or more beyond is 5450,
    # the end of B's entry switch section, where the overlap lies
    assert times["U:A-B block 3/2"].clear_s == pytest.approx((5450.0 + L) / V, abs=1e-6)
    # B's exit signal 5520: no detection point beyond, the plain overlap
    assert times["B/U1"].clear_s == pytest.approx(
        (5750.0 + L) / V, abs=1e-6
    )  # the platform to B2's clearance
    line = _line((2100.0, 2300.0, 3600.0, 5450.0))
    entry = line.paths["up"].steps[-1].alternatives[0]
    assert entry.overlap_m == pytest.approx(SIG.overlap_m)


def test_the_overlap_stays_within_the_next_routes_first_section() -> None:
    # a detection point only far beyond block 1's signal: the overlap ends with block 2, which is one
    # track section (from signal 2000 to signal 3500), not at 4000 in block 3
    t = _times(_line((4000.0, 5450.0)))
    assert t["U:A-B block 1"].clear_s == pytest.approx((3500.0 + L) / V, abs=1e-6)


def test_without_detection_points_the_overlap_is_the_plain_length() -> None:
    t = _times(_line(()))
    assert t["U:A-B block 1"].clear_s == pytest.approx((2000.0 + SIG.overlap_m + L) / V, abs=1e-6)
    # and the detection points lengthen the blocking time by the extra overlap over the speed
    t2 = _times(_line((2100.0,)))
    assert t2["U:A-B block 1"].end_s - t["U:A-B block 1"].end_s == pytest.approx(50.0 / V, abs=1e-6)


def test_moving_block_keeps_no_overlap() -> None:
    mb = Signalling(system="moving_block", overlap_m=0.0)
    line = build_line("t", 6000.0, "double_track", STATIONS, mb, tracks={"up": TrackLayout((2100.0,))})
    assert all(r.overlap_m == 0.0 for st in line.paths["up"].steps for r in st.alternatives)


def test_moving_block_ignores_detection_points() -> None:
    # trains are released by their position reports: a line with axle counters gives the same routes
    # as without them (switches at their clearance point / blade tip, single track one section)
    mb = Signalling(system="moving_block", overlap_m=0.0, moving_block_step_m=250.0)
    dets = (2100.0, 3600.0, 5300.0, 5450.0, 5850.0)
    for layout, key in (("double_track", "up"), ("single_track", "both")):

        def build(detection: tuple[float, ...], layout=layout, key=key):
            tracks = {key: TrackLayout(detection, SWITCHES)}
            return build_line("t", 6000.0, layout, STATIONS, mb, tracks=tracks)

        with_dets, without = build(dets), build(())
        for d in ("up", "down"):
            assert with_dets.paths[d].steps == without.paths[d].steps
        # the entry switch is released at its clearance point 5260, not at the axle counter 5300
        entry = next(s for s in with_dets.paths["up"].steps if s.kind == "entry" and s.station == "B")
        assert entry.alternatives[0].resources[0].end_m == pytest.approx(5260.0)
    # fixed block does use them
    fb = build_line("t", 6000.0, "double_track", STATIONS, SIG, tracks={"up": TrackLayout(dets, SWITCHES)})
    entry = next(s for s in fb.paths["up"].steps if s.kind == "entry" and s.station == "B")
    assert entry.alternatives[0].resources[0].end_m == pytest.approx(5300.0)
