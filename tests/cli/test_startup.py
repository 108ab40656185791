"""Start-up budget (issue 14): what ``import trainsim``, ``trainsim --help`` and ``trainsim run`` import.

Each command runs in a fresh interpreter (a module once imported by an earlier test would hide the
import here) through the same entry as ``python -m trainsim``, and reports the modules it
imported. A heavy library imported where it is not needed fails the test with the chain of modules
that imported it, read from ``python -X importtime``.

Why it matters, CPU time of whole processes on the shared 2-core development machine (load 5-7),
beyond `python -c "import numpy"` (0.27 s there): matplotlib.figure +0.6 s, scipy.optimize +0.5 s,
pandas +0.4 s, scipy.linalg +0.3 s; numba with its first cached function 7x the numpy process
(benchmarks/bench_startup.py, "numba floor").
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
METRO = REPO / "examples" / "metro_b" / "scenario.yaml"

#: libraries that neither ``import trainsim`` nor ``trainsim --help`` needs
HEAVY = (
    "numba",
    "llvmlite",
    "scipy",
    "pandas",
    "pydantic",
    "matplotlib",
    "numpy",
    "jsonschema",
    "yaml",
    "casadi",
)

# Runs ``python -m trainsim ARGS`` (or only ``import trainsim`` without ARGS) and prints the sorted
# modules in sys.modules as JSON on the last line of stderr, whatever the exit.
PROBE = """
import json, runpy, sys
args = sys.argv[1:]
try:
    if args:
        sys.argv = ["trainsim", *args]
        runpy.run_module("trainsim", run_name="__main__", alter_sys=True)
    else:
        import trainsim
except SystemExit as exc:
    code = exc.code
else:
    code = 0
sys.stderr.write("\\n" + json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def imported(*args: str) -> tuple[object, set[str]]:
    """(exit code, modules imported, and their top-level packages) of ``python -m trainsim *args`` in a
    fresh process."""
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, *args], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    last = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ""
    try:
        report = json.loads(last)
    except json.JSONDecodeError:
        pytest.fail(f"the probe printed no module list; stderr:\n{proc.stderr[-3000:]}")
    modules = set(report["modules"])
    return report["code"], modules | {m.split(".")[0] for m in modules}


def importers(module: str, *args: str) -> str:
    """The import chain that first loads ``module`` (from ``python -X importtime``), for a failure message."""
    code = "import trainsim" if not args else None
    cmd = [sys.executable, "-X", "importtime"] + (["-c", code] if code else ["-m", "trainsim", *args])
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, timeout=300)
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("import time:")]
    for k, line in enumerate(lines):
        name = line.rsplit("|", 1)[-1]
        if name.strip() == module:
            depth = len(name) - len(name.lstrip())
            chain = [name.strip()]
            for later in lines[k + 1 :]:  # parents are listed after their children, less indented
                later_name = later.rsplit("|", 1)[-1]
                later_depth = len(later_name) - len(later_name.lstrip())
                if later_depth < depth:
                    chain.append(later_name.strip())
                    depth = later_depth
            return " <- ".join(chain)
    return "(not found in -X importtime)"


def assert_not_imported(modules: set[str], forbidden: tuple[str, ...], *args: str) -> None:
    found = sorted(set(forbidden) & modules)
    if found:
        chains = "\n".join(importers(m, *args) for m in found)
        pytest.fail(f"{' '.join(args) or 'import trainsim'} imported {found}:\n{chains}")


def test_import_trainsim_loads_nothing_heavy():
    code, modules = imported()
    assert code == 0
    assert "trainsim" in modules  # the probe itself works
    assert_not_imported(modules, HEAVY)


def test_help_loads_nothing_heavy():
    code, modules = imported("--help")
    assert code == 0
    assert "typer" in modules
    assert_not_imported(modules, HEAVY, "--help")


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
def test_probe_sees_a_heavy_import():
    # the check can fail: a command that needs numpy is seen importing it
    _, modules = imported("check", str(METRO))
    assert {"numpy", "pydantic"} <= modules


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
def test_run_without_out_writes_no_plot_and_loads_no_plotting_or_tables():
    code, modules = imported("run", str(METRO))
    assert code == 0
    assert "trainsim.sim._kernel_c" in modules  # the run itself happened
    assert_not_imported(modules, ("matplotlib", "pandas", "casadi"), "run", str(METRO))


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
def test_run_with_out_and_no_plots_loads_no_matplotlib(tmp_path):
    code, modules = imported("run", str(METRO), "--out", str(tmp_path), "--no-plots")
    assert code == 0
    assert (tmp_path / "trace.csv").exists()
    assert not list(tmp_path.glob("*.png"))
    assert_not_imported(
        modules, ("matplotlib", "pandas"), "run", str(METRO), "--out", str(tmp_path), "--no-plots"
    )


