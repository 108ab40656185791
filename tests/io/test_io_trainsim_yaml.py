"""trainsim's own YAML formats: the examples load with the figures of their sources, and bad input
gives one InputError naming file, line and field path."""

from __future__ import annotations

import copy
import math
import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.trainsim_yaml import (
    dump_yaml,
    load_route_yaml,
    load_scenario_yaml,
    load_train_yaml,
    read_train_spec,
    route_from_dict,
    scenario_from_dict,
    train_from_dict,
    train_spec_from_dict,
)

G = 9.80665  # standard gravity, the default of trainsim files (trainsim.constants.STANDARD_GRAVITY)
KMH = 1 / 3.6


def _yaml(path: Path) -> dict[str, Any]:
    return yaml.safe_load(path.read_text(encoding="utf-8"))


@pytest.fixture
def metro(examples_dir: Path) -> dict[str, Any]:
    return _yaml(examples_dir / "metro_b" / "train.yaml")


@pytest.fixture
def metro_route(examples_dir: Path) -> dict[str, Any]:
    return _yaml(examples_dir / "metro_b" / "route.yaml")


def _error(data: dict[str, Any], source: str = "bad.yaml") -> InputError:
    with pytest.raises(InputError) as err:
        train_from_dict(data, source)
    return err.value


# ====================================================================== examples
def test_metro_b_train_is_source_002(examples_dir: Path) -> None:
    train = load_train_yaml(examples_dir / "metro_b" / "train.yaml")
    # Table 2: 4 x 49.8 t + 2 x 44.5 t; gamma 0.2; 80 km/h.
    assert train.mass_kg == pytest.approx(4 * 49800 + 2 * 44500)
    assert train.rotating_mass_factor == pytest.approx(1.2)
    assert train.max_speed_mps == pytest.approx(80 * KMH)
    assert train.length_m == pytest.approx(6 * 19.0)
    assert len(train.vehicles) == 6 and sum(v.powered for v in train.vehicles) == 4
    # Table 3 per motor car x 4 motor cars (eq. 2), interpolated linearly (eq. 1).
    assert train.max_traction_n(0.0) == pytest.approx(4 * 93.25e3)
    assert train.max_traction_n(46 * KMH) == pytest.approx(4 * (93.25 + (83.75 - 93.25) * 4 / 8) * 1e3)
    assert train.max_traction_n(80 * KMH) == pytest.approx(4 * 45e3)
    # Table 4, negative in the paper, service force as printed (table_is: service).
    assert train.braking.service_force is not None
    assert train.max_braking_n(3 * KMH) == pytest.approx(150e3)
    assert train.max_braking_n(30 * KMH) == pytest.approx(335e3)
    assert train.max_braking_n(72.25 * KMH) == pytest.approx(305e3)
    assert train.braking.full_force is None
    assert train.braking.regenerative is None
    # Davis in kN with V in km/h: 2.43 + 0.02997 V + 0.00078 V^2.
    v = 80.0
    assert train.running_resistance_n(v * KMH) == pytest.approx((2.43 + 0.02997 * v + 0.00078 * v * v) * 1e3)
    e = train.electrical
    assert e is not None
    assert (e.line_voltage_v, e.traction_efficiency, e.regenerative_efficiency, e.power_factor) == (
        1000,
        0.98,
        0.98,
        0.95,
    )
    assert e.auxiliary_power_w == 0


def test_metro_b_route_and_scenario(examples_dir: Path) -> None:
    route = load_route_yaml(examples_dir / "metro_b" / "route.yaml")
    assert route.length_m == pytest.approx(4590.97)
    assert [s.position_m for s in route.stations] == [0.0, 1600.68, 3139.8, 4590.97]
    assert [s.dwell_s for s in route.stations] == [0, 51, 49, 0]
    assert all(s.stop for s in route.stations)
    assert [(x.start_m, x.end_m, x.limit_mps) for x in route.speed_limits] == [
        (0, 4590.97, pytest.approx(80 * KMH))
    ]
    assert route.gradients == ()
    lr = route.line_resistance
    assert (lr.curve_formula, lr.tunnel_formula, lr.gradient_formula, lr.apply_over) == (
        "tbt1407",
        "tbt1407",
        "small_angle",
        "head",
    )
    scenario = load_scenario_yaml(examples_dir / "metro_b" / "scenario.yaml")
    assert scenario.train.mass_kg == pytest.approx(288200)
    assert scenario.route.length_m == pytest.approx(4590.97)
    assert scenario.settings.max_step_m == 5


