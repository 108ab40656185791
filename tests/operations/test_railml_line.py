"""An operation file whose line (route, stations' signals, block signals) is read from railML 2 or 3."""

from __future__ import annotations

from pathlib import Path

import pytest

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.io.railml_signalling import read_signalling

ROOT = Path(__file__).resolve().parents[2]
RAILML = ROOT / "tests" / "io" / "railml_signalling"
TRAIN = ROOT / "tests" / "data" / "trainruns" / "trains" / "local.yaml"


def _write(tmp_path: Path, xml: str, line_extra: str = "", railml_extra: str = "") -> Path:
    text = f"""schema: trainsim/operation
version: 1
name: railML line
line:
  railml:
    file: {RAILML / xml}
    ocps: [A, B, C]
    line_resistance: {{curve_formula: none, tunnel_formula: none}}
{railml_extra}
  layout: single_track
{line_extra}
  signalling: {{system: fixed_block, aspects: 3}}
trains:
  - {{id: U1, train: {TRAIN}, direction: up, origin: A, destination: C, departure: "06:00",
      stops: [{{station: B, dwell_s: 30}}]}}
  - {{id: D1, train: {TRAIN}, direction: down, origin: C, destination: A, departure: "06:01",
      stops: [{{station: B, dwell_s: 30}}]}}
"""
    path = tmp_path / "op.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("xml", ["line_railml2.xml", "line_railml3.xml"])
def test_stations_and_signal_distances_come_from_the_railml_file(tmp_path, xml):
    op = read_operation(_write(tmp_path, xml))
    read = {s["name"]: s for s in read_signalling(RAILML / xml, ocps=["A", "B", "C"]).station_signals("up")}
    assert op.geometry.end_m == pytest.approx(6000.0)
    stations = {s.name: s for s in op.line.stations}
    assert sorted(stations) == ["A", "B", "C"]
    for name, entry in read.items():
        st = stations[name]
        assert st.position_m == pytest.approx(entry["position_m"])
        assert st.tracks == entry["tracks"]
        if "entry_signal_distance_m" in entry:
            assert st.entry_signal_distance_m == pytest.approx(entry["entry_signal_distance_m"])
        if "exit_signal_offset_m" in entry:
            assert st.exit_signal_offset_m == pytest.approx(entry["exit_signal_offset_m"])
    # B's home signal stands 500 m before it in both files, not the 400 m default
    assert stations["B"].entry_signal_distance_m == pytest.approx(500.0)
    result = run_operation(op)
    assert {t.id for t in result.trains} == {"U1", "D1"}


def test_a_station_given_in_the_file_overrides_what_was_read(tmp_path):
    extra = "  stations:\n    - {name: B, entry_signal_distance_m: 350}"
    op = read_operation(_write(tmp_path, "line_railml2.xml", line_extra=extra))
    b = next(s for s in op.line.stations if s.name == "B")
    assert b.entry_signal_distance_m == pytest.approx(350.0)
    assert b.tracks == 2  # still read from the railML file


def test_route_and_railml_together_are_refused(tmp_path):
    path = _write(tmp_path, "line_railml2.xml", railml_extra="  route: somewhere.yaml")
    with pytest.raises(InputError) as err:
        read_operation(path)
    assert "line.route, line.railml or line.spreadsheet" in str(err.value)


def test_a_missing_railml_file_names_the_field(tmp_path):
    path = _write(tmp_path, "no_such_file.xml")
    with pytest.raises(InputError) as err:
        read_operation(path)
    assert "line.railml.file" in str(err.value)
