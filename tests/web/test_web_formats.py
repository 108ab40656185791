"""Uploads of every format the CLI reads go through the same readers and give the same messages."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

import trainsim

from .conftest import REPO

DATA = REPO / "tests" / "interchange" / "data"
TTOBENCH = REPO.parent / "shared" / "data" / "ttobench"


def _zip(folder: Path) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for f in sorted(folder.iterdir()):
            zf.write(f, f"{folder.name}/{f.name}")
    return buf.getvalue()


@pytest.mark.parametrize("name", ["testline_railml2.xml", "testline_railml3.xml"])
def test_railml_train_upload_reads_the_file_as_the_cli(client: TestClient, name: str) -> None:
    r = client.post("/api/train/upload", files={"file": (name, (DATA / name).read_bytes())})
    assert r.status_code == 200, r.text
    cli = trainsim.load_train(DATA / name)
    assert r.json()["figures"]["mass_t"] == pytest.approx(cli.mass_kg / 1000)
    assert any("railml" in n.lower() for n in r.json()["notes"])


def test_railml3_route_without_formulas_gets_the_cli_message(client: TestClient) -> None:
    r = client.post(
        "/api/route/upload", files={"file": ("line.xml", (DATA / "testline_railml3.xml").read_bytes())}
    )
    with pytest.raises(trainsim.InputError) as cli:
        trainsim.load_route(DATA / "testline_railml3.xml")
    assert r.status_code == 422
    assert r.json()["message"] == str(cli.value).replace(str(DATA / "testline_railml3.xml"), "line.xml")


def test_zipped_csv_tables_and_a_run(client: TestClient) -> None:
    content = _zip(DATA / "testline_csv")
    assert client.post("/api/train/upload", files={"file": ("t.zip", content)}).status_code == 200
    r = client.post("/api/route/upload", files={"file": ("t.zip", content)})
    assert r.status_code == 200, r.text
    run = client.post("/api/runs", json={})
    assert run.status_code == 201 and run.json()["status"] == "ok"
    assert (run.json()["train"], run.json()["route"]) == ("Test IC", "Testline")


@pytest.mark.skipif(not TTOBENCH.is_dir(), reason="TTOBench data not found next to the repository")
def test_ttobench_train_and_track(client: TestClient) -> None:
    train = TTOBENCH / "trains" / "CH_Stadler_FLIRT_TPF.json"
    track = sorted((TTOBENCH / "tracks").glob("*.json"))[0]
    assert (
        client.post("/api/train/upload", files={"file": (train.name, train.read_bytes())}).status_code == 200
    )
    r = client.post("/api/route/upload", files={"file": (track.name, track.read_bytes())})
    assert r.status_code == 200, r.text
    assert client.post("/api/runs", json={"settings": {"max_step_m": 50}}).status_code == 201


def test_xml_that_is_not_railml_is_not_called_yaml(client: TestClient) -> None:
    r = client.post("/api/train/upload", files={"file": ("x.xml", b"<html><body/></html>")})
    assert r.status_code == 422 and "YAML" not in r.json()["message"]


def test_compare_a_drive_with_the_fastest_run_of_its_own_train_line_and_distance(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive") as ws:
        ws.send_json({"type": "start", "clock": "manual"})
        while ws.receive_json()["type"] != "state":
            pass
        ws.send_json({"type": "step", "dt_s": 20, "command": 1.0})
        ws.receive_json()
        ws.send_json({"type": "finish"})
        while (msg := ws.receive_json())["type"] != "finished":
            pass
    drive_id = msg["run"]["id"]
    # another train and line loaded in the meantime must not matter
    metro.post("/api/examples/freight_000")
    r = metro.post(f"/api/runs/{drive_id}/fastest")
    assert r.status_code == 422 and "second station" in r.json()["message"]  # it never left S1's section
    metro.post("/api/examples/metro_b")
    with metro.websocket_connect("/api/drive") as ws:
        ws.send_json({"type": "start", "clock": "manual"})
        init = ws.receive_json()
        s2 = init["profile"]["stations"][1]
        msg = ws.receive_json()
        while msg["position_m"] < s2["position_m"] + 100:  # full power past S2 (ATP holds the limit)
            ws.send_json({"type": "step", "dt_s": 10, "command": 1.0})
            msg = ws.receive_json()
        ws.send_json({"type": "finish"})
        while (msg := ws.receive_json())["type"] != "finished":
            pass
    drive = msg["run"]
    metro.post("/api/examples/freight_000")  # the session's train and line now differ: must not matter
    r = metro.post(f"/api/runs/{drive['id']}/fastest")
    assert r.status_code == 201, r.text
    fastest = r.json()
    assert (fastest["train"], fastest["route"]) == (drive["train"], drive["route"])
    assert f"to {s2['name']}" in fastest["label"]
    assert fastest["plot"]["position_m"][-1] == pytest.approx(s2["position_m"])


@pytest.mark.filterwarnings("ignore")
def test_energy_time_curve(metro: TestClient) -> None:
    r = metro.post("/api/curves/energy-time", json={"supplements_percent": [10, 0, 20]})
    assert r.status_code == 200, r.text
    points = r.json()["points"]
    assert [p["supplement_percent"] for p in points] == [0, 10, 20]
    times = [p["running_time_s"] for p in points]
    energies = [p["energy_kwh"] for p in points]
    assert times == sorted(times) and energies == sorted(energies, reverse=True)
    body = json.dumps({"supplements_percent": [float("inf")] * 20})
    bad = metro.post("/api/curves/energy-time", content=body, headers={"content-type": "application/json"})
    assert bad.status_code == 422


@pytest.mark.filterwarnings("ignore")
def test_energy_efficient_run_with_timing_point_windows(metro: TestClient) -> None:
    def run(points: object) -> object:
        body = {"strategy": "energy_efficient", "params": {"supplement_percent": 10, "timing_points": points}}
        return metro.post("/api/runs", content=json.dumps(body), headers={"content-type": "application/json"})

    met = run([{"position_m": 800, "earliest_s": 10, "latest_s": 200, "name": "P1"}])
    assert met.status_code == 201 and not met.json()["summary"]["warnings"]
    missed = run([{"position_m": 800, "latest_s": 5, "name": "P1"}])
    assert missed.status_code == 201 and any("P1" in w for w in missed.json()["summary"]["warnings"])
    bad = run([{"position_m": 800, "latest_s": float("nan")}])
    assert bad.status_code == 422 and bad.json()["detail"][0]["field"] == "params.timing_points[0].latest_s"
