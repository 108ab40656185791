"""The power file's ``synchronisation:`` block and ``trainsim power --synchronise`` (issue 18)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.errors import InputError
from trainsim.io.power_file import load_power_file, run_power_file

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"


def _file(tmp_path: Path, sync: dict | None, count: int = 2) -> Path:
    data = yaml.safe_load((EXAMPLES / "metro_750v_diode.yaml").read_text())
    for t in data["trains"]:
        t["scenario"] = str(EXAMPLES / t["scenario"])
        t["headway"]["count"] = count
    if sync is not None:
        data["synchronisation"] = sync
    path = tmp_path / "sync.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("sync", "field"),
    [
        ({"window_s": -5}, "synchronisation.window_s"),
        ({"step_s": 0}, "synchronisation.step_s"),
        ({"window_s": 10, "step_s": 20}, "synchronisation.step_s"),
        ({"rounds": 0}, "synchronisation.rounds"),
        ({"min_headway_s": -1}, "synchronisation.min_headway_s"),
        ({"per": "day"}, "synchronisation.per"),
        ({"windows": 3}, "synchronisation.windows"),
    ],
)
def test_bad_block_values_name_the_field(tmp_path, sync, field):
    with pytest.raises(InputError) as err:
        load_power_file(_file(tmp_path, sync))
    problem = err.value.problems[0]
    assert problem.field == field and problem.file.endswith("sync.yaml")


@pytest.fixture(scope="module")
def synchronised(tmp_path_factory):
    """Two departures each way, +-20 s on a 20 s grid (one pass): few network solutions."""
    tmp = tmp_path_factory.mktemp("sync")
    path = _file(tmp, {"window_s": 20, "step_s": 20, "rounds": 1, "refinements": 0, "min_headway_s": 150})
    return path, run_power_file(path)


def test_block_reports_energies_offsets_and_keeps_the_constraints(synchronised):
    _, (summary, status) = synchronised
    sync = summary["synchronisation"]
    assert sync["status"] == "ok" and sync["per"] == "departure"
    assert sync["saving_kwh"] == pytest.approx(sync["baseline_kwh"] - sync["synchronised_kwh"], rel=1e-12)
    assert sync["saving_percent"] == pytest.approx(100 * sync["saving_kwh"] / sync["baseline_kwh"], rel=1e-12)
    assert sync["saving_kwh"] >= 0
    deps = sync["departures"]
    assert [d["id"] for d in deps] == ["up#0", "up#1", "down#0", "down#1"]
    assert all(abs(d["offset_s"]) <= 20 and d["offset_s"] in (-20, 0, 20) for d in deps)
    for service in ("up", "down"):
        times = [d["synchronised_departure_s"] for d in deps if d["service"] == service]
        assert times[1] - times[0] >= 150 - 1e-9
    # the study is solved over the synchronisation's span: its substation energy is the synchronised one
    assert summary["substations_energy_kwh"] == pytest.approx(sync["synchronised_kwh"], rel=1e-9)
    assert status == summary["status"]


def _assert_close(got, want, where="synchronisation"):
    """Nested dicts and lists compared number by number (pytest.approx takes no nesting)."""
    if isinstance(want, dict):
        assert set(got) == set(want), where
        for key in want:
            _assert_close(got[key], want[key], f"{where}.{key}")
    elif isinstance(want, (list, tuple)):
        assert len(got) == len(want), where
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            _assert_close(g, w, f"{where}[{k}]")
    elif isinstance(want, float):
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12), where
    else:
        assert got == want, where


def test_cli_json_and_table(synchronised, tmp_path):
    path, (summary, _) = synchronised
    runner = CliRunner()
    res = runner.invoke(app, ["power", str(path), "--json"])
    assert res.exit_code in (0, 3), res.output
    data = json.loads(res.output)
    _assert_close(data["synchronisation"], summary["synchronisation"])
    res = runner.invoke(app, ["power", str(path), "--no-synchronise", "--json"])
    assert "synchronisation" not in json.loads(res.output)


def test_an_impossible_headway_is_a_status_and_exit_3(tmp_path):
    path = _file(tmp_path, {"window_s": 10, "step_s": 10, "rounds": 1, "min_headway_s": 250}, count=2)
    res = CliRunner().invoke(app, ["power", str(path)])
    assert res.exit_code == 3, res.output
    assert "headway_not_met" in res.output and "250 s" in res.output


def test_the_synchronised_example_reads():
    spec, _, services = load_power_file(EXAMPLES / "metro_750v_diode_sync.yaml")
    s = spec.synchronisation
    assert (s.window_s, s.step_s, s.rounds, s.refinements, s.min_headway_s, s.per, s.avoid_overload) == (
        20,
        10,
        2,
        1,
        150,
        "departure",
        True,
    )
    assert sum(len(x.departures_s) for x in services) == 20
