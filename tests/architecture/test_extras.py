"""The light core install: the README's first command runs without any extra, and each command that
needs an extra says which one to install. The extras' modules are hidden from a child process by an
import hook, which stands for an install without them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from trainsim.extras import MODULE_EXTRAS

ROOT = Path(__file__).resolve().parents[2]

HIDE = """
import sys
from importlib.abc import MetaPathFinder

HIDDEN = set(sys.argv[1].split(","))

class Hide(MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in HIDDEN:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, Hide())
sys.argv = ["trainsim", *sys.argv[2:]]
from trainsim.cli.app import main
main()
"""


def run_without(modules: set[str], *args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", HIDE, ",".join(sorted(modules)), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
    )


EVERY_EXTRA = set(MODULE_EXTRAS)


def test_readme_first_command_runs_on_the_core(tmp_path):
    proc = run_without(
        EVERY_EXTRA, "run", str(ROOT / "examples/metro_b/scenario.yaml"), "--out", str(tmp_path)
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert (tmp_path / "trace.csv").is_file() and (tmp_path / "summary.json").is_file()
    assert len(list(tmp_path.glob("*.png"))) >= 5


@pytest.mark.parametrize(
    ("extra", "args"),
    [
        ("interchange", ("check", "tests/interchange/data/testline_railml2.xml")),
        ("batch", ("batch", "examples/studies/metro_load_efficiency.yaml", "--dry-run")),
        ("web", ("serve", "--port", "1")),
        (
            "reference",
            ("optimize", "examples/metro_b/scenario.yaml", "--supplement", "10%", "--strategy", "reference"),
        ),
    ],
)
def test_a_command_names_the_extra_it_needs(extra, args):
    hidden = {module for module, name in MODULE_EXTRAS.items() if name == extra}
    proc = run_without(hidden, *args)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "pip install" in proc.stderr and f"trainsim[{extra}]" in proc.stderr
    assert "Traceback" not in proc.stderr
