"""How the railML and spreadsheet readers read what they read: speed changes and their end,
directions, paths through the network, timetables, rolling stock variants, what is not read."""

from __future__ import annotations

import pytest
from interchange_cases import DATA, FORMULAS, line_of, railml, run

from trainsim.constants import KMH
from trainsim.io import convert, railml2, railml3, spreadsheet
from trainsim.io import railml_common as rc

DAVIS = (
    '<trainResistance daviesFactorA="2000" daviesFactorB="20" daviesFactorC="0.4" '
    'daviesMassDependent="false"/>'
)
COACH = (
    '<vehicle id="v_coach" name="Coach" length="25" speed="140" tareWeight="40" bruttoWeight="45" '
    'numberNonDrivenAxles="4">'
)


def _write(tmp_path, text: str):
    path = tmp_path / "variant.xml"
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------- railML 2 line data
def test_speed_restriction_end_and_direction():
    content = railml2.read_railml2(DATA / "testline_railml2.xml")
    limits = [(x["from_m"], x["limit_kmh"]) for x in content.route["speed_limits"]]
    # sc3 'end' restores 100 km/h; sc6 (dir down, 40 km/h) does not apply to this up run
    assert limits == [(1000, 100), (3000, 60), (3600, 100), (7000, 80)]
    assert any("<speedChange id='sc4'>" in x and "speed profile" in x for x in content.ignored)


def test_virtual_end_speed_before_railml_23(tmp_path):
    text = railml("testline_railml2.xml", **{'vMax="end"': 'vMax="999.9"'})
    content = railml2.read_railml2(_write(tmp_path, text))
    assert [x["limit_kmh"] for x in content.route["speed_limits"]] == [100, 60, 100, 80]
    assert any("999.9 read as the end of a temporary restriction" in n for n in content.notes)


def test_reverse_path_with_undirected_changes(tmp_path, yaml_train):
    """Speed changes without direction are the track's limits both ways; a train running towards
    decreasing positions sees every gradient with the other sign."""
    text = railml(
        "testline_railml2.xml",
        **{
            '"sc1" pos="0" dir="up"': '"sc1" pos="0"',
            '"sc2" pos="2000" dir="up"': '"sc2" pos="2000"',
            '"sc3" pos="2600" dir="up"': '"sc3" pos="2600"',
            '"sc5" pos="1000" dir="up"': '"sc5" pos="0"',
        },
    )
    content = railml2.read_railml2(_write(tmp_path, text), ocps=["Dunmore", "Bexley", "ocpA"])
    route = rc.build_route(content)
    # from the end of track 2 (route origin 0, no mileage for a reverse path) back to track 1's begin
    assert (route.start_m, route.end_m) == (0.0, 9000.0)
    assert [(s.name, s.position_m) for s in route.stations] == [
        ("Dunmore", 200.0),
        ("Bexley", 6000.0),
        ("Aford", 8800.0),
    ]
    limits = [(x.start_m, x.end_m, x.limit_mps / KMH) for x in route.speed_limits]
    # sc6 (dir down, 40 km/h) applies to this run from its position on
    expected = [(0, 2000, 80), (2000, 4000, 40), (4000, 6400, 100), (6400, 7000, 60), (7000, 9000, 100)]
    # flat lists: pytest.approx does not compare nested structures
    assert [x for row in limits for x in row] == pytest.approx([x for row in expected for x in row])
    grades = {(g.start_m, g.end_m): g.gradient_permille for g in route.gradients}
    assert grades == {(1500, 4000): -2.0, (4000, 5500): 3.0, (5500, 7500): -5.0}
    assert content.notes[0] == "route from the operational points given: a stop at each, dwell 0 s"
    assert run(yaml_train, route).status == "ok"


def test_path_through_a_switch(tmp_path):
    """The shunting train part runs from Bexley onto the siding through switch sw1."""
    content = railml2.read_railml2(DATA / "testline_railml2.xml", train_id="S 9", formation_id="f_ic")
    route = rc.build_route(content)
    assert content.figures["route path"] == "tr1 (0..4800 m) -> tr3 (0..800 m)"
    assert [(s.name, s.position_m) for s in route.stations] == [("Bexley", 4000.0), ("Siding end", 6400.0)]
    assert route.speed_limits[-1].limit_mps == pytest.approx(30 * KMH)


def test_train_choice_and_names():
    content = railml2.read_railml2(DATA / "testline_railml2.xml", train_id="t_ic1")
    assert content.route["name"] == "IC 1 path"
    assert not any("trains in the timetable" in n for n in content.notes)
    with pytest.raises(Exception, match="no train or train part of that id, number or name"):
        railml2.read_railml2(DATA / "testline_railml2.xml", train_id="nope")


