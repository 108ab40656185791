"""The JSON API with FastAPI's test client: every endpoint, valid and invalid input."""

from __future__ import annotations

import copy
import io
import json

import pandas as pd
import pytest
import yaml
from fastapi.testclient import TestClient

import trainsim
from trainsim.web import WebSettings, create_app, strategies
from trainsim.web.sessions import COOKIE_NAME, HEADER_NAME

from .conftest import REPO

# what `trainsim run examples/metro_b/scenario.yaml` gives (the web must give the same)
METRO_RUNNING_TIME_S = trainsim.run(
    trainsim.load_scenario(REPO / "examples" / "metro_b" / "scenario.yaml")
).running_time_s


def _fields(response) -> list[str | None]:
    return [d["field"] for d in response.json()["detail"]]


# ====================================================================== session, pages, docs
def test_health_and_page_and_assets_are_served(client: TestClient) -> None:
    assert client.get("/api/health").json()["status"] == "ok"
    page = client.get("/")
    assert page.status_code == 200 and "<title>trainsim</title>" in page.text
    assert client.head("/").status_code == 200
    js = client.get("/vendor/plotly.min.js")
    assert js.status_code == 200 and len(js.content) > 1_000_000 and b"plotly" in js.content[:2000].lower()
    for path in ("/static/js/main.js", "/static/js/editor.js", "/static/js/plots.js", "/static/app.css"):
        assert client.get(path).status_code == 200, path


def test_docs_are_offline_and_openapi_lists_the_endpoints(client: TestClient) -> None:
    docs = client.get("/docs")
    assert docs.status_code == 200
    assert "/vendor/docs/swagger-ui-bundle.js" in docs.text and "cdn" not in docs.text.lower()
    assert client.get("/vendor/docs/swagger-ui-bundle.js").status_code == 200
    assert client.get("/redoc").status_code == 200
    spec = client.get("/openapi.json").json()
    for path in (
        "/api/train",
        "/api/route",
        "/api/runs",
        "/api/runs/{run_id}/trace.csv",
        "/api/examples/{name}",
        "/api/train/upload",
        "/api/strategies",
    ):
        assert path in spec["paths"], path


def test_a_new_session_comes_back_in_cookie_and_header(client: TestClient) -> None:
    r = client.get("/api/session")
    sid = r.json()["id"]
    assert r.headers[HEADER_NAME] == sid
    assert f"{COOKIE_NAME}={sid}" in r.headers["set-cookie"] and "HttpOnly" in r.headers["set-cookie"]
    # the cookie keeps the session: no new cookie, same id
    again = client.get("/api/session")
    assert again.json()["id"] == sid and "set-cookie" not in again.headers


def test_the_header_names_the_session_for_api_clients(app) -> None:
    with TestClient(app) as a, TestClient(app) as b:
        sid = a.post("/api/examples/metro_b").headers[HEADER_NAME]
        assert b.get("/api/train").status_code == 404
        r = b.get("/api/train", headers={HEADER_NAME: sid})
        assert r.status_code == 200 and r.json()["name"].startswith("Type B metro")
        # a made-up id gets a new session, not someone else's
        assert b.get("/api/session", headers={HEADER_NAME: "x" * 30}).json()["id"] != "x" * 30


def test_sessions_do_not_see_or_disturb_each_other(app) -> None:
    with TestClient(app) as a, TestClient(app) as b:
        a.post("/api/examples/metro_b")
        run_a = a.post("/api/runs", json={}).json()
        assert b.get("/api/train").status_code == 404
        assert b.get("/api/runs").json() == []
        assert b.get(f"/api/runs/{run_a['id']}").status_code == 404
        b.post("/api/examples/loco_001")
        b.delete(f"/api/runs/{run_a['id']}")
        assert a.get("/api/train").json()["name"].startswith("Type B metro")
        assert [r["id"] for r in a.get("/api/runs").json()] == [run_a["id"]]


