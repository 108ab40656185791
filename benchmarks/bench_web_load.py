"""Load test of the web application on loopback: concurrent clients running the metro example.

    python benchmarks/bench_web_load.py [--clients 20] [--runs 10] [--max-seconds 60]

Starts ``uvicorn`` with the trainsim app on 127.0.0.1 (a free port), then ``--clients`` clients,
each with its own session (cookie), load the metro example and run its fastest run ``--runs``
times, all at once. Prints requests per second and latency percentiles of the run requests and of
all requests. Bounded: at most clients x (runs + 2) requests, and no new request after
``--max-seconds``. Every answer is checked (status, the metro's running time, and that a
client's run list holds its own runs only).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import socket
import statistics
import subprocess
import sys
import time

import httpx

METRO_RUNNING_TIME_S = 278.98761151498184


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
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"server exited: {proc.stderr.read().decode() if proc.stderr else ''}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            time.sleep(0.1)
    proc.kill()
    raise RuntimeError("server did not start in 30 s")


async def one_client(base: str, k: int, runs: int, stop_at: float, lat: dict[str, list[float]]) -> int:
    """One browser-like client; returns the number of runs it made. Raises on a wrong answer."""
    async with httpx.AsyncClient(base_url=base, timeout=60) as c:

        async def call(kind: str, method: str, url: str, **kw) -> httpx.Response:
            t0 = time.perf_counter()
            r = await c.request(method, url, **kw)
            lat[kind].append(time.perf_counter() - t0)
            return r

        r = await call("other", "POST", "/api/examples/metro_b")
        assert r.status_code == 200, r.text
        done = 0
        for i in range(runs):
            if time.monotonic() > stop_at:
                break
            r = await call("run", "POST", "/api/runs", json={"label": f"client {k} run {i}"})
            assert r.status_code == 201, r.text
            assert abs(r.json()["summary"]["running_time_s"] - METRO_RUNNING_TIME_S) < 1e-6
            done += 1
        r = await call("other", "GET", "/api/runs")
        labels = {x["label"] for x in r.json()}
        assert labels and all(label.startswith(f"client {k} ") for label in labels), labels
        return done


async def load(base: str, clients: int, runs: int, max_seconds: float) -> dict[str, float]:
    """Run the load against ``base``; returns the figures."""
    lat: dict[str, list[float]] = {"run": [], "other": []}
    stop_at = time.monotonic() + max_seconds
    t0 = time.perf_counter()
    done = await asyncio.gather(*(one_client(base, k, runs, stop_at, lat) for k in range(clients)))
    wall = time.perf_counter() - t0
    every = lat["run"] + lat["other"]

    def pct(values: list[float], q: float) -> float:
        return (
            statistics.quantiles(values, n=100, method="inclusive")[q - 1] if len(values) > 1 else values[0]
        )

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
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument("--runs", type=int, default=10, help="fastest runs per client")
    parser.add_argument("--max-seconds", type=float, default=60.0)
    args = parser.parse_args()
    port = free_port()
    proc = start_server(port)
    try:
        base = f"http://127.0.0.1:{port}"
        # warm-up: the numba kernel's first call loads its compiled code
        asyncio.run(load(base, 1, 1, 30))
        figures = asyncio.run(load(base, args.clients, args.runs, args.max_seconds))
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    print(f"web load on 127.0.0.1, {os.cpu_count()} cores, one uvicorn worker:")
    print(
        f"  {figures['clients']} concurrent clients, {figures['runs']} metro fastest runs, "
        f"{figures['requests']} requests in {figures['wall_s']:.2f} s"
    )
    print(f"  throughput: {figures['requests_per_s']:.1f} requests/s ({figures['runs_per_s']:.1f} runs/s)")
    print(
        f"  run request latency: p50 {figures['run_p50_ms']:.0f} ms, p95 {figures['run_p95_ms']:.0f} ms, "
        f"max {figures['run_max_ms']:.0f} ms; all requests p95 {figures['all_p95_ms']:.0f} ms"
    )


if __name__ == "__main__":
    main()
