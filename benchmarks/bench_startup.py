"""Start-up of trainsim as a user meets it, whole processes, against `python -c "import numpy"`.

Run: python benchmarks/bench_startup.py [--repeat N] [--cold] [--as-is]

Each figure is the median wall time of N whole processes (after one warm-up), and the median of its
ratios to the baseline `python -c "import numpy"` timed in the same run, pair by pair (the order of
each pair swapped every round; the machine is shared and noisy: quote the ratios); then the same in
CPU time of the child process (user + system, from getrusage), the figure that a loaded machine does
not inflate. Targets (issue 14): `trainsim --help` <= 0.15 s, `import trainsim` <= 0.25 s,
`trainsim run` of the metro example <= 0.6 s or <= 3x the baseline; with --cold, the first run after a
fresh install (empty numba cache) <= 5 s.

Two reference rows say what part of a run no change inside trainsim can remove while its kernels are
numba dispatchers: `import numba`, and "numba floor", a process that imports numba and calls one
trivial ``njit(cache=True)`` function loaded from its cache. Loading the first cached function makes
numba load its whole lowering library (numba.core.cpu.CPUContext.load_additional_registries: every
numba.np / numba.cpython implementation module, and through numba.np.arraymath's BLAS check
scipy.linalg), whatever the function uses. "run above the floor" is the run's median minus that floor.

Bytecode: a warm machine has compiled bytecode (``pip install`` writes it for every module). With
PYTHONDONTWRITEBYTECODE set (as in some containers) an editable install recompiles every trainsim module
from source at each start while numpy's bytecode was compiled at its install, which is unfair to
trainsim. The child processes therefore run with bytecode written to and read from a temporary
PYTHONPYCACHEPREFIX (the work tree is left untouched), the baseline alike; --as-is keeps the caller's
environment instead.
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
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
METRO = ROOT / "examples" / "metro_b" / "scenario.yaml"

sys.path.insert(0, str(Path(__file__).resolve().parent))

BASELINE = [sys.executable, "-c", "import numpy"]

#: the module of the "numba floor" process: one trivial function compiled once, then loaded from cache
FLOOR_MODULE = """
from numba import njit


@njit(cache=True)
def one(x):
    return x + 1.0
"""

RUN = "trainsim run metro (warm)"
FLOOR = "numba floor (1 cached fn)"


def timed(cmd: Sequence[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall time and CPU time (user + system of the child process) of one whole process [s]."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, env=env, cwd=ROOT)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return elapsed, cpu


def child_env(work: Path, as_is: bool) -> dict[str, str]:
    """The environment of every timed process (see the module docstring on bytecode)."""
    env = dict(os.environ)
    if not as_is:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    return env


def cases(work: Path) -> dict[str, tuple[list[str], float | None]]:
    """name -> (command, target [s] or None for a reference row)."""
    (work / "floor").mkdir()
    (work / "floor" / "floor_mod.py").write_text(FLOOR_MODULE)
    floor = f"import sys; sys.path.insert(0, {str(work / 'floor')!r}); import floor_mod; floor_mod.one(1.0)"
    return {
        "trainsim --help": ([sys.executable, "-m", "trainsim", "--help"], 0.15),
        "import trainsim": ([sys.executable, "-c", "import trainsim"], 0.25),
        RUN: ([sys.executable, "-m", "trainsim", "run", str(METRO)], 0.6),
        "import numba (reference)": ([sys.executable, "-c", "import numba"], None),
        FLOOR: ([sys.executable, "-c", floor], None),
    }


def paired(
    cmd: list[str], repeat: int, env: dict[str, str]
) -> tuple[list[float], list[float], list[float], list[float]]:
    """(case wall, baseline wall, case CPU, baseline CPU) [s], ``repeat`` pairs, order swapped each round."""
    out: tuple[list[float], list[float], list[float], list[float]] = ([], [], [], [])
    for k in range(repeat):
        if k % 2:
            b, bc = timed(BASELINE, env)
            t, c = timed(cmd, env)
        else:
            t, c = timed(cmd, env)
            b, bc = timed(BASELINE, env)
        for series, value in zip(out, (t, b, c, bc), strict=True):
            series.append(value)
    return out


def ratio(a: list[float], b: list[float]) -> float:
    """Median of the per-pair ratios a / b."""
    return statistics.median(x / max(y, 1e-6) for x, y in zip(a, b, strict=True))


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--cold", action="store_true", help="also time a first run with an empty numba cache")
    parser.add_argument(
        "--as-is", action="store_true", help="keep the environment's bytecode settings (see the docstring)"
    )
    args = parser.parse_args(argv)
    import _timing

    print(f"machine: {_timing.machine()}")
    work = Path(tempfile.mkdtemp(prefix="trainsim-startup-"))
    try:
        env = child_env(work, args.as_is)
        print(
            "bytecode: "
            + (
                "the caller's environment (--as-is)"
                if args.as_is
                else f"written and read under a temporary PYTHONPYCACHEPREFIX ({work / 'pycache'})"
            )
        )
        table = cases(work)
        for cmd, _ in table.values():  # warm-up: bytecode, numba's caches and the OS's file cache
            timed(cmd, env)
        timed(BASELINE, env)
        print(
            f"{'figure':32s} {'median s':>9s} {'baseline s':>10s} {'ratio':>7s} {'CPU s':>7s} {'base CPU':>8s} "
            f"{'CPU ratio':>9s} {'target s':>9s}"
        )
        medians: dict[str, tuple[float, float, float, float]] = {}
        for name, (cmd, target) in table.items():
            t, b, c, bc = paired(cmd, args.repeat, env)
            medians[name] = (
                statistics.median(t),
                statistics.median(b),
                statistics.median(c),
                statistics.median(bc),
            )
            print(
                f"{name:32s} {medians[name][0]:9.3f} {medians[name][1]:10.3f} {ratio(t, b):7.2f} "
                f"{medians[name][2]:7.3f} {medians[name][3]:8.3f} {ratio(c, bc):9.2f} "
                f"{'' if target is None else f'{target:9.2f}'}"
            )
        run_t, run_b, run_c, run_bc = medians[RUN]
        floor_t, floor_b, floor_c, floor_bc = medians[FLOOR]
        # medians, not pairs: the run and the floor were timed in different rounds
        print(
            f"{'run above the numba floor':32s} {run_t - floor_t:9.3f} {'':10s} "
            f"{(run_t - floor_t) / ((run_b + floor_b) / 2):7.2f} {run_c - floor_c:7.3f} {'':8s} "
            f"{(run_c - floor_c) / max((run_bc + floor_bc) / 2, 1e-6):9.2f}"
        )
        if args.cold:
            cmd = table[RUN][0]
            times, ratios, cpus, cpu_ratios = [], [], [], []
            for _ in range(max(1, args.repeat // 3)):
                cache = tempfile.mkdtemp(prefix="trainsim-numba-")
                try:
                    t, c = timed(cmd, env={**env, "NUMBA_CACHE_DIR": cache})
                    b, bc = timed(BASELINE, env)
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
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"machine at the end: {_timing.machine()}")


if __name__ == "__main__":
    main()
