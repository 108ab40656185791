"""Strict values, one rule for every reader: true/false and quoted numbers are not numbers, NaN/inf and
absurd magnitudes are refused with the allowed range (trainsim.model.bounds), ambiguous spreadsheet
cells and duplicate railML ids are errors naming the cell or element."""

from __future__ import annotations

import copy
import math
import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml

import trainsim
from trainsim.errors import InputError
from trainsim.model import bounds

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
DATA = Path(__file__).resolve().parents[1] / "interchange" / "data"


def _doc(name: str) -> dict[str, Any]:
    return yaml.safe_load((EXAMPLES / "metro_b" / name).read_text(encoding="utf-8"))


def _set(data: dict[str, Any], path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    out = copy.deepcopy(data)
    cur: Any = out
    for key in path[:-1]:
        cur = cur[key]
    cur[path[-1]] = value
    return out


def _refused(tmp_path: Path, kind: str, data: dict[str, Any]) -> InputError:
    path = tmp_path / f"{kind}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    if kind == "scenario":
        for other in ("train.yaml", "route.yaml"):
            shutil.copy(EXAMPLES / "metro_b" / other, tmp_path / other)
    with pytest.raises(InputError) as err:
        getattr(trainsim, f"load_{kind}")(path)
    error = err.value
    assert error.file == str(path) and error.line is not None
    assert len(str(error)) < 400
    return error


@pytest.mark.parametrize(
    ("kind", "path", "value", "field", "reason"),
    [
        ("train", ("formation", 0, "count"), True, "formation[0].count", "not true/false"),
        ("train", ("formation", 0, "count"), "3", "formation[0].count", "not text"),
        ("train", ("formation", 0, "count"), 1_000_000_000, "formation[0].count", "out of range"),
        ("train", ("formation", 0, "mass_t"), "12", "formation[0].mass_t", "not text"),
        ("train", ("formation", 0, "mass_t"), 1e308, "formation[0].mass_t", "out of range"),
        ("train", ("formation", 0, "mass_t"), 10**400, "formation[0].mass_t", "out of range"),
        ("train", ("formation", 0, "mass_t"), math.nan, "formation[0].mass_t", "finite"),
        (
            "train",
            ("electrical", "traction_efficiency"),
            True,
            "electrical.traction_efficiency",
            "true/false",
        ),
        ("train", ("traction", "speed_kmh", 1), "5", "traction.speed_kmh[1]", "not text"),
        ("train", ("traction", "force_kn", 2), math.inf, "traction.force_kn[2]", "finite"),
        ("route", ("stations", 1, "dwell_s"), 1e308, "stations[1].dwell_s", "out of range"),
        ("route", ("stations", 1, "position_m"), 1e308, "stations[1].position_m", "out of range"),
        ("route", ("speed_limits", 0, "limit_kmh"), "5", "speed_limits[0].limit_kmh", "not text"),
        ("scenario", ("settings", "braking_fraction"), True, "settings.braking_fraction", "true/false"),
    ],
)
def test_one_rule_for_numbers(
    tmp_path: Path, kind: str, path: tuple[Any, ...], value: Any, field: str, reason: str
) -> None:
    error = _refused(tmp_path, kind, _set(_doc(f"{kind}.yaml"), path, value))
    assert error.field == field
    assert reason in str(error)
    assert error.allowed  # every refusal says what is allowed
    [problem] = error.problems
    assert problem.field == field and problem.allowed == error.allowed


def test_bounds_name_the_unit_of_the_file(tmp_path: Path) -> None:
    error = _refused(tmp_path, "route", _set(_doc("route.yaml"), ("stations", 1, "dwell_s"), 1e308))
    assert error.allowed == ">= -1e+06 s and <= 1e+06 s"
    error = _refused(tmp_path, "train", _set(_doc("train.yaml"), ("max_speed_kmh",), 5000))
    assert error.allowed == ">= 0 km/h and <= 720 km/h"


def test_bounds_table() -> None:
    assert bounds.check(80, "speed", unit="km/h", factor=1 / 3.6) == pytest.approx(80 / 3.6)
    with pytest.raises(InputError, match="out of range") as err:
        bounds.check(800, "speed", field="v", unit="km/h", factor=1 / 3.6)
    assert err.value.allowed == ">= 0 km/h and <= 720 km/h" and err.value.field == "v"
    for bad in (True, "1", None, math.nan, math.inf):
        with pytest.raises(InputError):
            bounds.check(bad, "mass")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="out of range"):
        bounds.check(10**400, "mass")  # an int too large for a float
    assert not bounds.BOUNDS["efficiency"].contains(0.0) and bounds.BOUNDS["efficiency"].contains(1.0)
    assert bounds.bound_for("count").quantity == "count"
    assert bounds.bound_for("vehicle_count").quantity == "count"
    assert bounds.bound_for("dwell_s", "time").quantity == "time"
    assert bounds.bound_for("c2_whatever").quantity == "coefficient"
    assert bounds.check_count(3.0) == 3
    for bad in (True, 2.5, -1, 100_001, "3", math.nan):
        with pytest.raises(InputError):
            bounds.check_count(bad)


# ====================================================================== spreadsheets
def _csv_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "csv"
    shutil.copytree(DATA / "testline_csv", folder)
    return folder


def test_ambiguous_thousands_separator_names_the_cell(tmp_path: Path) -> None:
    folder = _csv_folder(tmp_path)
    sections = folder / "sections.csv"
    sections.write_text(
        sections.read_text(encoding="utf-8").replace(",1500\n", ',"1,500"\n', 1), encoding="utf-8"
    )
    with pytest.raises(InputError, match="ambiguous number") as err:
        trainsim.load_route(folder)
    assert err.value.field == "sections!J2"
    assert err.value.value == "1,500" and err.value.line == 2
    assert "1500 or 1.500" in str(err.value)


