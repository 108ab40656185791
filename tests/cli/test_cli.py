"""The ``trainsim`` command line, driven through typer's CliRunner."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.plots import PLOT_FILES

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "metro_b"

# A small trainsim scenario (docs/FORMAT.md), so the CLI is tested even without the examples and
# with features the example lacks: regenerative braking, a gradient, a dwell.
TRAIN_YAML = """\
schema: trainsim/train
version: 1
name: Test EMU
mass_t: 200
length_m: 100
rotating_mass_factor: 1.1
max_speed_kmh: 80
traction: {model: table, speed_kmh: [0, 40, 80], force_kn: [200, 200, 100]}
braking:
  model: deceleration
  deceleration_mps2: 0.8
  regenerative: {model: fraction_of_traction, fraction: 0.8}
resistance:
  - {family: davis, applies_to: train, a_n: 2000, b_n_s_per_m: 20, c_n_s2_per_m2: 5}
electrical: {line_voltage_v: 1500, traction_efficiency: 0.85}
"""

ROUTE_YAML = """\
schema: trainsim/route
version: 1
name: Test line
length_m: 3000
stations:
  - {name: A, position_m: 0}
  - {name: B, position_m: 1500, dwell_s: 30}
  - {name: C, position_m: 3000}
speed_limits:
  - {from_m: 0, limit_kmh: 70}
gradients:
  - {from_m: 0, gradient_permille: 0}
  - {from_m: 1000, gradient_permille: 5}