# ====================================================================== examples and schemas
def test_examples_list_and_load(client: TestClient) -> None:
    names = [e["name"] for e in client.get("/api/examples").json()]
    assert names == ["metro_b", "loco_001", "freight_000"]
    r = client.post("/api/examples/freight_000")
    assert r.status_code == 200
    body = r.json()
    assert body["route"]["profile"]["end_m"] == 60000
    assert body["train"]["figures"]["mass_t"] == pytest.approx(2 * 138 + 50 * 80)
    assert client.get("/api/session").json()["settings"]["max_step_m"] > 0


def test_unknown_example_is_404_with_the_allowed_names(client: TestClient) -> None:
    for url in ("/api/examples/nope", "/api/train/example/nope", "/api/route/example/nope"):
        r = client.post(url)
        assert r.status_code == 404 and "metro_b" in r.json()["message"]


def test_schemas(client: TestClient) -> None:
    train = client.get("/api/schema/train").json()
    assert "DavisKnKmhTerm" in train["$defs"]
    assert "stations" in client.get("/api/schema/route").json()["properties"]
    assert client.get("/api/schema/scenario").status_code == 404


# ====================================================================== train
def test_train_get_before_loading_is_404(client: TestClient) -> None:
    r = client.get("/api/train")
    assert r.status_code == 404 and "no train" in r.json()["message"]


def test_train_example_has_spec_curves_and_figures(client: TestClient) -> None:
    body = client.post("/api/train/example/metro_b").json()
    assert body["spec"]["traction"]["force_kn"][0] == 93.25
    curves = body["curves"]
    assert len(curves["speed_kmh"]) == len(curves["traction_kn"]) == len(curves["resistance_kn"])
    assert curves["traction_kn"][0] == pytest.approx(4 * 93.25)
    assert body["figures"]["mass_t"] == pytest.approx(288.2)
    assert client.get("/api/train").json()["spec"] == body["spec"]


def test_put_train_updates_curves(metro: TestClient) -> None:
    spec = metro.get("/api/train").json()["spec"]
    spec["traction"]["force_kn"][0] = 100.0
    r = metro.put("/api/train", json=spec)
    assert r.status_code == 200
    assert r.json()["curves"]["traction_kn"][0] == pytest.approx(400.0)
    assert r.json()["source"].endswith("(edited)")


def test_put_invalid_train_gives_field_level_422_and_keeps_the_last_valid(metro: TestClient) -> None:
    good = metro.get("/api/train").json()["spec"]
    bad = copy.deepcopy(good)
    bad["formation"][1]["mass_t"] = -3
    r = metro.put("/api/train", json=bad)
    assert r.status_code == 422
    detail = r.json()["detail"]
    assert detail[0]["field"] == "formation[1].mass_t"
    assert detail[0]["loc"] == ["formation", 1, "mass_t"]
    assert "out of range" in detail[0]["msg"] and "> 0" in detail[0]["msg"]
    assert "formation[1].mass_t" in r.json()["message"]
    # still serving, the valid train kept
    assert metro.get("/api/train").json()["spec"] == good


def test_put_train_with_several_problems_names_each_field(metro: TestClient) -> None:
    bad = metro.get("/api/train").json()["spec"]
    bad["formation"][0]["mass_t"] = "heavy"
    bad["max_speed_kmh"] = -1
    r = metro.put("/api/train", json=bad)
    assert r.status_code == 422
    fields = _fields(r)
    assert "formation[0].mass_t" in fields and "max_speed_kmh" in fields
    by_field = {d["field"]: d["msg"] for d in r.json()["detail"]}
    assert "number" in by_field["formation[0].mass_t"]
    assert "allowed" in by_field["max_speed_kmh"]


