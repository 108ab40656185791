"""The same route (and train) written by hand as railML 2, railML 3, spreadsheet tables (CSV and
Excel) and trainsim YAML gives the same route and the same run."""

from __future__ import annotations

import dataclasses

import pytest
from interchange_cases import DATA, FORMULAS, run

from trainsim.io import convert, railml2, railml3, spreadsheet
from trainsim.io import railml_common as rc


def _excel_from_csv(folder, path):
    """The CSV tables as one workbook, one sheet per table (as a user would save them)."""
    import csv

    import openpyxl

    book = openpyxl.Workbook()
    book.remove(book.active)
    for f in sorted(folder.glob("*.csv")):
        ws = book.create_sheet(f.stem)
        with f.open(newline="", encoding="utf-8") as fh:
            for row in csv.reader(fh):
                ws.append([float(c) if c.replace(".", "", 1).lstrip("-").isdigit() else c for c in row])
    book.save(path)
    return path


@pytest.fixture(scope="module")
def contents(tmp_path_factory):
    xlsx = _excel_from_csv(DATA / "testline_csv", tmp_path_factory.mktemp("xl") / "testline.xlsx")
    return {
        "railML 2": railml2.read_railml2(DATA / "testline_railml2.xml"),
        "railML 3": railml3.read_railml3(DATA / "testline_railml3.xml", line_resistance=FORMULAS),
        "CSV": spreadsheet.read_spreadsheet(DATA / "testline_csv"),
        "Excel": spreadsheet.read_spreadsheet(xlsx),
    }


@pytest.mark.parametrize("fmt", ["railML 2", "railML 3", "CSV", "Excel"])
def test_same_route(contents, fmt, yaml_route):
    route = rc.build_route(contents[fmt])
    assert dataclasses.replace(route, name=yaml_route.name) == yaml_route


@pytest.mark.parametrize("fmt", ["railML 2", "railML 3", "CSV", "Excel"])
def test_same_train(contents, fmt, yaml_train):
    train = rc.build_train(contents[fmt])
    assert train.name == yaml_train.name
    assert train.mass_kg == yaml_train.mass_kg
    assert train.length_m == yaml_train.length_m
    assert train.rotating_mass_factor == pytest.approx(yaml_train.rotating_mass_factor, rel=1e-12)
    assert train.max_speed_mps == pytest.approx(yaml_train.max_speed_mps, rel=1e-12)
    assert train.braking.deceleration_mps2 == yaml_train.braking.deceleration_mps2
    assert train.electrical == yaml_train.electrical
    for v in (0.0, 5.0, 11.1, 22.2, 33.3):
        assert train.traction(v) == pytest.approx(yaml_train.traction(v), rel=1e-12)
        assert train.braking.regenerative(v) == pytest.approx(yaml_train.braking.regenerative(v), rel=1e-12)
        assert train.running_resistance_n(v) == pytest.approx(yaml_train.running_resistance_n(v), rel=1e-12)


def test_same_run_four_ways(contents, yaml_train, yaml_route):
    reference = run(yaml_train, yaml_route)
    assert reference.status == "ok"
    assert [s.to_station for s in reference.sections] == ["Bexley", "Dunmore"]  # Carnforth is passed
    for content in contents.values():
        result = run(rc.build_train(content), rc.build_route(content))
        assert result.running_time_s == pytest.approx(reference.running_time_s, rel=1e-9)
        assert result.energy_kwh.net == pytest.approx(reference.energy_kwh.net, rel=1e-9)
        assert result.dwell_s == reference.dwell_s == 30.0


def test_detect_and_load_scenario_from_each_format(yaml_train, yaml_route):
    """The loader's hook reads a whole scenario (train, route) from one railML or table file."""
    reference = run(yaml_train, yaml_route)
    for path, options in (
        (DATA / "testline_railml2.xml", {}),
        (DATA / "testline_railml3.xml", FORMULAS),
        (DATA / "testline_csv", {}),
    ):
        scenario = convert.detect_and_load(path, "scenario", **options)
        result = run(scenario.train, scenario.route)
        assert result.running_time_s == pytest.approx(reference.running_time_s, rel=1e-9)
    assert convert.detect_and_load(DATA / "testline_route.yaml", "route") is None  # YAML: the loader's


@pytest.mark.parametrize(
    "version,namespace",
    [
        ("2.2", "http://www.railml.org/schemas/2013"),
        ("2.3", "http://www.railml.org/schemas/2016"),
        ("2.5", "https://www.railml.org/schemas/2021"),
    ],
)
def test_railml2_versions(version, namespace, tmp_path, yaml_route):
    """2.2 to 2.5 differ in namespace and version; the elements read are the same."""
    text = (DATA / "testline_railml2.xml").read_text()
    text = text.replace('"https://www.railml.org/schemas/2018"', f'"{namespace}"').replace(
        'version="2.4"', f'version="{version}"'
    )
    path = tmp_path / "v.xml"
    path.write_text(text)
    content = railml2.read_railml2(path)
    assert content.format == f"railML {version}"
    assert dataclasses.replace(rc.build_route(content), name=yaml_route.name) == yaml_route


def test_railml3_version_31(tmp_path, yaml_route):
    text = (
        (DATA / "testline_railml3.xml")
        .read_text()
        .replace("schemas/3.2", "schemas/3.1")
        .replace('version="3.2"', 'version="3.1"')
    )
    path = tmp_path / "v.xml"
    path.write_text(text)
    content = railml3.read_railml3(path, line_resistance=FORMULAS)
    assert content.format == "railML 3.1"
    assert dataclasses.replace(rc.build_route(content), name=yaml_route.name) == yaml_route