line_resistance: {curve_formula: none, tunnel_formula: none}
"""

SCENARIO_YAML = """\
schema: trainsim/scenario
version: 1
name: CLI test scenario
train: train.yaml
route: route.yaml
settings: {max_step_m: 10}
"""

SUMMARY_KEYS = {
    "status",
    "warnings",
    "distance_m",
    "running_time_s",
    "total_time_s",
    "peak_current_a",
    "energy_kwh",
}
SECTION_KEYS = {"from", "to", "distance_m", "running_time_s", "dwell_s", "energy_kwh"}
ENERGY_KEYS = {"traction", "regenerated", "net"}


@pytest.fixture
def runner() -> CliRunner:
    return CliRunner()


@pytest.fixture
def small(tmp_path: Path) -> Path:
    """Directory holding train.yaml, route.yaml and scenario.yaml of the small scenario."""
    d = tmp_path / "small"
    d.mkdir()
    (d / "train.yaml").write_text(TRAIN_YAML)
    (d / "route.yaml").write_text(ROUTE_YAML)
    (d / "scenario.yaml").write_text(SCENARIO_YAML)
    return d


@pytest.fixture(params=["example", "small"])
def scenario_dir(request: pytest.FixtureRequest, small: Path) -> Path:
    if request.param == "example":
        if not (EXAMPLE / "scenario.yaml").exists():
            pytest.skip("examples/metro_b not present")
        return EXAMPLE
    return small


def assert_user_error(result, *needles: str) -> None:
    """Exit code 2, one ``error:`` message on stderr, no traceback anywhere."""
    assert result.exit_code == 2, result.output
    # the command ended by exiting, not by an exception escaping it
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert result.stderr.startswith("error: "), result.stderr
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle in result.stderr


def check_summary(summary: dict) -> None:
    assert summary.keys() >= SUMMARY_KEYS
    assert summary["status"] == "ok"
    assert summary["warnings"] == []
    for key in ("distance_m", "running_time_s", "total_time_s", "peak_current_a"):
        assert summary[key] > 0, key
    assert summary["total_time_s"] >= summary["running_time_s"]
    assert summary["energy_kwh"].keys() >= ENERGY_KEYS
    assert summary["energy_kwh"]["traction"] > 0
    assert summary["energy_kwh"]["net"] > 0
    assert len(summary["sections"]) >= 1
    for section in summary["sections"]:
        assert section.keys() >= SECTION_KEYS
        assert section["distance_m"] > 0
        assert section["running_time_s"] > 0
        assert section["dwell_s"] >= 0
        assert section["energy_kwh"].keys() >= ENERGY_KEYS
    total = sum(s["distance_m"] for s in summary["sections"])
    assert total == pytest.approx(summary["distance_m"])


# ---------------------------------------------------------------------------- run
def test_run_json_scenario(runner: CliRunner, scenario_dir: Path) -> None:
    result = runner.invoke(app, ["run", str(scenario_dir / "scenario.yaml"), "--json"])
    assert result.exit_code == 0, result.output
    # --json: stdout is the JSON document and nothing else
    check_summary(json.loads(result.stdout))


def test_run_json_train_and_route(runner: CliRunner, scenario_dir: Path) -> None:
    result = runner.invoke(
        app,
        [
            "run",
            "--train",
            str(scenario_dir / "train.yaml"),
            "--route",
            str(scenario_dir / "route.yaml"),
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    check_summary(json.loads(result.stdout))


def test_run_small_figures(runner: CliRunner, small: Path) -> None:
    summary = json.loads(runner.invoke(app, ["run", str(small / "scenario.yaml"), "--json"]).stdout)
    assert summary["distance_m"] == pytest.approx(3000.0)
    assert [(s["from"], s["to"]) for s in summary["sections"]] == [("A", "B"), ("B", "C")]
    assert summary["sections"][0]["dwell_s"] == pytest.approx(30.0)
    assert summary["total_time_s"] == pytest.approx(summary["running_time_s"] + 30.0)
    assert summary["energy_kwh"]["regenerated"] > 0  # the train brakes regeneratively


def test_run_step_override(runner: CliRunner, small: Path) -> None:
    coarse = runner.invoke(app, ["run", str(small / "scenario.yaml"), "--json", "--step", "50"])
    assert coarse.exit_code == 0, coarse.output
    fine = json.loads(runner.invoke(app, ["run", str(small / "scenario.yaml"), "--json"]).stdout)
    # the envelope is exact at breakpoints whatever the step: the step barely changes the run time
    assert json.loads(coarse.stdout)["running_time_s"] == pytest.approx(fine["running_time_s"], rel=1e-3)


def test_run_bad_step(runner: CliRunner, small: Path) -> None:
    result = runner.invoke(app, ["run", str(small / "scenario.yaml"), "--step", "0"])
    assert_user_error(result, "max_step_m")


def test_run_table_and_out(runner: CliRunner, small: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(small / "scenario.yaml"), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "total" in result.stdout and "A → C" in result.stdout
    for name in ("trace.csv", "summary.json", *PLOT_FILES):
        path = out / name
        assert path.is_file(), name
        assert path.stat().st_size > 0, name
        assert str(path) in result.stdout  # the output paths are printed
    for name in PLOT_FILES:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    with (out / "trace.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    columns = set(rows[0])
    assert {
        "time_s",
        "position_m",
        "speed_mps",
        "speed_kmh",
        "regime",
        "traction_force_n",
        "speed_limit_mps",
        "electrical_power_w",
        "line_current_a",
        "paper_line_current_a",
        "electrical_energy_j",
    } <= columns
    assert float(rows[-1]["position_m"]) == pytest.approx(3000.0)
    check_summary(json.loads((out / "summary.json").read_text()))


def test_run_no_plots(runner: CliRunner, small: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = runner.invoke(
        app, ["run", str(small / "scenario.yaml"), "--out", str(out), "--no-plots", "--json"]
    )
    assert result.exit_code == 0, result.output
    json.loads(result.stdout)
    assert sorted(p.name for p in out.iterdir()) == ["summary.json", "trace.csv"]


# ---------------------------------------------------------------------------- user errors
def test_run_missing_file(runner: CliRunner, tmp_path: Path) -> None:
    missing = tmp_path / "nope.yaml"
    assert_user_error(runner.invoke(app, ["run", str(missing)]), "nope.yaml", "not found")
    assert_user_error(runner.invoke(app, ["run", str(missing), "--json"]), "nope.yaml")


def test_run_missing_route(runner: CliRunner, small: Path) -> None:
    result = runner.invoke(
        app, ["run", "--train", str(small / "train.yaml"), "--route", str(small / "nope.yaml")]
    )
    assert_user_error(result, "nope.yaml")


def test_run_invalid_file(runner: CliRunner, small: Path) -> None:
    (small / "train.yaml").write_text(TRAIN_YAML.replace("mass_t: 200", "mass_t: -200"))
    result = runner.invoke(app, ["run", str(small / "scenario.yaml"), "--json"])
    assert_user_error(result, "mass_t")
    assert result.stdout == ""  # no half-written JSON


def test_run_broken_yaml(runner: CliRunner, tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("schema: trainsim/scenario\nname: [unclosed\n")
    assert_user_error(runner.invoke(app, ["run", str(bad)]), "bad.yaml")


def test_run_needs_scenario_or_train_and_route(runner: CliRunner, small: Path) -> None:
    assert_user_error(runner.invoke(app, ["run"]))
    assert_user_error(runner.invoke(app, ["run", "--train", str(small / "train.yaml")]), "--route")
    both = ["run", str(small / "scenario.yaml"), "--train", str(small / "train.yaml")]
    assert_user_error(runner.invoke(app, both), "not both")


def test_error_is_one_paragraph(runner: CliRunner, small: Path) -> None:
    (small / "route.yaml").write_text(ROUTE_YAML.replace("limit_kmh: 70", "limit_kmh: fast"))
    result = runner.invoke(app, ["run", str(small / "scenario.yaml")])
    assert_user_error(result, "limit_kmh")
    assert result.stderr.count("\n") == 1  # one line: a paragraph the terminal wraps itself


# ---------------------------------------------------------------------------- check
def test_check_valid(runner: CliRunner, small: Path) -> None:
    for name, expected in (
        ("train.yaml", "Test EMU"),
        ("route.yaml", "Test line"),
        ("scenario.yaml", "CLI test"),
    ):
        result = runner.invoke(app, ["check", str(small / name)])
        assert result.exit_code == 0, result.output
        assert expected in result.stdout
        assert result.stderr == ""


def test_check_missing_and_invalid(runner: CliRunner, small: Path, tmp_path: Path) -> None:
    assert_user_error(runner.invoke(app, ["check", str(tmp_path / "nope.yaml")]), "nope.yaml")
    (small / "train.yaml").write_text(TRAIN_YAML + "colour: red\n")
    assert_user_error(runner.invoke(app, ["check", str(small / "train.yaml")]), "colour")
    assert_user_error(runner.invoke(app, ["check", str(tmp_path)]), "not a file")


# ---------------------------------------------------------------------------- analyze-acceleration
def test_analyze_acceleration(runner: CliRunner, small: Path, tmp_path: Path) -> None:
    out = tmp_path / "acc"
    args = ["analyze-acceleration", str(small / "train.yaml"), "--power-kw", "2000", "--efficiency", "0.85"]
    result = runner.invoke(app, [*args, "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "balancing speed" in result.stdout
    png = out / "acceleration_analysis.png"
    assert png.is_file() and png.stat().st_size > 0


def test_analyze_acceleration_bad_efficiency(runner: CliRunner, small: Path) -> None:
    args = ["analyze-acceleration", str(small / "train.yaml"), "--power-kw", "2000", "--efficiency", "1.5"]
    assert_user_error(runner.invoke(app, args), "efficiency")
