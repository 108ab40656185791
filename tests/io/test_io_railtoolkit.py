"""railtoolkit / TrainRuns.jl files: every TrainRuns.jl 1.0.4 test train and path loads with the
figures TrainRuns.jl computes, and every broken file gives an InputError naming file and problem."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.railtoolkit import (
    RailtoolkitDefaultWarning,
    load_railtoolkit_path,
    load_railtoolkit_settings,
    load_railtoolkit_train,
    read_railtoolkit_path,
    read_railtoolkit_train,
)

G = 9.80665  # TrainRuns.jl's g (trainsim.constants.TRAINRUNS_GRAVITY)
KMH = 1 / 3.6
V00 = 100 * KMH
DV_AIR = 15 * KMH


def wende(v: float, m: float, m_td: float, f_td: float, f_tc: float, f_air: float) -> float:
    """Wende's traction-unit law as TrainRuns.jl writes it (calcTractionUnitResistance) [N]."""
    return (
        f_td / 1000 * m_td * G
        + f_tc / 1000 * (m - m_td) * G
        + f_air / 1000 * m * G * ((v + DV_AIR) / V00) ** 2
    )


def strahl(v: float, m: float, f0: float, f2: float) -> float:
    return m * G * (f0 / 1000 + f2 / 1000 * (v / V00) ** 2)


def sauthoff(v: float, m: float, f0: float, f1: float, f2: float) -> float:
    return m * G * (f0 / 1000 + f1 / 1000 * v / V00 + f2 / 1000 * ((v + DV_AIR) / V00) ** 2)


