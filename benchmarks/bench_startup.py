"""Start-up of trainsim as a user meets it, whole processes, against `python -c "import numpy"`.

Run: python benchmarks/bench_startup.py [--repeat N] [--no-cold] [--as-is] [--only TEXT ...]

Every start-up figure of issue 14's table, each as the median wall time of N whole processes (after one
warm-up) and the median of its ratios to the baseline `python -c "import numpy"` timed in the same run,
pair by pair (the order of each pair swapped every round; the machine is shared and noisy: quote the
ratios); then the same in CPU time of the child process (user + system, from getrusage), the figure
that a loaded machine inflates least. Targets (issue 14): `trainsim --help` <= 0.15 s, `import
trainsim` <= 0.25 s, a warm `trainsim run` of the metro example <= 0.6 s or <= 3x the baseline, the
first `trainsim run` after a fresh install <= 5 s.

Rows:

* ``trainsim --help``, ``import trainsim``;
* ``trainsim run`` of the metro, warm: as printed (no files), ``--out DIR --no-plots`` (trace.csv and
  summary.json) and ``--out DIR`` (the same and five PNG plots);
* the first ``trainsim run`` after an install: an empty ``NUMBA_CACHE_DIR`` and a fresh, empty
  bytecode prefix for every sample, so that nothing any earlier process cached is reused (every module,
  numpy's and pydantic's too, is compiled to bytecode again: harsher than an install, which writes
  bytecode); its ratio is to the warm baseline of the same round; and the same with only numba's
  cache empty (bytecode as after ``pip install``, which writes it): what a run compiles at run time;
* two reference rows: ``import numba``, and the *numba floor*, a process that imports numba and calls
  one trivial ``njit(cache=True)`` function loaded from its cache: the least any process running a numba
  kernel pays (loading the first cached function makes numba load its whole lowering library, and
  through numba.np.arraymath's BLAS check scipy.linalg). The commands that still run numba kernels
  (optimize, operate, power, multi-point runs) pay at least this.

The last line says whether a warm ``trainsim run`` of the metro loaded numba at all (it should not:
its kernels are compiled at install).

Bytecode: a warm machine has compiled bytecode (``pip install`` writes it for every module). With
PYTHONDONTWRITEBYTECODE set (as in some containers) an editable install recompiles every trainsim module
from source at each start while numpy's bytecode was compiled at its install, which is unfair to
trainsim. The warm child processes therefore run with bytecode written to and read from a temporary
PYTHONPYCACHEPREFIX (the work tree is left untouched), the baseline alike; --as-is keeps the caller's
environment instead (the first-run row keeps its fresh prefix).
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

#: prints whether a warm `trainsim run` of the metro imported numba (the last line of stdout)
NUMBA_PROBE = """
import runpy, sys
sys.argv = ["trainsim", "run", sys.argv[1]]
try:
    runpy.run_module("trainsim", run_name="__main__", alter_sys=True)
except SystemExit:
    pass
