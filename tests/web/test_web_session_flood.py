"""A flood of requests without a session cannot push active users out (issue 19): each client may
make only so many new sessions (429 with Retry-After past that), and when the store is full empty
sessions go before sessions that hold something."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from trainsim.web import WebSettings, create_app
from trainsim.web.config import WebSettings as Settings
from trainsim.web.sessions import SessionRateError, SessionRateLimit, SessionStore


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_token_bucket_burst_rate_and_retry_after() -> None:
    clock = _Clock()
    limit = SessionRateLimit(burst=3, per_minute=6.0, max_clients=2, clock=clock)  # one per 10 s
    for _ in range(3):
        limit.take("a")
    with pytest.raises(SessionRateError) as err:
        limit.take("a")
    assert err.value.retry_after_s == 10
    limit.take("b")  # another client has its own allowance
    clock.now += 4.0
    with pytest.raises(SessionRateError) as err:
        limit.take("a")
    assert err.value.retry_after_s == 6  # 0.4 of a token refilled: 6 s to the next
    clock.now += 6.0
    limit.take("a")
    limit.take("c")  # a third client: the least recently seen ("b") is forgotten
    assert set(limit._buckets) == {"a", "c"}


def test_a_full_store_drops_empty_sessions_before_sessions_that_hold_something() -> None:
    store = SessionStore(Settings(max_sessions=3))
    active = store.create()
    active.train = object()  # type: ignore[assignment]  # what matters: it holds a train
    for _ in range(10):
        store.create()
    assert store.get(active.id) is active
    assert len(store) == 3


def test_a_flood_from_one_client_gets_429_and_does_not_evict_an_active_session() -> None:
    settings = WebSettings(workers=0, drive_hosts=0, max_sessions=20, session_burst=10, sessions_per_minute=6)
    app = create_app(settings)
    with (
        TestClient(app, client=("10.0.0.1", 50000)) as user,
        TestClient(app, client=("10.0.0.66", 50000)) as flood,
    ):
        r = user.post("/api/examples/metro_b")
        assert r.status_code == 200
        sid = {"X-Trainsim-Session": r.headers["x-trainsim-session"]}
        statuses = []
        for _ in range(300):
            flood.cookies.clear()  # a flood keeps no cookie: every request asks for a new session
            statuses.append(flood.get("/api/session").status_code)
        assert statuses[:10] == [200] * 10 and set(statuses[10:]) == {429}
        flood.cookies.clear()
        r = flood.get("/api/session")
        assert r.status_code == 429
        assert 1 <= int(r.headers["retry-after"]) <= 10  # one session per 10 s, part refilled already
        assert "new sessions" in r.json()["message"] and "per minute" in r.json()["message"]
        assert "set-cookie" not in r.headers
        # the active user still has their session, train and route, and can run
        assert user.get("/api/session", headers=sid).json()["id"] == sid["X-Trainsim-Session"]
        run = user.post("/api/runs", json={"strategy": "fastest"}, headers=sid)
        assert run.status_code == 201
        # a flood from many addresses fills the store only with empty sessions, dropped first
        for k in range(60):
            with TestClient(app, client=(f"10.1.0.{k}", 1)) as one:
                assert one.get("/api/session").status_code == 200
        assert user.get("/api/runs", headers=sid).json()[0]["strategy"] == "fastest"
        assert len(app.state.store) <= settings.max_sessions