def test_loco_001_train_is_source_001(examples_dir: Path) -> None:
    train = load_train_yaml(examples_dir / "loco_001" / "train.yaml")
    assert train.mass_kg == pytest.approx((72 + 12 * 42) * 1000)
    assert train.rotating_mass_factor == pytest.approx(1.1)
    assert train.adhesion_mass_kg == pytest.approx(72000)
    # Power-limited: min(mu m_adh g, eta P / v).
    assert train.max_traction_n(0.0) == pytest.approx(0.30 * 72000 * G)
    assert train.max_traction_n(100 * KMH) == pytest.approx(0.85 * 1e6 / (100 * KMH))
    # RAV: loco 6.5 M + 130 N_e + 0.1 M V + 0.3 V^2; carriages 12 x (12 M + 0.09 M V + 0.0044 M V^2).
    v = 100.0
    loco = 6.5 * 72 + 130 * 4 + 0.1 * 72 * v + 0.3 * v * v
    car = 12 * 42 + 0.09 * 42 * v + 0.0044 * 42 * v * v
    assert train.running_resistance_n(v * KMH) == pytest.approx(loco + 12 * car)
    assert loco == pytest.approx(4708)  # REFERENCE.md: 4.7 kN for 72 t, 4 axles at 100 km/h
    assert train.braking.deceleration_mps2 == pytest.approx(0.375)
    assert train.electrical is None
    route = load_route_yaml(examples_dir / "loco_001" / "route.yaml")
    assert route.length_m == 20000 and len(route.stations) == 2
    assert route.line_resistance.curve_formula == "french800"


def test_freight_000_train(examples_dir: Path) -> None:
    train = load_train_yaml(examples_dir / "freight_000" / "train.yaml")
    assert train.mass_kg == pytest.approx((2 * 138 + 50 * 80) * 1000)
    assert train.length_m == pytest.approx(2 * 22 + 50 * 14)
    assert train.max_speed_mps == pytest.approx(80 * KMH)
    # Piecewise: quadratic from 0, then constant power 9.6 MW from 36 km/h.
    assert train.max_traction_n(0.0) == pytest.approx(1040e3)
    assert train.max_traction_n(20 * KMH) == pytest.approx((1040 - 1.5 * 20 - 0.01 * 400) * 1e3)
    assert train.max_traction_n(60 * KMH) == pytest.approx(9.6e6 / (60 * KMH))
    # table_is: full -> service = 0.75 x full (source 000).
    assert train.braking.full_force is not None
    assert float(train.braking.full_force(0.0)) == pytest.approx(2200e3)
    assert train.max_braking_n(0.0) == pytest.approx(0.75 * 2200e3)
    assert train.max_braking_n(50 * KMH) == pytest.approx(0.75 * 1675e3)
    regen = train.braking.regenerative
    assert regen is not None and float(regen(0.0)) == pytest.approx(0.8 * 1040e3)
    # R_b = m (a1 + a2 v^2).
    v = 20.0
    assert train.running_resistance_n(v) == pytest.approx(train.mass_kg * (0.012 + 2.6e-5 * v * v))


def test_freight_000_route(examples_dir: Path) -> None:
    route = load_route_yaml(examples_dir / "freight_000" / "route.yaml")
    assert route.length_m == 60000
    assert [s.name for s in route.stations] == ["Aville", "Bburg", "Cstadt"]
    grades = [g.gradient_permille for g in route.gradients]
    assert max(grades) == 10 and min(grades) == -10
    assert route.gradients[0].start_m == 3000 and route.gradients[0].end_m == 8000
    assert [c.radius_m for c in route.curves] == [600, 280, 250, 450, 1200]
    assert route.curves[-1].end_m == 47800  # from length_m
    assert [(t.start_m, t.end_m, t.limiting_gradient) for t in route.tunnels] == [
        (10500, 12300, True),
        (37000, 37900, False),
    ]
    assert [(x.start_m, x.end_m) for x in route.speed_limits] == [(0, 11000), (11000, 12600), (12600, 60000)]
    assert route.electrification[0].voltage_v == 25000 and route.electrification[0].end_m == 60000
    lr = route.line_resistance
    assert (lr.curve_formula, lr.tunnel_formula, lr.gradient_formula, lr.apply_over) == (
        "wang",
        "wang",
        "exact",
        "train_length",
    )


