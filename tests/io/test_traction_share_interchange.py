"""ElectrificationSection.traction_share through every interchange format that carries electrification:
railML 2 (``electrificationChange@ts:tractionShare``), railML 3 (``electrificationSection@ts:tractionShare``)
and spreadsheets (column ``traction share (%)``) write it and read it back; a share of 1 writes nothing
new; a share outside (0, 1] read from a file is an error naming the file, the field and the range."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from lxml import etree

import trainsim
from trainsim.errors import InputError
from trainsim.io import railml2, railml3, spreadsheet
from trainsim.io import railml_common as rc
from trainsim.model.route import ElectrificationSection, Route

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SHARES = (0.6, 1.0, 0.075, 0.834)  # one section at full effort between limited ones


@pytest.fixture(scope="module")
def route() -> Route:
    """The metro example's route, electrified at 750 V in four sections with different shares (and a
    1500 V section, so that a voltage change and a share change are told apart)."""
    base = trainsim.load_scenario(EXAMPLES / "metro_b" / "scenario.yaml").route
    # cuts on whole decimetres: railML positions are written to 6 decimals at most
    cuts = [round(base.start_m + k * (base.end_m - base.start_m) / 5, 1) for k in range(5)] + [base.end_m]
    voltages = (750.0, 750.0, 750.0, 750.0, 1500.0)
    shares = (*SHARES, 0.5)
    sections = tuple(
        ElectrificationSection(a, b, u, s)
        for a, b, u, s in zip(cuts[:-1], cuts[1:], voltages, shares, strict=True)
    )
    return dataclasses.replace(base, electrification=sections)


def _railml(kind: str, route: Route, path: Path, version: str) -> Route:
    writer, reader = {"2": (railml2.write_railml2, railml2.read_railml2),
                      "3": (railml3.write_railml3, railml3.read_railml3)}[kind]  # fmt: skip
    writer(path, route=route, version=version)
    content = reader(path)
    assert content.ignored == []  # the reader uses everything the writer writes
    return rc.build_route(content)


@pytest.mark.parametrize(
    ("kind", "version"), [("2", "2.2"), ("2", "2.4"), ("2", "2.5"), ("3", "3.1"), ("3", "3.2")]
)
def test_railml_round_trip_keeps_the_shares(route, tmp_path, kind, version):
    back = _railml(kind, route, tmp_path / "line.xml", version)
    # the shares are written as given (repr of the float): the sections come back equal
    assert back.electrification == route.electrification
    text = (tmp_path / "line.xml").read_text()
    assert text.count("ts:tractionShare=") == sum(e.traction_share != 1.0 for e in route.electrification)


@pytest.mark.parametrize("suffix", ["", ".xlsx"])
def test_spreadsheet_round_trip_keeps_the_shares(route, tmp_path, suffix):
    path = spreadsheet.write_spreadsheet(tmp_path / f"line{suffix}", route=route)
    back = rc.build_route(spreadsheet.read_spreadsheet(path))
    assert len(back.electrification) == len(route.electrification)
    for got, want in zip(back.electrification, route.electrification, strict=True):
        assert (got.start_m, got.end_m, got.voltage_v) == pytest.approx(
            (want.start_m, want.end_m, want.voltage_v)
        )
        # written in percent: x 100 then x 0.01 may move the last bit
        assert got.traction_share == pytest.approx(want.traction_share, rel=1e-12)


def test_full_shares_write_nothing_new(route, tmp_path):
    """A route at full effort everywhere is written as before: no attribute, no column."""
    # equal neighbours are one section once read: give them as one
    e = route.electrification
    full = dataclasses.replace(
        route,
        electrification=(
            ElectrificationSection(e[0].start_m, e[3].end_m, 750.0),
            ElectrificationSection(e[4].start_m, e[4].end_m, 1500.0),
        ),
    )
    for kind, version in (("2", "2.4"), ("3", "3.2")):
        path = tmp_path / f"full{kind}.xml"
        assert _railml(kind, full, path, version).electrification == full.electrification
        assert "tractionShare" not in path.read_text()
    folder = spreadsheet.write_spreadsheet(tmp_path / "full", route=full)
    assert "traction share" not in (folder / "sections.csv").read_text()
    assert rc.build_route(spreadsheet.read_spreadsheet(folder)).electrification == full.electrification


@pytest.mark.parametrize("kind", ["2", "3"])
@pytest.mark.parametrize("bad", ["0", "-0.2", "1.5", "nan", "half"])
def test_railml_share_out_of_range_is_a_clear_error(route, tmp_path, kind, bad):
    path = tmp_path / "bad.xml"
    (railml2.write_railml2 if kind == "2" else railml3.write_railml3)(path, route=route)
    tree = etree.parse(str(path))
    attr = f"{{{rc.EXTENSION_NS}}}tractionShare"
    holder = next(el for el in tree.iter() if el.get(attr) is not None)
    holder.set(attr, bad)
    tree.write(str(path), xml_declaration=True, encoding="UTF-8")
    with pytest.raises(InputError) as err:
        (railml2.read_railml2 if kind == "2" else railml3.read_railml3)(path)
    text = str(err.value)
    assert str(path) in text and "ts:tractionShare" in text and "0 < share <= 1" in text, text
    assert bad in text and f"line {holder.sourceline}" in text, text


@pytest.mark.parametrize("bad", ["0", "150", "-5"])
def test_spreadsheet_share_out_of_range_is_a_clear_error(route, tmp_path, bad):
    folder = spreadsheet.write_spreadsheet(tmp_path / "bad", route=route)
    sections = folder / "sections.csv"
    lines = sections.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index("traction share (%)")
    cells = lines[1].split(",")
    cells[col] = bad
    lines[1] = ",".join(cells)
    sections.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        spreadsheet.read_spreadsheet(folder)
    text = str(err.value)
    assert "sections.csv" in text and "traction share" in text and "0 < share <= 1" in text, text
    assert bad in text, text


def test_spreadsheet_share_needs_a_voltage(route, tmp_path):
    folder = spreadsheet.write_spreadsheet(tmp_path / "novolt", route=route)
    sections = folder / "sections.csv"
    lines = sections.read_text().splitlines()
    col = lines[0].split(",").index("voltage (V)")
    cells = lines[1].split(",")
    cells[col] = ""
    lines[1] = ",".join(cells)
    sections.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="traction share needs the section's voltage"):
        spreadsheet.read_spreadsheet(folder)
