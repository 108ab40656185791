"""railML files and tables with errors give errors naming the element (or cell) and its line."""

from __future__ import annotations

import shutil

import pytest
from interchange_cases import DATA, FORMULAS, line_of, railml

from trainsim.errors import InputError
from trainsim.io import convert, railml2, railml3, spreadsheet


def _write(tmp_path, text: str, name: str = "bad.xml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------- missing positions
def test_railml2_missing_position(tmp_path):
    text = railml("testline_railml2.xml", **{'<speedChange id="sc2" pos="2000"': '<speedChange id="sc2"'})
    with pytest.raises(InputError) as err:
        railml2.read_railml2(_write(tmp_path, text))
    message = str(err.value)
    assert "<speedChange id='sc2'>" in message
    assert "@pos" in message
    line = line_of(text, 'id="sc2"')
    assert f"line {line}" in message
    assert err.value.line == line_of(text, 'id="sc2"')
    assert "missing position on the track [m]" in message


def test_railml2_missing_track_end_position(tmp_path):
    text = railml("testline_railml2.xml", **{'<trackEnd id="tr2_e" pos="4000"': '<trackEnd id="tr2_e"'})
    with pytest.raises(
        InputError, match=r"line \d+.*<trackEnd id='tr2_e'> @pos.*missing position of the track end"
    ):
        railml2.read_railml2(_write(tmp_path, text))


def test_railml2_position_outside_track(tmp_path):
    text = railml(
        "testline_railml2.xml",
        **{'ocpRef="ocpD" pos="3800"': 'ocpRef="ocpD" pos="4800"'},
    )
    with pytest.raises(InputError) as err:
        railml2.read_railml2(_write(tmp_path, text))
    assert "<crossSection id='cs4'>" in str(err.value)
    assert "position outside its track" in str(err.value)
    assert err.value.line == line_of(text, 'id="cs4"')


def test_railml3_missing_position(tmp_path):
    text = railml(
        "testline_railml3.xml",
        **{'posBegin="1500" posEnd="3500"': 'posEnd="3500"'},
    )
    with pytest.raises(InputError) as err:
        railml3.read_railml3(_write(tmp_path, text), line_resistance=FORMULAS)
    message = str(err.value)
    assert "<associatedNetElement>" in message
    assert "missing position of the begin (posBegin, intrinsicCoordBegin or linearCoordinateBegin)" in message
    assert err.value.line == line_of(text, 'posEnd="3500"')


def test_railml3_operational_point_without_position(tmp_path):
    text = railml(
        "testline_railml3.xml",
        **{'applicationDirection="both" pos="3800"/>': 'applicationDirection="both"/>'},
    )
    with pytest.raises(InputError) as err:
        railml3.read_railml3(_write(tmp_path, text), line_resistance=FORMULAS)
    assert "<spotLocation id='opD_sl'>" in str(err.value)
    assert err.value.line == line_of(text, 'id="opD_sl"')


# ---------------------------------------------------------------------- overlapping sections
def test_railml3_overlapping_speed_sections(tmp_path):
    text = railml(
        "testline_railml3.xml",
        **{'posBegin="2000" posEnd="2600"': 'posBegin="1900" posEnd="2600"'},
    )
    with pytest.raises(InputError) as err:
        railml3.read_railml3(_write(tmp_path, text), line_resistance=FORMULAS)
    message = str(err.value)
    assert "<speedSection id='sps2'>" in message
    line = line_of(text, 'id="sps1"')
    assert f"overlaps <speedSection id='sps1'> (line {line})" in message
    assert err.value.line == line_of(text, 'id="sps2"')
    assert "2900 m and 3000 m of the route" in message


def test_railml3_overlapping_gradient_curves(tmp_path):
    text = railml(
        "testline_railml3.xml", **{'posBegin="2500" posEnd="4000"': 'posBegin="2400" posEnd="4000"'}
    )
    with pytest.raises(
        InputError,
        match=r"field '<gradientCurve id='gc5'>': this gradient curve overlaps <gradientCurve id='gc4'>",
    ):
        railml3.read_railml3(_write(tmp_path, text), line_resistance=FORMULAS)


def test_railml2_overlapping_tunnels(tmp_path):
    text = railml(
        "testline_railml2.xml",
        **{'length="500" crossSection="60"/>': 'length="500"/>\n<tunnel id="tn1b" pos="4600" length="300"/>'},
    )
    with pytest.raises(InputError) as err:
        railml2.read_railml2(_write(tmp_path, text))
    assert "field '<tunnel id='tn1b'>': this tunnel overlaps <tunnel id='tn1'>" in str(err.value)
    assert err.value.line == line_of(text, 'id="tn1b"')


def test_railml2_conflicting_changes_at_one_position(tmp_path):
    text = railml(
        "testline_railml2.xml",
        **{'slope="-3"/>': 'slope="-3"/>\n<gradientChange id="gc3b" pos="3500" slope="4"/>'},
    )
    with pytest.raises(
        InputError,
        match=r"field '<gradientChange id='gc3b'> @pos': two gradientChange elements at the same position",
    ):
        railml2.read_railml2(_write(tmp_path, text))


# ---------------------------------------------------------------------- unknown units
def test_railml2_unknown_unit(tmp_path):
    text = railml(
        "testline_railml2.xml",
        **{'yValueName="tractiveEffort" yValueUnit="kN"': 'yValueName="tractiveEffort" yValueUnit="lbf"'},
    )
    with pytest.raises(InputError) as err:
        railml2.read_railml2(_write(tmp_path, text))
    message = str(err.value)
    assert "field '<valueTable> @yValueUnit': unknown unit 'lbf'" in message
    assert err.value.line == line_of(text, 'yValueUnit="lbf"')
    assert "allowed: force: N, kN" in message


def test_railml3_wrong_kind_of_unit(tmp_path):
    text = railml(
        "testline_railml3.xml",
        **{'yValueName="brakeEffort" yValueUnit="kN"': 'yValueName="brakeEffort" yValueUnit="km/h"'},
    )
    with pytest.raises(InputError, match=r"'km/h' is a unit of speed, expected force"):
        railml3.read_railml3(_write(tmp_path, text), line_resistance=FORMULAS)


def test_railml3_unknown_positioning_unit(tmp_path):
    text = railml("testline_railml3.xml", **{'units="m"': 'units="mi"'})
    with pytest.raises(
        InputError, match=r"field '<linearPositioningSystem id='lps1'> @units': unknown unit 'mi'"
    ):
        railml3.read_railml3(_write(tmp_path, text), line_resistance=FORMULAS)


# ---------------------------------------------------------------------- other problems
def test_several_problems_are_reported_together(tmp_path):
    text = railml(
        "testline_railml2.xml",
        **{
            '<speedChange id="sc2" pos="2000"': '<speedChange id="sc2"',
            'pos="1400" radius="0"': 'pos="1400" radius="flat"',
        },
    )
    with pytest.raises(InputError) as err:
        railml2.read_railml2(_write(tmp_path, text))
    message = str(err.value)
    assert message.count(" problems: ") == 1
    assert (
        "<speedChange id='sc2'> @pos" in message
        and "field '<radiusChange id='rc2'> @radius': not a number" in message
    )
    fields = [p.field for p in err.value.problems]
    assert "<radiusChange id='rc2'> @radius" in fields and all(p.line for p in err.value.problems)


def test_malformed_xml_names_the_line(tmp_path):
    text = railml(
        "testline_railml2.xml", **{'<ocp id="ocpC" name="Carnforth">': '<ocp id="ocpC" name="Carnforth>'}
    )
    with pytest.raises(InputError, match=r"line \d+: malformed XML"):
        convert.read_content(_write(tmp_path, text), "railml2")


def test_unknown_ocp_reference(tmp_path):
    text = railml("testline_railml2.xml", **{'<ocpTT ocpRef="ocpC"': '<ocpTT ocpRef="ocpX"'})
    with pytest.raises(InputError, match=r"field '<ocpTT> @ocpRef': ocpRef to an unknown ocp \(got 'ocpX'\)"):
        railml2.read_railml2(_write(tmp_path, text))


def test_disconnected_tracks(tmp_path):
    text = railml("testline_railml2.xml", **{'<connection id="c2" ref="c1"/>': '<openEnd id="tr2_oe"/>'})
    with pytest.raises(InputError, match=r"no way from 'Bexley' to 'Carnforth' through the network"):
        railml2.read_railml2(_write(tmp_path, text))


def test_missing_line_resistance_formulas():
    with pytest.raises(InputError, match=r"railML does not say which curve and tunnel resistance formulas"):
        railml3.read_railml3(DATA / "testline_railml3.xml")


def test_speed_restriction_end_without_restriction(tmp_path):
    text = railml("testline_railml2.xml", **{'<speedChange id="sc2" pos="2000" dir="up" vMax="60"/>': ""})
    with pytest.raises(
        InputError,
        match=r"field '<speedChange id='sc3'>': end of a speed restriction \('end'\) with no restriction",
    ):
        railml2.read_railml2(_write(tmp_path, text))


def test_missing_rotating_mass_factor(tmp_path):
    text = railml("testline_railml2.xml", **{'<wagon rotationMassFactor="1.04"': "<wagon"})
    with pytest.raises(InputError) as err:
        railml2.read_railml2(_write(tmp_path, text))
    assert "rotating mass factor is missing for vehicle(s) Coach" in str(err.value)
    assert err.value.line == line_of(text, '<formation id="f_ic"')
    # the train's factor given instead
    content = railml2.read_railml2(_write(tmp_path, text), rotating_mass_factor=1.06)
    assert content.train["rotating_mass_factor"] == 1.06


def test_error_after_reading_points_at_the_source(tmp_path):
    """A problem trainsim's validation finds later (a limit of 800 km/h) names the element it came from."""
    from trainsim.io import railml_common as rc

    text = railml("testline_railml2.xml", **{'vMax="80"/>': 'vMax="800"/>'})
    content = railml2.read_railml2(_write(tmp_path, text))
    with pytest.raises(InputError) as err:
        rc.build_route(content)
    assert "speed_limits[3].limit_kmh" in str(err.value)
    line = line_of(text, 'id="sc5"')
    assert f"read from <speedChange id='sc5'> at line {line}" in str(err.value)


# ---------------------------------------------------------------------- spreadsheets
def _tables(tmp_path):
    folder = tmp_path / "tables"
    shutil.copytree(DATA / "testline_csv", folder)
    return folder


def test_spreadsheet_unknown_unit(tmp_path):
    folder = _tables(tmp_path)
    f = folder / "traction.csv"
    f.write_text(f.read_text().replace("Traction force (kN)", "Traction force (lbf)"))
    with pytest.raises(InputError) as err:
        spreadsheet.read_spreadsheet(folder)
    assert str(err.value).startswith(
        f"{f}, line 1, field 'traction!B1 ('Traction force (lbf)')': unknown unit 'lbf'"
    )


def test_spreadsheet_column_without_unit(tmp_path):
    folder = _tables(tmp_path)
    f = folder / "sections.csv"
    f.write_text(f.read_text().replace("Track speed (km/h)", "Track speed"))
    with pytest.raises(InputError, match=r"sections!D1 .*this column needs its unit in the header"):
        spreadsheet.read_spreadsheet(folder)


def test_spreadsheet_bad_cell(tmp_path):
    folder = _tables(tmp_path)
    f = folder / "vehicles.csv"
    f.write_text(f.read_text().replace("Coach,4,40,5", "Coach,4,forty,5"))
    with pytest.raises(InputError) as err:
        spreadsheet.read_spreadsheet(folder)
    assert "vehicles!C3" in str(err.value) and "not a number (got 'forty')" in str(err.value)
    assert err.value.line == 3


def test_spreadsheet_unknown_column_and_parameter(tmp_path):
    folder = _tables(tmp_path)
    f = folder / "stations.csv"
    f.write_text(f.read_text().replace("Stop\n", "Platform\n", 1))
    with pytest.raises(InputError, match=r"stations!D1 \('Platform'\)': unknown column"):
        spreadsheet.read_spreadsheet(folder)
    folder = _tables(tmp_path / "b")
    f = folder / "train.csv"
    f.write_text(f.read_text() + "Colour,red\n")
    with pytest.raises(InputError, match=r"train!A12': unknown parameter"):
        spreadsheet.read_spreadsheet(folder)


def test_spreadsheet_gap_in_sections_names_the_row(tmp_path):
    folder = _tables(tmp_path)
    f = folder / "sections.csv"
    f.write_text(f.read_text().replace("3,2400,100,", "3,2450,50,"))
    with pytest.raises(InputError) as err:
        from trainsim.io import railml_common as rc

        rc.build_route(spreadsheet.read_spreadsheet(folder))
    assert "gap in speed_limits" in str(err.value)
    assert "sections.csv, row 2" in str(err.value)