def _write(tmp_path: Path, data: dict[str, Any], name: str = "file.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


# ====================================================================== trains
def test_freight_train(trainruns_dir: Path) -> None:
    path = trainruns_dir / "trains" / "freight.yaml"
    with pytest.warns(RailtoolkitDefaultWarning, match="0.225"):
        train = load_railtoolkit_train(path)
    assert train.mass_kg == pytest.approx((80 + 10 * (25 + 59)) * 1000)  # 920 t, fully loaded
    assert train.length_m == pytest.approx(14.32 + 10 * 19.04)
    assert train.max_speed_mps == pytest.approx(80 * KMH)  # V 90 limit (wagons: 100)
    assert train.braking.deceleration_mps2 == pytest.approx(0.225)  # freight default, no a_braking
    # (1.09 x 80 + 10 x 1.03 x 25) / (80 + 250): weighted by EMPTY masses.
    assert train.rotating_mass_factor == pytest.approx((1.09 * 80 + 10 * 1.03 * 25) / 330)
    assert train.adhesion_mass_kg == pytest.approx(80000)
    for v in (0.0, 10.0, 22.0):
        expected = wende(v, 80e3, 80e3, 2.2, 0.0, 10) + strahl(v, 10 * 84e3, 1.4, 3.9)
        assert train.running_resistance_n(v) == pytest.approx(expected, rel=1e-12)
    assert train.max_traction_n(0.0) == pytest.approx(186940)
    assert train.max_traction_n(44.5 * KMH) == pytest.approx((50000 + 48660) / 2)
    assert [v.name for v in train.vehicles] == ["DB_V90"] + ["Facs124"] * 10


def test_local_train(trainruns_dir: Path) -> None:
    loaded = read_railtoolkit_train(trainruns_dir / "trains" / "local.yaml")
    train = loaded.train
    assert train.mass_kg == pytest.approx(88000)  # 68 t + 20 t load_limit
    assert train.braking.deceleration_mps2 == pytest.approx(0.4253)  # |a_braking|
    assert train.rotating_mass_factor == pytest.approx(1.08)
    assert train.length_m == pytest.approx(41.7)
    assert train.max_speed_mps == pytest.approx(120 * KMH)
    assert loaded.train_id == "RB50-1" and loaded.schema_version == "2022.05"
    assert not any("a_braking" in n for n in loaded.notes)
    # The multiple unit is the loco: Wende on its EMPTY mass, no car term.
    for v in (0.0, 15.0, 33.0):
        assert train.running_resistance_n(v) == pytest.approx(
            wende(v, 68e3, 45.333e3, 3.0, 1.4, 3.9), rel=1e-12
        )
    assert len(train.resistance) == 1


def test_longdistance_train(trainruns_dir: Path) -> None:
    with pytest.warns(RailtoolkitDefaultWarning, match="0.375"):
        train = load_railtoolkit_train(trainruns_dir / "trains" / "longdistance.yaml")
    assert train.mass_kg == pytest.approx((85 + 4 * 70 + 78) * 1000)
    assert train.length_m == pytest.approx(18.9 + 4 * 26.8 + 27.27)
    assert train.max_speed_mps == pytest.approx(160 * KMH)
    assert train.braking.deceleration_mps2 == pytest.approx(0.375)  # passenger default
    assert train.rotating_mass_factor == pytest.approx((1.09 * 85 + 1.06 * (4 * 50 + 58)) / (85 + 258))
    v = 30.0
    expected = wende(v, 85e3, 85e3, 2.5, 0.0, 6.0) + sauthoff(v, (4 * 70 + 78) * 1e3, 2.0, 0.715, 3.64)
    assert train.running_resistance_n(v) == pytest.approx(expected, rel=1e-12)


def test_same_train_in_json(trainruns_dir: Path) -> None:
    train = load_railtoolkit_train(trainruns_dir / "train_schema_2022.json")
    assert train.mass_kg == pytest.approx(88000)


def test_train_selection_and_errors(tmp_path: Path, trainruns_dir: Path) -> None:
    data = yaml.safe_load((trainruns_dir / "trains" / "freight.yaml").read_text(encoding="utf-8"))
    two = copy.deepcopy(data)
    two["trains"].append({"name": "loco only", "id": "L1", "formation": ["DB_V90"]})
    path = _write(tmp_path, two)
    with pytest.warns(RailtoolkitDefaultWarning):
        assert load_railtoolkit_train(path, "L1").mass_kg == pytest.approx(80000)
    assert any("2 trains" in n for n in read_railtoolkit_train(path).notes)
    with pytest.raises(InputError) as err:
        load_railtoolkit_train(path, "X9")
    assert "Fr100, L1" in str(err.value)

    unknown = copy.deepcopy(data)
    unknown["trains"][0]["formation"][3] = "Facs125"
    with pytest.raises(InputError) as err:
        load_railtoolkit_train(_write(tmp_path, unknown))
    assert err.value.field == "trains[0].formation[3]"
    assert "'Facs125'" in str(err.value) and "file.yaml" in str(err.value)

    no_loco = copy.deepcopy(data)
    no_loco["trains"][0]["formation"] = ["Facs124", "Facs124"]
    with pytest.raises(InputError, match="no traction unit") as err:
        load_railtoolkit_train(_write(tmp_path, no_loco))
    assert err.value.field == "trains[0].formation"

    no_effort = copy.deepcopy(data)
    del no_effort["vehicles"][1]["tractive_effort"]
    with pytest.raises(InputError, match="tractive_effort") as err:
        load_railtoolkit_train(_write(tmp_path, no_effort))
    assert err.value.field == "vehicles[1].tractive_effort"

    bad_version = copy.deepcopy(data)
    bad_version["schema_version"] = "2023.01"
    with pytest.raises(InputError) as err:
        load_railtoolkit_train(_write(tmp_path, bad_version))
    assert err.value.field == "schema_version" and "2022.05" in str(err.value)

    bad_value = copy.deepcopy(data)
    bad_value["vehicles"][0]["length"] = -19.04
    with pytest.raises(InputError) as err:
        load_railtoolkit_train(_write(tmp_path, bad_value))
    assert err.value.field == "vehicles[0].length" and "> 0" in str(err.value)

    vehicles_only = copy.deepcopy(data)
    del vehicles_only["trains"]
    with pytest.raises(InputError, match="no 'trains'"):
        load_railtoolkit_train(_write(tmp_path, vehicles_only))


def test_path_file_is_not_a_train(trainruns_dir: Path) -> None:
    with pytest.raises(InputError) as err:
        load_railtoolkit_train(trainruns_dir / "paths" / "const.yaml")
    assert err.value.field == "schema" and "running path file" in str(err.value)


# ====================================================================== paths
def test_const_path(trainruns_dir: Path) -> None:
    loaded = read_railtoolkit_path(trainruns_dir / "paths" / "const.yaml")
    route = loaded.route
    assert (route.start_m, route.end_m) == (0.0, 10000.0)
    assert [(x.start_m, x.end_m, x.limit_mps) for x in route.speed_limits] == [
        (0.0, 10000.0, pytest.approx(160 * KMH))
    ]
    assert route.gradients == ()
    assert [(s.name, s.position_m, s.dwell_s, s.stop) for s in route.stations] == [
        ("start", 0.0, 0.0, True),
        ("end", 10000.0, 0.0, True),
    ]
    pois = loaded.points_of_interest
    assert len(pois) == 7 and pois[2].name == "point_3" and pois[2].measure == "rear"
    assert pois[2].position_m == pytest.approx(3333.3)
    lr = route.line_resistance
    assert (lr.curve_formula, lr.tunnel_formula, lr.gradient_formula, lr.apply_over) == (
        "none",
        "none",
        "small_angle",
        "head",
    )


def test_slope_path_resistance_as_gradients(trainruns_dir: Path) -> None:
    route = load_railtoolkit_path(trainruns_dir / "paths" / "slope.yaml")
    assert [(g.start_m, g.end_m, g.gradient_permille) for g in route.gradients] == [
        (1000.0, 2000.0, 1.0),
        (2000.0, 3000.0, 2.0),
        (3000.0, 4000.0, 5.0),
        (4000.0, 5000.0, -3.0),
        (5000.0, 6000.0, 5.0),
        (6000.0, 7000.0, -10.0),
        (7000.0, 8000.0, 15.0),
        (8000.0, 8500.0, -10.0),
        (8500.0, 9000.0, 20.0),
    ]


def test_speed_path_and_strip_model(trainruns_dir: Path) -> None:
    route = load_railtoolkit_path(trainruns_dir / "paths" / "speed.yaml", mass_model="homogeneous_strip")
    assert [(x.start_m, round(x.limit_mps / KMH)) for x in route.speed_limits] == [
        (0.0, 160),
        (3000.0, 60),
        (4000.0, 160),
        (5000.0, 60),
        (6000.0, 160),
        (6500.0, 60),
        (6700.0, 65),
        (6800.0, 70),
        (7000.0, 120),
    ]
    assert route.speed_limits[-1].end_m == 10000.0
    assert route.line_resistance.apply_over == "train_length"
    with pytest.raises(InputError, match="unknown mass model"):
        load_railtoolkit_path(trainruns_dir / "paths" / "speed.yaml", mass_model="point")


def test_realworld_path(trainruns_dir: Path) -> None:
    route = load_railtoolkit_path(trainruns_dir / "paths" / "realworld.yaml")
    assert route.length_m == pytest.approx(101800.0)
    # First rows: 0 / 40 / 0.0, 318 / 40 / 2.0, 399 / 40 / -3.0.
    assert (route.gradients[0].start_m, route.gradients[0].end_m, route.gradients[0].gradient_permille) == (
        318.0,
        399.0,
        2.0,
    )
    assert route.speed_limits[0].end_m == 1800.0  # 40 km/h merged over the first rows
    assert max(g.gradient_permille for g in route.gradients) == 20.0


def test_same_path_in_json(trainruns_dir: Path) -> None:
    assert load_railtoolkit_path(trainruns_dir / "path_schema_2022.json").length_m == 10000.0


@pytest.mark.parametrize(
    ("name", "field", "words"),
    [
        ("broken.yaml", "paths", "must be a list, not a mapping"),
        ("missing_path.yml", "paths", "no 'paths'"),
        ("missing_schema.yml", "schema", "no 'schema' line"),
        ("missing_schema_version.yml", "schema_version", "no 'schema_version' line"),
    ],
)
def test_broken_trainruns_paths(trainruns_dir: Path, name: str, field: str, words: str) -> None:
    path = trainruns_dir / "paths" / name
    with pytest.raises(InputError) as err:
        load_railtoolkit_path(path)
    assert err.value.file == str(path)
    assert err.value.field == field
    assert str(path) in str(err.value) and words in str(err.value)


PATH_2024 = """\
schema: https://railtoolkit.org/schema/running-path.json
schema_version: "2024.07"
paths:
  - id: example
    description: "Example"
    points_of_interest:
      - {position: 850.0, label: "1:view point", measure: front}
      - {position: 5500.0, label: "A:platform", measure: middle}
      - {position: 9050.0, label: "1:clearing point", measure: rear}
    characteristic_sections:
      - {position: 0.0, speed: 160, resistance: 0.0}
      - {position: 1000.0, speed: 160, resistance: 1.0}
      - {position: 6000.0, resistance: -10.0}
      - {position: 7000.0, speed: 80, resistance: 15.0}
      - {position: 8000.0, speed: 120}
      - {position: 9000.0, speed: 160, resistance: 0.0}
      - {position: 10000.0, speed: 160, resistance: 0.0}
"""


def test_path_2024_format(tmp_path: Path) -> None:
    """The current railtoolkit/schema form (2024.07): rows are mappings, values may be left out."""
    path = tmp_path / "path2024.yaml"
    path.write_text(PATH_2024, encoding="utf-8")
    loaded = read_railtoolkit_path(path)
    route = loaded.route
    assert loaded.schema_version == "2024.07" and route.name == "Example"
    assert route.length_m == 10000.0
    # A missing speed or resistance carries over from the row before.
    assert [(x.start_m, round(x.limit_mps / KMH)) for x in route.speed_limits] == [
        (0.0, 160),
        (7000.0, 80),
        (8000.0, 120),
        (9000.0, 160),
    ]
    assert [(g.start_m, g.end_m, g.gradient_permille) for g in route.gradients] == [
        (1000.0, 6000.0, 1.0),
        (6000.0, 7000.0, -10.0),
        (7000.0, 9000.0, 15.0),
    ]
    assert [p.measure for p in loaded.points_of_interest] == ["front", "middle", "rear"]
    data = yaml.safe_load(PATH_2024)
    data["schema_version"] = "2022.05"  # mappings are not rows of the 2022.05 schema
    with pytest.raises(InputError) as err:
        load_railtoolkit_path(_write(tmp_path, data))
    assert "characteristic_sections[0]" in str(err.value) and "must be a list" in str(err.value)


def test_duplicate_section_position(tmp_path: Path, trainruns_dir: Path) -> None:
    data = yaml.safe_load((trainruns_dir / "paths" / "slope.yaml").read_text())
    data["paths"][0]["characteristic_sections"][2][0] = 1000.0
    with pytest.raises(InputError, match="same position") as err:
        load_railtoolkit_path(_write(tmp_path, data))
    assert err.value.field == "paths[0].characteristic_sections"


# ====================================================================== settings
def test_settings_files(trainruns_dir: Path) -> None:
    strip = load_railtoolkit_settings(trainruns_dir / "settings" / "strip.yaml")
    assert (strip.mass_model, strip.apply_over, strip.ignored) == ("homogeneous_strip", "train_length", {})
    velocity = load_railtoolkit_settings(trainruns_dir / "settings" / "velocity.yaml")
    assert velocity.mass_model == "mass_point"
    assert velocity.ignored == {"stepVariable": "velocity", "stepSize": 0.1}
    assert any("stepSize" in n and "ignored" in n for n in velocity.notes)
    course = load_railtoolkit_settings(trainruns_dir / "settings" / "driving_course.yaml")
    assert course.ignored == {"outputDetail": "driving_course"}


def test_invalid_settings(tmp_path: Path) -> None:
    path = _write(tmp_path, {"settings": {"massModel": "point_mass"}})
    with pytest.raises(InputError) as err:
        load_railtoolkit_settings(path)
    assert err.value.field == "settings.massModel" and "homogeneous_strip" in str(err.value)
    with pytest.raises(InputError, match="no 'settings'"):
        load_railtoolkit_settings(_write(tmp_path, {"massModel": "mass_point"}))
