"""Each hostile input the issue lists, and the limits of the worker pool: a clear 4xx or 503 answer,
never a 500, and nothing invalid stored."""

from __future__ import annotations

import asyncio
import json
import re
import time

import pytest
from fastapi.testclient import TestClient

from trainsim.web import WebSettings, create_app
from trainsim.web.workers import ClientGoneError, JobLimitError, PoolBusyError, WorkerPool


def _put(client: TestClient, path: str, doc: object):
    # NaN and Infinity as Python's json writes them
    return client.put(path, content=json.dumps(doc).encode(), headers={"content-type": "application/json"})


def test_a_billion_vehicles_is_refused_at_once_in_every_path(metro: TestClient) -> None:
    spec = metro.get("/api/train").json()["spec"]
    spec["formation"][0]["count"] = 1_000_000_000
    t0 = time.monotonic()
    r = _put(metro, "/api/train", spec)
    assert r.status_code == 422 and time.monotonic() - t0 < 5
    assert r.json()["detail"][0]["field"] == "formation[0].count"
    assert "at most 1000 vehicles" in r.json()["detail"][0]["msg"]
    text = re.sub(r"count: \d+", "count: 1000000000", metro.get("/api/train/yaml").text, count=1)
    r = metro.post("/api/train/upload", files={"file": ("t.yaml", text.encode())})
    assert r.status_code == 422 and "vehicles" in r.json()["message"] and "t.yaml" in r.json()["message"]


def test_uploads_and_put_share_the_list_bound(metro: TestClient) -> None:
    route = metro.get("/api/route").json()["spec"]
    route["gradients"] = [{"from_m": i, "gradient_permille": 0} for i in range(6000)]
    assert _put(metro, "/api/route", route).status_code == 422
    import yaml

    r = metro.post("/api/route/upload", files={"file": ("r.yaml", yaml.safe_dump(route).encode())})
    assert r.status_code == 422 and r.json()["detail"][0]["field"] == "gradients"


@pytest.mark.parametrize("value", [float("nan"), float("inf"), 1e308, 1e30])
def test_non_finite_or_huge_values_are_never_stored(metro: TestClient, value: float) -> None:
    before = metro.get("/api/train").json()["spec"]
    spec = json.loads(json.dumps(before))
    spec["resistance"][0]["a_kn"] = value
    r = _put(metro, "/api/train", spec)
    assert r.status_code == 422 and r.json()["detail"][0]["field"] == "resistance[0].a_kn"
    assert metro.get("/api/train").json()["spec"] == before  # the last valid train stays