def test_decimal_comma_still_reads(tmp_path: Path) -> None:
    folder = _csv_folder(tmp_path)
    stations = folder / "stations.csv"
    stations.write_text(
        stations.read_text(encoding="utf-8").replace("Aford,1.2,", 'Aford,"1,2",'), encoding="utf-8"
    )
    route = trainsim.load_route(folder)
    assert route.stations[0].position_m == pytest.approx(1200.0)


def test_spreadsheet_counts_and_magnitudes(tmp_path: Path) -> None:
    folder = _csv_folder(tmp_path)
    vehicles = folder / "vehicles.csv"
    text = vehicles.read_text(encoding="utf-8")
    vehicles.write_text(text.replace("Coach,4,", "Coach,1000000000,"), encoding="utf-8")
    with pytest.raises(InputError, match="out of range") as err:
        trainsim.load_train(folder)
    assert err.value.field == "vehicles!B3"
    vehicles.write_text(text.replace("Coach,4,40,", "Coach,4,1e308,"), encoding="utf-8")
    with pytest.raises(InputError, match="out of range") as err:
        trainsim.load_train(folder)
    assert err.value.field == "vehicles!C3"


# ====================================================================== railML
@pytest.mark.parametrize("name", ["testline_railml2.xml", "testline_railml3.xml"])
def test_railml_duplicate_ids_refused(tmp_path: Path, name: str) -> None:
    text = (DATA / name).read_text(encoding="utf-8")
    ids = [part.split('"', 1)[0] for part in text.split(' id="')[1:]]
    first, second = ids[1], ids[2]
    bad = tmp_path / name
    bad.write_text(text.replace(f' id="{second}"', f' id="{first}"', 1), encoding="utf-8")
    with pytest.raises(InputError, match="duplicate id") as err:
        trainsim.load_route(bad)
    assert err.value.value == first and err.value.line is not None and err.value.file == str(bad)


def test_railml_whole_numbers(tmp_path: Path) -> None:
    text = (DATA / "testline_railml2.xml").read_text(encoding="utf-8")
    assert 'arrivalDay="' not in text
    bad = tmp_path / "bad.xml"
    bad.write_text(
        text.replace('scope="scheduled"', 'scope="scheduled" departureDay="1,5"', 1), encoding="utf-8"
    )
    with pytest.raises(InputError, match="whole number") as err:
        trainsim.load_route(bad)
    assert err.value.value == "1,5"


# ====================================================================== gravity
def test_route_gravity_is_a_bounded_setting(tmp_path: Path) -> None:
    from trainsim.constants import STANDARD_GRAVITY, TRAINRUNS_GRAVITY

    route = _doc("route.yaml")
    path = tmp_path / "route.yaml"
    path.write_text(yaml.safe_dump(route), encoding="utf-8")
    assert trainsim.load_route(path).gravity_mps2 == STANDARD_GRAVITY
    path.write_text(yaml.safe_dump({**route, "gravity_mps2": 9.81}), encoding="utf-8")
    assert trainsim.load_route(path).gravity_mps2 == 9.81
    error = _refused(tmp_path, "route", {**route, "gravity_mps2": 1.62})  # the Moon
    assert error.field == "gravity_mps2" and error.allowed == ">= 9.7 m/s^2 and <= 9.9 m/s^2"
    trainruns = Path(__file__).resolve().parents[1] / "data" / "trainruns" / "paths" / "const.yaml"
    if trainruns.is_file():
        assert trainsim.load_route(trainruns).gravity_mps2 == TRAINRUNS_GRAVITY


def test_version_true_is_not_version_1(tmp_path: Path) -> None:
    error = _refused(tmp_path, "route", {**_doc("route.yaml"), "version": True})
    assert error.field == "version" and error.allowed == "1"


# ====================================================================== bounded tables
def test_csv_cell_beyond_the_field_limit(tmp_path: Path) -> None:
    folder = _csv_folder(tmp_path)
    stations = folder / "stations.csv"
    stations.write_text(
        stations.read_text(encoding="utf-8") + '"' + "x" * 200_000 + '",1,0,yes\n', encoding="utf-8"
    )
    with pytest.raises(InputError, match="not a readable CSV table") as err:
        trainsim.load_route(folder)
    assert err.value.file == str(stations) and err.value.line is not None and len(str(err.value)) < 400


def test_workbooks_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from trainsim.io import spreadsheet

    folder = DATA / "testline_csv"
    book = spreadsheet.write_spreadsheet(
        tmp_path / "line.xlsx", train=trainsim.load_train(folder), route=trainsim.load_route(folder)
    )
    assert trainsim.load_route(book).length_m > 0
    monkeypatch.setattr(spreadsheet, "MAX_WORKBOOK_UNPACKED_BYTES", 1000)
    with pytest.raises(InputError, match="unpacks to too much") as err:
        trainsim.load_route(book)
    assert err.value.file == str(book)
    monkeypatch.setattr(spreadsheet, "MAX_WORKBOOK_UNPACKED_BYTES", 10**9)
    monkeypatch.setattr(spreadsheet, "MAX_TABLE_ROWS", 3)
    with pytest.raises(InputError, match="table too long"):
        trainsim.load_route(book)
    fake = tmp_path / "fake.xlsx"
    fake.write_bytes(b"not a zip archive")
    with pytest.raises(InputError, match="not an Excel workbook"):
        trainsim.load_route(fake)
