"""Exit codes, statuses and help of the command line: a status other than ok is shown in the table and
the JSON alike, and the process exits with 3; bad input with 2; a missing extra is named."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.cli.context import ExitCode, user_errors

ROOT = Path(__file__).resolve().parents[2]
METRO = ROOT / "examples" / "metro_b" / "scenario.yaml"


@pytest.fixture
def too_fast_timetable(tmp_path: Path) -> Path:
    # every section of the metro needs more than 89 s at full power: 50 s cannot be met
    path = tmp_path / "timetable.yaml"
    path.write_text(
        "schema: trainsim/timetable\nversion: 1\nsections:\n"
        + "".join("  - running_time_s: 50\n" for _ in range(3))
    )
    return path


def test_infeasible_schedule_says_so_in_table_json_and_exit_code(too_fast_timetable):
    runner = CliRunner()
    table = runner.invoke(app, ["optimize", str(METRO), "--timetable", str(too_fast_timetable)])
    assert table.exit_code == ExitCode.NOT_AS_ASKED, table.output
    assert "status infeasible schedule" in table.stdout  # the table's caption
    assert "status: infeasible schedule" in table.stdout
    assert "cannot be met" in table.output
    as_json = runner.invoke(app, ["optimize", str(METRO), "--timetable", str(too_fast_timetable), "--json"])
    assert as_json.exit_code == ExitCode.NOT_AS_ASKED
    assert json.loads(as_json.stdout)["status"] == "infeasible schedule"


def test_ok_run_exits_0_and_bad_input_2(tmp_path):
    runner = CliRunner()
    ok = runner.invoke(app, ["run", str(METRO), "--json"])
    assert ok.exit_code == 0 and json.loads(ok.stdout)["status"] == "ok"
    missing = runner.invoke(app, ["run", str(tmp_path / "nope.yaml")])
    assert missing.exit_code == ExitCode.USER_ERROR
    assert "error:" in missing.output and "Traceback" not in missing.output


def test_several_problems_are_listed_one_per_line():
    from trainsim.errors import InputError, Problem

    error = InputError.from_problems(
        [Problem("must be > 0", field="mass_t", value=-1), Problem("unknown field", field="colour")],
        file="train.yaml",
    )
    runner = CliRunner()

    def raise_it():
        with user_errors():
            raise error

    import typer

    single = typer.Typer()
    single.command()(raise_it)
    result = runner.invoke(single, [])
    assert result.exit_code == ExitCode.USER_ERROR
    lines = result.output.strip().splitlines()
    assert lines[0] == "error: 2 problems in train.yaml:"
    assert lines[1].startswith("  - field 'mass_t': must be > 0 (got -1)")
    assert lines[2] == "  - field 'colour': unknown field"


def test_a_missing_extra_is_named():
    import typer

    def needs_web():
        with user_errors():
            raise ModuleNotFoundError("No module named 'fastapi'", name="fastapi")

    single = typer.Typer()
    single.command()(needs_web)
    result = CliRunner().invoke(single, [])
    assert result.exit_code == ExitCode.USER_ERROR
    assert 'pip install "trainsim[web]"' in result.output


def test_help_lists_every_command_and_the_exit_codes():
    result = CliRunner().invoke(app, ["--help"])
    assert result.exit_code == 0
    for command in ("run", "check", "optimize", "batch", "convert", "export-results", "runtimes", "serve"):
        assert f"  {command} " in result.output
    text = " ".join(result.output.split())  # the help wraps to the terminal's width
    assert "Exit codes: 0 ok" in text and "3 ran, but the result is not what was asked" in text
    flags = CliRunner().invoke(app, ["run", "--help"]).output
    assert "--plots / --no-plots" in flags and "<bool>" not in flags


def test_python_m_trainsim_and_version():
    out = subprocess.run(
        [sys.executable, "-m", "trainsim", "--version"], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0 and out.stdout.startswith("trainsim ")
    out = subprocess.run(
        [sys.executable, "-m", "trainsim.cli", "--help"], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0 and "export-results" in out.stdout


@pytest.mark.parametrize(
    ("file", "kind"),
    [
        ("examples/studies/metro_load_efficiency.yaml", "study"),
        ("examples/operations/metro_cbtc.yaml", "operation"),
        ("examples/power/main_line_25kv.yaml", "power supply"),
    ],
)
def test_check_reads_the_files_of_every_layer(file, kind):
    result = CliRunner().invoke(app, ["check", str(ROOT / file)])
    assert result.exit_code == 0, result.output
    assert f": {kind} '" in result.output
