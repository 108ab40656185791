"""20 concurrent clients on one server (loopback only): every answer right, no session sees another's
runs. Bounded: 20 x 3 runs, no new request after 60 s. Figures: benchmarks/bench_web_load.py."""

from __future__ import annotations

import asyncio
import importlib.util

import pytest

from .conftest import REPO, LiveServer


@pytest.mark.slow
def test_twenty_concurrent_clients_run_the_metro_example() -> None:
    spec = importlib.util.spec_from_file_location("bench_web_load", REPO / "benchmarks" / "bench_web_load.py")
    if spec is None or spec.loader is None or not (REPO / "benchmarks" / "bench_web_load.py").exists():
        pytest.skip("benchmarks/bench_web_load.py not found (not a source checkout)")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    with LiveServer() as server:
        assert server.url.startswith("http://127.0.0.1:")
        figures = asyncio.run(bench.load(server.url, clients=20, runs=3, max_seconds=60))
    assert figures["clients"] == 20
    assert figures["runs"] == 60  # every client made every run (60 s is far from reached)
    assert figures["requests"] == 20 * (3 + 2)
