"""Start-up (issue 14, stop 26): options coerced without pydantic, the same values and messages.

typer 0.2x coerces every option through a pydantic TypeAdapter, which cost a warm `trainsim run` of
the metro pydantic's schema machinery and ``importlib.metadata`` (its plugin loader); with the quick
reader of the trainsim YAML specs no validator is built at all. Guarded without timing: what a run
imports, and, value by value, that the plain coercion gives what typer's own gives (or leaves the
value to it, so that a bad option gets typer's message).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
METRO = REPO / "examples" / "metro_b" / "scenario.yaml"

PROBE = """
import io, json, runpy, sys, contextlib
sys.argv = ["trainsim", *sys.argv[1:]]
out = io.StringIO()
try:
    with contextlib.redirect_stdout(out):
        runpy.run_module("trainsim", run_name="__main__", alter_sys=True)
except SystemExit as exc:
    code = exc.code
from pydantic import BaseModel
def subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from subclasses(sub)
built = sorted(c.__name__ for c in subclasses(BaseModel) if c.__pydantic_complete__)
print(json.dumps({"code": code, "modules": sorted(sys.modules), "built": built, "out": out.getvalue()}))
"""


def probe(*args: str) -> dict:
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, *args], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    if not proc.stdout.strip():
        pytest.fail(f"the probe printed nothing; stderr:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def metro_run() -> dict:
    return probe("run", str(METRO), "--step", "5")


def test_a_warm_run_of_the_metro_builds_no_pydantic_validator(metro_run: dict) -> None:
    assert metro_run["code"] == 0
    assert "total time" in metro_run["out"]  # the run happened and printed its summary
    assert metro_run["built"] == []


def test_a_warm_run_of_the_metro_loads_neither_typers_adapters_nor_package_metadata(metro_run: dict) -> None:
    modules = set(metro_run["modules"])
    assert "trainsim.sim._kernel_c" in modules
    assert not {"typer._adapters", "importlib.metadata", "pydantic.plugin._loader"} & modules


def test_a_run_of_a_trainsim_scenario_does_not_import_the_railtoolkit_reader(metro_run: dict) -> None:
    assert "trainsim.io.loader" in metro_run["modules"]
    assert "trainsim.io.railtoolkit" not in metro_run["modules"]


def test_a_run_with_a_problem_still_reports_it(tmp_path: Path) -> None:
    """The fallback works: the metro with a bad step is read by pydantic, which names the field."""
    for name in ("train.yaml", "route.yaml"):
        (tmp_path / name).write_text((METRO.parent / name).read_text())
    (tmp_path / "s.yaml").write_text(METRO.read_text().replace("max_step_m: 5", "max_step_m: -5"))
    proc = subprocess.run(
        [sys.executable, "-m", "trainsim", "run", str(tmp_path / "s.yaml")],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        f"error: {tmp_path / 's.yaml'}, line 9, field 'settings.max_step_m': out of range (got -5); "
        "allowed: >= 0.01."
    )


# ---------------------------------------------------------------------- value by value
VALUES = {
    "step": ["5", "-1", "1e3", ".5", "5.", "+2.5E-1", "0", "1_000", "inf", "nan", " 5", "abc", "", "0x10"],
    "mass_model": ["mass_point", "homogeneous_strip", "MASS_POINT", "foo", ""],
    "out": ["results", "a/b/c", "-", ".", "", str(METRO)],
    "scenario": [str(METRO), "missing.yaml", str(METRO.parent)],
}


@pytest.fixture(scope="module")
def run_command() -> object:
    from trainsim.cli.app import load_command

    return load_command("run")


def _typers_own(param: object, value: str, ctx: object) -> object:
    from typer._coercion import build_runtime_param

    return build_runtime_param(param.type_descriptor).coerce(value, param=param, ctx=ctx)  # type: ignore[attr-defined]


def _outcome(call: object) -> tuple[str, object]:
    try:
        value = call()  # type: ignore[operator]
        return "value", (type(value).__name__, repr(value))  # repr: nan equals nan
    except Exception as exc:  # typer's BadParameter: compared by type and message
        return type(exc).__name__, str(exc)


@pytest.mark.parametrize("name", sorted(VALUES))
def test_plain_coercion_gives_what_typer_gives(run_command: object, name: str) -> None:
    pytest.importorskip("typer._coercion")
    import typer

    from trainsim.cli.context import PlainCoercion, use_plain_coercion

    ctx = typer.Context(run_command)  # type: ignore[arg-type]
    param = next(p for p in run_command.params if p.name == name)  # type: ignore[attr-defined]
    use_plain_coercion([param])
    assert isinstance(param._runtime_param, PlainCoercion)
    for value in VALUES[name]:
        ours = _outcome(lambda value=value: param._runtime_param.coerce(value, param=param, ctx=ctx))
        theirs = _outcome(lambda value=value: _typers_own(param, value, ctx))
        assert ours == theirs, value


def test_plain_coercion_takes_the_plain_values_itself(run_command: object) -> None:
    """The plain cases do not reach typer's pydantic adapters (else nothing would be gained)."""
    pytest.importorskip("typer._coercion")
    import typer

    from trainsim.cli.context import _TYPER, use_plain_coercion

    ctx = typer.Context(run_command)  # type: ignore[arg-type]
    params = {p.name: p for p in run_command.params}  # type: ignore[attr-defined]
    use_plain_coercion(params.values())
    plain = {
        "step": ["5", "1e3", "-1"],
        "mass_model": ["mass_point"],
        "out": ["results"],
        "scenario": [str(METRO)],
    }
    for name, values in plain.items():
        for value in values:
            assert params[name]._runtime_param._plain(value, params[name], ctx) is not _TYPER, (name, value)
    assert params["step"]._runtime_param._plain("1_000", params["step"], ctx) is _TYPER