def test_put_train_model_level_errors_and_bad_bodies(metro: TestClient) -> None:
    spec = metro.get("/api/train").json()["spec"]
    spec["traction"]["speed_kmh"] = [0, 50, 40, 60, 70, 80]
    r = metro.put("/api/train", json=spec)
    assert r.status_code == 422 and _fields(r) == ["traction.speed_kmh[2]"]
    spec = metro.get("/api/train").json()["spec"]
    spec["resistance"][0]["family"] = "davies"
    r = metro.put("/api/train", json=spec)
    assert r.status_code == 422 and "davis_kn_kmh" in r.json()["detail"][0]["msg"]
    assert metro.put("/api/train", json=[1, 2]).status_code == 422
    assert (
        metro.put(
            "/api/train", content=b"{not json", headers={"content-type": "application/json"}
        ).status_code
        == 422
    )
    assert metro.put("/api/train", json={"schema": "trainsim/route", "version": 1}).status_code == 422


def test_put_train_list_and_body_bounds() -> None:
    app = create_app(WebSettings(max_list_items=10, max_body_bytes=20_000))
    with TestClient(app) as c:
        c.post("/api/examples/metro_b")
        spec = c.get("/api/train").json()["spec"]
        spec["traction"]["speed_kmh"] = list(range(11))
        spec["traction"]["force_kn"] = [100] * 11
        r = c.put("/api/train", json=spec)
        assert r.status_code == 422 and sorted(_fields(r)) == ["traction.force_kn", "traction.speed_kmh"]
        spec["description"] = "x" * 30_000
        r = c.put("/api/train", json=spec)
        assert r.status_code == 413 and "too large" in r.json()["message"]
        assert c.get("/api/health").status_code == 200


def test_train_yaml_download_reads_back(metro: TestClient, tmp_path) -> None:
    r = metro.get("/api/train/yaml")
    assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
    path = tmp_path / "train.yaml"
    path.write_text(r.text)
    train = trainsim.load_train(path)
    assert train.mass_kg == pytest.approx(288_200)


def test_train_yaml_before_loading_is_404(client: TestClient) -> None:
    assert client.get("/api/train/yaml").status_code == 404
    assert client.get("/api/route/yaml").status_code == 404


def test_train_upload_trainsim_and_scenario_files(client: TestClient) -> None:
    text = (REPO / "examples/loco_001/train.yaml").read_bytes()
    r = client.post("/api/train/upload", files={"file": ("loco.yaml", text)})
    assert r.status_code == 200 and r.json()["spec"]["traction"]["model"] == "power_limited"
    assert r.json()["source"] == "loco.yaml"
    inline = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": "s",
        "train": yaml.safe_load(text),
        "route": "route.yaml",
    }
    r = client.post("/api/train/upload", files={"file": ("s.yaml", yaml.safe_dump(inline).encode())})
    assert r.status_code == 200
    # a scenario naming its train file cannot be opened alone
    r = client.post(
        "/api/train/upload",
        files={"file": ("s.yaml", (REPO / "examples/loco_001/scenario.yaml").read_bytes())},
    )
    assert r.status_code == 422 and r.json()["detail"][0]["field"] == "train"


def test_train_upload_railtoolkit_runs_as_the_file(client: TestClient) -> None:
    path = REPO / "tests/data/trainruns/trains/freight.yaml"
    r = client.post("/api/train/upload", files={"file": ("freight.yaml", path.read_bytes())})
    assert r.status_code == 200, r.text
    assert any("railtoolkit" in n for n in r.json()["notes"])
    client.post(
        "/api/route/upload",
        files={"file": ("const.yaml", (REPO / "tests/data/trainruns/paths/const.yaml").read_bytes())},
    )
    web = client.post("/api/runs", json={"settings": {"max_step_m": 10}}).json()["summary"]
    direct = trainsim.run_fastest(
        trainsim.load_train(path),
        trainsim.load_route(REPO / "tests/data/trainruns/paths/const.yaml"),
        trainsim.RunSettings(max_step_m=10),
    )
    assert web["running_time_s"] == pytest.approx(direct.running_time_s, rel=1e-9)
    # and the converted train saves as a trainsim file
    assert "schema: trainsim/train" in client.get("/api/train/yaml").text


