"""railML double track (issue 17): the down track's signals, detection points and switches mapped to route
positions, station tracks per direction, and the railML tracks (railML 3 functional tracks).

The files ``railml_signalling/double_track_railml{2,3}.xml`` describe the same line by hand. The up track
runs with the route's mileage: A 500 m, B 3000 m, C 5500 m. The down track's own coordinate increases
from C (400) through B (2900) to A (5500): 2500 m between C and B as on the up track, 2600 m between B and
A. An element x metres along the down track maps to route positions
    between C and B:  5500 - (x - 400)                 (1 m down = 1 m back)
    between B and A:  3000 - (x - 2900) * 2500 / 2600
    beyond A:         500 - (x - 5500)
"""

from __future__ import annotations

from pathlib import Path

import pytest

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.io.railml_signalling import read_signalling

DATA = Path(__file__).resolve().parent / "railml_signalling"
FILES = ["double_track_railml2.xml", "double_track_railml3.xml"]
TRAIN = Path(__file__).resolve().parents[1] / "data" / "trainruns" / "trains" / "local.yaml"


def _down_m(x: float) -> float:
    """The mapping of the module docstring, written out independently of the reader."""
    if x <= 2900:
        return 5500 - (x - 400)
    if x <= 5500:
        return 3000 - (x - 2900) * 2500 / 2600
    return 500 - (x - 5500)


# name, position on the down track's own coordinate, kind
DOWN_SIGNALS = [
    ("A home down", 5006.0, "main"),
    ("B exit down", 2926.0, "main"),
    ("B home down", 2400.0, "main"),
    ("Block D", 1650.0, "block"),
    ("C exit down", 420.0, "main"),
]
UP_SIGNALS = [
    ("A exit", 520.0, "main"),
    ("Block 1", 1600.0, "block"),
    ("B home", 2500.0, "main"),
    ("B exit", 3030.0, "main"),
    ("C home", 5000.0, "main"),
]


def _read(name: str, **kw):
    return read_signalling(DATA / name, ocps=["A", "B", "C"], **kw)


@pytest.mark.parametrize("name", FILES)
def test_down_track_signals_are_mapped_to_route_positions(name: str) -> None:
    line = _read(name, double_track=True)
    up = [(s.name, s.position_m, s.kind) for s in line.signals if s.direction == "up"]
    down = [(s.name, s.position_m, s.kind) for s in line.signals if s.direction == "down"]
    assert up == UP_SIGNALS
    assert [n for n, _p, _k in down] == [n for n, _x, _k in DOWN_SIGNALS]
    for (_n, p, k), (_m, x, kind) in zip(down, DOWN_SIGNALS, strict=True):
        assert p == pytest.approx(_down_m(x), abs=1e-9) and k == kind
    assert [p for _n, p, _k in down] == pytest.approx([975.0, 2975.0, 3500.0, 4250.0, 5480.0], abs=1e-9)
    assert line.block_signals_m() == {"up": [1600.0], "down": [4250.0]}
    # a signal of the down track facing the up direction is wrong-line signalling: noted, not read
    assert any("Wrong-line" in n or "s_wrong" in n for n in line.notes)


@pytest.mark.parametrize("name", FILES)
def test_down_track_detection_points_switches_and_tracks(name: str) -> None:
    line = _read(name, double_track=True)
    assert [(d.name, d.path) for d in line.detection_points] == [("AC D2", "down"), ("AC D1", "down")]
    assert [d.position_m for d in line.detection_points] == pytest.approx([_down_m(5600), _down_m(1650)])
    assert [s.name for s in line.switches] == ["W D2", "W D1"]
    assert [s.position_m for s in line.switches] == pytest.approx([_down_m(3300), _down_m(2500)])
    tracks = [(t.name, t.kind, t.main_direction, t.path) for t in line.tracks]
    assert tracks == [("Up track", "mainTrack", "up", "up"), ("Down track", "mainTrack", "down", "down")]
    down = line.tracks[1]
    # the down track's ends (0 and 6100 on its own coordinate) as route positions
    assert (down.start_m, down.end_m) == pytest.approx((_down_m(6100), _down_m(0)))


@pytest.mark.parametrize("name", FILES)
def test_station_tracks_per_direction(name: str) -> None:
    line = _read(name, double_track=True)
    assert [(s.name, s.tracks, s.down_tracks) for s in line.stations] == [
        ("A", 1, 1),
        ("B", 1, 2),  # the loop at B is on the down side
        ("C", 1, 1),
    ]
    up = {e["name"]: e for e in line.station_signals("up")}
    down = {e["name"]: e for e in line.station_signals("down")}
    assert up["B"]["tracks"] == 1 and down["B"]["tracks"] == 2
    # B's down home signal 500 m before B in the down direction (3500 - 3000), A's 475 m (500 - 975)
    assert down["B"]["entry_signal_distance_m"] == pytest.approx(500.0)
    assert down["A"]["entry_signal_distance_m"] == pytest.approx(_down_m(5006) - 500.0)


