"""Loading a long route: a trainsim route file with N gradient entries (default 200,000).

Run: python benchmarks/bench_load.py [--entries N] [--repeat K]

Writes the route to a temporary directory (one ``{from_m, gradient_permille}`` entry every 10 m, the
gradient cycling through -3 .. 3 per mille) and times, in the same run:

* ``trainsim.load_route`` on it: the whole path a user's file takes (bounded YAML reading in
  ``trainsim.io.documents``, pydantic validation, the ``Route`` object);
* the baseline: ``yaml.load(text, Loader=yaml.CSafeLoader)`` on the same text, PyYAML's C loader
  alone (no validation, no bounds, nothing built).

It prints the median wall and CPU time of each over ``--repeat`` repetitions, their ratios and the
peak resident memory of the process (on a busy machine the CPU figures are the ones to read). The target (issue 13) is under 2 s for
200,000 entries on an idle machine; the ratio is the figure to compare between machines: at or below
1 means the whole load costs no more than PyYAML's C loader alone.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import tempfile
import time
from pathlib import Path


def write_route(path: Path, entries: int) -> None:
    """A trainsim route file with ``entries`` gradient sections of 10 m."""
    length = entries * 10 + 10
    lines = [
        "schema: trainsim/route",
        "version: 1",
        "name: long route",
        f"length_m: {length}",
        "stations:",
        "  - {name: A, position_m: 0, dwell_s: 0}",
        f"  - {{name: B, position_m: {length}, dwell_s: 0}}",
        "speed_limits:",
        "  - {from_m: 0, limit_kmh: 80}",
        "gradients:",
    ]
    lines += [f"  - {{from_m: {i * 10}, gradient_permille: {(i % 7) - 3}}}" for i in range(entries)]
    lines += [
        "line_resistance:",
        "  curve_formula: none",
        "  tunnel_formula: none",
        "  gradient_formula: small_angle",
        "  apply_over: head",
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--entries", type=int, default=200_000, help="gradient entries (default 200000)")
    parser.add_argument("--repeat", type=int, default=3, help="repetitions, median reported (default 3)")
    args = parser.parse_args()

    import yaml

    import trainsim

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "route.yaml"
        write_route(path, args.entries)
        text = path.read_text(encoding="utf-8")
        ours, base, cpu, base_cpu = [], [], [], []
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            route = trainsim.load_route(path)
            ours.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            t0, c0 = time.perf_counter(), time.process_time()
            yaml.load(text, Loader=yaml.CSafeLoader)
            base.append(time.perf_counter() - t0)
            base_cpu.append(time.process_time() - c0)
        level = sum(1 for i in range(args.entries) if i % 7 == 3)  # level sections are not kept
        assert len(route.gradients) == args.entries - level, "the route lost gradient entries"
    t_ours, t_base = statistics.median(ours), statistics.median(base)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"route file: {args.entries} gradient entries, {len(text) / 1e6:.1f} MB")
    print(
        f"trainsim.load_route          {t_ours:7.2f} s wall, {statistics.median(cpu):.2f} s CPU (target < 2 s)"
    )
    print(f"yaml.CSafeLoader (baseline)  {t_base:7.2f} s wall, {statistics.median(base_cpu):.2f} s CPU")
    print(f"ratio load_route / baseline  {t_ours / t_base:7.2f} wall, {sum(cpu) / sum(base_cpu):.2f} CPU")
    print(f"peak resident memory         {peak_mb:7.0f} MB")


if __name__ == "__main__":
    main()
