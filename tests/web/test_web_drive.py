"""Live driving over the WebSocket ``/api/drive`` (manual clock for exact checks, real time at 20x)."""

from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from trainsim.web import WebSettings, create_app
from trainsim.web.sessions import HEADER_NAME


def _until(ws, kind: str, limit: int = 200) -> dict:
    for _ in range(limit):
        msg = ws.receive_json()
        if msg["type"] == kind:
            return msg
    raise AssertionError(f"no {kind!r} message")


def _start(ws, **kw) -> tuple[dict, dict]:
    ws.send_json({"type": "start", **kw})
    init = _until(ws, "init")
    return init, _until(ws, "state")


def _step(ws, dt: float, command: float) -> dict:
    ws.send_json({"type": "step", "dt_s": dt, "command": command})
    return _until(ws, "state")


def stop_at_next_station(ws, state: dict) -> dict:
    """A simple driver: accelerate, then brake so as to stop at the next station (manual clock)."""
    decel = 0.9  # m/s^2 the driver aims for (the metro's service braking gives about 0.97)
    for _ in range(5000):
        v = state["speed_kmh"] / 3.6
        d = state["next_stop_distance_m"]
        if state["dwell_remaining_s"] > 0 or state["finished"]:
            return state
        if (v > 0 and v * v / (2 * d) >= decel * 0.8) or d < 3:
            need = v * v / (2 * max(d, 0.1))
            command = -min(1.0, need / 0.97 * 1.05) if v > 0.05 else (0.2 if d > 3 else -1)
        else:
            command = 1.0 if v < 15 else 0.0
        state = _step(ws, 0.2 if d < 200 else 1.0, command)
    raise AssertionError("the driver never stopped")


