"""The benchmark scripts of issue 14 run with their smallest settings (``--quick``), so they cannot rot.

They are timed nowhere here: a smoke test only checks that each script runs through and prints its
tables. Each script is loaded from its file and its ``main`` called in this process (no second numba
start-up)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def load(name: str):
    sys.path.insert(0, str(BENCHMARKS))
    try:
        spec = importlib.util.spec_from_file_location(f"_bench_{name}", BENCHMARKS / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses look their module up
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCHMARKS))
    return module


def test_timing_helpers():
    timing = load("_timing")
    p = timing.paired(lambda: sum(range(100)), repeat=3)
    assert len(p.case) == len(p.base) == 3 and p.ratio > 0 and p.ratio_cpu >= 0
    assert timing.loglog_slope([1, 2, 4], [3, 6, 12]) == pytest.approx(1.0)
    assert "cores" in timing.machine()


@pytest.mark.filterwarnings("ignore")
def test_bench_fastest_quick(capsys):
    load("bench_fastest").main(["--quick", "--case", "metro_b"])
    out = capsys.readouterr().out
    for heading in ("1. wall time", "2. where one run goes", "3. convergence", "4. converged run"):
        assert heading in out
    assert "metro_b" in out and "compile_route" in out


@pytest.mark.filterwarnings("ignore")
def test_bench_cost_model_quick(capsys):
    load("bench_cost_model").main(["--quick"])
    out = capsys.readouterr().out
    for dimension in ("km [km]", "stops [stop]", "effort points [point]", "trace points [point]", "vehicles"):
        assert dimension in out
    assert out.count("growth:") == 5