print("numba" in sys.modules)
"""

RUN = "trainsim run metro (warm)"
FIRST = "first trainsim run (install)"
EMPTY_NUMBA = "run, empty numba cache only"


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
    """The environment of every warm process (see the module docstring on bytecode)."""
    env = dict(os.environ)
    if not as_is:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    return env


def cases(work: Path) -> dict[str, tuple[list[str], float | None]]:
    """name -> (command, target [s] or None) of the warm rows."""
    (work / "floor").mkdir()
    (work / "floor" / "floor_mod.py").write_text(FLOOR_MODULE)
    floor = f"import sys; sys.path.insert(0, {str(work / 'floor')!r}); import floor_mod; floor_mod.one(1.0)"
    trainsim = [sys.executable, "-m", "trainsim"]
    return {
        "trainsim --help": ([*trainsim, "--help"], 0.15),
        "import trainsim": ([sys.executable, "-c", "import trainsim"], 0.25),
        RUN: ([*trainsim, "run", str(METRO)], 0.6),
        "run --out --no-plots (warm)": (
            [*trainsim, "run", str(METRO), "--out", str(work / "out_csv"), "--no-plots"],
            None,
        ),
        "run --out, 5 plots (warm)": ([*trainsim, "run", str(METRO), "--out", str(work / "out_png")], None),
        "import numba (reference)": ([sys.executable, "-c", "import numba"], None),
        "numba floor (1 cached fn)": ([sys.executable, "-c", floor], None),
    }


def first_run_env(work: Path, k: int, warm: dict[str, str] | None = None) -> dict[str, str]:
    """A first run after an install: nothing cached by numba, no bytecode (a fresh prefix per sample);
    with ``warm``, that environment's bytecode and only numba's cache empty."""
    env = dict(os.environ) if warm is None else dict(warm)
    if warm is None:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(work / f"first-pycache-{k}")
    env["NUMBA_CACHE_DIR"] = str(work / f"first-numba-{k}{'' if warm is None else '-warm'}")
    return env


def paired(
    cmd: list[str], repeat: int, env: dict[str, str], case_env: dict[str, str] | None = None
) -> tuple[list[float], list[float], list[float], list[float]]:
    """(case wall, baseline wall, case CPU, baseline CPU) [s], ``repeat`` pairs, order swapped each round."""
    out: tuple[list[float], list[float], list[float], list[float]] = ([], [], [], [])
    for k in range(repeat):
        if k % 2:
            b, bc = timed(BASELINE, env)
            t, c = timed(cmd, case_env or env)
        else:
            t, c = timed(cmd, case_env or env)
            b, bc = timed(BASELINE, env)
        for series, value in zip(out, (t, b, c, bc), strict=True):
            series.append(value)
    return out


def ratio(a: list[float], b: list[float]) -> float:
    """Median of the per-pair ratios a / b."""
    return statistics.median(x / max(y, 1e-6) for x, y in zip(a, b, strict=True))


def row(
    name: str, t: list[float], b: list[float], c: list[float], bc: list[float], target: float | None
) -> str:
    return (
        f"{name:32s} {statistics.median(t):9.3f} {statistics.median(b):10.3f} {ratio(t, b):7.2f} "
        f"{statistics.median(c):7.3f} {statistics.median(bc):8.3f} {ratio(c, bc):9.2f} "
        f"{'' if target is None else f'{target:9.2f}'}"
    )


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--no-cold", action="store_true", help="skip the first run after an install")
    parser.add_argument("--cold", action="store_true", help="(the default; kept for older command lines)")
    parser.add_argument(
        "--as-is", action="store_true", help="keep the environment's bytecode settings (see the docstring)"
    )
    parser.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="TEXT",
        help="time only the warm rows whose name contains TEXT (repeatable; e.g. --only run --only help)",
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
        every = cases(work)
        table = {
            name: case for name, case in every.items() if not args.only or any(t in name for t in args.only)
        }
        if not table:
            parser.error(f"no row matches --only {args.only}; rows: {', '.join(every)}")
        for cmd, _ in table.values():  # warm-up: bytecode, numba's caches and the OS's file cache
            timed(cmd, env)
        timed(BASELINE, env)
        print(
            f"{'figure':32s} {'median s':>9s} {'baseline s':>10s} {'ratio':>7s} {'CPU s':>7s} {'base CPU':>8s} "
            f"{'CPU ratio':>9s} {'target s':>9s}"
        )
        for name, (cmd, target) in table.items():
            print(row(name, *paired(cmd, args.repeat, env), target), flush=True)
        if not args.no_cold and RUN in table:
            for name, warm in ((FIRST, None), (EMPTY_NUMBA, env)):
                series: tuple[list[float], list[float], list[float], list[float]] = ([], [], [], [])
                for k in range(args.repeat):
                    one = paired(table[RUN][0], 1, env, first_run_env(work, k, warm))
                    for s, v in zip(series, one, strict=True):
                        s += v
                print(row(name, *series, 5.0), flush=True)
        probe = subprocess.run(
            [sys.executable, "-c", NUMBA_PROBE, str(METRO)], capture_output=True, text=True, env=env, cwd=ROOT
        )
        loaded = probe.stdout.strip().splitlines()[-1] if probe.stdout.strip() else "?"
        print(f"a warm trainsim run of the metro loads numba: {'yes' if loaded == 'True' else 'no'}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"machine at the end: {_timing.machine()}")


if __name__ == "__main__":
    main()
