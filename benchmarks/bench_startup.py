"""Start-up of trainsim as a user meets it, whole processes, against `python -c "import numpy"`.

Run: python benchmarks/bench_startup.py [--repeat N] [--cold]

Each figure is the median wall time of N whole processes (after one warm-up), and its ratio to the
baseline `python -c "import numpy"` timed in the same run, pair by pair (the machine is shared and
noisy: quote the ratios); then the same in CPU time of the child process (user + system, from
getrusage), the figure that a loaded machine does not inflate. Targets (issue 14): `trainsim --help` <= 0.15 s, `import trainsim`
<= 0.25 s, `trainsim run` of the metro example <= 0.6 s or <= 3x the baseline; with --cold, the
first run after a fresh install (empty numba cache) <= 5 s.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
METRO = ROOT / "examples" / "metro_b" / "scenario.yaml"

BASELINE = [sys.executable, "-c", "import numpy"]
CASES: dict[str, tuple[list[str], float]] = {
    "trainsim --help": ([sys.executable, "-m", "trainsim", "--help"], 0.15),
    "import trainsim": ([sys.executable, "-c", "import trainsim"], 0.25),
    "trainsim run metro (warm)": ([sys.executable, "-m", "trainsim", "run", str(METRO)], 0.6),
}


def wall(cmd: list[str], env: dict[str, str] | None = None) -> float:
    return timed(cmd, env)[0]


def timed(cmd: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall time and CPU time (user + system of the child process) of one whole process [s]."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, env=env, cwd=ROOT)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return elapsed, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--cold", action="store_true", help="also time a first run with an empty numba cache")
    args = parser.parse_args()
    for cmd, _ in CASES.values():  # warm-up: numba's cache and the OS's file cache
        wall(cmd)
    wall(BASELINE)
    print(
        f"{'figure':32s} {'median s':>9s} {'baseline s':>10s} {'ratio':>7s} {'CPU s':>7s} {'base CPU':>8s} "
        f"{'CPU ratio':>9s} {'target s':>9s}"
    )
    for name, (cmd, target) in CASES.items():
        times, bases, ratios, cpus, base_cpus, cpu_ratios = [], [], [], [], [], []
        for _ in range(args.repeat):
            t, c = timed(cmd)
            b, bc = timed(BASELINE)
            times.append(t)
            bases.append(b)
            ratios.append(t / b)
            cpus.append(c)
            base_cpus.append(bc)
            cpu_ratios.append(c / max(bc, 1e-6))
        med = statistics.median(times)
        print(
            f"{name:32s} {med:9.3f} {statistics.median(bases):10.3f} {statistics.median(ratios):7.2f} "
            f"{statistics.median(cpus):7.3f} {statistics.median(base_cpus):8.3f} "
            f"{statistics.median(cpu_ratios):9.2f} {target:9.2f}"
        )
    if args.cold:
        cmd = CASES["trainsim run metro (warm)"][0]
        times, ratios, cpus, cpu_ratios = [], [], [], []
        for _ in range(max(1, args.repeat // 3)):
            cache = tempfile.mkdtemp(prefix="trainsim-numba-")
            try:
                env = {**os.environ, "NUMBA_CACHE_DIR": cache}
                t, c = timed(cmd, env=env)
                b, bc = timed(BASELINE)
            finally:
                shutil.rmtree(cache, ignore_errors=True)
            times.append(t)
            ratios.append(t / b)
            cpus.append(c)
            cpu_ratios.append(c / max(bc, 1e-6))
        print(
            f"{'trainsim run metro (cold cache)':32s} {statistics.median(times):9.3f} {'':10s} "
            f"{statistics.median(ratios):7.1f} {statistics.median(cpus):7.3f} {'':8s} "
            f"{statistics.median(cpu_ratios):9.1f} {5.0:9.2f}"
        )


if __name__ == "__main__":
    main()
