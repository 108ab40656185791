"""Per-browser sessions: each holds its own train, route, runs and live drive.

A session is found by the id in the ``trainsim_session`` cookie (browsers) or the
``X-Trainsim-Session`` header (API clients). Sessions never share data: every request works on
the one session its id names, under that session's lock. The store is bounded: sessions expire
after ``session_ttl_s`` without use, there are at most ``max_sessions`` (the least recently used
without a live drive goes first), at most ``max_runs_per_session`` runs per session and at most
``max_total_trace_points`` trace points over all sessions (the oldest runs go first).

A flood of requests without a session must not push active users out: each client (IP address)
may make ``session_burst`` sessions at once and ``sessions_per_minute`` after that
(:class:`SessionRateLimit`, a token bucket; past it :class:`SessionRateError` and 429), and when the
store is full, empty sessions (no train, route or run: what a flood makes) go before sessions
that hold something.
"""

from __future__ import annotations

import math
import re
import secrets
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim.result import RunResult
from trainsim.web.config import WebSettings

COOKIE_NAME = "trainsim_session"
HEADER_NAME = "X-Trainsim-Session"
_ID_PATTERN = re.compile(r"^[A-Za-z0-9_-]{16,64}$")


def valid_session_id(value: str | None) -> bool:
    """Whether ``value`` has the form of a session id (it may still be unknown or expired)."""
    return bool(value) and _ID_PATTERN.match(value or "") is not None


@dataclass
class StoredRun:
    """A run kept in a session: the result and what is needed to plot it later.

    Attributes:
        id: run id within the session (``r1``, ``r2`` ...).
        label: name shown in the page.
        strategy: strategy name, or ``drive`` for a recorded drive.
        created: wall-clock time of creation [s since the epoch].
        result: the core's result.
        route: the route it ran on (the session's route may change afterwards).
        train: the train it ran.
        params: the strategy parameters and run settings used.
    """

    id: str
    label: str
    strategy: str
    created: float
    result: RunResult
    route: Route
    train: Train
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def points(self) -> int:
        return len(self.result.trace)


@dataclass
class Loaded:
    """A train or route as the session holds it: the validated spec, the model, where it came from."""

    spec: Any  # TrainSpec | RouteSpec
    model: Any  # Train | Route
    source: str
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: the JSON body of GET /api/train or /api/route, computed when it was validated
    payload: bytes | None = None
    #: hash of the validated spec (:func:`trainsim.web.cache.identity`)
    key: str = ""


@dataclass
class WebSession:
    """One browser's data."""

    id: str
    created: float
    last_used: float
    lock: threading.RLock = field(default_factory=threading.RLock, repr=False)
    train: Loaded | None = None
    route: Loaded | None = None
    settings: RunSettings = field(default_factory=RunSettings)
    runs: OrderedDict[str, StoredRun] = field(default_factory=OrderedDict)
    run_counter: int = 0
    drive_counter: int = 0
    #: token of the live drive of this session (a new drive replaces it), or None
    drive_token: object | None = None
    #: requests of this session in the worker processes now
    jobs: int = 0

    def next_run_id(self) -> str:
        self.run_counter += 1
        return f"r{self.run_counter}"


class SessionRateError(Exception):
    """A client made new sessions faster than allowed; ``retry_after_s`` until it may again [s]."""

    def __init__(self, retry_after_s: float) -> None:
        super().__init__(f"too many new sessions from this client; try again in {retry_after_s:.0f} s")
        self.retry_after_s = retry_after_s


class SessionRateLimit:
    """Token bucket per client: ``burst`` new sessions at once, refilled at ``per_minute`` per
    minute; at most ``max_clients`` clients remembered (least recently seen forgotten first)."""

    def __init__(self, burst: int, per_minute: float, max_clients: int, clock: Any = time.monotonic) -> None:
        self.burst = float(burst)
        self.rate_per_s = per_minute / 60.0
        self.max_clients = max_clients
        self._clock = clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # client -> (tokens, when)

    def take(self, client: str) -> None:
        """Take one new session for ``client`` or raise :class:`SessionRateError`."""
        now = self._clock()
        tokens, when = self._buckets.pop(client, (self.burst, now))
        tokens = min(self.burst, tokens + (now - when) * self.rate_per_s)
        if tokens < 1.0:
            self._buckets[client] = (tokens, now)
            wait = (1.0 - tokens) / self.rate_per_s if self.rate_per_s > 0 else 3600.0
            raise SessionRateError(max(1.0, math.ceil(wait)))
        self._buckets[client] = (tokens - 1.0, now)
        while len(self._buckets) > self.max_clients:
            self._buckets.popitem(last=False)


