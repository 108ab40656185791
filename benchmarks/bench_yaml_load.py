"""Reading a long route file (issue 13): ``load_route`` and ``trainsim check`` on N gradient entries.

Run: python benchmarks/bench_yaml_load.py [--entries N] [--repeat K]

Writes a trainsim route with N one-line gradient entries (``- {from_m: 0, gradient_permille: -3}``,
default 200,000, about 8.8 MB) to a temporary directory and times, alternating in the same run:

* ``trainsim.load_route``: the whole path of a user's file (bounded YAML reading, validation, Route);
* ``trainsim.io.loader.check_file``: what ``trainsim check`` does after its imports;
* the baseline: ``json.loads`` of the same data written as JSON, the C parser of the standard
  library, which builds the same Python lists and dicts and checks nothing.

The machine is shared: wall times vary with the load, so the CPU time of this process and the ratio
to the baseline of the same run are the figures to read. It also runs ``trainsim check`` as a
command once and prints its CPU time and peak resident memory. Target: under 2 s (issue 13).
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def write_route(path: Path, entries: int) -> None:
    """A trainsim route file with ``entries`` gradient sections of 10 m (gradients -3 .. 3 per mille)."""
    length = entries * 10 + 10
    head = (
        f"schema: trainsim/route\nversion: 1\nname: long route\nlength_m: {length}\n"
        f"stations:\n  - {{name: A, position_m: 0}}\n  - {{name: B, position_m: {length}}}\n"
        "speed_limits:\n  - {from_m: 0, limit_kmh: 80}\ngradients:\n"
    )
    rows = "".join(f"  - {{from_m: {i * 10}, gradient_permille: {(i % 7) - 3}}}\n" for i in range(entries))
    tail = "line_resistance:\n  curve_formula: none\n  tunnel_formula: none\n"
    path.write_text(head + rows + tail, encoding="utf-8")


def _timed(func: Callable[[], Any]) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    func()
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--entries", type=int, default=200_000, help="gradient entries (default 200000)")
    parser.add_argument("--repeat", type=int, default=3, help="repetitions, median reported (default 3)")
    args = parser.parse_args()

    import trainsim
    from trainsim.io import documents
    from trainsim.io.loader import check_file
    from trainsim.io.yaml_route import route_spec_from_dict

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "route.yaml"
        write_route(path, args.entries)
        size_mb = path.stat().st_size / 1e6
        data = documents.read_yaml(path)
        route_spec_from_dict(data)  # the imports of validation, outside the timings
        js = json.dumps(data)
        times: dict[str, list[tuple[float, float]]] = {"load_route": [], "check_file": [], "json.loads": []}
        for _ in range(args.repeat):
            times["json.loads"].append(_timed(lambda: json.loads(js)))
            times["load_route"].append(_timed(lambda: trainsim.load_route(path)))
            times["check_file"].append(_timed(lambda: check_file(path)))
        route = trainsim.load_route(path)
        level = sum(1 for i in range(args.entries) if i % 7 == 3)  # level sections are not kept
        assert len(route.gradients) == args.entries - level, "the route lost gradient entries"
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        cli = [sys.executable, "-m", "trainsim", "check", str(path)]
        wall0 = time.perf_counter()
        done = subprocess.run(cli, capture_output=True, text=True, check=False)
        cli_wall = time.perf_counter() - wall0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)

    base_wall = statistics.median(w for w, _ in times["json.loads"])
    base_cpu = statistics.median(c for _, c in times["json.loads"])
    print(f"route file: {args.entries} gradient entries, {size_mb:.1f} MB")
    print(f"{'':24s} {'wall [s]':>9s} {'CPU [s]':>9s} {'x json.loads (CPU)':>19s}")
    for name, samples in times.items():
        wall = statistics.median(w for w, _ in samples)
        cpu = statistics.median(c for _, c in samples)
        print(f"{name:24s} {wall:9.2f} {cpu:9.2f} {cpu / base_cpu:19.1f}")
    cli_cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    print(
        f"trainsim check (command) {cli_wall:9.2f} {cli_cpu:9.2f}  exit {done.returncode}, "
        f"peak {after.ru_maxrss / 1024:.0f} MB (with imports)"
    )
    print(f"peak resident memory of this process: {peak:.0f} MB; json.loads wall {base_wall:.2f} s")


if __name__ == "__main__":
    main()
