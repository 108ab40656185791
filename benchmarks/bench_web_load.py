"""Load test of the web application on loopback: concurrent clients running and driving the metro example.

    python benchmarks/bench_web_load.py [--clients 20] [--runs 10] [--drives 20] [--drive-seconds 8]
                                        [--max-seconds 60]

Starts ``uvicorn`` with the trainsim app on 127.0.0.1 (a free port; two worker processes), then:

1. **baseline**: one client alone makes ``--runs`` run requests, one after the other;
2. **runs**: ``--clients`` clients at once, each with its own session (cookie), load the metro
   example and repeat the page's run request (``POST /api/runs``) ``--runs`` times;
3. **distinct runs**: the same, but every request asks for a different integration step, so that
   no run is served from the result cache (every one is computed in a worker);
4. **live driving**: one drive alone at 20x (baseline), then ``--drives`` drives at once at 20x
   with full power for ``--drive-seconds``; the figure is the time between two state messages
   (nominally 0.1 s).

Prints latency percentiles and throughput with their ratio to the baseline, and the server's CPU
time per request (server and worker processes, from /proc), which says what the machine can do
when it is not shared. Bounded: at most clients x (runs + 2) requests per phase, no new request
after ``--max-seconds``, drives end after ``--drive-seconds``. Every answer is checked (status, the
metro's running time as the CLI computes it, a client's run list holds its own runs only).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import re
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

import httpx


def metro_running_time_s(step_m: float | None = None) -> float:
    """The metro example's running time as the CLI computes it (the web must give the same)."""
    import dataclasses

    import trainsim

    root = Path(__file__).resolve().parents[1]
    scenario = trainsim.load_scenario(root / "examples" / "metro_b" / "scenario.yaml")
    if step_m is not None:
        scenario = dataclasses.replace(
            scenario, settings=dataclasses.replace(scenario.settings, max_step_m=step_m)
        )
    return trainsim.run(scenario).running_time_s


