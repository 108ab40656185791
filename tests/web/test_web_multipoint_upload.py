"""Uploading one's own multi-point scenario (issue 19): read as ``trainsim run`` reads it (the same
readers), run with the multi-point model, answered with the heat map and extreme couplers; errors
name the file inside the upload, the line and the field."""

from __future__ import annotations

import io
import zipfile
from typing import Any

import pytest
import yaml
from fastapi.testclient import TestClient

import trainsim
from trainsim.web import WebSettings, create_app

from .conftest import REPO

HEAVY = REPO / "examples" / "heavy_haul"


def small_scenario() -> dict[str, Any]:
    """The heavy-haul example cut to 1 locomotive + 12 wagons on the first 6 km (a quick run)."""
    train = yaml.safe_load((HEAVY / "train.yaml").read_text())
    train["formation"][0]["count"] = 1
    train["formation"][1]["count"] = 12
    route = yaml.safe_load((HEAVY / "route.yaml").read_text())
    route["length_m"] = 6000
    route["stations"] = [{"name": "Mine", "position_m": 0}, {"name": "Siding", "position_m": 6000}]
    for key in ("speed_limits", "gradients", "curves", "tunnels", "electrification"):
        if isinstance(route.get(key), list):
            route[key] = [x for x in route[key] if x.get("from_m", x.get("position_m", 0)) < 6000]
    scenario = yaml.safe_load((HEAVY / "scenario_head.yaml").read_text())
    scenario["train"], scenario["route"] = train, route
    scenario["multi_point"]["locomotive_positions"] = [0]
    return scenario


def _zip(files: dict[str, str]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as zf:
        for name, text in files.items():
            zf.writestr(name, text)
    return out.getvalue()


@pytest.fixture(scope="module")
def client():
    with TestClient(create_app(WebSettings(workers=0, drive_hosts=0))) as c:
        yield c


def test_an_uploaded_scenario_runs_as_the_cli_runs_it(client: TestClient, tmp_path) -> None:
    scenario = small_scenario()
    text = yaml.safe_dump(scenario, sort_keys=False)
    r = client.post("/api/multipoint/upload", files={"file": ("mine.yaml", text.encode())})
    assert r.status_code == 200, r.text
    mp = r.json()
    assert mp["scenario"] == "mine.yaml" and mp["vehicles"] == 13 and mp["locomotives"] == [0]
    assert len(mp["heatmap"]["force_kn"]) == 12  # one row per coupling
    # the command line's reading of the same file gives the same run
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    cli = trainsim.run(trainsim.load_scenario(path))
    assert mp["running_time_s"] == pytest.approx(cli.run.running_time_s, rel=1e-12)
    assert mp["max_draft"]["force_kn"] == pytest.approx(cli.max_draft.force_n / 1e3, rel=1e-12)
    # the same as a zip of a scenario folder whose scenario names its train and route files
    folder = {
        "heavy/scenario.yaml": yaml.safe_dump({**scenario, "train": "train.yaml", "route": "route.yaml"}),
        "heavy/train.yaml": yaml.safe_dump(scenario["train"]),
        "heavy/route.yaml": yaml.safe_dump(scenario["route"]),
    }
    r = client.post("/api/multipoint/upload", files={"file": ("heavy.zip", _zip(folder))})
    assert r.status_code == 200, r.text
    assert r.json()["running_time_s"] == pytest.approx(cli.run.running_time_s, rel=1e-12)


def test_errors_name_the_file_in_the_upload_the_line_and_the_field(client: TestClient) -> None:
    scenario = small_scenario()
    train = yaml.safe_dump(scenario["train"], sort_keys=False).replace("mass_t: 150", "mass_t: -150")
    folder = {
        "scenario.yaml": yaml.safe_dump({**scenario, "train": "train.yaml"}),
        "train.yaml": train,
    }
    r = client.post("/api/multipoint/upload", files={"file": ("mine.zip", _zip(folder))})
    assert r.status_code == 422, r.text
    d = r.json()["detail"][0]
    assert d["file"] == "mine.zip/train.yaml" and d["field"] == "formation[0].mass_t" and d["line"]
    assert "tmp" not in r.text and "trainsim-web-" not in r.text
    # not the multi-point model
    single = {k: v for k, v in scenario.items() if k not in ("model", "multi_point")}
    r = client.post("/api/multipoint/upload", files={"file": ("one.yaml", yaml.safe_dump(single).encode())})
    assert r.status_code == 422 and r.json()["detail"][0]["field"] == "model"
    assert r.json()["detail"][0]["file"] == "one.yaml"
    # a billion wagons are refused before anything is built
    scenario["train"]["formation"][1]["count"] = 1_000_000_000
    r = client.post("/api/multipoint/upload", files={"file": ("big.yaml", yaml.safe_dump(scenario).encode())})
    assert r.status_code == 422 and "vehicles" in r.text
    for name, content in (("x.zip", b"not a zip"), ("x.xlsx", b"PK"), ("x.zip", _zip({"a.yaml": "a: 1"}))):
        r = client.post("/api/multipoint/upload", files={"file": (name, content)})
        assert r.status_code == 422, (name, r.text)
        assert r.json()["detail"][0]["file"] == name
