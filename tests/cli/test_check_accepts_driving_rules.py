"""``trainsim optimize`` accepts the driving rules only from strategies that apply them (issue 13):
``--min-regime-time`` or ``--coast-min-speed`` with ``--strategy lesov`` or ``fastest`` ran without
them and added a warning that turned the status into "infeasible schedule" (exit 3), blaming a
timetable that can be met. It is now an input error naming the option and the strategies (exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.cli.context import ExitCode

METRO = Path(__file__).resolve().parents[2] / "examples" / "metro_b" / "scenario.yaml"


@pytest.mark.parametrize("strategy", ["lesov", "fastest"])
@pytest.mark.parametrize("option", [["--min-regime-time", "5"], ["--coast-min-speed", "40"]])
def test_a_driving_rule_asked_of_a_strategy_that_does_not_apply_it_is_an_input_error(strategy, option):
    r = CliRunner().invoke(
        app, ["optimize", str(METRO), "--supplement", "10%", "--strategy", strategy, *option]
    )
    assert r.exit_code == ExitCode.USER_ERROR, r.output
    assert r.stdout == ""  # refused before any run: no table, no status
    message = r.stderr.strip()
    assert message.startswith("error: ") and "Traceback" not in r.output
    assert f"{option[0]} applies to the optimal and reference strategies" in message
    assert f"strategy {strategy} does not apply it" in message


def test_the_same_rule_with_the_optimal_strategy_runs_and_other_constraints_stay_open_to_all():
    runner = CliRunner()
    base = ["optimize", str(METRO), "--supplement", "10%", "--json"]
    optimal = runner.invoke(app, [*base, "--coast-min-speed", "40"])
    assert optimal.exit_code == ExitCode.OK, optimal.output
    assert json.loads(optimal.stdout)["status"] == "ok"
    # a speed margin applies to every strategy: fastest takes it without a status flip
    fastest = runner.invoke(app, [*base, "--strategy", "fastest", "--speed-margin", "2"])
    assert fastest.exit_code == ExitCode.OK, fastest.output
    assert json.loads(fastest.stdout)["status"] == "ok"
