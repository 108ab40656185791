"""Round trips: trainsim YAML -> railML 2 / railML 3 / spreadsheet -> trainsim gives the same run
(running time and energy within 0.01 %), for the three examples."""

from __future__ import annotations

import dataclasses

import pytest
from interchange_cases import EXAMPLES, ROUND_TRIP, relative

import trainsim
from trainsim.io import convert, railml2, railml3, spreadsheet
from trainsim.io import railml_common as rc

EXAMPLE_NAMES = ["metro_b", "loco_001", "freight_000"]


@pytest.fixture(scope="module")
def runs():
    """Each example's scenario and its fastest run (computed once)."""
    out = {}
    for name in EXAMPLE_NAMES:
        scenario = trainsim.load_scenario(EXAMPLES / name / "scenario.yaml")
        out[name] = (scenario, trainsim.run(scenario))
    return out


def _same_run(scenario, reference, train, route):
    result = trainsim.run(dataclasses.replace(scenario, train=train, route=route))
    assert result.status == "ok"
    assert relative(result.running_time_s, reference.running_time_s) < ROUND_TRIP
    assert relative(result.energy_kwh.net, reference.energy_kwh.net) < ROUND_TRIP
    assert relative(result.energy_kwh.traction, reference.energy_kwh.traction) < ROUND_TRIP
    return result


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
@pytest.mark.parametrize("version", ["2.2", "2.4", "2.5"])
def test_railml2_round_trip(runs, name, version, tmp_path):
    scenario, reference = runs[name]
    path = tmp_path / "out.xml"
    notes = railml2.write_railml2(path, train=scenario.train, route=scenario.route, version=version)
    content = railml2.read_railml2(path)
    assert content.format == f"railML {version}"
    assert content.ignored == []  # the reader uses everything the writer writes
    _same_run(scenario, reference, rc.build_train(content), rc.build_route(content))
    # the freight train's quadratic / hyperbolic traction law has no railML form: sampled, and said so
    assert bool(notes) == (name == "freight_000")


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
@pytest.mark.parametrize("version", ["3.1", "3.2"])
def test_railml3_round_trip(runs, name, version, tmp_path):
    scenario, reference = runs[name]
    path = tmp_path / "out.xml"
    railml3.write_railml3(path, train=scenario.train, route=scenario.route, version=version)
    content = railml3.read_railml3(path)
    assert content.format == f"railML {version}"
    assert content.ignored == []
    _same_run(scenario, reference, rc.build_train(content), rc.build_route(content))


def test_metro_round_trip_is_exact(runs, tmp_path):
    """A table-based train on a line without gradients comes back bit for bit (up to rounding)."""
    scenario, reference = runs["metro_b"]
    for writer, reader in (
        (railml2.write_railml2, railml2.read_railml2),
        (railml3.write_railml3, railml3.read_railml3),
    ):
        path = tmp_path / "metro.xml"
        writer(path, train=scenario.train, route=scenario.route)
        content = reader(path)
        route = rc.build_route(content)
        assert dataclasses.replace(route, name=scenario.route.name) == scenario.route
        train = rc.build_train(content)
        assert train.mass_kg == pytest.approx(scenario.train.mass_kg, rel=1e-12)
        assert train.rotating_mass_factor == pytest.approx(scenario.train.rotating_mass_factor, rel=1e-12)
        result = _same_run(scenario, reference, train, route)
        assert relative(result.running_time_s, reference.running_time_s) < 1e-9


@pytest.mark.parametrize("name", EXAMPLE_NAMES)
@pytest.mark.parametrize("suffix", [".xlsx", "_csv"])
def test_spreadsheet_round_trip(runs, name, suffix, tmp_path):
    scenario, reference = runs[name]
    path = tmp_path / f"tables{suffix}"
    spreadsheet.write_spreadsheet(path, train=scenario.train, route=scenario.route)
    content = spreadsheet.read_spreadsheet(path)
    _same_run(scenario, reference, rc.build_train(content), rc.build_route(content))


def test_converted_yaml_runs_the_same(runs, tmp_path):
    """railML -> `convert` -> trainsim YAML: the scenario file runs as the original."""
    scenario, reference = runs["metro_b"]
    xml = tmp_path / "metro.xml"
    railml2.write_railml2(xml, train=scenario.train, route=scenario.route)
    out, _ = convert.convert(xml, tmp_path / "metro.yaml")
    converted = trainsim.load_scenario(out)
    assert out.read_text().startswith("# converted by trainsim from metro.xml (railML 2.4)")
    _same_run(scenario, reference, converted.train, converted.route)


@pytest.mark.filterwarnings("ignore::trainsim.io.railtoolkit.RailtoolkitDefaultWarning")
def test_convert_trainsim_and_railtoolkit_yaml(runs, tmp_path):
    """Any readable input converts: a trainsim scenario and a railtoolkit train + path."""
    scenario, reference = runs["loco_001"]
    out, _ = convert.convert(EXAMPLES / "loco_001" / "scenario.yaml", tmp_path / "s.yaml")
    converted = trainsim.load_scenario(out)
    _same_run(scenario, reference, converted.train, converted.route)
    data = EXAMPLES.parent / "tests" / "data" / "trainruns"
    if not (data / "trains" / "freight.yaml").is_file():
        pytest.skip("TrainRuns.jl test data not present")
    original = trainsim.load_train(data / "trains" / "freight.yaml")
    out, notes = convert.convert(data / "trains" / "freight.yaml", tmp_path / "t.yaml")
    train = trainsim.load_train(out)
    route = trainsim.load_route(data / "paths" / "const.yaml")
    a = trainsim.run_fastest(original, route, trainsim.RunSettings(max_step_m=20))
    b = trainsim.run_fastest(train, route, trainsim.RunSettings(max_step_m=20))
    assert relative(b.running_time_s, a.running_time_s) < ROUND_TRIP
    assert "written from the model objects" in notes
