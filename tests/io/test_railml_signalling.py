"""Signalling of a line from railML 2 and 3 (issue 17): signals, train detection points, switches and
station tracks placed on a route's path. The two test files (``railml_signalling/``) describe the same
single-track line A (500 m) - B (3000 m, a passing loop) - C (5500 m) by hand; every expected position
is read off the files (railML 2: ``pos`` on the one main track; railML 3: netElement begin + ``pos``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from trainsim.errors import InputError
from trainsim.io.railml_signalling import read_signalling

DATA = Path(__file__).resolve().parent / "railml_signalling"
FILES = ["line_railml2.xml", "line_railml3.xml"]

UP = [
    ("A exit", 520.0, "main"),
    ("Block 1", 1600.0, "block"),
    ("B distant", 1800.0, "distant"),
    ("B home", 2500.0, "main"),
    ("B exit", 3030.0, "main"),
    ("C home", 5000.0, "main"),
]
DOWN = [
    ("A home down", 1000.0, "main"),
    ("B exit down", 2970.0, "main"),
    ("B home down", 3500.0, "main"),
    ("Block 2", 4200.0, "block"),
    ("C exit down", 5480.0, "main"),
]


def _signals(line, direction):
    return [(s.name, s.position_m, s.kind) for s in line.signals if s.direction == direction]


@pytest.mark.parametrize("name", FILES)
def test_signals_on_the_path_with_direction_and_kind(name):
    line = read_signalling(DATA / name, ocps=["A", "B", "C"])
    assert (line.start_m, line.end_m) == (0.0, 6000.0)
    assert _signals(line, "up") == UP
    assert _signals(line, "down") == DOWN
    # the shunting signal is not read and says so; the loop's exit signal is off the path
    assert any("s_sh" in n and "not read" in n for n in line.notes)
    assert any(n == "signals not on the route's path, not read: 1" for n in line.notes)
    # each signal names the element and the line it was read from
    text = (DATA / name).read_text()
    block = next(s for s in line.signals if s.name == "Block 1")
    assert "id='s_b1'" in block.source
    line_no = text[: text.index('id="s_b1"')].count("\n") + 1
    assert block.source.endswith(f"line {line_no}")


@pytest.mark.parametrize("name", FILES)
def test_detection_points_switches_and_station_tracks(name):
    line = read_signalling(DATA / name, ocps=["A", "B", "C"])
    assert [(d.name, d.position_m, d.kind) for d in line.detection_points] == [
        ("AC1", 510.0, "axle_counter"),
        ("AC2", 2450.0, "axle_counter"),
        ("TCB1", 4000.0, "track_circuit_border"),
    ]
    assert [(s.name, s.position_m) for s in line.switches] == [("W1", 2600.0), ("W2", 3400.0)]
    # B lies on the main track and on the loop: two tracks
    assert [(s.name, s.position_m, s.tracks) for s in line.stations] == [
        ("A", 500.0, 1),
        ("B", 3000.0, 2),
        ("C", 5500.0, 1),
    ]


@pytest.mark.parametrize("name", FILES)
def test_operation_line_inputs(name):
    line = read_signalling(DATA / name, ocps=["A", "B", "C"])
    # entry: station - last main signal before it; exit: first main signal at or after it
    assert line.station_signals("up") == [
        {"name": "A", "position_m": 500.0, "tracks": 1, "exit_signal_offset_m": 20.0},
        {
            "name": "B",
            "position_m": 3000.0,
            "tracks": 2,
            "entry_signal_distance_m": 500.0,
            "exit_signal_offset_m": 30.0,
        },
        {"name": "C", "position_m": 5500.0, "tracks": 1, "entry_signal_distance_m": 500.0},
    ]
    down = {st["name"]: st for st in line.station_signals("down")}
    assert down["C"]["exit_signal_offset_m"] == pytest.approx(5500.0 - 5480.0)
    assert down["B"]["entry_signal_distance_m"] == pytest.approx(3500.0 - 3000.0)
    assert down["B"]["exit_signal_offset_m"] == pytest.approx(3000.0 - 2970.0)
    assert down["A"]["entry_signal_distance_m"] == pytest.approx(1000.0 - 500.0)
    assert "exit_signal_offset_m" not in down["A"] and "entry_signal_distance_m" not in down["C"]
    assert line.block_signals_m() == {"up": [1600.0], "down": [4200.0]}


def test_a_path_against_the_track_direction_turns_the_signals_round():
    # C -> A runs against the railML 2 track: route position = 6000 - pos, and the signals facing
    # "down" govern this train
    line = read_signalling(DATA / "line_railml2.xml", ocps=["C", "B", "A"])
    assert _signals(line, "up") == [(n, 6000.0 - x, k) for n, x, k in reversed(DOWN)]
    assert _signals(line, "down") == [(n, 6000.0 - x, k) for n, x, k in reversed(UP)]
    assert [s.name for s in line.stations] == ["C", "B", "A"]


def test_a_signal_off_its_track_is_an_error(tmp_path):
    text = (DATA / "line_railml2.xml").read_text().replace('pos="1600" dir="up"', 'pos="7600" dir="up"')
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_signalling(path, ocps=["A", "B", "C"])
    message = str(err.value)
    assert "s_b1" in message and "position outside its track" in message and "7600" in message


def test_a_signal_without_direction_is_an_error(tmp_path):
    text = (DATA / "line_railml2.xml").read_text().replace('pos="1600" dir="up"', 'pos="1600"')
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(InputError, match="a signal needs its direction"):
        read_signalling(path, ocps=["A", "B", "C"])


def test_railml3_signal_on_an_unknown_net_element(tmp_path):
    text = (
        (DATA / "line_railml3.xml")
        .read_text()
        .replace('id="l3" netElementRef="ne_a"', 'id="l3" netElementRef="ne_x"')
    )
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_signalling(path, ocps=["A", "B", "C"])
    assert "ne_x" in str(err.value) and "unknown netElement" in str(err.value)


def test_not_railml(tmp_path):
    path = tmp_path / "x.xml"
    path.write_text("<other/>")
    with pytest.raises(InputError, match="not a railML 2 or 3 file"):
        read_signalling(path)


def test_without_a_path(tmp_path):
    with pytest.raises(InputError, match="no route"):
        read_signalling(DATA / "line_railml2.xml")


def test_the_operations_layer_builds_its_line_from_it():
    # the form the operations layer takes: station layouts and the main signals of the built line are
    # the file's (A's entry signal is not in the file: the operations default, 400 m, applies)
    from trainsim.operations.line import Signalling, StationLayout, build_line

    line = read_signalling(DATA / "line_railml2.xml", ocps=["A", "B", "C"])
    stations = tuple(StationLayout(**st) for st in line.station_signals("up"))
    built = build_line("signal line", line.end_m, "single_track", stations, Signalling())
    mains = [s.position_m for s in line.signals if s.direction == "up" and s.kind == "main"]
    assert list(built.paths["up"].signal_positions()) == [500.0 - 400.0, *mains]


def test_an_operational_point_without_id_is_a_clear_error(tmp_path):
    # the walk keeps the points by id; one without id, asked for by its name, is refused with the
    # element and its line (a mutation found a KeyError here)
    text = (DATA / "line_railml2.xml").read_text().replace('<ocp id="ocpB" name="B"/>', '<ocp name="B"/>')
    path = tmp_path / "no_id.xml"
    path.write_text(text)
    with pytest.raises(InputError, match=r"<ocp name='B'>.*has no position on a track"):
        read_signalling(path, ocps=["A", "B", "C"])


@pytest.mark.parametrize(
    ("name", "double_track"),
    [*((f, False) for f in FILES), ("double_track_railml2.xml", True), ("double_track_railml3.xml", True)],
)
def test_mutated_files_read_or_refused_never_a_traceback(name, double_track, tmp_path):
    # seeded structural mutations (an attribute changed or removed, an element removed or renamed):
    # each file is read or refused with an InputError, nothing else
    import random

    from lxml import etree

    text = (DATA / name).read_text()
    outcomes = {"read": 0, "refused": 0}
    for seed in range(150):
        rng = random.Random(seed)
        root = etree.fromstring(text.encode())
        el = rng.choice([e for e in root.iter() if isinstance(e.tag, str)])
        op = rng.random()
        if op < 0.6 and el.attrib:
            attr = rng.choice(sorted(el.attrib))
            if rng.random() < 0.7:
                el.set(attr, rng.choice(["", "-1", "1e309", "nan", "x", "99999"]))
            else:
                del el.attrib[attr]
        elif op < 0.85 and el.getparent() is not None:
            el.getparent().remove(el)
        else:
            el.tag = el.tag + "x"
        path = tmp_path / f"m{seed}.xml"
        path.write_bytes(etree.tostring(root))
        try:
            read_signalling(path, ocps=["A", "B", "C"], double_track=double_track)
            outcomes["read"] += 1
        except InputError:
            outcomes["refused"] += 1
    assert outcomes["read"] > 0 and outcomes["refused"] > 0, outcomes


def test_positions_follow_the_route_mileage_and_its_timetable_path():
    # the interchange test line: its first track begins at mileage 1000 m (trackBegin@absPos), the
    # timetable train's path is the route; sig1 sits at pos 2900 of that track, sw1 at 4800
    line = read_signalling(
        Path(__file__).resolve().parents[1] / "interchange" / "data" / "testline_railml2.xml"
    )
    assert line.start_m == 1000.0
    assert [(s.name, s.position_m, s.direction, s.kind) for s in line.signals] == [
        ("sig1", 3900.0, "up", "main")
    ]
    assert [(s.name, s.position_m) for s in line.switches] == [("sw1", 5800.0)]
    assert [st.position_m for st in line.stations] == [1200.0, 4000.0, 6500.0, 9800.0]
