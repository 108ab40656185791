"""Signals, station tracks and train detection points of a line in operation from spreadsheet tables
(a CSV folder or an Excel workbook; issue 17). The example folder
``examples/operations/sheets_double_track/line`` is read; every expected value is in its CSV files."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.io.spreadsheet import read_spreadsheet_signalling

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "operations" / "sheets_double_track"
LINE = EXAMPLE / "line"


def test_signals_station_tracks_and_detection_points_from_the_csv_folder() -> None:
    line = read_spreadsheet_signalling(LINE)
    assert (line.start_m, line.end_m) == (0.0, 6000.0)
    up = [(s.name, s.position_m, s.kind) for s in line.signals if s.direction == "up"]
    assert up == [
        ("A exit", 30.0, "main"), ("Block U1", 1500.0, "block"), ("B home", 2650.0, "main"),
        ("B exit", 3030.0, "main"), ("Block U2", 4500.0, "block"), ("C home", 5650.0, "main"),
    ]  # fmt: skip
    assert len([s for s in line.signals if s.direction == "down"]) == 6
    assert line.block_signals_m() == {"up": [1500.0, 4500.0], "down": [1500.0, 4500.0]}
    stations = {s["name"]: s for s in line.station_signals("up")}
    assert stations["B"] == {
        "name": "B", "position_m": 3000.0, "tracks": 2, "entry_signal_distance_m": 350.0,
        "exit_signal_offset_m": 30.0,
    }  # fmt: skip
    assert stations["A"]["tracks"] == 1  # not in the station tracks table
    assert [(d.name, d.position_m, d.kind) for d in line.detection_points][:2] == [
        ("AC A", 10.0, "axle_counter"),
        ("AC 1", 1480.0, "axle_counter"),
    ]
    assert line.signals[0].source.endswith("signals.csv, row 2")


def test_an_excel_workbook_with_the_same_sheets_reads_the_same(tmp_path: Path) -> None:
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.Workbook()
    book.remove(book.active)
    for f in sorted(LINE.glob("*.csv")):
        sheet = book.create_sheet(f.stem.replace("_", " "))  # "station tracks": the sheet's own name
        for row in csv.reader(f.read_text().splitlines()):
            sheet.append([float(c) if c.replace(".", "").lstrip("-").isdigit() else c for c in row])
    path = tmp_path / "line.xlsx"
    book.save(path)
    a, b = read_spreadsheet_signalling(LINE), read_spreadsheet_signalling(path)
    assert [(s.name, s.position_m, s.direction, s.kind) for s in a.signals] == [
        (s.name, s.position_m, s.direction, s.kind) for s in b.signals
    ]
    assert a.station_signals("up") == b.station_signals("up")
    assert "sheet 'signals'" in b.signals[0].source


def test_the_operation_file_takes_its_line_from_the_sheets() -> None:
    op = read_operation(EXAMPLE / "operation.yaml")
    stations = {s.name: s for s in op.line.stations}
    assert stations["B"].tracks == 2 and stations["B"].entry_signal_distance_m == pytest.approx(350.0)
    assert op.line_args["block_signals_m"] == {"up": [1500.0, 4500.0], "down": [1500.0, 4500.0]}
    result = run_operation(op)
    assert result.status == "ok" and len(result.trains) == 5


def _broken(tmp_path: Path, table: str, old: str, new: str) -> Path:
    d = tmp_path / "line"
    shutil.copytree(LINE, d)
    f = d / table
    text = f.read_text()
    assert old in text
    f.write_text(text.replace(old, new))
    return d


@pytest.mark.parametrize(
    ("table", "old", "new", "words"),
    [
        ("signals.csv", "Block U1,1500,up", "Block U1,1500,north", ["signals!C3", "'north'", "up, down"]),
        ("signals.csv", "Block U1,1500,up", "Block U1,7000,up", ["signals!B3", "'7000'", "0 .. 6000 m"]),
        ("signals.csv", "Block U1,1500,up", "Block U1,15x0,up", ["signals!B3", "not a number", "'15x0'"]),
        (
            "signals.csv",
            "Block U1,1500,up,block",
            "Block U1,1500,up,shunt",
            ["signals!D3", "main, block, distant"],
        ),
        (
            "signals.csv",
            "Name,Position (m),Direction,Kind",
            "Name,Position (m),Way,Kind",
            ["signals!C1", "'Way'"],
        ),
        (
            "signals.csv",
            "Name,Position (m),Direction,Kind",
            "Name,Position,Direction,Kind",
            ["signals!B1", "unit"],
        ),
        ("station_tracks.csv", "B,2", "X,2", ["station_tracks!A2", "'X'", "A, B, C"]),
        ("station_tracks.csv", "B,2", "B,0", ["station_tracks!B2", "1 .. 50"]),
        ("station_tracks.csv", "B,2", "B,2\nB,3", ["station_tracks!A3", "given twice"]),
        (
            "detection_points.csv",
            "AC 1,1480,axle_counter",
            "AC 1,1480,magnet",
            ["detection_points!C3", "magnet"],
        ),
    ],
)
def test_bad_cells_name_file_sheet_cell_value_and_what_is_allowed(tmp_path, table, old, new, words) -> None:
    d = _broken(tmp_path, table, old, new)
    with pytest.raises(InputError) as err:
        read_spreadsheet_signalling(d)
    text = str(err.value)
    assert table in text
    for w in words:
        assert w in text


def test_no_signals_table_is_an_error(tmp_path: Path) -> None:
    d = tmp_path / "line"
    shutil.copytree(LINE, d)
    (d / "signals.csv").unlink()
    with pytest.raises(InputError, match="no 'signals' table"):
        read_spreadsheet_signalling(d)


def test_the_cli_reports_a_bad_sheet_in_one_line_exit_2(tmp_path: Path) -> None:
    _broken(tmp_path, "signals.csv", "Block U1,1500,up", "Block U1,1500,north")
    text = (
        (EXAMPLE / "operation.yaml")
        .read_text()
        .replace("../../metro_b/", f"{EXAMPLE.parent.parent / 'metro_b'}/")
    )
    op = tmp_path / "op.yaml"
    op.write_text(text)
    result = CliRunner().invoke(app, ["operate", str(op), "--json"])
    assert result.exit_code == 2, result.output
    assert "signals!C3" in result.stderr and "Traceback" not in result.output
    (tmp_path / "op2.yaml").write_text(text.replace("{file: line}", "{file: nowhere}"))
    result = CliRunner().invoke(app, ["operate", str(tmp_path / "op2.yaml")])
    assert result.exit_code == 2 and "line.spreadsheet.file" in result.stderr


def test_mutated_tables_read_or_refused_never_a_traceback(tmp_path: Path) -> None:
    # seeded mutations of one cell (header or body) of a signalling table: each folder is read or
    # refused with an InputError, nothing else
    import random

    tables = ["signals.csv", "station_tracks.csv", "detection_points.csv"]
    values = [
        "",
        "-1",
        "1e309",
        "nan",
        "x",
        "99999",
        "up",
        "block",
        "2,5",
        "1,500",
        "B",
        "Position (km)",
        "Kind (m)",
    ]
    outcomes = {"read": 0, "refused": 0}
    for seed in range(120):
        rng = random.Random(seed)
        d = tmp_path / f"m{seed}"
        shutil.copytree(LINE, d)
        f = d / rng.choice(tables)
        rows = [r.split(",") for r in f.read_text().splitlines()]
        r = rng.randrange(len(rows))
        c = rng.randrange(len(rows[r]))
        rows[r][c] = rng.choice(values)
        f.write_text("\n".join(",".join(x) for x in rows) + "\n")
        try:
            read_spreadsheet_signalling(d)
            outcomes["read"] += 1
        except InputError:
            outcomes["refused"] += 1
    assert outcomes["read"] > 0 and outcomes["refused"] > 0, outcomes
