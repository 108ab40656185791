"""Power-file fields of the regulation curves, the AC reversible flag and EN 50163 limits."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.power_file import load_power_file
from trainsim.power.limits import EN50163, standard_limits

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples" / "power"
METRO = (EXAMPLES / "metro_scenario.yaml").as_posix()


def _file(tmp_path: Path, substation: dict) -> Path:
    doc = yaml.safe_load((EXAMPLES / "metro_750v_diode.yaml").read_text())
    doc["trains"] = [
        {"id": "up", "scenario": METRO, "track": "up", "origin_km": 0, "direction": 1, "departures_s": [0]}
    ]
    doc["network"]["substations"][0] = {**doc["network"]["substations"][0], **substation}
    path = tmp_path / "power.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_regulation_curve_sets_e_and_r(tmp_path):
    curve = [[0, 850], [2000, 830], [6000, 750]]
    path = _file(tmp_path, {"regulation": curve})
    doc = yaml.safe_load(path.read_text())
    del doc["network"]["substations"][0]["no_load_voltage_v"]
    del doc["network"]["substations"][0]["internal_resistance_ohm"]
    path.write_text(yaml.safe_dump(doc))
    _, net, _ = load_power_file(path)
    s = net.substations[0]
    assert s.no_load_voltage_v == 850.0
    assert s.internal_resistance_ohm == pytest.approx(0.01, rel=1e-12)
    assert s.regulation == ((0.0, 850.0), (2000.0, 830.0), (6000.0, 750.0))


@pytest.mark.parametrize(
    ("substation", "words"),
    [
        ({"regulation": [[0, 850], [2000, 830]]}, "not both"),
        ({"no_load_voltage_v": None, "internal_resistance_ohm": None}, "or a regulation curve"),
    ],
)
def test_bad_substation_sources(tmp_path, substation, words):
    path = _file(tmp_path, {k: v for k, v in substation.items() if v is not None})
    if substation.get("no_load_voltage_v", 0) is None:
        doc = yaml.safe_load(path.read_text())
        del doc["network"]["substations"][0]["no_load_voltage_v"]
        del doc["network"]["substations"][0]["internal_resistance_ohm"]
        path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError, match=words) as info:
        load_power_file(path)
    assert info.value.problems[0].field == "network.substations[0]"
    assert info.value.problems[0].file == str(path)


def test_unsorted_regulation_curve_names_the_substation(tmp_path):
    path = _file(tmp_path, {"regulation": [[2000, 830], [100, 850]]})
    doc = yaml.safe_load(path.read_text())
    del doc["network"]["substations"][0]["no_load_voltage_v"]
    del doc["network"]["substations"][0]["internal_resistance_ohm"]
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError, match="current 0") as info:
        load_power_file(path)
    assert info.value.problems[0].field == "network.substations[0].regulation"


def test_en50163_table():
    """EN 50163:2004+A1:2007 / IEC 60850:2014 Table 1 (Umin2, Umin1, Un, Umax1, Umax2, Umax3) [V],
    typed here from the table and checked against the rules the table follows: Umin1 = Umin2 for
    DC, Umax1 = 1.2 Un for DC (1.1 for AC except 15 kV: 1.15), ordered limits."""
    table = {
        "dc_600": (400, 400, 600, 720, 800, 1015),
        "dc_750": (500, 500, 750, 900, 1000, 1270),
        "dc_1500": (1000, 1000, 1500, 1800, 1950, 2540),
        "dc_3000": (2000, 2000, 3000, 3600, 3900, 5075),
        "ac_15000": (11000, 12000, 15000, 17250, 18000, 24300),
        "ac_25000": (17500, 19000, 25000, 27500, 29000, 38750),
    }
    assert {k: tuple(float(x) for x in v) for k, v in table.items()} == EN50163
    for name, values in EN50163.items():
        assert list(values) == sorted(values)
        lim = standard_limits(name)
        assert (lim.min2_v, lim.min1_v, lim.nominal_v, lim.max1_v, lim.max2_v, lim.max3_v) == values
        if name.startswith("dc"):
            assert values[0] == values[1]
            assert values[3] == pytest.approx(1.2 * values[2])
    assert EN50163["ac_25000"][3] == pytest.approx(1.1 * 25000)
    assert EN50163["ac_15000"][3] == pytest.approx(1.15 * 15000)


def test_max3_below_max2_is_an_error():
    with pytest.raises(InputError, match="max3_v"):
        standard_limits("dc_750").with_overrides(max3_v=990.0)