def _holds_something(session: WebSession) -> bool:
    return session.train is not None or session.route is not None or bool(session.runs)


class SessionStore:
    """All sessions of the application, bounded in number, age and size."""

    def __init__(self, settings: WebSettings, clock: Any = time.time) -> None:
        self.settings = settings
        self._clock = clock
        self._sessions: OrderedDict[str, WebSession] = OrderedDict()
        self._lock = threading.Lock()
        self.active_drives = 0
        self.rate = SessionRateLimit(
            settings.session_burst, settings.sessions_per_minute, settings.max_rate_clients
        )

    def __len__(self) -> int:
        return len(self._sessions)

    # ------------------------------------------------------------------ sessions
    def _expire(self, now: float) -> None:
        ttl = self.settings.session_ttl_s
        for sid in [
            s for s, x in self._sessions.items() if now - x.last_used > ttl and x.drive_token is None
        ]:
            del self._sessions[sid]

    def get(self, sid: str | None) -> WebSession | None:
        """The session of that id, or None if unknown or expired; marks it used."""
        if not valid_session_id(sid):
            return None
        now = self._clock()
        with self._lock:
            self._expire(now)
            session = self._sessions.get(sid or "")
            if session is not None:
                session.last_used = now
                self._sessions.move_to_end(session.id)
            return session

    def create(self, client: str | None = None) -> WebSession:
        """A new empty session; drops expired and, if full, least recently used sessions (empty
        ones first). With ``client`` (its address) the client's rate limit applies
        (:class:`SessionRateError`)."""
        now = self._clock()
        with self._lock:
            if client is not None:
                self.rate.take(client)
            self._expire(now)
            while len(self._sessions) >= self.settings.max_sessions:
                free = [s for s in self._sessions.values() if s.drive_token is None]
                victim = next((s for s in free if not _holds_something(s)), free[0] if free else None)
                if victim is None:
                    break  # every session drives: exceed the bound rather than cut a live drive
                del self._sessions[victim.id]
            sid = secrets.token_urlsafe(24)
            session = WebSession(id=sid, created=now, last_used=now)
            self._sessions[sid] = session
            return session

    def get_or_create(self, sid: str | None, client: str | None = None) -> tuple[WebSession, bool]:
        """The session of ``sid``, or a new one (within ``client``'s rate limit); the flag says
        whether it is new."""
        session = self.get(sid)
        if session is not None:
            return session, False
        return self.create(client), True

    # ------------------------------------------------------------------ drives
    def reserve_drive(self) -> bool:
        """Take a live-drive slot if one is free (atomically; no await between check and count)."""
        with self._lock:
            if self.active_drives >= self.settings.max_drives:
                return False
            self.active_drives += 1
            return True

    def release_drive(self) -> None:
        """Give a live-drive slot back."""
        with self._lock:
            self.active_drives = max(0, self.active_drives - 1)

    # ------------------------------------------------------------------ runs
    def add_run(self, session: WebSession, run: StoredRun) -> None:
        """Keep a run in a session, dropping the session's oldest runs and, over all sessions, the
        oldest runs until the bounds hold (the new run itself is always kept)."""
        with self._lock:
            session.runs[run.id] = run
            while len(session.runs) > self.settings.max_runs_per_session:
                session.runs.popitem(last=False)
            total = sum(r.points for s in self._sessions.values() for r in s.runs.values())
            while total > self.settings.max_total_trace_points:
                oldest = min(
                    ((s, r) for s in self._sessions.values() for r in s.runs.values() if r is not run),
                    key=lambda sr: sr[1].created,
                    default=None,
                )
                if oldest is None:
                    break
                s, r = oldest
                del s.runs[r.id]
                total -= r.points
