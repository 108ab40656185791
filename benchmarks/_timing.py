"""Paired timing against a baseline for the benchmarks on a shared, loaded machine.

A figure on a machine shared with other work is only meaningful as a ratio to a baseline timed in the
same run, sample by sample: ``paired`` alternates the calls (A B A B ..., the order of each pair swapped
every round so that neither side always runs first) and ``Paired`` quotes medians, the best time and
the median of the per-pair ratios.

The baseline ``rk4_line`` is a fixed amount of compiled floating-point work that any compiled train
integrator has to do at least: a plain fixed-step RK4 of the single-point equation of motion in the
distance domain (kinetic energy per unit mass E = v^2 / 2 over position) for a freight train under
maximum traction min(F0, P / v) against a Davis resistance and a gradient, 10 m steps over 100 km
(10,000 steps, 40,000 force evaluations), no events, no output arrays. It is compiled by numba like
trainsim's kernels, so machine load, CPU frequency and the interpreter slow both sides alike, and
"ratio 2.0" reads "as long as two plain RK4 integrations of a 100 km line".
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

#: The baseline's work: RK4 steps of BASELINE_STEP_M over BASELINE_LENGTH_M.
BASELINE_LENGTH_M = 100_000.0
BASELINE_STEP_M = 10.0


@njit(cache=False, inline="always")
def _slope(e: float, grade: float) -> float:
    # dE/ds [m/s^2] of a 2,000 t freight train: min(400 kN, 4 MW / v) - Davis - gradient
    v = math.sqrt(max(2.0 * e, 0.0))
    f = min(4.0e5, 4.0e6 / v) if v > 0 else 4.0e5
    return (f - (2.0e4 + 300.0 * v + 8.0 * v * v) - grade) / (1.06 * 2.0e6)


@njit(cache=False)
def _rk4_line(length_m: float, h: float) -> float:
    n = int(length_m / h)
    e = 0.0
    out = 0.0
    for k in range(n):
        grade = 9.81 * 2.0e6 * 0.002 * (1.0 if (k // 500) % 2 == 0 else -1.0)
        k1 = _slope(e, grade)
        k2 = _slope(e + 0.5 * h * k1, grade)
        k3 = _slope(e + 0.5 * h * k2, grade)
        k4 = _slope(e + h * k3, grade)
        e += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out += e
    return out


def rk4_line() -> float:
    """The baseline: one fixed-step RK4 integration of a 100 km line (see the module docstring)."""
    return _rk4_line(BASELINE_LENGTH_M, BASELINE_STEP_M)


@dataclass
class Paired:
    """Samples of a case and its baseline taken pair by pair [s per call], wall and CPU time.

    On a machine loaded beyond its cores, a call of tens of milliseconds is preempted and its wall
    time inflated several times, while a sub-millisecond baseline mostly fits in one time slice: the
    wall ratio is then biased upwards. The CPU-time ratio is not (it still carries the slowdown of a
    shared cache and of hyper-threads), so both are quoted.
    """

    case: list[float]
    base: list[float]
    case_cpu: list[float]
    base_cpu: list[float]

    @property
    def median(self) -> float:
        return statistics.median(self.case)

    @property
    def best(self) -> float:
        return min(self.case)

    @property
    def cpu(self) -> float:
        return statistics.median(self.case_cpu)

    @property
    def base_median(self) -> float:
        return statistics.median(self.base)

    @property
    def ratio(self) -> float:
        """Median of the per-pair wall-time ratios case / baseline."""
        return statistics.median(a / b for a, b in zip(self.case, self.base, strict=True))

    @property
    def ratio_cpu(self) -> float:
        """Median of the per-pair CPU-time ratios case / baseline."""
        return statistics.median(a / max(b, 1e-9) for a, b in zip(self.case_cpu, self.base_cpu, strict=True))

    @property
    def ratio_best(self) -> float:
        """Best case over best baseline, wall time (the figure of a quiet machine)."""
        return min(self.case) / min(self.base)


def _time(fn: Callable[[], object], inner: int) -> tuple[float, float]:
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(inner):
        fn()
    return (time.perf_counter() - t0) / inner, (time.process_time() - c0) / inner


def paired(
    case: Callable[[], object],
    repeat: int,
    base: Callable[[], object] = rk4_line,
    inner: int = 1,
    warmup: int = 1,
) -> Paired:
    """Time ``case`` and ``base`` alternately ``repeat`` times each (``inner`` calls per sample); the
    baseline is called as many times as it takes to last about as long as the case (at most 64)."""
    for _ in range(warmup):
        case()
        base()
    t_case = _time(case, inner)[0]
    t_base = _time(base, 1)[0]
    base_inner = int(min(64, max(1, round(t_case * inner / max(t_base, 1e-9)))))
    out = Paired([], [], [], [])
    for k in range(repeat):
        order = ((base, base_inner, False), (case, inner, True))
        for fn, n, is_case in order if k % 2 else order[::-1]:
            wall, cpu = _time(fn, n)
            if is_case:
                out.case.append(wall)
                out.case_cpu.append(cpu)
            else:
                out.base.append(wall)
                out.base_cpu.append(cpu)
    return out


def loglog_slope(x: list[float], y: list[float]) -> float:
    """Least-squares slope of log y over log x: the growth exponent (1 = linear)."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.asarray(y, float)), 1)[0])


def machine() -> str:
    """One line: CPU, cores usable, load average, Python and numba versions."""
    import numba

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = "/".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (
        f"{cpu}, {cores} cores, load average {load} (1/5/15 min); Python {platform.python_version()}, "
        f"numba {numba.__version__}, numpy {np.__version__}"
    )
