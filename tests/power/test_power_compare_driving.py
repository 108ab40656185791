"""``trainsim power FILE --compare-driving fastest,optimal --supplement 10%`` (issue 18): the same
timetable driven fastest and optimally, judged at the pantographs and at the substations."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from trainsim.batch.power_timetable import read_study_trains, run_power_file
from trainsim.cli import app
from trainsim.errors import InputError
from trainsim.io.power_compare import compare_driving

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"


def _write(folder: Path, name: str, scenario: str, **changes: object) -> Path:
    """A short copy of metro_750v_diode.yaml: one train each way, 400 s, every train on ``scenario``."""
    data = yaml.safe_load((EXAMPLES / "metro_750v_diode.yaml").read_text())
    for t in data["trains"]:
        t["scenario"] = str(EXAMPLES / scenario)
        t["headway"]["count"] = 1
    data["simulation"]["end_s"] = 400
    for key, value in changes.items():
        where = data
        *parts, last = key.split(".")
        for p in parts:
            where = where[int(p)] if isinstance(where, list) else where[p]
        where[int(last) if isinstance(where, list) else last] = value
    path = folder / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("compare_driving")
    return _write(folder, "fast.yaml", "metro_scenario.yaml"), _write(
        folder, "eco.yaml", "metro_scenario_eco.yaml"
    )


@pytest.fixture(scope="module")
def compared(files: tuple[Path, Path]) -> tuple[dict, int]:
    result = CliRunner().invoke(
        app, ["power", str(files[0]), "--compare-driving", "fastest,optimal", "--supplement", "10%", "--json"]
    )
    return json.loads(result.stdout), result.exit_code


FIGURES = ("trains_energy_kwh", "substations_energy_kwh", "losses_kwh")


def test_the_comparison_equals_two_independent_runs(files, compared):
    document, code = compared
    block = document["driving_comparison"]
    assert [r["strategy"] for r in block["runs"]] == ["fastest", "optimal"]
    singles = [run_power_file(f, plots=False) for f in files]
    for run, (summary, status) in zip(block["runs"], singles, strict=True):
        assert run["status"] == status
        for key in FIGURES:
            assert run[key] == pytest.approx(summary[key], rel=0, abs=1e-9)
        asked = sum(t["traction_demand_kwh"] for t in summary["trains"])
        assert run["traction_demand_kwh"] == pytest.approx(asked, rel=0, abs=1e-9)
        for key in ("used_by_trains", "returned", "dissipated"):
            assert run["regen_kwh"][key] == pytest.approx(summary["regen_kwh"][key], rel=0, abs=1e-9)
    (fast, _), (eco, _) = singles
    saving = block["savings"][0]
    assert (saving["strategy"], saving["against"]) == ("optimal", "fastest")
    for where, key in (("pantographs", "trains_energy_kwh"), ("substations", "substations_energy_kwh")):
        kwh = fast[key] - eco[key]
        assert saving[where]["kwh"] == pytest.approx(kwh, rel=0, abs=1e-9)
        assert saving[where]["percent"] == pytest.approx(100 * kwh / fast[key], rel=1e-12)
    # the optimal driving saves energy at the pantographs on this line: the comparison is not of equals
    assert saving["pantographs"]["kwh"] > 0
    assert block["status"] == "ok" and code == 0


def test_optimal_without_any_supplement_is_refused_naming_the_option(files):
    with pytest.raises(InputError) as info:
        compare_driving(files[0], ("fastest", "optimal"), read_study=read_study_trains)
    assert info.value.problems[0].field == "--supplement"
    assert "train up" in str(info.value)


def test_the_scenarios_own_supplement_is_used_without_the_option(files, compared):
    # the eco file's scenarios give supplement: 10%: without --supplement the same figures
    block, _ = compare_driving(files[1], ("optimal", "fastest"), read_study=read_study_trains)
    optimal = next(r for r in compared[0]["driving_comparison"]["runs"] if r["strategy"] == "optimal")
    assert block["runs"][0]["substations_energy_kwh"] == pytest.approx(
        optimal["substations_energy_kwh"], rel=0, abs=1e-9
    )


def test_a_run_not_ok_gives_exit_3_and_is_shown(tmp_path):
    # substations that may not exceed 200 kW: every strategy overloads them
    changes = {f"network.substations.{k}.overload_power_kw": 200 for k in range(3)}
    changes |= {f"network.substations.{k}.rated_power_kw": 100 for k in range(3)}
    path = _write(tmp_path, "weak.yaml", "metro_scenario.yaml", **changes, **{"simulation.end_s": 60})
    result = CliRunner().invoke(
        app, ["power", str(path), "--compare-driving", "fastest,optimal", "--supplement", "10%"]
    )
    assert result.exit_code == 3
    assert "status (fastest): substation_overloaded" in result.stdout
    assert "status: substation_overloaded" in result.stdout


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--compare-driving", "fastest,bogus"], "--compare-driving"),
        (["--compare-driving", "fastest"], "--compare-driving"),
        (["--compare-driving", "optimal,optimal"], "--compare-driving"),
        (["--compare-driving", "fastest,optimal", "--supplement", "ten"], "--supplement"),
        (["--compare-driving", "fastest,optimal", "--supplement", "400%"], "--supplement"),
        (["--supplement", "10%"], "--supplement"),
        (["--compare-driving", "fastest,optimal", "--supplement", "10%", "--synchronise"], "--synchronise"),
    ],
)
def test_bad_option_values_exit_2_naming_the_option(files, args, option):
    result = CliRunner().invoke(app, ["power", str(files[0]), *args])
    assert result.exit_code == 2, result.output
    assert option in result.output
    assert "Traceback" not in result.output


def test_an_operation_file_is_refused():
    path = EXAMPLES / "metro_750v_operated.yaml"
    result = CliRunner().invoke(
        app, ["power", str(path), "--compare-driving", "fastest,optimal", "--supplement", "10%"]
    )
    assert result.exit_code == 2
    assert "--compare-driving" in result.output and "operation" in result.output