def test_train_upload_errors_name_the_file_and_line(client: TestClient) -> None:
    r = client.post("/api/train/upload", files={"file": ("broken.yaml", b"name: [unclosed\n")})
    assert r.status_code == 422
    assert "broken.yaml" in r.json()["message"] and "line" in r.json()["message"]
    assert "/tmp" not in r.json()["message"]
    bad = yaml.safe_load((REPO / "examples/metro_b/train.yaml").read_text())
    bad["formation"][0]["mass_t"] = 0
    r = client.post("/api/train/upload", files={"file": ("t.yaml", yaml.safe_dump(bad).encode())})
    assert r.status_code == 422 and _fields(r) == ["formation[0].mass_t"]
    r = client.post(
        "/api/train/upload", files={"file": ("r.yaml", (REPO / "examples/metro_b/route.yaml").read_bytes())}
    )
    assert r.status_code == 422 and "expected a train file" in r.json()["message"]
    r = client.post("/api/train/upload", files={"file": ("bin.yaml", b"\xff\xfe\x00")})
    assert r.status_code == 422 and "UTF-8" in r.json()["message"]
    assert client.post("/api/train/upload").status_code == 422  # no file
    assert client.get("/api/train").status_code == 404


def test_upload_size_is_bounded() -> None:
    with TestClient(create_app(WebSettings(max_body_bytes=5000))) as c:
        r = c.post("/api/train/upload", files={"file": ("big.yaml", b"#" * 10_000)})
        assert r.status_code == 413
        assert c.get("/api/health").status_code == 200


# ====================================================================== route
def test_route_example_put_and_profile(client: TestClient) -> None:
    body = client.post("/api/route/example/metro_b").json()
    assert [s["name"] for s in body["profile"]["stations"]] == ["S1", "S2", "S3", "S4"]
    spec = body["spec"]
    spec["gradients"] = [{"from_m": 0, "gradient_permille": 0}, {"from_m": 500, "gradient_permille": 12}]
    spec["tunnels"] = [{"from_m": 2000, "length_m": 300}]
    r = client.put("/api/route", json=spec)
    assert r.status_code == 200
    profile = r.json()["profile"]
    assert profile["gradients"] == [[500, 4590.97, 12]]
    assert profile["tunnels"] == [[2000, 2300]]
    assert profile["elevation"]["elevation_m"][-1] == pytest.approx((4590.97 - 500) * 0.012, abs=1e-3)


def test_put_invalid_route_gives_field_level_422(client: TestClient) -> None:
    spec = client.post("/api/route/example/metro_b").json()["spec"]
    spec["stations"][1]["position_m"] = 9000
    r = client.put("/api/route", json=spec)
    assert r.status_code == 422
    assert _fields(r) == ["stations[1].position_m"] and "outside the route" in r.json()["detail"][0]["msg"]
    spec["stations"][1]["position_m"] = 1600
    spec["speed_limits"][0]["limit_kmh"] = 0
    r = client.put("/api/route", json=spec)
    assert r.status_code == 422 and _fields(r) == ["speed_limits[0].limit_kmh"]
    assert client.get("/api/route").json()["spec"]["speed_limits"][0]["limit_kmh"] == 80


def test_route_length_is_bounded() -> None:
    with TestClient(create_app(WebSettings(max_route_length_m=1000))) as c:
        spec = c.post("/api/route/example/metro_b").json()["spec"]
        r = c.put("/api/route", json=spec)
        assert r.status_code == 422 and _fields(r) == ["length_m"]


def test_route_upload_railtoolkit_and_yaml_download(client: TestClient, tmp_path) -> None:
    path = REPO / "tests/data/trainruns/paths/realworld.yaml"
    r = client.post("/api/route/upload", files={"file": ("realworld.yaml", path.read_bytes())})
    assert r.status_code == 200, r.text
    direct = trainsim.load_route(path)
    assert r.json()["figures"]["length_m"] == pytest.approx(direct.length_m)
    out = tmp_path / "route.yaml"
    out.write_text(client.get("/api/route/yaml").text)
    again = trainsim.load_route(out)
    assert again.speed_limits == direct.speed_limits and again.gradients == direct.gradients
    r = client.post(
        "/api/route/upload", files={"file": ("t.yaml", (REPO / "examples/metro_b/train.yaml").read_bytes())}
    )
    assert r.status_code == 422 and "expected a route file" in r.json()["message"]