#: what the fastest run no longer needs since its kernels are compiled at install (issue 14): numba
#: alone costs 7x a numpy process per start, scipy.linalg came with it
NUMBA = ("numba", "llvmlite", "scipy")


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
@pytest.mark.parametrize("plots", ["--no-plots", "--plots"])
def test_a_fastest_run_loads_no_numba(tmp_path, plots):
    args = ("run", str(METRO), "--out", str(tmp_path), plots)
    code, modules = imported(*args)
    assert code == 0
    assert (tmp_path / "summary.json").exists() and "trainsim.sim._kernel_c" in modules
    assert_not_imported(modules, NUMBA, *args)


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
def test_run_of_a_trainsim_scenario_loads_no_jsonschema():
    code, modules = imported("run", str(METRO))
    assert code == 0
    assert_not_imported(modules, ("jsonschema",), "run", str(METRO))


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
def test_run_writing_plots_loads_no_scipy_optimize(tmp_path):
    # the plots module names the acceleration analysis (which needs scipy.optimize) in annotations only
    code, modules = imported("run", str(METRO), "--out", str(tmp_path))
    assert code == 0
    assert (tmp_path / "speed_distance.png").exists()
    assert "matplotlib" in modules
    assert_not_imported(modules, ("scipy.optimize", "pandas"), "run", str(METRO), "--out", str(tmp_path))


HEAVY_HAUL = REPO / "examples" / "heavy_haul" / "scenario_head.yaml"


@pytest.mark.skipif(not HEAVY_HAUL.exists(), reason="examples/heavy_haul not present")
def test_multipoint_run_writing_tables_loads_no_pandas(tmp_path):
    code, modules = imported("run", str(HEAVY_HAUL), "--out", str(tmp_path), "--no-plots")
    assert code in (0, 3)
    assert (tmp_path / "coupler_forces.csv").exists() and (tmp_path / "vehicle_speeds.csv").exists()
    assert_not_imported(
        modules, ("pandas", "matplotlib"), "run", str(HEAVY_HAUL), "--out", str(tmp_path), "--no-plots"
    )


@pytest.mark.parametrize("number_format", ["%.3f", "%.4f"])
def test_multipoint_table_bytes_equal_pandas_to_csv(tmp_path, number_format):
    # the reference: what pandas wrote for these tables before (float_format applies to the index too)
    pd = pytest.importorskip("pandas")
    import numpy as np

    from trainsim.cli.multipoint import _write_table

    time_s = np.array([0.0, 1e-7, np.nan, 1.23456789e6, -0.0, np.inf, 0.5])
    row = [np.nan, -0.0, 1e25, 1e-9, -np.inf, 12345.6785, 0.00005]
    values = np.array([row[k:] + row[:k] for k in range(len(time_s))])
    columns = [f"c{k}_kn" for k in range(values.shape[1])]
    ours = _write_table(tmp_path / "ours.csv", time_s, values, columns, number_format).read_bytes()
    frame = pd.DataFrame(values, index=pd.Index(time_s, name="time_s"), columns=columns)
    frame.to_csv(tmp_path / "pandas.csv", float_format=number_format)
    assert ours == (tmp_path / "pandas.csv").read_bytes()


# ---------------------------------------------------------------- no numba anywhere
# Every kernel is compiled at install (Cython, setup.py): nothing is compiled at run time, so no
# command pays numba's 0.5 s CPU per process or its minutes of compilation after an install.


def test_no_module_of_trainsim_imports_numba():
    import ast

    found = []
    for path in sorted((REPO / "src" / "trainsim").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            found += [f"{path.relative_to(REPO)}:{node.lineno}" for n in names if n.split(".")[0] == "numba"]
    assert found == []


def test_numba_is_not_a_dependency_of_the_core_install():
    import tomllib

    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert not [d for d in project["dependencies"] if d.lower().startswith(("numba", "llvmlite"))]


@pytest.mark.skipif(not METRO.exists(), reason="examples/metro_b not present")
def test_an_energy_efficient_run_loads_no_numba():
    args = ("optimize", str(METRO), "--supplement", "10%")
    code, modules = imported(*args)
    assert code == 0
    assert "trainsim.optimize._pmp_c" in modules
    assert_not_imported(modules, ("numba", "llvmlite"), *args)