def test_manual_drive_accelerates_brakes_and_stops_with_dwell(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive") as ws:
        init, state = _start(ws, clock="manual")
        assert init["profile"]["stations"][1]["name"] == "S2"
        assert init["reference"]["running_time_s"] == pytest.approx(278.99, abs=0.01)
        assert state["speed_kmh"] == 0 and state["next_stop_name"] == "S2"
        fast = _step(ws, 20.0, 1.0)
        assert fast["speed_kmh"] > 40 and fast["regime"] == "traction"
        assert fast["line_current_a"] > 0 and fast["energy_kwh"] > 0
        slower = _step(ws, 5.0, -1.0)
        assert slower["speed_kmh"] < fast["speed_kmh"] and slower["regime"] == "braking"
        stopped = stop_at_next_station(ws, slower)
        assert stopped["dwell_remaining_s"] == pytest.approx(51, abs=0.2)
        assert abs(stopped["next_stop_distance_m"]) > 100  # the next stop is now S3
        assert stopped["next_stop_name"] == "S3"
        later = _step(ws, 10.0, 1.0)  # commands are ignored while dwelling
        assert later["dwell_remaining_s"] == pytest.approx(stopped["dwell_remaining_s"] - 10, abs=0.01)
        assert later["speed_kmh"] == 0
        ws.send_json({"type": "finish"})
        done = _until(ws, "finished")
        assert done["run"]["strategy"] == "drive" and done["summary"]["sections"][0]["to"] == "S2"
    runs = metro.get("/api/runs").json()
    assert [r["strategy"] for r in runs] == ["drive"]
    run = metro.get(f"/api/runs/{runs[0]['id']}").json()
    assert run["kind"] == "driven" and max(run["plot"]["speed_kmh"]) > 40


def test_realtime_drive_at_20x(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive") as ws:
        _start(ws, clock="realtime", time_scale=20)
        ws.send_json({"type": "command", "value": 1.0})
        first = _until(ws, "state")
        for _ in range(12):
            state = _until(ws, "state")
        assert state["speed_kmh"] > first["speed_kmh"]
        assert state["time_s"] - first["time_s"] > 10  # ~1 s of wall time at 20x
        assert state["time_scale"] == 20
        ws.send_json({"type": "pause"})
        paused = _until(ws, "state")
        assert paused["paused"]
        ws.send_json({"type": "time_scale", "value": 5})
        assert _until(ws, "state")["time_scale"] == 5
        ws.send_json({"type": "finish"})
        assert _until(ws, "finished")["run"]["label"] == "Drive 1"


def test_invalid_messages_get_errors_and_the_connection_stays(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive") as ws:
        ws.send_json({"type": "command", "value": 0.5})
        assert "start" in _until(ws, "error")["message"]
        _start(ws, clock="manual")
        bad = [
            ({"type": "command", "value": 2}, "value"),
            ({"type": "command", "value": "full"}, "value"),
            ({"type": "time_scale", "value": 7}, "value"),
            ({"type": "step", "dt_s": 0}, "dt_s"),
            ({"type": "step", "dt_s": 100}, "dt_s"),
            ({"type": "jump"}, "type"),
            ({"type": "start", "clock": "sundial"}, "clock"),
        ]
        for msg, field in bad:
            ws.send_json(msg)
            err = _until(ws, "error")
            assert err["detail"][0]["field"] == field, msg
        ws.send_text("not json")
        assert "not JSON" in _until(ws, "error")["message"]
        ws.send_text("[1]")
        assert _until(ws, "error")["detail"][0]["field"] == "type"
        ws.send_text("x" * 5000)
        assert "too long" in _until(ws, "error")["message"]
        assert _step(ws, 1.0, 0.5)["speed_kmh"] > 0  # still driving


def test_step_needs_the_manual_clock(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive") as ws:
        _start(ws, clock="realtime")
        ws.send_json({"type": "step", "dt_s": 1})
        assert "manual" in _until(ws, "error")["message"]


def test_drive_needs_a_session_with_train_and_route(app) -> None:
    with TestClient(app) as c:
        with c.websocket_connect("/api/drive") as ws:
            assert "session" in ws.receive_json()["reason"]
            with pytest.raises(WebSocketDisconnect):
                ws.receive_json()
        c.get("/api/session")
        with c.websocket_connect("/api/drive") as ws:
            ws.send_json({"type": "start"})
            assert "load a train" in _until(ws, "error")["message"]


def test_cross_origin_drive_is_refused(metro: TestClient) -> None:
    with metro.websocket_connect("/api/drive", headers={"origin": "http://evil.example"}) as ws:
        assert "cross-origin" in ws.receive_json()["reason"]


def test_drives_of_two_sessions_are_separate(app) -> None:
    with TestClient(app) as a, TestClient(app) as b:
        a.post("/api/examples/metro_b")
        b.post("/api/examples/metro_b")
        with a.websocket_connect("/api/drive") as wa, b.websocket_connect("/api/drive") as wb:
            _start(wa, clock="manual")
            _start(wb, clock="manual")
            sa = _step(wa, 30, 1.0)
            sb = _step(wb, 5, 0.25)
            assert sa["position_m"] > sb["position_m"] > 0
            wa.send_json({"type": "finish"})
            _until(wa, "finished")
        assert len(a.get("/api/runs").json()) == 1
        # b's drive is recorded when the server has seen its socket close
        deadline = time.monotonic() + 5
        while not b.get("/api/runs").json() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(b.get("/api/runs").json()) == 1


def test_a_new_drive_in_the_same_session_replaces_the_old_one(metro: TestClient) -> None:
    sid = metro.get("/api/session").json()["id"]
    with metro.websocket_connect("/api/drive") as first:
        _start(first, clock="realtime", time_scale=20)
        with metro.websocket_connect("/api/drive", headers={HEADER_NAME: sid}) as second:
            _start(second, clock="manual")
            assert "replaced" in _until(first, "ended")["reason"]
            assert metro.app.state.store.active_drives == 1


def test_live_drives_are_bounded() -> None:
    app = create_app(WebSettings(max_drives=1))
    with TestClient(app) as a, TestClient(app) as b:
        a.post("/api/examples/metro_b")
        b.post("/api/examples/metro_b")
        with a.websocket_connect("/api/drive") as wa:
            _start(wa, clock="manual")
            with b.websocket_connect("/api/drive") as wb:
                wb.send_json({"type": "start", "clock": "manual"})
                assert "too many" in _until(wb, "ended")["reason"]
            assert _step(wa, 1, 1)["speed_kmh"] > 0


def _full_power_speeds(client: TestClient, atp: bool, seconds: int = 120) -> list[dict]:
    states = []
    with client.websocket_connect("/api/drive") as ws:
        ws.send_json({"type": "start", "clock": "manual", "atp": atp})
        while ws.receive_json()["type"] != "state":
            pass
        for _ in range(seconds // 2):
            ws.send_json({"type": "step", "dt_s": 2, "command": 1.0})
            states.append(ws.receive_json())
    return states


def test_full_power_never_passes_the_design_speed_and_atp_holds_the_limit(metro: TestClient) -> None:
    states = _full_power_speeds(metro, atp=False)
    assert max(s["speed_kmh"] for s in states) <= 80.0 + 1.5  # the metro's design speed, 80 km/h
    route = metro.get("/api/route").json()["spec"]
    route["speed_limits"] = [{**route["speed_limits"][0], "limit_kmh": 40}]
    assert metro.put("/api/route", json=route).status_code == 200
    free = _full_power_speeds(metro, atp=False)
    assert max(s["speed_kmh"] for s in free) > 60 and any(s["overspeed"] for s in free)
    held = _full_power_speeds(metro, atp=True)
    assert max(s["speed_kmh"] for s in held) <= 40 + 3.0
    assert any(s["atp_braking"] for s in held) and any(s["lever_reset"] for s in held)
    moving = [s for s in held if s["speed_kmh"] > 0]
    assert moving[0]["clock_s"] >= 0 and moving[-1]["clock_s"] <= moving[-1]["time_s"]
    assert {
        "acceleration_mps2",
        "traction_force_kn",
        "braking_force_kn",
        "gradient_permille",
        "next_limit_distance_m",
        "next_stop_distance_m",
        "energy_kwh",
        "location",
    } <= set(held[-1])
    assert held[-1]["location"].startswith(("between", "at", "before", "past"))
