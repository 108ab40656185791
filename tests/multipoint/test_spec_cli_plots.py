"""The ``multi_point`` scenario block, the command line and the plots of the multi-point model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from trainsim.errors import InputError
from trainsim.io.multipoint_spec import (
    MultiPointSpec,
    load_multipoint_scenario,
    multipoint_settings_from_dict,
    run_multipoint_scenario,
)
from trainsim.multipoint import CouplerModel

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ROOT / "examples" / "heavy_haul"

TRAIN = {
    "name": "test freight",
    "formation": [
        {"name": "Loco", "count": 2, "mass_t": 120, "length_m": 20, "powered": True},
        {"name": "Wagon", "count": 12, "mass_t": 20, "load_t": 60, "length_m": 14},
    ],
    "rotating_mass_factor": 1.05,
    "max_speed_kmh": 80,
    "traction": {"model": "power_limited", "power_kw": 8000, "efficiency": 1.0, "max_force_kn": 600},
    "braking": {"model": "deceleration", "deceleration_mps2": 0.3},
    "resistance": [
        {"family": "per_mass", "applies_to": "train", "a1_n_per_kg": 0.012, "a2_n_s2_per_kg_m2": 2.6e-5}
    ],
}
ROUTE = {
    "name": "short line",
    "length_m": 3000,
    "stations": [{"name": "A", "position_m": 0}, {"name": "B", "position_m": 3000}],
    "speed_limits": [{"from_m": 0, "limit_kmh": 60}],
    "gradients": [{"from_m": 0, "gradient_permille": 0}, {"from_m": 1000, "gradient_permille": 4}],
    "curves": [{"from_m": 1500, "to_m": 1800, "radius_m": 500}],
    "line_resistance": {"curve_formula": "roeckl", "tunnel_formula": "none", "apply_over": "train_length"},
}


def scenario_file(tmp_path: Path, block: dict | None, model: str | None = "multi_point") -> Path:
    data = {"schema": "trainsim/scenario", "version": 1, "name": "mp test", "train": TRAIN, "route": ROUTE}
    if model is not None:
        data["model"] = model
    if block is not None:
        data["multi_point"] = block
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_the_example_scenarios_read_as_multi_point():
    for name, positions, source in (
        ("scenario_dp.yaml", [0, 53], "locomotives"),
        ("scenario_head.yaml", [0, 1], "head"),
    ):
        scenario, spec = load_multipoint_scenario(HEAVY / name)
        assert isinstance(spec, MultiPointSpec)
        assert spec.locomotive_positions == positions
        settings = spec.build()
        assert settings.couplers.slack_m == 0.025
        assert settings.brake_propagation.source == source
        assert settings.brake_propagation.speed_mps == 250.0
        assert len(scenario.train.vehicles) == 106
        assert scenario.train.mass_kg == pytest.approx(10_700e3)


def test_defaults_of_the_block_are_the_documented_freight_values():
    settings = multipoint_settings_from_dict({}).build()
    assert settings.couplers == CouplerModel()
    # friction draft gears: mean stiffness 1.4e7 / (1 + 2/3), loading branch 1.4e7 N/m
    assert settings.couplers.draft_stiffness_n_per_m == pytest.approx(8.4e6)
    assert settings.couplers.friction_ratio == pytest.approx(2 / 3)
    assert settings.time_step_s == 0.05
    assert settings.brake_propagation.speed_mps is None


def test_coupler_overrides_start_from_the_couplers_block():
    spec = multipoint_settings_from_dict(
        {
            "couplers": {"slack_m": 0.02, "draft_stiffness_n_per_m": 2e7},
            "coupler_overrides": [{"coupler": 0, "slack_m": 0}],
        }
    )
    settings = spec.build()
    assert settings.coupler_overrides[0].slack_m == 0.0
    assert settings.coupler_overrides[0].draft_stiffness_n_per_m == 2e7


@pytest.mark.parametrize(
    "block, field, text",
    [
        (
            {"couplers": {"draft_stifness_n_per_m": 1e7}},
            "multi_point.couplers.draft_stifness_n_per_m",
            "did you mean",
        ),
        ({"couplers": {"slack_m": -0.01}}, "multi_point.couplers.slack_m", "out of range"),
        ({"time_step_s": 5}, "multi_point.time_step_s", "out of range"),
        ({"strategy": "follow"}, "multi_point.profile", "needs a 'profile'"),
        (
            {"brakes": {"propagation_from": "rear"}},
            "multi_point.brakes.propagation_from",
            "not an allowed value",
        ),
        (
            {"couplers": {"solid_stiffness_n_per_m": 1e6}},
            "multi_point.couplers.solid_stiffness_n_per_m",
            "solid",
        ),
    ],
)
def test_errors_in_the_block_name_the_field(tmp_path, block, field, text):
    path = scenario_file(tmp_path, block)
    with pytest.raises(InputError) as err:
        load_multipoint_scenario(path)
    assert err.value.field == field
    assert text in str(err.value)
    assert str(path) in str(err.value)


def test_model_choice():
    with pytest.raises(InputError, match="unknown model"):
        load_multipoint_scenario(
            scenario_file(Path(pytest.importorskip("tempfile").mkdtemp()), None, "three_point")
        )


def test_a_block_without_the_multi_point_model_is_an_error(tmp_path):
    with pytest.raises(InputError, match="needs 'model: multi_point'"):
        load_multipoint_scenario(scenario_file(tmp_path, {"time_step_s": 0.1}, None))
    scenario, spec = load_multipoint_scenario(scenario_file(tmp_path, None, "single_point"))
    assert spec is None and scenario.train.name == "test freight"


def test_run_a_scenario_and_follow_a_profile_file(tmp_path):
    import trainsim
    from trainsim.io.export import write_trace_csv

    path = scenario_file(tmp_path, {"locomotive_positions": [0, 7], "couplers": {"slack_m": 0.02}})
    scenario, spec = load_multipoint_scenario(path)
    fastest = run_multipoint_scenario(scenario, spec)
    single = trainsim.run(scenario)
    assert fastest.status == "ok"
    assert fastest.running_time_s == pytest.approx(single.running_time_s, rel=5e-3)
    assert list(fastest.mptrain.locomotive_indices) == [0, 7]
    # follow the single-point run's trace.csv as written by `trainsim run --out`
    write_trace_csv(single, tmp_path / "trace.csv")
    follow = run_multipoint_scenario(
        scenario,
        {"strategy": "follow", "profile": "trace.csv", "locomotive_positions": [0, 7]},
        base_dir=tmp_path,
    )
    assert follow.status == "ok"
    assert follow.running_time_s == pytest.approx(single.running_time_s, rel=1e-2)


def test_command_line_writes_outputs(tmp_path):
    from trainsim.cli import app

    path = scenario_file(tmp_path, {"couplers": {"slack_m": 0.02}})
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "max draft" in result.output and "max buff" in result.output
    for name in (
        "trace.csv",
        "summary.json",
        "coupler_forces.csv",
        "vehicle_speeds.csv",
        "coupler_heatmap.png",
        "coupler_force.png",
        "vehicle_speeds.png",
    ):
        assert (out / name).stat().st_size > 0, name
    import json

    summary = json.loads((out / "summary.json").read_text())
    assert summary["multi_point"]["vehicles"] == 14
    json_run = CliRunner().invoke(app, ["run", str(path), "--json"])
    assert json_run.exit_code == 0
    assert json.loads(json_run.output)["status"] == "ok"


def test_command_line_errors_exit_with_code_2(tmp_path):
    from trainsim.cli import app

    result = CliRunner().invoke(app, ["multipoint", str(scenario_file(tmp_path, None, "single_point"))])
    assert result.exit_code == 2
    assert "model: multi_point" in result.output
    result = CliRunner().invoke(app, ["run", str(tmp_path / "missing.yaml")])
    assert result.exit_code == 2


def test_plots(tmp_path):
    from trainsim.multipoint.plots import plot_coupler_force, plot_coupler_heatmap, save_multipoint_plots

    scenario, spec = load_multipoint_scenario(scenario_file(tmp_path, {"locomotive_positions": [0, 7]}))
    result = run_multipoint_scenario(scenario, spec)
    fig = plot_coupler_heatmap(result, against="position")
    assert fig.axes[0].get_xlabel() == "head position [km]"
    fig = plot_coupler_force(result, couplers=[3, 9])
    labels = [line.get_label() for line in fig.axes[0].get_lines()]
    assert "coupling 3" in labels and "coupling 9" in labels
    with pytest.raises(ValueError, match="no coupling"):
        plot_coupler_force(result, couplers=13)
    paths = save_multipoint_plots(result, tmp_path / "plots")
    assert all(p.stat().st_size > 10_000 for p in paths)
    assert np.isfinite(result.max_draft.force_n)