METRO_RUNNING_TIME_S = metro_running_time_s()
RUNNING_TIME = re.compile(rb'"running_time_s":([-+0-9.eE]+)')


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(port: int) -> subprocess.Popen:
    cmd = [
        sys.executable,
        "-m",
        "uvicorn",
        "--factory",
        "trainsim.web.app:app_factory",
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        "--log-level",
        "warning",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"server exited: {proc.stderr.read().decode() if proc.stderr else ''}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            time.sleep(0.1)
    proc.kill()
    raise RuntimeError("server did not start in 60 s")


def cpu_seconds(pid: int) -> float:
    """CPU time of a process and its children (workers, fork server) so far [s]."""
    tick = os.sysconf("SC_CLK_TCK")
    total = 0.0
    pids = [pid]
    seen = set()
    while pids:
        p = pids.pop()
        if p in seen:
            continue
        seen.add(p)
        try:
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / tick
            for task in Path(f"/proc/{p}/task").iterdir():  # children are listed per thread
                pids += [int(c) for c in (task / "children").read_text().split()]
        except (OSError, IndexError, ValueError):
            continue
    return total


def pct(values: list[float], q: int) -> float:
    if len(values) == 1:
        return values[0]
    return statistics.quantiles(values, n=100, method="inclusive")[q - 1]


class RawHttp:
    """A minimal HTTP/1.1 keep-alive client on one connection (a browser's tab): the client shares the
    2 cores with the server, and httpx costs several times the server's own CPU per request, which
    would measure the client more than the server. Enough for JSON requests and answers with a
    Content-Length (what the API sends)."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.session: str | None = None
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None

    async def request(self, method: str, path: str, body: object | None = None) -> tuple[int, bytes]:
        if self._writer is None:
            self._reader, self._writer = await asyncio.open_connection("127.0.0.1", self.port)
        assert self._reader is not None
        data = json.dumps(body).encode() if body is not None else b""
        head = f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: {len(data)}\r\n"
        if body is not None:
            head += "Content-Type: application/json\r\n"
        if self.session:
            head += f"X-Trainsim-Session: {self.session}\r\n"
        self._writer.write(head.encode() + b"\r\n" + data)
        raw = await self._reader.readuntil(b"\r\n\r\n")
        lines = raw.decode("latin-1").split("\r\n")
        status = int(lines[0].split()[1])
        headers = {}
        for line in lines[1:]:
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
        answer = await self._reader.readexactly(int(headers.get("content-length", "0")))
        self.session = headers.get("x-trainsim-session", self.session)
        return status, answer

    async def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            with contextlib.suppress(OSError):
                await self._writer.wait_closed()


async def one_client(
    base: str, k: int, runs: int, stop_at: float, lat: dict[str, list[float]], distinct: bool = False
) -> int:
    """One browser-like client; returns the number of runs it made. Raises on a wrong answer."""
    c = RawHttp(int(base.rsplit(":", 1)[1]))

    async def call(kind: str, method: str, url: str, body: object | None = None) -> tuple[int, bytes]:
        t0 = time.perf_counter()
        out = await c.request(method, url, body)
        lat[kind].append(time.perf_counter() - t0)
        return out

    try:
        status, answer = await call("other", "POST", "/api/examples/metro_b")
        assert status == 200, answer[:300]
        done = 0
        for i in range(runs):
            if time.monotonic() > stop_at:
                break
            body: dict = {"label": f"client {k} run {i}"}
            if distinct:  # a step no other request uses: computed, not cached
                body["settings"] = {"max_step_m": round(5.0 + 0.001 * (k * 1000 + i + 1), 4)}
            status, answer = await call("run", "POST", "/api/runs", body)
            assert status == 201, answer[:300]
            if not distinct:
                # the run's figure at the head of the answer: no full parse of the 80 KB of plot data
                # (it would cost the client more CPU than the server spends on the request)
                found = RUNNING_TIME.search(answer, 0, 2000)
                assert found and abs(float(found.group(1)) - METRO_RUNNING_TIME_S) < 1e-6, answer[:300]
            done += 1
        status, answer = await call("other", "GET", "/api/runs")
        labels = {x["label"] for x in json.loads(answer)}
        assert labels and all(label.startswith(f"client {k} ") for label in labels), labels
        return done
    finally:
        await c.close()


async def load(
    base: str, clients: int, runs: int, max_seconds: float, distinct: bool = False
) -> dict[str, float]:
    """Run the load against ``base``; returns the figures."""
    lat: dict[str, list[float]] = {"run": [], "other": []}
    stop_at = time.monotonic() + max_seconds
    t0, c0 = time.perf_counter(), time.process_time()
    done = await asyncio.gather(*(one_client(base, k, runs, stop_at, lat, distinct) for k in range(clients)))
    wall = time.perf_counter() - t0
    client_cpu = time.process_time() - c0
    every = lat["run"] + lat["other"]
    return {
        "clients": clients,
        "runs": sum(done),
        "requests": len(every),
        "wall_s": wall,
        "requests_per_s": len(every) / wall,
        "runs_per_s": len(lat["run"]) / wall,
        "run_p50_ms": 1000 * pct(lat["run"], 50),
        "run_p95_ms": 1000 * pct(lat["run"], 95),
        "run_max_ms": 1000 * max(lat["run"]),
        "all_p95_ms": 1000 * pct(every, 95),
        "client_cpu_ms": 1000 * client_cpu / len(every),
        "load_average": os.getloadavg()[0],
    }


async def warm_up(base: str) -> None:
    async with httpx.AsyncClient(base_url=base, timeout=300) as c:
        r = await c.post("/api/examples/metro_b")
        assert r.status_code == 200, r.text
        r = await c.post("/api/runs", json={})
        assert r.status_code == 201, r.text


async def one_drive(
    base: str, seconds: float, gaps: list[float], speeds: list[float], sim_s: list[float]
) -> None:
    """A live drive at 20x with full power; records the time between state messages [s]."""
    import websockets

    async with httpx.AsyncClient(base_url=base, timeout=60) as c:
        r = await c.post("/api/examples/metro_b")
        assert r.status_code == 200, r.text
        sid = r.headers["x-trainsim-session"]
    url = base.replace("http://", "ws://") + f"/api/drive?session={sid}"
    async with websockets.connect(url, open_timeout=30, max_size=2**22) as ws:
        await ws.send(json.dumps({"type": "start", "time_scale": 20}))
        await ws.send(json.dumps({"type": "command", "value": 1.0}))
        end = time.monotonic() + seconds
        last = None
        sim_end = 0.0
        while time.monotonic() < end:
            msg = json.loads(await asyncio.wait_for(ws.recv(), 30))
            if msg["type"] == "state" and msg["clock"] == "realtime":
                now = time.perf_counter()
                if last is not None and msg["speed_kmh"] > 0:
                    gaps.append(now - last)
                last = now
                speeds.append(msg["speed_kmh"])
                sim_end = msg["time_s"]
            elif msg["type"] in ("finished", "ended"):
                break
        await ws.send(json.dumps({"type": "finish"}))
        sim_s.append(sim_end)


async def drives(base: str, count: int, seconds: float) -> dict[str, float]:
    gaps: list[float] = []
    speeds: list[float] = []
    sim_s: list[float] = []
    await asyncio.gather(*(one_drive(base, seconds, gaps, speeds, sim_s) for _ in range(count)))
    return {
        "drives": count,
        "states": len(gaps),
        "gap_p50_ms": 1000 * pct(gaps, 50),
        "gap_p95_ms": 1000 * pct(gaps, 95),
        "gap_max_ms": 1000 * max(gaps),
        "max_speed_kmh": max(speeds),
        "simulated_s": sum(sim_s),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument("--runs", type=int, default=10, help="run requests per client")
    parser.add_argument("--drives", type=int, default=20)
    parser.add_argument("--drive-seconds", type=float, default=8.0)
    parser.add_argument("--max-seconds", type=float, default=60.0)
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    port = free_port()
    proc = start_server(port)
    out: dict[str, dict[str, float]] = {}
    cpu: dict[str, float] = {}
    try:
        base = f"http://127.0.0.1:{port}"
        # warm-up: the workers are started and have run once (the fork server compiles the kernels
        # first when numba's cache is stale: up to minutes on a loaded machine)
        asyncio.run(warm_up(base))
        for name, clients, distinct in (
            ("baseline", 1, False),
            ("runs", args.clients, False),
            ("distinct", args.clients, True),
        ):
            c0 = cpu_seconds(proc.pid)
            out[name] = asyncio.run(load(base, clients, args.runs, args.max_seconds, distinct))
            cpu[name] = (cpu_seconds(proc.pid) - c0) / out[name]["requests"]
        for name, count, seconds in (
            ("drive_baseline", 1, min(args.drive_seconds, 4.0)),
            ("drive", args.drives, args.drive_seconds),
        ):
            c0 = cpu_seconds(proc.pid)
            out[name] = asyncio.run(drives(base, count, seconds))
            cpu[name] = (cpu_seconds(proc.pid) - c0) / max(out[name]["simulated_s"], 1e-9)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
    b = out["baseline"]
    load_avg = os.getloadavg()[0]
    print(f"load average before the run {load_before:.1f} (1 min)")
    print(
        f"web load on 127.0.0.1, {os.cpu_count()} cores (load average {load_avg:.1f}), one uvicorn process:"
    )
    for name, what in (
        ("baseline", "1 client alone (baseline)"),
        ("runs", f"{args.clients} clients repeating the page's run request"),
        ("distinct", f"{args.clients} clients, every run a different step (computed, not cached)"),
    ):
        f = out[name]
        print(
            f"  {what}: {f['runs']} runs in {f['wall_s']:.2f} s = {f['runs_per_s']:.0f} runs/s "
            f"(x{f['runs_per_s'] / b['runs_per_s']:.2f} of baseline); run p50 {f['run_p50_ms']:.0f} ms, "
            f"p95 {f['run_p95_ms']:.0f} ms (x{f['run_p95_ms'] / b['run_p95_ms']:.1f}), max {f['run_max_ms']:.0f} ms; "
            f"server CPU {1000 * cpu[name]:.1f} ms, client CPU {f['client_cpu_ms']:.1f} ms per request; "
            f"load average {f['load_average']:.1f} after"
        )
    d0, d = out["drive_baseline"], out["drive"]
    for key, f, what in (
        ("drive_baseline", d0, "1 live drive at 20x (baseline)"),
        ("drive", d, f"{args.drives} live drives at 20x"),
    ):
        print(
            f"  {what}: {f['states']} state messages, interval p50 {f['gap_p50_ms']:.0f} ms, "
            f"p95 {f['gap_p95_ms']:.0f} ms (x{f['gap_p95_ms'] / d0['gap_p95_ms']:.2f} of baseline), "
            f"max {f['gap_max_ms']:.0f} ms; top speed {f['max_speed_kmh']:.1f} km/h; server CPU "
            f"{1000 * cpu[key]:.2f} ms per simulated second ({f['simulated_s']:.0f} s simulated)"
        )


if __name__ == "__main__":
    main()
