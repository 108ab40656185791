"""The house plan holds: layers import downwards only, no import circles, no repeated code, no
generated file in git, and ``import trainsim`` stays light."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_import_contracts_are_kept():
    # the contracts live in pyproject.toml ([tool.importlinter]); a new upward import breaks them
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports())",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "0 broken" in proc.stdout


GENERATED = re.compile(
    r"(__pycache__/|\.py[cod]$|\.nb[ic]$|\.egg-info/|(^|/)build/|(^|/)dist/|\.so$|\.ruff_cache/|"
    r"\.pytest_cache/|(^|/)site/|(^|/)out/|\.coverage$|^src/.*\.c$|^src/.*/_\w+\.html$)"
)


def test_no_generated_file_is_tracked():
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    listed = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True, timeout=60
    ).stdout.splitlines()
    tracked = [name for name in listed if GENERATED.search(name)]
    assert tracked == []


def test_import_trainsim_is_light():
    # numba, scipy, pandas, pydantic and matplotlib load only when a run, a reader or a plot needs them
    code = (
        "import sys, trainsim; "
        "print(','.join(m for m in ('numba', 'scipy', 'pandas', 'pydantic', 'matplotlib', 'yaml') "
        "if m in sys.modules))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == ""


def test_help_imports_no_command():
    code = (
        "import sys; from trainsim.cli.app import app\n"
        "try:\n    app(['--help'], prog_name='trainsim')\nexcept SystemExit:\n    pass\n"
        "print('LOADED:' + ','.join(m for m in sys.modules if m.startswith('trainsim.cli.') and "
        "m not in ('trainsim.cli.app', 'trainsim.cli.context')))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "LOADED:"


def test_the_generated_patterns_catch_compiled_extension_artefacts():
    # Cython writes the C source and the annotated HTML next to the .pyx; the build, the module
    for name in (
        "src/trainsim/sim/_forces.c",
        "src/trainsim/sim/_forces.html",
        "src/trainsim/sim/_forces.cpython-311-x86_64-linux-gnu.so",
        "build/temp.linux-x86_64-cpython-311/x.o",
    ):
        assert GENERATED.search(name), name
    assert not GENERATED.search("src/trainsim/sim/_forces.pyx")
    assert not GENERATED.search("src/trainsim/sim/_forces.pxd")