def test_railml3_station_tracks_are_functional_tracks() -> None:
    # without the down path every track at a station counts. B lies on netElements u1, u2 (one
    # functional track, the up track), d2 (the down track) and l (the loop): 3 tracks, not 4 netElements
    three = {s.name: s.tracks for s in _read("double_track_railml3.xml").stations}
    two = {s.name: s.tracks for s in _read("double_track_railml2.xml").stations}
    assert three == two == {"A": 2, "B": 3, "C": 2}


@pytest.mark.parametrize("name", FILES)
def test_without_double_track_the_down_track_is_not_read(name: str) -> None:
    line = _read(name)
    assert all(s.direction == "up" for s in line.signals) and not line.detection_points
    assert "signals not on the route's path, not read: 6" in line.notes
    assert all(s.down_tracks is None for s in line.stations)


def test_double_track_on_a_single_track_file_names_the_station() -> None:
    with pytest.raises(InputError) as err:
        read_signalling(DATA / "line_railml2.xml", ocps=["A", "B", "C"], double_track=True)
    text = str(err.value)
    assert "line_railml2.xml" in text and "double_track" in text and "station 'C'" in text


def test_a_railml3_track_on_an_unknown_net_element_is_an_error(tmp_path: Path) -> None:
    text = (DATA / "double_track_railml3.xml").read_text()
    bad = tmp_path / "bad.xml"
    bad.write_text(
        text.replace(
            '<associatedNetElement netElementRef="ne_l" keepsOrientation="true"/>',
            '<associatedNetElement netElementRef="ne_x" keepsOrientation="true"/>',
        )
    )
    with pytest.raises(InputError) as err:
        _read_path(bad)
    assert "ne_x" in str(err.value) and "unknown netElement" in str(err.value) and "line" in str(err.value)


def test_a_down_track_missing_a_station_is_an_error(tmp_path: Path) -> None:
    text = (DATA / "double_track_railml2.xml").read_text()
    bad = tmp_path / "bad.xml"
    bad.write_text(
        text.replace('<crossSection id="cs_d_b" ocpRef="ocpB" pos="2900"/>', "").replace(
            '<crossSection id="cs_l_b" ocpRef="ocpB" pos="400"/>', ""
        )
    )
    with pytest.raises(InputError) as err:
        _read_path(bad, double_track=True)
    assert "'B'" in str(err.value) and "double_track" in str(err.value)


def _read_path(path: Path, **kw):
    return read_signalling(path, ocps=["A", "B", "C"], **kw)


@pytest.mark.parametrize("name", FILES)
def test_an_operation_on_the_double_track_read_from_railml(tmp_path: Path, name: str) -> None:
    op_file = tmp_path / "op.yaml"
    op_file.write_text(f"""schema: trainsim/operation
version: 1
name: railML double track
line:
  railml:
    file: {DATA / name}
    ocps: [A, B, C]
    double_track: true
    line_resistance: {{curve_formula: none, tunnel_formula: none}}
  layout: double_track
  signalling: {{system: fixed_block, aspects: 3}}
trains:
  - {{id: U1, train: {TRAIN}, direction: up, origin: A, destination: C, departure: "06:00"}}
  - {{id: D1, train: {TRAIN}, direction: down, origin: C, destination: A, departure: "06:00"}}
""")
    op = read_operation(op_file)
    assert op.line_args["block_signals_m"] == {"up": [1600.0], "down": [4250.0]}
    stations = {s.name: s for s in op.line.stations}
    assert stations["B"].tracks == 1 and stations["B"].entry_signal_distance_m == pytest.approx(500.0)
    result = run_operation(op)
    assert result.status == "ok" and {t.id for t in result.trains} == {"U1", "D1"}


def test_a_down_track_that_needs_reversing_is_an_error(tmp_path: Path) -> None:
    # A placed at the C end of the down track: from B the down path would have to reverse
    text = (DATA / "double_track_railml2.xml").read_text()
    bad = tmp_path / "bad.xml"
    bad.write_text(text.replace('ocpRef="ocpA" pos="5500"', 'ocpRef="ocpA" pos="100"'))
    with pytest.raises(InputError) as err:
        _read_path(bad, double_track=True)
    text = str(err.value)
    assert "no down path" in text and "no way from 'B' to 'A'" in text and "double_track" in text


@pytest.mark.parametrize("name", ["testline_railml2.xml", "testline_railml3.xml"])
def test_the_shipped_test_line_tracks_and_its_single_track(name: str) -> None:
    path = Path(__file__).resolve().parents[1] / "interchange" / "data" / name
    line = read_signalling(path)
    if name.endswith("2.xml"):  # railML 2: each track along the path, from the route's mileage
        assert [(t.name, t.start_m, t.end_m) for t in line.tracks] == [
            ("Testline track 1", 1000.0, 6000.0),
            ("Testline track 2", 6000.0, 10000.0),
        ]
    else:  # the railML 3 twin has no functional tracks: none read, stations count netElements
        assert line.tracks == []
    assert [s.tracks for s in line.stations] == [1, 1, 1, 1]
    with pytest.raises(InputError, match="station 'Dunmore' lies on no track besides the route's path"):
        read_signalling(path, double_track=True)