# ====================================================================== runs
def test_strategies_list_fastest(client: TestClient) -> None:
    names = [s["name"] for s in client.get("/api/strategies").json()]
    assert "fastest" in names


def test_run_needs_train_and_route(client: TestClient) -> None:
    r = client.post("/api/runs", json={})
    assert r.status_code == 409
    client.post("/api/train/example/metro_b")
    assert client.post("/api/runs", json={}).status_code == 409


def test_run_metro_gives_the_cli_running_time(metro: TestClient) -> None:
    r = metro.post("/api/runs", json={"strategy": "fastest", "label": "metro"})
    assert r.status_code == 201
    run = r.json()
    assert run["summary"]["running_time_s"] == pytest.approx(METRO_RUNNING_TIME_S, rel=1e-9)
    assert run["label"] == "metro" and run["status"] == "ok"
    plot = run["plot"]
    assert (
        len(plot["time_s"]) == len(plot["speed_kmh"]) == len(plot["line_current_a"]) == plot["shown_points"]
    )
    assert max(plot["speed_kmh"]) == pytest.approx(80, abs=0.01)
    assert [s["from"] for s in run["summary"]["sections"]] == ["S1", "S2", "S3"]
    assert run["profile"]["end_m"] == pytest.approx(4590.97)


def test_changing_a_speed_limit_changes_the_run(metro: TestClient) -> None:
    before = metro.post("/api/runs", json={}).json()["running_time_s"]
    spec = metro.get("/api/route").json()["spec"]
    spec["speed_limits"][0]["limit_kmh"] = 60
    assert metro.put("/api/route", json=spec).status_code == 200
    after = metro.post("/api/runs", json={}).json()["running_time_s"]
    assert before == pytest.approx(METRO_RUNNING_TIME_S)
    assert after == pytest.approx(329.9065, abs=1e-3)


def test_run_invalid_requests(metro: TestClient) -> None:
    r = metro.post("/api/runs", json={"strategy": "eco"})
    assert r.status_code == 422 and _fields(r) == ["strategy"] and "fastest" in r.json()["detail"][0]["msg"]
    r = metro.post("/api/runs", json={"params": {"supplement": 5}})
    assert r.status_code == 422 and _fields(r) == ["params.supplement"]
    r = metro.post("/api/runs", json={"settings": {"max_step_m": 0}})
    assert r.status_code == 422 and _fields(r) == ["settings.max_step_m"]
    r = metro.post("/api/runs", json={"settings": {"braking_fraction": "all"}})
    assert r.status_code == 422 and _fields(r) == ["settings.braking_fraction"]
    r = metro.post("/api/runs", json={"colour": "red"})
    assert r.status_code == 422 and _fields(r) == ["colour"]
    assert metro.get("/api/runs").json() == []


def test_run_length_is_bounded() -> None:
    with TestClient(create_app(WebSettings(max_grid_points=1000))) as c:
        c.post("/api/examples/metro_b")
        r = c.post("/api/runs", json={"settings": {"max_step_m": 1}})
        assert r.status_code == 422 and _fields(r) == ["settings.max_step_m"]
        assert "allowed: >= 4.59 m" in r.json()["message"]
        assert c.post("/api/runs", json={"settings": {"max_step_m": 5}}).status_code == 201


def test_run_with_stops_less_than_two_is_a_field_error(metro: TestClient) -> None:
    spec = metro.get("/api/route").json()["spec"]
    for s in spec["stations"][1:]:
        s["stop"] = False
    assert metro.put("/api/route", json=spec).status_code == 200
    r = metro.post("/api/runs", json={})
    assert r.status_code == 422 and _fields(r) == ["stations"]