def test_dwell_from_scheduled_times(tmp_path):
    """Without stopTimes the dwell is the scheduled departure - arrival."""
    text = railml(
        "testline_railml2.xml", **{'<stopDescription><stopTimes minimalTime="PT30S"/></stopDescription>': ""}
    )
    text = text.replace(
        'arrival="08:03:00" departure="08:03:30"', 'arrival="08:03:00" departure="08:03:45.5"'
    )
    content = railml2.read_railml2(_write(tmp_path, text))
    assert content.route["stations"][1]["dwell_s"] == 45.5


# ---------------------------------------------------------------------- railML 2 rolling stock
def test_rolling_stock_variants(tmp_path, yaml_train):
    """Deceleration tables, vehicle families, Strahl and tabulated resistance."""
    text = railml(
        "testline_railml2.xml",
        **{
            '<trainBrakes meanDeceleration="0.6" brakeType="compressedAir"/>': (
                '<trainBrakeOperation ts:tableIs="full">\n'
                "          <decelerationTable>\n"
                '            <valueTable xValueName="speed" xValueUnit="km/h" yValueName="deceleration"'
                ' yValueUnit="m/s^2">\n'
                '              <valueLine xValue="0"><values yValue="0.9"/></valueLine>\n'
                '              <valueLine xValue="120"><values yValue="0.7"/></valueLine>\n'
                "            </valueTable>\n"
                "          </decelerationTable>\n"
                "        </trainBrakeOperation>"
            ),
            DAVIS: ('<trainResistance strahlFactor="0.03" tunnelFactor="1.5"/>'),
            COACH: ('<vehicle id="v_coach" name="Coach" vehicleFamilyRef="v_family" bruttoWeight="45">'),
            "    </vehicles>": (
                '      <vehicle id="v_family" name="Coach family" length="25" speed="140" tareWeight="40"'
                ' numberNonDrivenAxles="4"/>\n'
                "    </vehicles>"
            ),
        },
    )
    content = railml2.read_railml2(_write(tmp_path, text))
    train = rc.build_train(content)
    assert train.mass_kg == yaml_train.mass_kg and train.length_m == yaml_train.length_m
    # full braking table, 0.75 of it in service (source 000), force = deceleration x inertial mass
    assert train.braking.service_force(0.0) == pytest.approx(0.75 * 0.9 * train.inertial_mass_kg)
    assert train.braking.full_force(120 * KMH) == pytest.approx(0.7 * train.inertial_mass_kg)
    # Strahl: w = 2.5 + k (V/10)^2 per mille of the weight
    v = 100 * KMH
    assert train.running_resistance_n(v) == pytest.approx((2.5 + 0.03 * 100) / 1000 * train.mass_kg * 9.80665)
    assert any("tunnelFactor not used" in n for n in content.notes)


def test_resistance_table_fitted(tmp_path):
    speeds = [0, 40, 80, 120]
    lines = "".join(
        f'<valueLine xValue="{v}"><values yValue="{2 + 0.02 * v + 0.0004 * v * v:.6f}"/></valueLine>'
        for v in speeds
    )
    text = railml(
        "testline_railml2.xml",
        **{
            DAVIS: (
                "<trainResistance>"
                '<valueTable xValueName="speed" xValueUnit="km/h" yValueName="resistance" yValueUnit="kN">'
                f"{lines}</valueTable>"
                "</trainResistance>"
            )
        },
    )
    content = railml2.read_railml2(_write(tmp_path, text))
    davis = content.train["resistance"][0]
    assert davis["a_n"] == pytest.approx(2000, rel=1e-6)
    assert davis["b_n_s_per_m"] == pytest.approx(72, rel=1e-6)
    assert davis["c_n_s2_per_m2"] == pytest.approx(5.184, rel=1e-6)
    assert any("fitted with A + B v + C v^2" in n for n in content.notes)


# ---------------------------------------------------------------------- railML 3
def test_railml3_follows_train_references():
    content = railml3.read_railml3(DATA / "testline_railml3.xml", train_id="IC 1", line_resistance=FORMULAS)
    assert content.route["name"] == "IC 1 path"
    assert content.train["name"] == "Test IC"  # formation f_ic, reached through the train variant
    assert [s["dwell_s"] for s in content.route["stations"]] == [0.0, 30.0, 0.0, 0.0]  # operational times
    assert [s["stop"] for s in content.route["stations"]] == [True, True, False, True]


def test_railml3_other_itinerary_and_formation():
    content = railml3.read_railml3(
        DATA / "testline_railml3.xml",
        train_id="bi_shunt",
        formation_id="f_shunter",
        line_resistance=FORMULAS,
        rotating_mass_factor=1.1,
    )
    assert content.figures["route path"] == "ne1 (0..5000 m) -> ne3 (0..800 m)"
    assert content.train["formation"][0]["name"] == "Loco"
    assert content.train["rotating_mass_factor"] == 1.1
    train = rc.build_train(content)
    # resistance given in N/kN of the train's weight at 0, 40, 80 km/h: 2 + 0.00025 V^2 (fitted exactly)
    expected = (2 + 0.00025 * 72**2) / 1000 * 80_000 * 9.80665
    assert train.running_resistance_n(20.0) == pytest.approx(expected, rel=1e-9)


