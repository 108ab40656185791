"""The interchange commands (convert, check, export-results, runtimes) through typer's CliRunner,
registered here as trainsim.cli registers them."""

from __future__ import annotations

import json

import pytest
import typer
from interchange_cases import DATA, line_of, railml
from typer.testing import CliRunner

import trainsim
from trainsim.cli import interchange as ci

app = typer.Typer()
app.command()(ci.convert)
app.command()(ci.check)
app.command("export-results")(ci.export_results)
app.command()(ci.runtimes)
runner = CliRunner()


def test_convert_railml3_with_formulas(tmp_path):
    out = tmp_path / "scenario.yaml"
    result = runner.invoke(
        app,
        [
            "convert",
            str(DATA / "testline_railml3.xml"),
            str(out),
            "--curve-formula",
            "roeckl",
            "--tunnel-formula",
            "wang",
        ],
    )
    assert result.exit_code == 0, result.output
    assert f"wrote {out}" in result.output
    scenario = trainsim.load_scenario(out)
    assert scenario.route.line_resistance.curve_formula == "roeckl"
    assert [s.name for s in scenario.route.stops] == ["Aford", "Bexley", "Dunmore"]


def test_convert_one_kind_and_ocps(tmp_path):
    out = tmp_path / "route.yaml"
    result = runner.invoke(
        app,
        [
            "convert",
            str(DATA / "testline_railml2.xml"),
            str(out),
            "--kind",
            "route",
            "--ocps",
            "Aford,Dunmore",
        ],
    )
    assert result.exit_code == 0, result.output
    route = trainsim.load_route(out)
    assert [s.name for s in route.stations] == ["Aford", "Dunmore"]


def test_convert_error_exit_code(tmp_path):
    result = runner.invoke(app, ["convert", str(DATA / "testline_railml3.xml"), str(tmp_path / "x.yaml")])
    assert result.exit_code == 2
    assert "error: " in result.output and "curve and tunnel resistance formulas" in result.output


def test_check_railml_with_error_line(tmp_path):
    text = railml("testline_railml2.xml", **{'<speedChange id="sc5" pos="1000"': '<speedChange id="sc5"'})
    bad = tmp_path / "bad.xml"
    bad.write_text(text)
    result = runner.invoke(app, ["check", str(bad)])
    assert result.exit_code == 2
    line = line_of(text, 'id="sc5"')
    assert f"line {line}" in result.output and "<speedChange id='sc5'> @pos" in result.output


def test_check_any_format():
    for path in (DATA / "testline_railml2.xml", DATA / "testline_csv", DATA / "testline_route.yaml"):
        result = runner.invoke(app, ["check", str(path)])
        assert result.exit_code == 0, result.output
    assert (
        "not read: <ocsElements>" in runner.invoke(app, ["check", str(DATA / "testline_railml2.xml")]).output
    )


def test_export_results(tmp_path):
    result = runner.invoke(
        app, ["export-results", str(DATA / "testline_csv"), "--out", str(tmp_path), "--format", "csv,parquet"]
    )
    assert result.exit_code == 0, result.output
    figures = json.loads(result.output.splitlines()[0])
    assert figures["running_time_s"] > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "summary.csv",
        "summary.parquet",
        "trace.csv",
        "trace.parquet",
    ]
    result = runner.invoke(
        app, ["export-results", str(DATA / "testline_csv"), "--out", str(tmp_path), "--format", "xls"]
    )
    assert result.exit_code == 2


@pytest.mark.parametrize(
    "name,extra",
    [
        ("testline_railml2.xml", []),
        ("testline_railml3.xml", ["--curve-formula", "roeckl", "--tunnel-formula", "wang"]),
    ],
)
def test_runtimes(tmp_path, name, extra):
    out = tmp_path / "with_times.xml"
    result = runner.invoke(app, ["runtimes", str(DATA / name), str(out), *extra])
    assert result.exit_code == 0, result.output
    assert "calculated" in out.read_text()


@pytest.mark.parametrize(
    ("name", "old", "new", "element"),
    [
        (
            "testline_railml2.xml",
            '<ocpTT ocpRef="ocpB" sequence="2"',
            '<ocpTT ocpRef="ocpB" sequence="1,5"',
            "<ocpTT> @sequence",
        ),
        (
            "testline_railml3.xml",
            '<baseItineraryPoint id="bp1" locationRef="opA">',
            '<baseItineraryPoint id="bp1" locationRef="opA" sequence="1,5">',
            "<baseItineraryPoint id='bp1'> @sequence",
        ),
    ],
)
def test_check_names_a_sequence_that_is_not_a_whole_number(tmp_path, name, old, new, element):
    # issue 13: "1,5" was sorted as 0 and the route then failed with "no way from ... to ...", which
    # names the wrong thing
    text = railml(name, **{old: new})
    bad = tmp_path / "bad.xml"
    bad.write_text(text)
    result = runner.invoke(app, ["check", str(bad)])
    assert result.exit_code == 2, result.output
    assert element in result.output and "'1,5'" in result.output, result.output
    assert f"line {line_of(text, new)}" in result.output
