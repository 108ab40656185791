"""Blocking times and minimum headways against the analytic constant-speed case."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.operations.blocking import (
    Trajectory,
    blocking_times,
    braking_distance_table,
    compression,
    minimum_headway,
)
from trainsim.operations.line import Signalling, StationLayout, build_line

V = 25.0  # m/s
L = 200.0  # train length, m


def _constant_speed(length_m: float) -> Trajectory:
    s = np.linspace(0.0, length_m, 2001)
    return Trajectory(s / V, s, np.full_like(s, V), L)


def _line(sig: Signalling, block_length_m: float = 2000.0):
    stations = (StationLayout("A", 1000.0), StationLayout("B", 40000.0))
    return build_line("test", 41000.0, "double_track", stations, sig, block_length_m=block_length_m)


def _headway(line, sig, approach=None, plain_line_only=False):
    path = line.paths["up"]
    steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
    traj = _constant_speed(line.length_m)
    bt = blocking_times("a", traj, path, steps, [], sig, approach_distance_m=approach)
    if plain_line_only:
        bt = [b for b in bt if "block" in b.resource]
    return minimum_headway("a", bt, 0.0, "b", bt, 0.0), path


@pytest.mark.parametrize(("aspects", "blocks_in_stair"), [(3, 2), (4, 3)])
@pytest.mark.parametrize("reaction_s", [0.0, 9.0])
def test_fixed_block_minimum_headway_is_analytic(
    aspects: int, blocks_in_stair: int, reaction_s: float
) -> None:
    sig = Signalling(
        aspects=aspects,
        sighting_distance_m=250.0,
        overlap_m=80.0,
        setup_s=7.0,
        reaction_s=reaction_s,
        release_s=4.0,
    )
    line = _line(sig)
    h, path = _headway(line, sig)
    block = np.diff(path.signal_positions())[3]  # uniform plain-line blocks
    assert np.allclose(np.diff(path.signal_positions())[1:-2], block)
    expected = (block * blocks_in_stair + 80.0 + L + 250.0) / V + 7.0 + reaction_s + 4.0
    assert h.min_headway_s == pytest.approx(expected, abs=1e-6)
    assert "block" in h.critical_route


def test_two_aspect_headway_includes_the_distant_signal() -> None:
    sig = Signalling(aspects=2, distant_distance_m=1000.0, sighting_distance_m=150.0, overlap_m=50.0)
    line = _line(sig)
    h, path = _headway(line, sig)
    block = np.diff(path.signal_positions())[3]
    expected = (block + 1000.0 + 50.0 + L + 150.0) / V + sig.setup_s + sig.reaction_s + sig.release_s
    assert h.min_headway_s == pytest.approx(expected, abs=1e-6)


def test_moving_block_headway_is_braking_distance_plus_margin() -> None:
    a = 0.8
    sig = Signalling(
        system="moving_block",
        safety_margin_m=60.0,
        moving_block_step_m=25.0,
        setup_s=0.0,
        reaction_s=2.0,
        release_s=1.0,
    )
    line = _line(sig)
    brake = braking_distance_table(lambda v: np.full_like(v, a), 40.0)
    assert brake(V) == pytest.approx(V * V / (2 * a), rel=1e-9)
    h, _ = _headway(line, sig, brake)
    # the station routes (entry signal to the platform's clearance point) are longer than a virtual
    # section and set the headway of the whole line; the open line is the analytic case
    assert "entry" in h.critical_route
    h, _ = _headway(line, sig, brake, plain_line_only=True)
    expected = (V * V / (2 * a) + 60.0 + 25.0 + L) / V + 2.0 + 1.0
    assert h.min_headway_s == pytest.approx(expected, abs=1e-6)


def test_compression_of_identical_trains_is_their_headway() -> None:
    sig = Signalling()
    line = _line(sig)
    h, path = _headway(line, sig)
    steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
    bt = blocking_times("a", _constant_speed(line.length_m), path, steps, [], sig)
    later = [b for b in bt]
    cap = compression([bt, later], period_s=600.0)
    assert cap.occupation_s == pytest.approx(2 * h.min_headway_s, abs=1e-9)
    assert cap.consumption == pytest.approx(2 * h.min_headway_s / 600.0)


def test_first_time_at_is_exact_for_constant_acceleration() -> None:
    acc = 0.5
    t = np.linspace(0, 40, 9)
    traj = Trajectory(t, 0.5 * acc * t**2, acc * t, 100.0)
    x = np.array([1.0, 33.3, 150.0, 399.0])
    assert np.allclose(traj.first_time_at(x), np.sqrt(2 * x / acc), atol=1e-9)


def test_bad_signalling_and_layout_are_input_errors() -> None:
    with pytest.raises(InputError) as e:
        Signalling(aspects=5, overlap_m=-1)
    assert len(e.value.problems) == 2
    with pytest.raises(InputError, match="too close"):
        build_line(
            "x", 5000, "double_track", (StationLayout("A", 100), StationLayout("B", 500)), Signalling()
        )
    with pytest.raises(InputError, match="off the line"):
        build_line(
            "x", 5000, "double_track", (StationLayout("A", 100), StationLayout("B", 7000)), Signalling()
        )
    with pytest.raises(InputError, match="open line"):
        build_line(
            "x", 9000, "double_track", (StationLayout("A", 500), StationLayout("B", 8000)), Signalling(),
            block_signals_m={"up": [3000.0, 8500.0]},
        )  # fmt: skip


def test_etcs_l2_headway_uses_the_indication_distance() -> None:
    from trainsim.model import Braking, EffortCurve, Train
    from trainsim.operations.etcs import EtcsNationalValues, supervision_curves
    from trainsim.operations.separation import EtcsBraking, etcs_approach_distance

    train = Train("t", 400e3, 1.06, L, 44.0, EffortCurve.constant(200e3), Braking(deceleration_mps2=0.7), ())
    etcs = EtcsBraking(1.0, 0.8, 2.0, 3.0, 1.0)
    sig = Signalling(system="etcs_l2", overlap_m=50.0, setup_s=3.0, reaction_s=4.0, release_s=2.0)
    line = _line(sig)
    approach = etcs_approach_distance(train, etcs, sig.overlap_m)
    direct = supervision_curves(etcs.train_data(train), EtcsNationalValues(), None, 0.0, svl_position_m=50.0)
    assert approach(V) == pytest.approx(-float(direct.indication_point_m(V)), rel=2e-3)
    h, path = _headway(line, sig, approach, plain_line_only=True)
    block = np.diff(path.signal_positions())[3]
    expected = (approach(V) + block + 50.0 + L) / V + 3.0 + 4.0 + 2.0
    assert h.min_headway_s == pytest.approx(expected, abs=1e-6)
    # side by side at the same block length: fixed 3-aspect > ETCS L2 (here) > moving block
    fixed = Signalling(overlap_m=50.0, setup_s=3.0, reaction_s=4.0, release_s=2.0)
    h_fixed, _ = _headway(_line(fixed), fixed, plain_line_only=True)
    moving = Signalling(system="moving_block", overlap_m=0.0, setup_s=3.0, reaction_s=4.0, release_s=2.0)
    brake = braking_distance_table(lambda v: np.full_like(v, 0.7), 44.0)
    h_moving, _ = _headway(_line(moving), moving, brake, plain_line_only=True)
    assert h_fixed.min_headway_s > h.min_headway_s > h_moving.min_headway_s


def test_too_many_sections_is_an_input_error() -> None:
    sig = Signalling(system="moving_block", moving_block_step_m=1.0)
    with pytest.raises(InputError, match="more than") as e:
        build_line("x", 100_000, "double_track", (StationLayout("A", 500), StationLayout("B", 99_000)), sig)
    assert e.value.problems[0].field == "signalling.moving_block_step_m"


def test_sectional_release_frees_the_switch_zone_before_the_block() -> None:
    ends = {}
    for release in ("sectional", "whole_route"):
        sig = Signalling(release=release, overlap_m=80.0, release_s=4.0)
        line = _line(sig)
        path = line.paths["up"]
        steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
        bt = blocking_times("a", _constant_speed(line.length_m), path, steps, [], sig)
        exit_route = [b for b in bt if b.route == "U:A-B block 1"]
        ends[release] = {b.resource: b.end_s for b in exit_route}
    zone, block = "A/U-exit-switch", "U:A-B block 1"
    x_exit = 1020.0  # the exit signal, 20 m beyond the stopping point
    block_end = x_exit + np.diff(_line(Signalling()).paths["up"].signal_positions())[1]
    assert ends["sectional"][zone] == pytest.approx((x_exit + 100.0 + L) / V + 4.0, abs=1e-9)
    assert ends["sectional"][block] == pytest.approx((block_end + 80.0 + L) / V + 4.0, abs=1e-9)
    assert ends["whole_route"][zone] == pytest.approx(ends["whole_route"][block], abs=1e-12)
    assert ends["whole_route"][block] == pytest.approx(ends["sectional"][block], abs=1e-9)
