"""Live driving over a WebSocket (``/api/drive``), on the core's step-by-step driving API.

The browser opens the socket (its session cookie says whose train and route are driven) and sends
JSON messages; the server answers with JSON messages. In real time the server steps the core's
:class:`~trainsim.sim.driving.DrivingSession` every ``drive_tick_s`` of wall-clock time by that
time times the time scale (1x, 5x, 20x) with the driver's current command, and sends the state.

Client -> server:

* ``{"type": "start", "time_scale": 1, "clock": "realtime", "atp": true}`` starts a drive from the
  first stop (again: a new drive). ``clock: "manual"`` makes the server step only on ``step``
  messages. ``atp`` (default true): on overspeed the train protection applies full service braking
  until the speed is back at the limit, then leaves the lever at neutral.
* ``{"type": "command", "value": c}``: the driver's command in [-1, 1] (positive: that share of
  the maximum tractive effort; negative: that share of service braking; 0: coasting).
* ``{"type": "time_scale", "value": 1 | 5 | 20}``, ``{"type": "pause"}``, ``{"type": "resume"}``.
* ``{"type": "step", "dt_s": 0.5, "command": c}``: manual clock only: advance by dt_s (0 < dt_s <= 60).
* ``{"type": "finish"}``: end the drive now and record it.

Server -> client:

* ``{"type": "init", "profile": {...}, "reference": {...} | null, ...}`` once per drive: the line
  profile and the fastest run's speed over distance to drive against;
* ``{"type": "state", ...}`` after every step (speed, position, limits, next stop, current, energy...);
* ``{"type": "finished", "run": {...}, "summary": {...}}`` when the drive ends: it is recorded in
  the session's runs (``GET /api/runs``) and can be compared with any other run;
* ``{"type": "error", "message": ..., "detail": [...]}`` for a message it cannot follow (the
  connection stays open), and ``{"type": "ended", "reason": ...}`` before the server closes.

Each session has at most one live drive (a new one, e.g. from a second tab, replaces it); the
number of live drives over all sessions and their wall-clock duration are bounded.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.web.config import WebSettings
from trainsim.web.drivehost import DriveHostError, DriveHosts
from trainsim.web.errors import input_error_detail
from trainsim.web.payloads import route_profile, run_brief
from trainsim.web.sessions import COOKIE_NAME, HEADER_NAME, SessionStore, StoredRun, WebSession

router = APIRouter()

TIME_SCALES = (1, 5, 20)
#: drives being recorded after their connection closed (kept referenced until done)
_ENDING: set[asyncio.Future] = set()
#: largest message a client may send [characters]
MAX_MESSAGE_CHARS = 4096


def state_message(view: dict[str, Any], drive: _Drive) -> dict[str, Any]:
    """A host's view of a drive with the server's fields (time scale, pause, clock)."""
    return {**view, "time_scale": drive.scale, "paused": drive.paused, "clock": drive.clock}


@dataclass
class _Drive:
    """One drive of a connection (its state lives in a drive host: :mod:`trainsim.web.drivehost`)."""

    number: int
    drive_id: int
    token: object
    clock: str
    scale: int
    started: float
    atp: bool
    last: dict[str, Any]
    command: float = 0.0
    paused: bool = False
    recorded: bool = False
    ticker: asyncio.Task | None = field(default=None, repr=False)
    train: Any = None
    route: Any = None


class _BadMessageError(Exception):
    def __init__(self, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.field = field


def _number(msg: dict[str, Any], key: str, lo: float, hi: float, *, low_open: bool = False) -> float:
    value = msg.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _BadMessageError(f"'{key}' must be a number", key)
    if value < lo or value > hi or (low_open and value <= lo):
        bounds = f"{lo:g} < {key} <= {hi:g}" if low_open else f"{lo:g} <= {key} <= {hi:g}"
        raise _BadMessageError(f"'{key}' out of range (got {value!r}); allowed: {bounds}", key)
    return float(value)


class DriveConnection:
    """The drives of one WebSocket connection."""

    def __init__(
        self, ws: WebSocket, store: SessionStore, session: WebSession, limits: WebSettings, hosts: DriveHosts
    ) -> None:
        self.ws = ws
        self.hosts = hosts
        self.store = store
        self.session = session
        self.limits = limits
        self.drive: _Drive | None = None
        self._send_lock = asyncio.Lock()

    async def send(self, message: dict[str, Any]) -> None:
        async with self._send_lock:
            await self.ws.send_text(json.dumps(message, allow_nan=False))

    async def error(self, message: str, field: str | None = None, detail: list | None = None) -> None:
        detail = (
            detail
            if detail is not None
            else [{"field": field, "loc": [field] if field else [], "msg": message}]
        )
        await self.send({"type": "error", "message": message, "detail": detail})

    # ------------------------------------------------------------------ main loop
    async def serve(self) -> None:
        try:
            while True:
                frame = await self.ws.receive()
                if frame["type"] == "websocket.disconnect":
                    break
                text = frame.get("text")
                try:
                    if text is None:
                        raise _BadMessageError("binary frames are not understood; send JSON text messages")
                    if len(text) > MAX_MESSAGE_CHARS:
                        raise _BadMessageError(
                            f"message too long; allowed: at most {MAX_MESSAGE_CHARS} characters"
                        )
                    try:
                        msg = json.loads(text)
                    except json.JSONDecodeError as exc:
                        raise _BadMessageError(f"not JSON: {exc.msg}") from exc
                    if not isinstance(msg, dict):
                        raise _BadMessageError("a message must be a JSON object with a 'type'", "type")
                    await self.handle(msg)
                except _BadMessageError as exc:
                    await self.error(exc.message, exc.field)
                except InputError as exc:
                    await self.error(str(exc), detail=input_error_detail(exc))
                except DriveHostError as exc:
                    await self.stop(record=False, notify=False)
                    await self.error(f"{exc}; the drive ended: start a new one")
        except (WebSocketDisconnect, RuntimeError):
            pass  # (RuntimeError: the socket closed while a message was being sent)
        finally:
            # recorded even when the connection's task is being cancelled
            ending = asyncio.ensure_future(self.stop(record=True, notify=False))
            _ENDING.add(ending)
            ending.add_done_callback(_ENDING.discard)
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.shield(ending)

    async def handle(self, msg: dict[str, Any]) -> None:
        kind = msg.get("type")
        if kind == "start":
            await self.start(msg)
            return
        if kind == "ping":
            await self.send({"type": "pong"})
            return
        drive = self.drive
        if kind not in ("command", "time_scale", "pause", "resume", "step", "finish"):
            raise _BadMessageError(
                f"unknown message type {kind!r}; allowed: start, command, time_scale, pause, resume, step, "
                "finish, ping",
                "type",
            )
        if drive is None:
            raise _BadMessageError('no drive: send {"type": "start"} first', "type")
        if kind == "command":
            drive.command = _number(msg, "value", -1.0, 1.0)
        elif kind == "time_scale":
            value = msg.get("value")
            if value not in TIME_SCALES or isinstance(value, bool):
                raise _BadMessageError(
                    f"time scale must be one of {', '.join(map(str, TIME_SCALES))} (got {value!r})", "value"
                )
            drive.scale = int(value)
        elif kind == "pause":
            drive.paused = True
        elif kind == "resume":
            drive.paused = False
        elif kind == "step":
            if drive.clock != "manual":
                raise _BadMessageError("'step' needs a drive started with clock 'manual'", "type")
            dt = _number(msg, "dt_s", 0.0, 60.0, low_open=True)
            if "command" in msg:
                drive.command = _number(msg, "command", -1.0, 1.0)
            await self.advance(drive, dt)
            return
        elif kind == "finish":
            await self.stop(record=True, notify=True)
            return
        # acknowledge with the current state so the page shows the change at once
        drive.last = await self.hosts.view(drive.drive_id, drive.command)
        await self.send(state_message(drive.last, drive))

    # ------------------------------------------------------------------ drives
    async def start(self, msg: dict[str, Any]) -> None:
        clock = msg.get("clock", "realtime")
        if clock not in ("realtime", "manual"):
            raise _BadMessageError(f"clock must be 'realtime' or 'manual' (got {clock!r})", "clock")
        scale = msg.get("time_scale", 1)
        if scale not in TIME_SCALES or isinstance(scale, bool):
            raise _BadMessageError(f"time scale must be one of 1, 5, 20 (got {scale!r})", "time_scale")
        atp = msg.get("atp", True)
        if not isinstance(atp, bool):
            raise _BadMessageError(f"'atp' must be true or false (got {atp!r})", "atp")
        await self.stop(record=True, notify=False)
        session = self.session
        with session.lock:
            if session.train is None or session.route is None:
                raise _BadMessageError("load a train and a route before driving", "type")
            train, route, settings = session.train.model, session.route.model, session.settings
        # the slot is taken before the first await: concurrent starts cannot pass the bound together
        if not self.store.reserve_drive():
            await self.send(
                {"type": "ended", "reason": "too many live drives on this server; try again later"}
            )
            await self.ws.close(code=1013)
            raise WebSocketDisconnect(1013)
        try:
            drive_id, reference, view = await self.hosts.open(train, route, settings, atp)
        except BaseException:
            self.store.release_drive()
            raise
        token = object()
        with session.lock:
            session.drive_counter += 1
            number = session.drive_counter
            session.drive_token = token
        drive = _Drive(number, drive_id, token, clock, int(scale), time.monotonic(), atp, view)
        drive.train, drive.route = train, route
        self.drive = drive
        await self.send(
            {
                "type": "init",
                "drive": number,
                "train": train.name,
                "route": route.name,
                "max_speed_kmh": train.max_speed_mps / KMH,
                "clock": clock,
                "atp": atp,
                "time_scales": list(TIME_SCALES),
                "profile": route_profile(route),
                "reference": reference,
            }
        )
        await self.send(state_message(view, drive))
        if clock == "realtime":
            drive.ticker = asyncio.create_task(self._tick(drive))

    async def advance(self, drive: _Drive, dt_s: float) -> None:
        view = await self.hosts.advance(drive.drive_id, drive.command, dt_s)
        if drive is not self.drive:
            return
        drive.last = view
        if view["lever_reset"]:
            drive.command = 0.0
        await self.send(state_message(view, drive))
        if view["finished"]:
            await self.stop(record=True, notify=True)

    async def _tick(self, drive: _Drive) -> None:
        tick = self.limits.drive_tick_s
        last = time.monotonic()
        due = last + tick
        while self.drive is drive:
            # ticks on a fixed schedule: the host's answer time is not added to every interval
            await asyncio.sleep(max(0.0, due - time.monotonic()))
            now = time.monotonic()
            due = max(due + tick, now + 0.5 * tick)
            # a late tick advances by the wall time it stood for, but by at most two ticks: an
            # overloaded server lets the drive fall behind the wall clock rather than take ever
            # longer steps (which would make it later still)
            dt_wall, last = min(now - last, 2 * tick), now
            if self.session.drive_token is not drive.token:
                await self.stop(record=True, notify=False)
                await self.send({"type": "ended", "reason": "replaced by a drive in another window"})
                return
            if now - drive.started > self.limits.max_drive_wall_s:
                await self.stop(record=True, notify=True, reason="the drive reached the time limit")
                return
            if drive.paused or dt_wall <= 0:
                continue
            try:
                await self.advance(drive, min(dt_wall * drive.scale, 60.0))
            except DriveHostError as exc:
                await self.stop(record=False, notify=False)
                await self.error(f"{exc}; the drive ended: start a new one")
                return

    async def stop(self, *, record: bool, notify: bool, reason: str | None = None) -> None:
        """End the current drive, record it in the session's runs if the train moved."""
        drive, self.drive = self.drive, None
        if drive is None:
            return
        if drive.ticker is not None and drive.ticker is not asyncio.current_task():
            drive.ticker.cancel()
        self.store.release_drive()
        with self.session.lock:
            if self.session.drive_token is drive.token:
                self.session.drive_token = None
        run = None
        result = None
        if record and not drive.recorded:
            drive.recorded = True
            try:
                result = await self.hosts.result(drive.drive_id)
            except DriveHostError:
                result = None
        await self.hosts.close_drive(drive.drive_id)
        if result is not None:
            with self.session.lock:
                run = StoredRun(
                    id=self.session.next_run_id(),
                    label=f"Drive {drive.number}",
                    strategy="drive",
                    created=time.time(),
                    result=result,
                    route=drive.route,
                    train=drive.train,
                    params={"settings": {"atp": drive.atp}},
                )
                self.store.add_run(self.session, run)
        if notify:
            await self.send(
                {
                    "type": "finished",
                    "reason": reason or drive.last.get("message", "drive ended"),
                    "run": run_brief(run) if run else None,
                    "summary": run.result.summary() if run else None,
                }
            )


@router.websocket("/api/drive")
async def drive_socket(ws: WebSocket) -> None:
    """Live driving (see the module docstring for the messages)."""
    store: SessionStore = ws.app.state.store
    limits: WebSettings = ws.app.state.web_settings
    sid = ws.query_params.get("session") or ws.headers.get(HEADER_NAME) or ws.cookies.get(COOKIE_NAME)
    session = store.get(sid)
    await ws.accept()
    origin = ws.headers.get("origin")
    if origin is not None and urlsplit(origin).netloc != ws.headers.get("host"):
        # another web site's page must not drive with this browser's session
        await ws.send_text(json.dumps({"type": "ended", "reason": "cross-origin connection refused"}))
        await ws.close(code=4403)
        return
    if session is None:
        await ws.send_text(
            json.dumps({"type": "ended", "reason": "unknown or expired session: reload the page"})
        )
        await ws.close(code=4401)
        return
    await DriveConnection(ws, store, session, limits, ws.app.state.drive_hosts).serve()