def test_railml3_reverse_direction_speed_sections(tmp_path):
    """A reverse-direction speed section applies to trains running the other way only."""
    content = railml3.read_railml3(
        DATA / "testline_railml3.xml", ocps=["opD", "opB"], line_resistance=FORMULAS
    )
    limits = [(x["from_m"], x["limit_kmh"]) for x in content.route["speed_limits"]]
    # the reverse path from ne2's end back to ne1's begin: the 'reverse' sections sps5, sps7 only
    assert limits == [(0.0, 40.0), (4000.0, 70.0)]
    assert content.route["stations"][0]["position_m"] == 200.0


# ---------------------------------------------------------------------- check and ignored
def test_check_report_lists_what_was_not_read():
    report = convert.check_file(DATA / "testline_railml2.xml")
    text = report.to_text()
    assert report.kind == "train and route"
    assert "railML 2.4" in text
    line = line_of((DATA / "testline_railml2.xml").read_text(), "<ocsElements>")
    assert f"not read: <ocsElements> at line {line}, 2 element(s) inside" in text
    assert "train mass                     260.0 t" in text
    assert "route stations" in text and "Carnforth @ 6500 m (no stop)" in text


def test_check_without_formulas_says_so():
    report = convert.check_file(DATA / "testline_railml3.xml")
    assert any("no line-resistance formulas in the file" in n for n in report.notes)


def test_spreadsheet_train_only_and_source_002_tables(tmp_path):
    """A train workbook laid out like source 002's tables 2-4 (per-motor traction, negative braking
    forces, gamma) reads as examples/metro_b/train.yaml."""
    import openpyxl

    import trainsim

    book = openpyxl.Workbook()
    ws = book.active
    ws.title = "train"
    for row in (
        ["Parameter name", "Variable"],
        ["Name", "Type B metro"],
        ["Designed max speed (km/h)", 80],
        ["Rotary mass coefficient", 0.2],
        ["Basic resistance parameter 1 (kN)", 2.43],
        ["Basic resistance parameter 2 (kN/(km/h))", 0.02997],
        ["Basic resistance parameter 3 (kN/(km/h)^2)", 0.00078],
        ["Traction motors", 4],
        ["Braking table is", "service"],
        ["Working voltage (V)", 1000],
        ["Energy conversion efficiency", 0.98],
        ["Regenerative efficiency", 0.98],
        ["Power factor", 0.95],
    ):
        ws.append(row)
    ws = book.create_sheet("vehicles")
    for row in (
        ["Name", "Count", "Mass (kg)", "Length (m)", "Axles", "Powered"],
        ["Mc", 4, 49800, 19, 4, "yes"],
        ["T", 2, 44500, 19, 4, "no"],
    ):
        ws.append(row)
    ws = book.create_sheet("traction")
    for row in (
        ["Velocity(km/h)", "Traction force (kN)"],
        [0, 93.25],
        [42, 93.25],
        [50, 83.75],
        [60, 70],
        [70, 59.5],
        [80, 45],
    ):
        ws.append(row)
    ws = book.create_sheet("braking")
    for row in (
        ["Velocity (km/h)", "Braking force (kN)"],
        [0, -150],
        [5, -150],
        [6, -335],
        [64.5, -335],
        [80, -275],
    ):
        ws.append(row)
    path = tmp_path / "metro.xlsx"
    book.save(path)
    content = spreadsheet.read_spreadsheet(path)
    assert content.route is None
    train = rc.build_train(content)
    metro = trainsim.load_train(DATA.parents[2] / "examples" / "metro_b" / "train.yaml")
    assert train.mass_kg == pytest.approx(metro.mass_kg)
    assert train.rotating_mass_factor == pytest.approx(metro.rotating_mass_factor)
    for v in (0.0, 10.0, 15.0, 22.0):
        assert train.traction(v) == pytest.approx(metro.traction(v))
        assert train.max_braking_n(v) == pytest.approx(metro.max_braking_n(v))
        assert train.running_resistance_n(v) == pytest.approx(metro.running_resistance_n(v))
    assert train.electrical == metro.electrical


def test_train_alone_needs_no_line_formulas(tmp_path):
    """Reading only the train of a railML 3 file does not ask for the route's formulas."""
    train = convert.detect_and_load(DATA / "testline_railml3.xml", "train")
    assert train.name == "Test IC"
    out, _ = convert.convert(DATA / "testline_railml3.xml", tmp_path / "train.yaml", kind="train")
    assert "schema: trainsim/train" in out.read_text()
