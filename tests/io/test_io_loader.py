"""Format detection, loading any known file, scenarios from files, and ``check_file`` reports."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.loader import (
    KNOWN_FORMATS,
    check_file,
    detect_format,
    load_route,
    load_scenario,
    load_train,
    scenario_from_files,
)
from trainsim.io.railtoolkit import RailtoolkitDefaultWarning
from trainsim.model.scenario import RunSettings


@pytest.mark.parametrize(
    ("relative", "kind", "fmt", "version"),
    [
        ("metro_b/train.yaml", "train", "trainsim/train", "1"),
        ("metro_b/route.yaml", "route", "trainsim/route", "1"),
        ("metro_b/scenario.yaml", "scenario", "trainsim/scenario", "1"),
    ],
)
def test_detect_trainsim(examples_dir: Path, relative: str, kind: str, fmt: str, version: str) -> None:
    detected = detect_format(examples_dir / relative)
    assert (detected.kind, detected.format, detected.version) == (kind, fmt, version)


@pytest.mark.parametrize(
    ("relative", "kind", "fmt"),
    [
        ("trains/freight.yaml", "train", "railtoolkit/rolling-stock"),
        ("paths/realworld.yaml", "route", "railtoolkit/running-path"),
        ("settings/strip.yaml", "settings", "trainruns/settings"),
        ("path_schema_2022.json", "route", "railtoolkit/running-path"),
    ],
)
def test_detect_railtoolkit(trainruns_dir: Path, relative: str, kind: str, fmt: str) -> None:
    detected = detect_format(trainruns_dir / relative)
    assert (detected.kind, detected.format) == (kind, fmt)


def test_unknown_format_lists_known_ones(tmp_path: Path) -> None:
    path = tmp_path / "other.yaml"
    path.write_text("schema: https://example.org/train.json\nname: x\n", encoding="utf-8")
    with pytest.raises(InputError) as err:
        detect_format(path)
    text = str(err.value)
    assert err.value.field == "schema" and str(path) in text
    for name in KNOWN_FORMATS:
        assert name in text
    path.write_text("name: x\nmass: 3\n", encoding="utf-8")
    with pytest.raises(InputError, match="no 'schema' line"):
        load_train(path)
    path.write_text("- 1\n- 2\n", encoding="utf-8")
    with pytest.raises(InputError, match="YAML mapping"):
        check_file(path)


def test_unreadable_yaml_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("schema: trainsim/route\nversion: 1\nstations: [\n  {name: A\n", encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_route(path)
    assert err.value.line is not None and err.value.line >= 4
    assert "invalid YAML" in str(err.value) and f"line {err.value.line}" in str(err.value)
    with pytest.raises(InputError, match="file not found") as err:
        load_train(tmp_path / "nope.yaml")
    assert err.value.file == str(tmp_path / "nope.yaml")


def test_load_any_train_and_route(examples_dir: Path, trainruns_dir: Path) -> None:
    assert load_train(examples_dir / "metro_b" / "train.yaml").mass_kg == pytest.approx(288200)
    assert load_train(trainruns_dir / "trains" / "local.yaml").mass_kg == pytest.approx(88000)
    assert load_route(examples_dir / "metro_b" / "route.yaml").length_m == pytest.approx(4590.97)
    strip = load_route(trainruns_dir / "paths" / "slope.yaml", mass_model="homogeneous_strip")
    assert strip.line_resistance.apply_over == "train_length"


def test_wrong_kind_of_file(examples_dir: Path, trainruns_dir: Path) -> None:
    with pytest.raises(InputError, match="this is a route file"):
        load_train(examples_dir / "metro_b" / "route.yaml")
    with pytest.raises(InputError, match="this is a train file"):
        load_route(trainruns_dir / "trains" / "local.yaml")
    with pytest.raises(InputError, match="expected a scenario file"):
        load_scenario(examples_dir / "metro_b" / "train.yaml")


def test_mass_model_contradicting_a_trainsim_route(examples_dir: Path) -> None:
    with pytest.raises(InputError, match="apply_over"):
        load_route(examples_dir / "metro_b" / "route.yaml", mass_model="homogeneous_strip")
    assert load_route(examples_dir / "metro_b" / "route.yaml", mass_model="mass_point").length_m > 0


def test_broken_trainruns_files_through_the_loader(trainruns_dir: Path) -> None:
    for name, field in [
        ("broken.yaml", "paths"),
        ("missing_path.yml", "paths"),
        ("missing_schema.yml", "schema"),
        ("missing_schema_version.yml", "schema_version"),
    ]:
        path = trainruns_dir / "paths" / name
        with pytest.raises(InputError) as err:
            load_route(path)
        assert err.value.field == field and str(path) in str(err.value)


def test_load_scenario(examples_dir: Path) -> None:
    scenario = load_scenario(examples_dir / "freight_000" / "scenario.yaml")
    assert scenario.train.mass_kg == pytest.approx(4276e3)
    assert [s.name for s in scenario.route.stops] == ["Aville", "Bburg", "Cstadt"]
    assert scenario.settings.max_step_m == 20


def test_scenario_from_files(trainruns_dir: Path, examples_dir: Path) -> None:
    with pytest.warns(RailtoolkitDefaultWarning):
        scenario = scenario_from_files(
            trainruns_dir / "trains" / "freight.yaml",
            trainruns_dir / "paths" / "slope.yaml",
            trainruns_dir / "settings" / "strip.yaml",
        )
    assert scenario.route.line_resistance.apply_over == "train_length"
    assert scenario.name == "V 90 with 10 ore wagons of type Facs 124 on 10 km, different gradient, 160 km/h"
    scenario = scenario_from_files(
        examples_dir / "metro_b" / "train.yaml",
        trainruns_dir / "paths" / "const.yaml",
        {"max_step_m": 2.5, "braking_fraction": 0.8},
        name="metro on const",
    )
    assert (scenario.settings.max_step_m, scenario.settings.braking_fraction) == (2.5, 0.8)
    assert scenario.name == "metro on const"
    scenario = scenario_from_files(
        examples_dir / "metro_b" / "train.yaml",
        examples_dir / "metro_b" / "route.yaml",
        RunSettings(max_step_m=1),
    )
    assert scenario.settings.max_step_m == 1
    with pytest.raises(InputError) as err:
        scenario_from_files(
            examples_dir / "metro_b" / "train.yaml", examples_dir / "metro_b" / "route.yaml", {"max_step": 3}
        )
    assert err.value.field == "settings.max_step" and "max_step_m" in str(err.value)


def test_check_trainsim_files(examples_dir: Path) -> None:
    report = check_file(examples_dir / "metro_b" / "train.yaml")
    assert (report.kind, report.format) == ("train", "trainsim/train v1")
    assert report.figures["mass"] == "288.2 t"
    assert report.figures["max speed"] == "80.0 km/h"
    assert report.figures["regenerative braking"] == "none"
    assert any("negative" in n for n in report.notes)
    text = report.to_text()
    assert "288.2 t" in text and "note:" in text
    route = check_file(examples_dir / "metro_b" / "route.yaml")
    assert route.figures["stations"].startswith("4: S1 @ 0 m, S2 @ 1600.68 m")
    freight = check_file(examples_dir / "freight_000" / "scenario.yaml")
    assert freight.kind == "scenario" and freight.figures["train mass"] == "4276.0 t"
    assert any("0.75" in n for n in freight.notes)


def test_check_railtoolkit_files(trainruns_dir: Path) -> None:
    report = check_file(trainruns_dir / "trains" / "freight.yaml")
    assert report.format == "railtoolkit/rolling-stock 2022.05"
    assert report.figures["mass"] == "920.0 t"
    assert report.figures["braking"] == "constant deceleration 0.225 m/s^2"
    assert any("Bruenger" in n for n in report.notes)
    assert any("UUID" in n and "picture" in n for n in report.notes)  # ignored fields
    path = check_file(trainruns_dir / "paths" / "slope.yaml")
    assert path.figures["length"].startswith("10000.00 m")
    assert path.figures["points of interest"].startswith("5: view_point_1 @ 850 m (front)")
    settings = check_file(trainruns_dir / "settings" / "velocity.yaml")
    assert settings.kind == "settings" and settings.figures["mass model"] == "mass_point"
    assert any("stepSize" in n for n in settings.notes)


def test_every_trainruns_file_checks_or_fails_clearly(trainruns_dir: Path) -> None:
    broken = {"broken.yaml", "missing_path.yml", "missing_schema.yml", "missing_schema_version.yml"}
    files = sorted(p for p in trainruns_dir.rglob("*") if p.suffix in (".yaml", ".yml", ".json"))
    assert len(files) >= 15
    for path in files:
        if path.name in broken:
            with pytest.raises(InputError) as err:
                check_file(path)
            assert str(path) in str(err.value)
        else:
            report = check_file(path)
            assert report.name and report.figures


def test_scenario_with_railtoolkit_references(tmp_path: Path, trainruns_dir: Path) -> None:
    data = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": "Desiro on slope",
        "train": str(trainruns_dir / "trains" / "local.yaml"),
        "route": str(trainruns_dir / "paths" / "slope.yaml"),
        "stops": ["start", "end"],
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    scenario = load_scenario(path)
    assert scenario.train.mass_kg == pytest.approx(88000)
    assert scenario.route.length_m == 10000.0
