"""Live drives hosted in worker processes, so that many drives at 20x use every core and the server's
event loop only relays messages.

A drive is the core's :class:`~trainsim.sim.driving.DrivingSession` with what a driver's desk adds
(:class:`HostedDrive`): automatic train protection (full service braking on overspeed, as an
option), the clock from departure, where the train is in
words, stopping accuracy, gradient and the distance to the next limit. Each host process keeps
the drives given to it; the server sends ``open``, ``advance``, ``view``, ``result`` and ``close``
requests over a pipe (one request at a time per host) and gets plain dictionaries back. With
``processes=0`` the drives run in the server process (tests and debugging).
"""

from __future__ import annotations

import asyncio
import bisect
import contextlib
import itertools
import math
import multiprocessing
import multiprocessing.connection
import signal
import traceback
from typing import Any

from trainsim.constants import KMH, KN, KWH
from trainsim.errors import InputError, TrainsimError
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train

__all__ = ["DriveHostError", "DriveHosts", "HostedDrive"]

#: longest single core step while ATP watches the train [s]
WATCH_STEP_S = 0.5
#: a request to a host that takes longer than this ends the drive [s]
HOST_TIMEOUT_S = 20.0


class DriveHostError(Exception):
    """A host process failed or did not answer: the drive ends."""


