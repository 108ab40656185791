"""A route file's electrification entries set ``traction_share`` (io/yaml_route.py): read strictly, passed
to the core, and honoured by an electric train's run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

import trainsim
from trainsim.cli import app
from trainsim.errors import InputError
from trainsim.io.yaml_route import route_spec_from_dict

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
ROUTE = EXAMPLES / "metro_b" / "route.yaml"
TRAIN = EXAMPLES / "power" / "metro_train.yaml"
LIMITED_TO_M = 1600.68  # the share applies from the origin to the second station


def _route_data(share: object) -> dict:
    data = yaml.safe_load(ROUTE.read_text())
    data["electrification"] = [
        {"from_m": 0.0, "to_m": LIMITED_TO_M, "voltage_v": 750, "traction_share": share},
        {"from_m": LIMITED_TO_M, "voltage_v": 750},
    ]
    return data


def _write(tmp_path: Path, share: object) -> Path:
    route = tmp_path / "route.yaml"
    route.write_text(yaml.safe_dump(_route_data(share)))
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(
        yaml.safe_dump(
            {
                "schema": "trainsim/scenario",
                "version": 1,
                "name": "share test",
                "train": str(TRAIN),
                "route": "route.yaml",
                "settings": {"max_step_m": 5},
            }
        )
    )
    return scenario


def _running_time_s(tmp_path: Path, share: float) -> float:
    sub = tmp_path / f"share_{share:g}"
    sub.mkdir()
    scenario = trainsim.load_scenario(_write(sub, share))
    assert scenario.train.electrical is not None, "the share only acts on an electric train"
    assert [e.traction_share for e in scenario.route.electrification] == [share, 1.0]
    return float(trainsim.run(scenario).trace.time_s[-1])


def test_share_slows_an_electric_train(tmp_path):
    full = _running_time_s(tmp_path, 1.0)
    half = _running_time_s(tmp_path, 0.5)
    # half the effort over the first stretch (a start from rest, power- and adhesion-limited) must cost
    # time there; the rest of the line is the same
    assert half > full + 1.0, (half, full)


def test_share_defaults_to_full_effort():
    data = _route_data(1.0)
    del data["electrification"][0]["traction_share"]
    route = route_spec_from_dict(data, "route.yaml").to_route("route.yaml")
    assert [e.traction_share for e in route.electrification] == [1.0, 1.0]


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        (0, "out of range"),
        (1.5, "out of range"),
        (-0.2, "out of range"),
        ("x", "not text"),
        ("0.5", "not text"),
        (True, "not true/false"),
        (math.nan, "finite"),
        (math.inf, "finite"),
    ],
)
def test_bad_share_refused(value, reason):
    with pytest.raises(InputError) as info:
        route_spec_from_dict(_route_data(value), "route.yaml").to_route("route.yaml")
    err = info.value
    text = str(err)
    assert err.file == "route.yaml"
    assert err.field == "electrification[0].traction_share"
    assert reason in text
    assert "> 0" in text, text  # what is allowed: above 0 ...
    if reason != "out of range" or value != -0.2:
        assert "<= 1" in text, text  # ... up to 1


def test_cli_check_accepts_and_rejects(tmp_path):
    scenario = _write(tmp_path, 0.5)
    runner = CliRunner()
    ok = runner.invoke(app, ["check", str(tmp_path / "route.yaml")])
    assert ok.exit_code == 0, ok.output
    run = runner.invoke(app, ["run", str(scenario), "--json"])
    assert run.exit_code == 0, run.output
    assert json.loads(run.output)["status"] == "ok"
    (tmp_path / "route.yaml").write_text(yaml.safe_dump(_route_data(1.5)))
    bad = runner.invoke(app, ["check", str(tmp_path / "route.yaml")])
    assert bad.exit_code == 2, bad.output
    assert "traction_share" in bad.output and "1.5" in bad.output
    assert "Traceback" not in bad.output


def test_a_share_survives_writing_the_route_back_to_yaml(tmp_path) -> None:
    """``trainsim convert`` writes the share where it is not 1, and the file reads back to the same
    electrification (routes without shares are written as before)."""
    import dataclasses

    from trainsim.io.convert import dump_yaml, route_document
    from trainsim.model.route import ElectrificationSection

    line = trainsim.load_route("examples/metro_b/route.yaml")
    mid = 0.5 * (line.start_m + line.end_m)
    full = (ElectrificationSection(line.start_m, mid, 750.0), ElectrificationSection(mid, line.end_m, 750.0))
    route = dataclasses.replace(line, electrification=full)
    half = dataclasses.replace(full[0], traction_share=0.5)
    shared = dataclasses.replace(route, electrification=(half, full[1]))
    doc = route_document(shared)
    assert doc["electrification"][0]["traction_share"] == 0.5
    assert all("traction_share" not in e for e in doc["electrification"][1:])
    assert all("traction_share" not in e for e in route_document(route)["electrification"])
    path = tmp_path / "route.yaml"
    path.write_text(dump_yaml(doc))
    assert trainsim.load_route(path).electrification == shared.electrification
