"""Issue 18 audit: the power file's numbers and switches take no bool or string in their place
(``rounds: true`` was 1 pass, ``avoid_overload: 'yes'`` was True) and a step wider than the window
is reported against ``synchronisation.step_s``; all through ``trainsim power FILE`` (exit 2)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from trainsim.cli import app

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"


def _file(tmp_path: Path, where: str, key: str, value: object) -> Path:
    """The synchronised metro example with one field changed (its scenario path made absolute)."""
    doc = yaml.safe_load((EXAMPLES / "metro_750v_diode_sync.yaml").read_text())
    for train in doc["trains"]:
        train["scenario"] = (EXAMPLES / train["scenario"]).as_posix()
    target = doc
    for part in where.split("."):
        target = target[int(part)] if isinstance(target, list) else target.setdefault(part, {})
    target[key] = value
    path = tmp_path / "power.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize(
    ("where", "key", "value", "field", "allowed"),
    [
        ("synchronisation", "rounds", True, "synchronisation.rounds", "a whole number"),
        ("synchronisation", "rounds", "3", "synchronisation.rounds", "a whole number"),
        ("synchronisation", "refinements", 1.5, "synchronisation.refinements", "a whole number"),
        ("synchronisation", "avoid_overload", "yes", "synchronisation.avoid_overload", "true or false"),
        ("synchronisation", "step_s", 50, "synchronisation.step_s", "<= window_s (20 s)"),
        ("synchronisation", "window_s", True, "synchronisation.window_s", "a number"),
        ("simulation.feedback", "enabled", "yes", "simulation.feedback.enabled", "true or false"),
        ("simulation.feedback", "knock_on", 1, "simulation.feedback.knock_on", "true or false"),
        (
            "simulation.feedback",
            "max_iterations",
            True,
            "simulation.feedback.max_iterations",
            "a whole number",
        ),
        ("simulation", "step_s", "1", "simulation.step_s", "a number"),
        ("network", "negative_earthed", "no", "network.negative_earthed", "true or false"),
        (
            "network.substations.0",
            "reversible",
            "false",
            "network.substations[0].reversible",
            "true or false",
        ),
        ("trains.0", "direction", True, "trains[0].direction", "1 or -1"),
        ("trains.0.headway", "count", True, "trains[0].headway.count", "a whole number"),
    ],
)
def test_a_bool_or_string_in_place_of_a_number_or_switch_exits_2(tmp_path, where, key, value, field, allowed):
    path = _file(tmp_path, where, key, value)
    result = CliRunner().invoke(app, ["power", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    text = " ".join(result.output.split())
    assert f"field '{field}'" in text
    assert f"(got {value!r})" in text
    assert f"allowed: {allowed}" in text


def test_the_strict_fields_still_take_ints_for_floats_and_minus_one(tmp_path):
    """Whole numbers where floats are wanted and direction -1 are not refused by the strict types."""
    path = _file(tmp_path, "synchronisation", "window_s", 30)
    from trainsim.io.power_file import load_power_file

    spec, _, services = load_power_file(path)
    assert spec.synchronisation.window_s == 30.0
    assert {s.direction for s in services} == {1, -1}