def _clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class HostedDrive:
    """A drive with a driver's desk around the core's driving session (SI inside, the page's units out)."""

    def __init__(self, train: Train, route: Route, settings: RunSettings, atp: bool) -> None:
        from trainsim.sim.driving import DrivingSession

        self.core = DrivingSession(train=train, route=route, settings=settings)
        self.train, self.route, self.settings = train, route, settings
        self.atp = atp
        self.atp_braking = False
        self.departure_s: float | None = None
        self.start_position_m = self.core.position_m
        # sections do not overlap: sorted by start, the one that may hold a position is the last
        # that starts at or before it
        self._gradients = sorted(route.gradients, key=lambda g: g.start_m)
        self._gradient_starts = [g.start_m for g in self._gradients]

    def reference(self) -> dict[str, Any] | None:
        """The fastest run's speed over distance, to drive against (None if it cannot be run)."""
        from trainsim.sim.fastest import run_fastest
        from trainsim.web.payloads import floats

        try:
            result = run_fastest(self.train, self.route, self.settings)
        except TrainsimError:
            return None
        tr = result.trace
        step = max(1, len(tr) // 1500)
        return {
            "running_time_s": result.running_time_s,
            "position_m": floats(tr.position_m[::step], 2),
            "speed_kmh": floats(tr.speed_mps[::step] / KMH, 2),
        }

    def effective_command(self, command: float) -> float:
        """The driver's command, overridden by ATP on overspeed (more than 1 km/h over the limit:
        full service braking until the speed is back at the limit). The design speed is the core's
        (:mod:`trainsim.sim.driving`: traction never takes the train past it)."""
        if not self.atp:
            return command
        v, limit = self.core.speed_mps, self.core.speed_limit_mps()
        if v > limit + 1.0 * KMH:
            self.atp_braking = True
        elif self.atp_braking and v <= limit:
            self.atp_braking = False
        return -1.0 if self.atp_braking else command

    def advance(self, command: float, dt_s: float) -> dict[str, Any]:
        """Drive ``dt_s`` seconds with the driver's ``command``; the view afterwards. ATP ending its
        braking leaves the lever at neutral (``lever_reset``): the driver must take it again."""
        was_braking = self.atp_braking
        left = dt_s
        while left > 1e-9 and not self.core.finished:
            h = min(left, WATCH_STEP_S)
            self.core.step(self.effective_command(command), h)
            left -= h
        reset = was_braking or self.atp_braking
        return self.view(0.0 if reset else command, lever_reset=reset)

    def _location(self, position_m: float, speed_mps: float) -> tuple[str, float | None]:
        stations = self.route.stations
        nearest = min(stations, key=lambda s: abs(s.position_m - position_m), default=None)
        if nearest is not None and abs(nearest.position_m - position_m) <= 50.0 and speed_mps < 0.01:
            return f"at {nearest.name}", position_m - nearest.position_m
        before = [s for s in stations if s.position_m <= position_m]
        after = [s for s in stations if s.position_m > position_m]
        if before and after:
            return f"between {before[-1].name} and {after[0].name}", None
        if after:
            return f"before {after[0].name}", None
        return (f"past {before[-1].name}" if before else "on the line"), None

    def _gradient_permille(self, position_m: float) -> float:
        k = bisect.bisect_right(self._gradient_starts, position_m) - 1
        if k >= 0:
            g = self._gradients[k]
            if g.start_m <= position_m < g.end_m:
                return float(g.gradient_permille)
        return 0.0

    def view(self, command: float, lever_reset: bool = False) -> dict[str, Any]:
        """What the driver sees (the ``state`` message without the server's fields)."""
        d = vars(self.core.state(command))
        if self.departure_s is None and d["speed_mps"] > 0:
            self.departure_s = d["time_s"]
        location, stop_error = self._location(d["position_m"], d["speed_mps"])
        limit = d["speed_limit_mps"]
        message = d["message"]
        if message.startswith("at ") and not location.startswith("at "):
            message = "departed " + message[3:]  # the core says where the drive began until an event
        out = {
            "type": "state",
            "time_s": d["time_s"],
            "clock_s": d["time_s"] - self.departure_s if self.departure_s is not None else 0.0,
            "position_m": d["position_m"],
            "location": location,
            "speed_kmh": d["speed_mps"] / KMH,
            "acceleration_mps2": d["acceleration_mps2"],
            "command": d["command"],
            "lever_reset": lever_reset,
            "regime": d["regime"],
            "traction_force_kn": d["traction_force_n"] / KN,
            "braking_force_kn": d["braking_force_n"] / KN,
            "gradient_permille": self._gradient_permille(d["position_m"]),
            "speed_limit_kmh": limit / KMH,
            "max_speed_kmh": self.train.max_speed_mps / KMH,
            "next_limit_position_m": d["next_limit_position_m"],
            "next_limit_kmh": d["next_limit_mps"] / KMH if d["next_limit_mps"] is not None else None,
            "next_limit_distance_m": (
                d["next_limit_position_m"] - d["position_m"]
                if d["next_limit_position_m"] is not None
                else None
            ),
            "next_stop_name": d["next_stop_name"],
            "next_stop_distance_m": d["next_stop_distance_m"],
            "stop_error_m": stop_error,
            "dwell_remaining_s": d["dwell_remaining_s"],
            "line_current_a": d["line_current_a"],
            "energy_kwh": d["electrical_energy_j"] / KWH,
            "overspeed": d["overspeed"],
            "overspeed_by_kmh": max(0.0, (d["speed_mps"] - limit) / KMH),
            "atp": self.atp,
            "atp_braking": self.atp_braking,
            "finished": d["finished"],
            "message": message,
        }
        return {k: _clean(v) for k, v in out.items()}

    def moved(self) -> bool:
        return self.core.position_m != self.start_position_m or self.core.time_s > 0

    def result(self) -> Any:
        return self.core.result() if self.moved() else None


# ====================================================================== host process
class _Drives:
    """The drives of one host (or of the server process with ``processes=0``)."""

    def __init__(self) -> None:
        self.drives: dict[int, HostedDrive] = {}

    def handle(self, op: str, drive_id: int, args: tuple[Any, ...]) -> Any:
        if op == "open":
            drive = HostedDrive(*args)
            self.drives[drive_id] = drive
            return drive.reference(), drive.view(0.0)
        drive = self.drives.get(drive_id)
        if drive is None:
            raise DriveHostError(f"no drive {drive_id} on this host")
        if op == "advance":
            return drive.advance(*args)
        if op == "view":
            return drive.view(*args)
        if op == "result":
            return drive.result()
        if op == "close":
            self.drives.pop(drive_id, None)
            return None
        raise DriveHostError(f"unknown request {op!r}")


def _host_main(conn: multiprocessing.connection.Connection) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    drives = _Drives()
    while True:
        try:
            op, drive_id, args = conn.recv()
        except (EOFError, OSError):
            return
        try:
            out: tuple[str, Any] = ("ok", drives.handle(op, drive_id, args))
        except InputError as exc:
            out = ("input", str(exc))
        except Exception:
            out = ("error", traceback.format_exc(limit=8))
        try:
            conn.send(out)
        except (BrokenPipeError, OSError):
            return


class _Host:
    def __init__(self, ctx: Any) -> None:
        parent, child = ctx.Pipe()
        self.process = ctx.Process(target=_host_main, args=(child,), daemon=True, name="trainsim-drive-host")
        self.process.start()
        child.close()
        self.conn = parent
        self.lock = asyncio.Lock()
        self.drives = 0


class DriveHosts:
    """Drive host processes (``processes``; 0: drives in the server process)."""

    def __init__(self, processes: int, start_timeout_s: float = 600.0) -> None:
        self.processes = processes
        self.start_timeout_s = start_timeout_s
        self._hosts: list[_Host] = []
        self._local = _Drives()
        self._ids = itertools.count(1)
        self._where: dict[int, _Host | None] = {}
        self._starting: asyncio.Task | None = None
        self._ctx = multiprocessing.get_context("forkserver")
        self._ctx.set_forkserver_preload(["trainsim.web._preload"])

    async def start(self) -> None:
        if self.processes <= 0:
            return
        if self._starting is None:
            self._starting = asyncio.ensure_future(self._start())
        await asyncio.shield(self._starting)

    async def _start(self) -> None:
        from trainsim.web.workers import in_daemon_thread

        self._hosts = await in_daemon_thread(lambda: [_Host(self._ctx) for _ in range(self.processes)])

    def close(self) -> None:
        for host in self._hosts:
            with contextlib.suppress(Exception):
                host.process.kill()
            with contextlib.suppress(Exception):
                host.conn.close()
            with contextlib.suppress(Exception):
                host.process.join(timeout=5)
        self._hosts = []

    async def _request(self, host: _Host | None, op: str, drive_id: int, args: tuple[Any, ...]) -> Any:
        if host is None:
            try:
                return self._local.handle(op, drive_id, args)
            except (InputError, DriveHostError):
                raise
            except Exception as exc:
                raise DriveHostError(f"the drive failed ({type(exc).__name__}: {exc})") from exc
        loop = asyncio.get_running_loop()
        async with host.lock:
            if not host.process.is_alive():
                raise DriveHostError("the drive's host process has stopped")
            ready = loop.create_future()
            fd = host.conn.fileno()
            host.conn.send((op, drive_id, args))
            loop.add_reader(fd, lambda: ready.done() or ready.set_result(None))
            try:
                await asyncio.wait_for(ready, HOST_TIMEOUT_S)
            except TimeoutError as exc:
                host.process.kill()
                raise DriveHostError("the drive's host did not answer in time") from exc
            finally:
                loop.remove_reader(fd)
            try:
                kind, value = host.conn.recv()
            except (EOFError, OSError) as exc:
                raise DriveHostError("the drive's host process has stopped") from exc
        if kind == "ok":
            return value
        if kind == "input":
            raise InputError(value)
        raise DriveHostError(f"the drive failed: {str(value).strip().splitlines()[-1]}")

    async def open(
        self, train: Train, route: Route, settings: RunSettings, atp: bool
    ) -> tuple[int, dict[str, Any] | None, dict[str, Any]]:
        """A new drive on the least busy host: (drive id, fastest-run reference, first view)."""
        try:
            await asyncio.wait_for(self.start(), timeout=self.start_timeout_s)
        except TimeoutError:
            from trainsim.web.workers import STARTING

            raise DriveHostError(STARTING) from None
        drive_id = next(self._ids)
        host = min(self._hosts, key=lambda h: h.drives) if self._hosts else None
        self._where[drive_id] = host
        if host is not None:
            host.drives += 1
        try:
            reference, view = await self._request(host, "open", drive_id, (train, route, settings, atp))
        except BaseException:
            self._forget(drive_id)
            raise
        return drive_id, reference, view

    def _forget(self, drive_id: int) -> None:
        host = self._where.pop(drive_id, None)
        if host is not None:
            host.drives -= 1

    async def advance(self, drive_id: int, command: float, dt_s: float) -> dict[str, Any]:
        return await self._request(self._where.get(drive_id), "advance", drive_id, (command, dt_s))

    async def view(self, drive_id: int, command: float) -> dict[str, Any]:
        return await self._request(self._where.get(drive_id), "view", drive_id, (command,))

    async def result(self, drive_id: int) -> Any:
        """The drive's record as a RunResult (None if the train never moved)."""
        return await self._request(self._where.get(drive_id), "result", drive_id, ())

    async def close_drive(self, drive_id: int) -> None:
        host = self._where.get(drive_id)
        try:
            await self._request(host, "close", drive_id, ())
        except DriveHostError:
            pass
        finally:
            self._forget(drive_id)