def test_runs_list_get_downloads_and_delete(metro: TestClient) -> None:
    run = metro.post("/api/runs", json={}).json()
    rid = run["id"]
    assert [r["id"] for r in metro.get("/api/runs").json()] == [rid]
    assert metro.get(f"/api/runs/{rid}").json()["summary"] == run["summary"]
    csv = metro.get(f"/api/runs/{rid}/trace.csv")
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
    df = pd.read_csv(io.StringIO(csv.text))
    assert {"time_s", "position_m", "speed_kmh", "regime", "line_current_a"} <= set(df.columns)
    assert df["time_s"].iloc[-1] == pytest.approx(run["summary"]["total_time_s"])
    summary = json.loads(metro.get(f"/api/runs/{rid}/summary.json").text)
    assert summary["running_time_s"] == pytest.approx(METRO_RUNNING_TIME_S)
    assert metro.delete(f"/api/runs/{rid}").status_code == 204
    for url in (f"/api/runs/{rid}", f"/api/runs/{rid}/trace.csv", f"/api/runs/{rid}/summary.json"):
        assert metro.get(url).status_code == 404
    assert metro.delete(f"/api/runs/{rid}").status_code == 404


def test_runs_are_bounded_per_session_and_overall() -> None:
    app = create_app(WebSettings(max_runs_per_session=3, max_total_trace_points=5000))
    with TestClient(app) as a, TestClient(app) as b:
        a.post("/api/examples/metro_b")
        b.post("/api/examples/metro_b")
        ids = [a.post("/api/runs", json={}).json()["id"] for _ in range(5)]
        assert [r["id"] for r in a.get("/api/runs").json()] == ids[-3:]
        # a run is about 1000 points: b's runs push a's oldest out of the global budget
        for _ in range(3):
            b.post("/api/runs", json={})
        total = len(a.get("/api/runs").json()) + len(b.get("/api/runs").json())
        assert total <= 5


def test_a_registered_strategy_runs_with_validated_params(metro: TestClient) -> None:
    from pydantic import BaseModel, ConfigDict, Field

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        braking_share: float = Field(0.5, gt=0, le=1)

    def run(train, route, settings, params):
        import dataclasses

        return trainsim.run_fastest(
            train, route, dataclasses.replace(settings, braking_fraction=params.braking_share)
        )

    strategies.register(strategies.Strategy("gentle", "Gentle", "half braking", Params, run))
    try:
        listed = {s["name"]: s for s in metro.get("/api/strategies").json()}
        assert "braking_share" in listed["gentle"]["params_schema"]["properties"]
        r = metro.post("/api/runs", json={"strategy": "gentle", "params": {"braking_share": 0.5}})
        assert r.status_code == 201 and r.json()["running_time_s"] > METRO_RUNNING_TIME_S
        r = metro.post("/api/runs", json={"strategy": "gentle", "params": {"braking_share": 2}})
        assert r.status_code == 422 and _fields(r) == ["params.braking_share"]
    finally:
        strategies.unregister("gentle")


def test_energy_efficient_strategy_meets_the_supplement_with_less_energy(metro: TestClient) -> None:
    if strategies.get("energy_efficient") is None:
        pytest.skip("the optimizer is not available")
    fastest = metro.post("/api/runs", json={}).json()
    r = metro.post("/api/runs", json={"strategy": "energy_efficient", "params": {"supplement_percent": 10}})
    assert r.status_code == 201, r.text
    eco = r.json()
    assert eco["running_time_s"] == pytest.approx(1.1 * fastest["running_time_s"], abs=0.5)
    assert eco["energy_net_kwh"] < fastest["energy_net_kwh"]
    timed = metro.post(
        "/api/runs",
        json={"strategy": "energy_efficient", "params": {"section_running_times_s": [110, 100, 95]}},
    ).json()
    assert [s["running_time_s"] for s in timed["summary"]["sections"]] == pytest.approx(
        [110, 100, 95], abs=0.5
    )
    r = metro.post("/api/runs", json={"strategy": "energy_efficient", "params": {"supplement_percent": -5}})
    assert r.status_code == 422 and _fields(r) == ["params.supplement_percent"]
