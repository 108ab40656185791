"""Units at the edge: quantities with units, suffixed field names, errors naming allowed units."""

from __future__ import annotations

import math

import pytest

from trainsim.errors import InputError
from trainsim.io.units import format_units, from_si, parse_quantity, split_suffix, to_si, to_unit


@pytest.mark.parametrize(
    ("text", "dimension", "si"),
    [
        ("80 km/h", "speed", 80 / 3.6),
        ("80km/h", "speed", 80 / 3.6),
        ("22.5 m/s", "speed", 22.5),
        ("49.8 t", "mass", 49800.0),
        ("49800 kg", "mass", 49800.0),
        ("1 MW", "power", 1.0e6),
        ("850 kW", "power", 850e3),
        ("4.5 ‰", "ratio", 0.0045),
        ("4.5 permille", "ratio", 0.0045),
        ("4.5 N/kN", "ratio", 0.0045),
        ("1.2 %", "ratio", 0.012),
        ("93.25 kN", "force", 93250.0),
        ("1.5 km", "length", 1500.0),
        ("2 min", "time", 120.0),
        ("0.375 m/s^2", "acceleration", 0.375),
        ("38.24 kWh", "energy", 38.24 * 3.6e6),
        ("25 kV", "voltage", 25000.0),
        ("-3.5 ‰", "ratio", -0.0035),
        ("1e3 kW", "power", 1.0e6),
    ],
)
def test_parse_quantity_to_si(text: str, dimension: str, si: float) -> None:
    assert parse_quantity(text, dimension) == pytest.approx(si, rel=1e-12)


def test_degrees_to_radians() -> None:
    assert parse_quantity("90 deg", "angle") == pytest.approx(math.pi / 2)


def test_bare_number_needs_a_unit_unless_one_is_given() -> None:
    with pytest.raises(InputError, match="without unit") as err:
        parse_quantity(80, "speed", field="max_speed")
    assert err.value.field == "max_speed"
    assert "km/h" in str(err.value)
    assert parse_quantity(80, "speed", bare_unit="km/h") == pytest.approx(80 / 3.6)


def test_unknown_unit_names_the_allowed_ones() -> None:
    with pytest.raises(InputError) as err:
        parse_quantity("80 furlong/fortnight", "speed", field="speed", file="t.yaml")
    text = str(err.value)
    assert "unknown unit 'furlong/fortnight'" in text
    assert "km/h" in text and "m/s" in text
    assert "t.yaml" in text
    assert "kWh" not in text  # only the units of the expected quantity are listed


def test_unit_of_another_quantity_is_refused() -> None:
    with pytest.raises(InputError, match="unit of mass, this field is a speed"):
        parse_quantity("80 t", "speed")


def test_case_matters_for_units() -> None:
    # mW would be milliwatt: refused rather than read as MW.
    with pytest.raises(InputError, match="unknown unit 'mW'"):
        parse_quantity("1 mW", "power")


@pytest.mark.parametrize("bad", ["fast", "", "km/h", True, None, [80]])
def test_malformed_quantities(bad: object) -> None:
    with pytest.raises(InputError):
        parse_quantity(bad, "speed")


def test_to_unit_and_back() -> None:
    assert to_unit("1 MW", "kW") == pytest.approx(1000.0)
    assert to_unit(49.8, "t") == 49.8
    assert to_unit("4.5 permille", "‰") == pytest.approx(4.5)
    assert to_si(80, "km/h") == pytest.approx(22.2222222)
    assert from_si(to_si(80, "km/h"), "km/h") == pytest.approx(80)


def test_split_suffix() -> None:
    assert split_suffix("max_speed_kmh") == ("max_speed", "km/h")
    assert split_suffix("mass_t") == ("mass", "t")
    assert split_suffix("gradient_permille") == ("gradient", "‰")
    assert split_suffix("deceleration_mps2") == ("deceleration", "m/s^2")
    assert split_suffix("gamma") is None
    assert split_suffix("b_kn_per_kmh") is None  # compound units have no generic form


def test_format_units_lists_spellings() -> None:
    text = format_units("ratio")
    assert "‰" in text and "permille" in text and "%" in text