@pytest.mark.parametrize("times", [[float("nan")] * 3, [float("inf")] * 3, [1e308] * 3, [0, 0, 0], "x"])
@pytest.mark.parametrize("strategy", ["energy_efficient", "lesov"])
def test_bad_timetables_get_422_and_nothing_is_stored(
    metro: TestClient, times: object, strategy: str
) -> None:
    body = {"strategy": strategy, "params": {"section_running_times_s": times}}
    r = metro.post("/api/runs", content=json.dumps(body), headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["field"].startswith("params.section_running_times_s")
    assert metro.get("/api/runs").json() == []


def test_lesov_with_nan_supplement(metro: TestClient) -> None:
    body = '{"strategy": "lesov", "params": {"supplement_percent": NaN}}'
    r = metro.post("/api/runs", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 422 and r.json()["detail"][0]["field"] == "params.supplement_percent"
    assert metro.get("/api/runs").status_code == 200


@pytest.mark.parametrize(
    "name,content",
    [
        ("deep.yaml", b"[" * 5000 + b"]" * 5000),
        ("..", b"schema: trainsim/train\n"),
        (".", b"x: 1\n"),
        ("../../x.yaml", b"x: 1\n"),
        ("bomb.xml", b'<!DOCTYPE r [<!ENTITY a "aaaa"><!ENTITY b "&a;&a;&a;">]><railml>&b;</railml>'),
        ("t.zip", b"PK not a zip"),
        ("t.csv", b"a,b\n"),
    ],
    ids=["deep-yaml", "dotdot", "dot", "path", "xml-entities", "bad-zip", "lone-csv"],
)
def test_hostile_uploads_get_422_naming_the_file(metro: TestClient, name: str, content: bytes) -> None:
    r = metro.post("/api/train/upload", files={"file": (name, content)})
    assert r.status_code == 422, r.text
    assert "/tmp" not in r.json()["message"] and "trainsim-web-" not in r.json()["message"]


def test_deep_json_bodies_get_4xx(metro: TestClient) -> None:
    for body in (b"[" * 100_000, b'{"a":' * 50_000):
        r = metro.put("/api/train", content=body, headers={"content-type": "application/json"})
        assert 400 <= r.status_code < 500
    deep = '{"schema": "trainsim/train", "x": ' + '{"a": [' * 100 + "1" + "]}" * 100 + "}"
    r = metro.put("/api/train", content=deep.encode(), headers={"content-type": "application/json"})
    assert r.status_code == 422 and "nested too deeply" in r.json()["message"]


def test_oversized_chunked_body_gets_413() -> None:
    with TestClient(create_app(WebSettings(max_body_bytes=100_000, workers=0))) as c:

        def chunks():
            for _ in range(10):
                yield b"x" * 65536

        r = c.put("/api/train", content=chunks(), headers={"content-type": "application/json"})
        assert r.status_code == 413


def test_health_security_headers_and_host_check(client: TestClient) -> None:
    r = client.get("/api/health")
    assert set(r.json()) == {"status", "version"}
    page = client.get("/")
    assert "default-src 'self'" in page.headers["content-security-policy"]
    assert page.headers["x-frame-options"] == "DENY"
    assert page.headers["x-content-type-options"] == "nosniff"
    r = client.get("/api/health", headers={"host": "evil.example"})
    assert r.status_code == 400 and "unknown host" in r.json()["message"]
    assert client.get("/api/health", headers={"host": "127.0.0.1:8000"}).status_code == 200
    assert client.get("/api/health", headers={"host": "[::1]:8000"}).status_code == 200


def test_a_run_over_the_time_limit_gets_422_and_the_worker_is_replaced() -> None:
    with TestClient(create_app(WebSettings(job_time_limit_s=0.05))) as c:
        c.post("/api/examples/freight_000")
        r = c.post("/api/runs", json={"settings": {"max_step_m": 0.5}})
        assert r.status_code == 422 and "longer than the limit" in r.json()["message"]
        assert c.app.state.pool.stats["timeouts"] == 1
        c.post("/api/examples/metro_b")
        c.app.state.pool.time_limit_s = 30
        assert c.post("/api/runs", json={}).status_code == 201  # a fresh worker answers


def test_a_run_over_the_memory_limit_gets_422() -> None:
    with TestClient(create_app(WebSettings(job_memory_limit_bytes=30 * 2**20, job_time_limit_s=60))) as c:
        c.post("/api/examples/freight_000")
        r = c.post("/api/runs", json={"settings": {"max_step_m": 0.2}})
        assert r.status_code == 422 and "more memory" in r.json()["message"], r.text[:300]
        c.post("/api/examples/metro_b")
        assert c.post("/api/runs", json={}).status_code == 201


def test_pool_queue_bound_and_cancellation() -> None:
    async def main() -> None:
        pool = WorkerPool(1, time_limit_s=20, memory_limit_bytes=0, max_queued=0)
        await pool.start()
        try:
            from trainsim.model.scenario import RunSettings
            from trainsim.web.examples import route_spec, train_spec

            train = train_spec("freight_000").to_train("f")
            route = route_spec("freight_000").to_route("f")
            slow = ("fastest", {}, train, route, RunSettings(max_step_m=0.5), 100)

            async def gone() -> bool:
                return True

            first = asyncio.create_task(pool.call("run", *slow))
            await asyncio.sleep(0.05)
            with pytest.raises(PoolBusyError):
                await pool.call("run", *slow)  # one worker busy, no room to wait: 503
            first.cancel()
            with pytest.raises(asyncio.CancelledError):
                await first
            with pytest.raises(ClientGoneError):
                await pool.call("run", *slow, gone=gone)  # client gone: stopped within 0.25 s
            assert pool.stats["cancelled"] == 1 and pool.stats["replaced"] == 2
            with pytest.raises(JobLimitError):
                await pool.call("run", *slow, time_limit_s=0.01)
        finally:
            pool.close()

    asyncio.run(main())


def test_one_session_cannot_hold_every_worker() -> None:
    app = create_app(WebSettings(max_jobs_per_session=1, job_time_limit_s=20))
    import httpx

    async def main() -> list[int]:
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
            r = await c.post("/api/examples/freight_000")
            h = {"X-Trainsim-Session": r.headers["x-trainsim-session"]}
            # three different runs (identical ones would share one computation)
            bodies = [{"settings": {"max_step_m": 1 + k / 10}} for k in range(3)]
            rs = await asyncio.gather(*(c.post("/api/runs", json=b, headers=h) for b in bodies))
            return sorted(r.status_code for r in rs)

    try:
        codes = asyncio.run(main())
    finally:
        app.state.pool.close()
    assert codes[0] == 201 and 429 in codes


def test_a_binary_websocket_frame_gets_an_error_and_the_drive_goes_on(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive") as ws:
        ws.send_bytes(b"\x00\x01binary")
        msg = ws.receive_json()
        assert msg["type"] == "error" and "binary" in msg["message"]
        ws.send_json({"type": "ping"})
        assert ws.receive_json()["type"] == "pong"


def test_concurrent_drive_starts_never_pass_the_bound() -> None:
    import httpx
    import websockets

    from .conftest import LiveServer

    limit, starts = 4, 24
    with LiveServer(WebSettings(max_drives=limit, workers=0)) as server:
        sids = []
        with httpx.Client(base_url=server.url) as c:
            for _ in range(starts):
                r = c.post("/api/examples/metro_b", headers={"X-Trainsim-Session": ""})
                sids.append(r.headers["x-trainsim-session"])
        ws_url = server.url.replace("http://", "ws://") + "/api/drive?session="

        async def start(sid: str) -> str:
            async with websockets.connect(ws_url + sid, open_timeout=20) as ws:
                await ws.send(json.dumps({"type": "start", "clock": "manual"}))
                first = json.loads(await asyncio.wait_for(ws.recv(), 20))
                if first["type"] == "init":
                    await asyncio.sleep(1.0)  # hold the drive while the others try
                return first["type"]

        async def main() -> list[str]:
            return await asyncio.gather(*(start(s) for s in sids))

        kinds = asyncio.run(main())
    assert kinds.count("init") == limit and kinds.count("ended") == starts - limit