@pytest.mark.parametrize("name", ["metro_b", "loco_001", "freight_000"])
def test_every_example_scenario_loads(examples_dir: Path, name: str) -> None:
    scenario = load_scenario_yaml(examples_dir / name / "scenario.yaml")
    assert scenario.train.mass_kg > 0 and scenario.route.length_m > 0
    assert len(scenario.route.stops) >= 2


# ====================================================================== format features
def test_generic_field_with_unit_equals_suffixed_field(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["formation"][1]["mass_t"]
    data["formation"][1]["mass"] = "44500 kg"
    data["max_speed"] = "80 km/h"
    del data["max_speed_kmh"]
    train = train_from_dict(data)
    assert train.mass_kg == pytest.approx(288200)
    assert train.max_speed_mps == pytest.approx(80 * KMH)


def test_gamma_and_rotating_mass_factor_are_the_same(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["gamma"]
    data["rotating_mass_factor"] = 1.2
    assert train_from_dict(data).rotating_mass_factor == pytest.approx(
        train_from_dict(metro).rotating_mass_factor
    )


def test_rotating_mass_factor_from_vehicles(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["gamma"]
    data["formation"][0]["rotating_mass_factor"] = 1.15
    data["formation"][1]["rotating_mass_factor"] = 1.05
    data["formation"][1]["load_t"] = 10
    train = train_from_dict(data)
    # Rotating parts add (xi - 1) x EMPTY mass of inertia.
    extra = 4 * 0.15 * 49800 + 2 * 0.05 * 44500
    assert train.rotating_mass_factor == pytest.approx(1 + extra / (288200 + 20000))


def test_whole_train_mass_instead_of_formation(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["formation"]
    data.update(mass_t=288.2, load_t=20, length_m=114, adhesion_mass_t=199.2)
    train = train_from_dict(data)
    assert train.mass_kg == pytest.approx(308200)
    assert train.length_m == 114 and train.vehicles == ()
    assert train.adhesion_mass_kg == pytest.approx(199200)


def test_vehicle_terms_equal_applies_to_terms(examples_dir: Path) -> None:
    data = _yaml(examples_dir / "loco_001" / "train.yaml")
    embedded = copy.deepcopy(data)
    embedded["formation"][0]["resistance"] = [{"family": "rav_locomotive_bb60000"}]
    embedded["formation"][1]["resistance"] = [{"family": "rav_carriage_4axle"}]
    del embedded["resistance"]
    a, b = train_from_dict(data), train_from_dict(embedded)
    for v in (0.0, 10.0, 30.0):
        assert a.running_resistance_n(v) == pytest.approx(b.running_resistance_n(v))


@pytest.mark.parametrize(
    ("term", "expected"),
    [
        ({"family": "davis", "a_n": 1000, "b_n_s_per_m": 50, "c_n_s2_per_m2": 5}, 1000 + 50 * 20 + 5 * 400),
        (
            {"family": "per_mass", "a1_n_per_kg": 0.01, "a2_n_s2_per_kg_m2": 1e-5},
            288200 * (0.01 + 1e-5 * 400),
        ),
        (
            {
                "family": "specific_n_per_kn",
                "a_n_per_kn": 2,
                "b_n_per_kn_per_kmh": 0.01,
                "c_n_per_kn_per_kmh2": 1e-4,
            },
            (2 + 0.01 * 72 + 1e-4 * 72**2) * 288200 * G / 1000,
        ),
        ({"family": "rav", "a_n": 500, "b_n_per_kmh": 10, "c_n_per_kmh2": 0.5}, 500 + 10 * 72 + 0.5 * 72**2),
        (
            {"family": "strahl", "f0_permille": 1.4, "f2_permille": 3.9},
            288200 * G * (1.4 + 3.9 * 0.72**2) / 1000,
        ),
    ],
)
def test_resistance_families_at_72_kmh(metro: dict[str, Any], term: dict[str, Any], expected: float) -> None:
    data = copy.deepcopy(metro)
    data["resistance"] = [{**term, "applies_to": "train"}]
    assert train_from_dict(data).running_resistance_n(20.0) == pytest.approx(expected, rel=1e-9)


def test_vehicle_term_uses_vehicle_mass_times_count(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["resistance"] = [{"family": "strahl", "applies_to": "T", "f0_permille": 2.0, "f2_permille": 0.0}]
    assert train_from_dict(data).running_resistance_n(10.0) == pytest.approx(2 * 44500 * G * 2.0 / 1000)


def test_braking_table_full_service_and_fraction(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["braking"]["table_is"] = "full"
    assert train_from_dict(data).max_braking_n(0.0) == pytest.approx(0.75 * 150e3)
    data["braking"]["service_fraction"] = 0.6
    assert train_from_dict(data).max_braking_n(0.0) == pytest.approx(0.6 * 150e3)
    data["braking"]["model"] = "fraction_of_full"
    del data["braking"]["table_is"]
    del data["braking"]["service_fraction"]
    train = train_from_dict(data)
    assert train.max_braking_n(0.0) == pytest.approx(0.75 * 150e3)
    assert train.braking.full_force is not None


def test_regenerative_braking_options(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["braking"]["regenerative"] = {"model": "fraction_of_traction", "fraction": 0.8}
    regen = train_from_dict(data).braking.regenerative
    assert regen is not None and float(regen(0.0)) == pytest.approx(0.8 * 373e3)
    data["braking"]["regenerative"] = {"model": "table", "speed_kmh": [0, 80], "force_kn": [-200, -100]}
    regen = train_from_dict(data).braking.regenerative
    assert regen is not None and float(regen(40 * KMH)) == pytest.approx(150e3)


def test_deceleration_braking_takes_magnitude(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["braking"] = {"model": "deceleration", "deceleration_mps2": -0.8}
    assert train_from_dict(data).braking.deceleration_mps2 == pytest.approx(0.8)


def test_piecewise_and_table_caps(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["traction"] = {
        "model": "piecewise",
        "max_force_kn": 300,
        "intervals": [{"from_kmh": 0, "ch_kw": 3000}],
    }
    train = train_from_dict(data)
    assert train.max_traction_n(1.0) == pytest.approx(300e3)
    assert train.max_traction_n(20.0) == pytest.approx(3e6 / 20)


def test_route_curves_by_angle_elevation_and_change_lists(metro_route: dict[str, Any]) -> None:
    data = copy.deepcopy(metro_route)
    del data["gradients"]
    data["elevation"] = [
        {"position_m": 0, "elevation_m": 100},
        {"position_m": 1000, "elevation_m": 105},
        {"position_m": 3000, "elevation_m": 95},
    ]
    data["curves"] = [{"from_m": 500, "length_m": 200, "central_angle_deg": 20}]
    data["speed_limits"] = [{"from_m": 0, "to_m": 2000, "limit_kmh": 60}, {"from_m": 2000, "limit_kmh": 80}]
    data["tunnels"] = [{"from_m": 100, "to_m": 400}]
    route = route_from_dict(data)
    assert [(g.start_m, g.end_m, g.gradient_permille) for g in route.gradients] == [
        (0, 1000, pytest.approx(5.0)),
        (1000, 3000, pytest.approx(-5.0)),
    ]
    # Source 002 eq. 6: R = (360 / 2 pi) L / alpha.
    assert route.curves[0].radius_m == pytest.approx(360 / (2 * math.pi) * 200 / 20)
    assert route.curves[0].end_m == 700
    assert route.speed_limits[1].end_m == pytest.approx(4590.97)
    assert route.tunnels[0].limiting_gradient is False


def test_scenario_stops_and_dwell_overrides(examples_dir: Path) -> None:
    data = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": "skip S2",
        "train": "train.yaml",
        "route": "route.yaml",
        "stops": ["S1", "S3", "S4"],
        "dwell_s": {"S3": 30},
    }
    scenario = scenario_from_dict(data, "inline.yaml", base_dir=examples_dir / "metro_b")
    assert [s.name for s in scenario.route.stops] == ["S1", "S3", "S4"]
    assert {s.name: s.dwell_s for s in scenario.route.stations}["S3"] == 30
    assert scenario.settings.max_step_m == 10  # default


def test_scenario_with_inline_train_and_route(metro: dict[str, Any], metro_route: dict[str, Any]) -> None:
    train = {k: v for k, v in metro.items() if k not in ("schema", "version")}
    data = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": "inline",
        "train": train,
        "route": metro_route,
    }
    scenario = scenario_from_dict(data)
    assert scenario.train.mass_kg == pytest.approx(288200)
    assert len(scenario.route.stations) == 4


def test_spec_round_trip(examples_dir: Path) -> None:
    for name in ("metro_b", "loco_001", "freight_000"):
        spec = read_train_spec(examples_dir / name / "train.yaml")
        again = train_spec_from_dict(yaml.safe_load(dump_yaml(spec)))
        assert again == spec
        assert again.to_train().mass_kg == spec.to_train().mass_kg


# ====================================================================== errors
def test_negative_mass_names_file_line_and_field(tmp_path: Path, examples_dir: Path) -> None:
    text = (examples_dir / "metro_b" / "train.yaml").read_text(encoding="utf-8")
    bad = tmp_path / "train.yaml"
    bad.write_text(text.replace("mass_t: 44.5", "mass_t: -44.5"), encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_train_yaml(bad)
    e = err.value
    assert e.field == "formation[1].mass_t"
    assert e.value == -44.5
    assert e.file == str(bad)
    line = next(i for i, s in enumerate(bad.read_text().splitlines(), 1) if "mass_t: -44.5" in s)
    assert e.line == line
    assert f"line {line}" in str(e) and "> 0" in str(e)


def test_unknown_field_is_an_error_with_a_hint(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["formation"][0]["lenght_m"] = data["formation"][0].pop("length_m")
    e = _error(data)
    assert e.field == "formation[0].lenght_m"
    assert "did you mean 'length_m'" in str(e)
    assert "bad.yaml" in str(e)


def test_wrong_unit_is_an_error(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["max_speed_kmh"]
    data["max_speed"] = "80 knots"
    e = _error(data)
    assert e.field == "max_speed"
    assert "unknown unit 'knots'" in str(e) and "km/h" in str(e)
    data["max_speed"] = "80 kN"
    assert "unit of force" in str(_error(data))


def test_string_in_suffixed_field_is_an_error(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["max_speed_kmh"] = "80 km/h"
    e = _error(data)
    assert e.field == "max_speed_kmh" and "max_speed: 80 km/h" in str(e)


def test_braking_table_needs_table_is(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["braking"]["table_is"]
    e = _error(data)
    assert e.field == "braking.table_is"
    assert "service" in str(e) and "full" in str(e)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [("schema", "trainsim/trian", "expects a 'trainsim/train' file"), ("version", 2, "unsupported version")],
)
def test_unknown_schema_or_version(metro: dict[str, Any], key: str, value: Any, message: str) -> None:
    data = copy.deepcopy(metro)
    data[key] = value
    e = _error(data)
    assert e.field == key and message in str(e) and repr(value) in str(e)


def test_missing_schema_line(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["schema"]
    assert "missing 'schema'" in str(_error(data))


def test_non_increasing_speeds(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["traction"]["speed_kmh"] = [0, 42, 50, 50, 70, 80]
    e = _error(data)
    assert e.field == "traction.speed_kmh[3]"
    assert "increase strictly" in str(e)


def test_unknown_model_and_family(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["traction"]["model"] = "tabel"
    e = _error(data)
    assert e.field == "traction.model" and "power_limited" in str(e)
    data = copy.deepcopy(metro)
    data["resistance"][0]["family"] = "davies"
    e = _error(data)
    assert e.field == "resistance[0].family" and "davis_kn_kmh" in str(e)


def test_several_problems_in_one_paragraph(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["formation"][1]["mass_t"] = -1
    data["formation"][0]["count"] = 0
    data["colour"] = "red"
    e = _error(data)
    text = str(e)
    assert text.count("\n") == 0
    assert "3 problems" in text
    for path in ("formation[0].count", "formation[1].mass_t", "colour"):
        assert path in text


def test_mixed_sign_braking_table(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["braking"]["force_kn"] = [-150, 150, -335, -335, -275]
    assert _error(data).field == "braking.force_kn"


def test_per_motor_needs_motors(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["traction"]["motors"]
    assert _error(data).field == "traction.motors"


def test_applies_to_unknown_vehicle(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    data["resistance"][0]["applies_to"] = "M"
    e = _error(data)
    assert e.field == "resistance[0].applies_to" and "Mc" in str(e)


def test_rotating_mass_factor_required(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["gamma"]
    assert _error(data).field == "rotating_mass_factor"


def test_route_errors(metro_route: dict[str, Any]) -> None:
    data = copy.deepcopy(metro_route)
    data["speed_limits"] = [{"from_m": 0, "to_m": 1000, "limit_kmh": 80}, {"from_m": 1200, "limit_kmh": 60}]
    with pytest.raises(InputError) as err:
        route_from_dict(data, "r.yaml")
    assert err.value.field == "speed_limits[0].to_m" and "gap" in str(err.value)
    data = copy.deepcopy(metro_route)
    data["curves"] = [{"from_m": 100, "to_m": 200, "radius_m": 300, "central_angle_deg": 10}]
    with pytest.raises(InputError) as err:
        route_from_dict(data, "r.yaml")
    assert err.value.field == "curves[0].radius_m"
    data = copy.deepcopy(metro_route)
    del data["line_resistance"]["curve_formula"]
    with pytest.raises(InputError) as err:
        route_from_dict(data, "r.yaml")
    assert err.value.field == "line_resistance.curve_formula" and "required" in str(err.value)
    data = copy.deepcopy(metro_route)
    data["stations"][2]["position_m"] = 1000
    with pytest.raises(InputError) as err:
        route_from_dict(data, "r.yaml")
    assert err.value.field == "stations[2]"


def test_scenario_unknown_stop(examples_dir: Path) -> None:
    data = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": "x",
        "train": "train.yaml",
        "route": "route.yaml",
        "stops": ["S1", "S5"],
    }
    with pytest.raises(InputError) as err:
        scenario_from_dict(data, "s.yaml", base_dir=examples_dir / "metro_b")
    assert err.value.field == "stops[1]" and "S4" in str(err.value)
    data["stops"] = None
    data["train"] = "no_such_train.yaml"
    with pytest.raises(InputError, match="referenced file not found"):
        scenario_from_dict(data, "s.yaml", base_dir=examples_dir / "metro_b")


def test_duplicate_keys_and_bad_yaml(tmp_path: Path) -> None:
    dup = tmp_path / "dup.yaml"
    dup.write_text("schema: trainsim/train\nversion: 1\nname: a\nname: b\n", encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_train_yaml(dup)
    assert err.value.line == 4 and "duplicate key 'name'" in str(err.value)
    broken = tmp_path / "broken.yaml"
    broken.write_text(
        textwrap.dedent(
            """\
            schema: trainsim/train
            version: 1
            traction: {model: table, speed_kmh: [0, 10
            name: x
            """
        ),
        encoding="utf-8",
    )
    with pytest.raises(InputError) as err:
        load_train_yaml(broken)
    assert err.value.line == 4 and "invalid YAML" in str(err.value)
    with pytest.raises(InputError, match="file not found"):
        load_train_yaml(tmp_path / "missing.yaml")


def test_generic_field_needs_a_unit(metro: dict[str, Any]) -> None:
    data = copy.deepcopy(metro)
    del data["max_speed_kmh"]
    data["max_speed"] = 80
    e = _error(data)
    assert e.field == "max_speed" and "needs a unit" in str(e) and "max_speed_kmh: 80" in str(e)


def test_inline_train_errors_carry_the_scenario_path(
    metro: dict[str, Any], metro_route: dict[str, Any]
) -> None:
    train = copy.deepcopy(metro)
    del train["formation"]
    train.update(mass_t=288.2, length_m=114)
    train["traction"] = {
        "model": "power_limited",
        "power_kw": 1000,
        "efficiency": 0.9,
        "adhesion_coefficient": 0.3,
    }
    data = {"schema": "trainsim/scenario", "version": 1, "name": "x", "train": train, "route": metro_route}
    with pytest.raises(InputError) as err:
        scenario_from_dict(data, "s.yaml")
    assert err.value.field == "train.traction.adhesion_mass_t"
    train["formation"] = [{"name": "A", "mass_t": 10, "length_m": 10, "bogus": 1}]
    with pytest.raises(InputError) as err:
        scenario_from_dict(data, "s.yaml")
    assert "train.formation[0].bogus" in str(err.value)
