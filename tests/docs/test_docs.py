"""The documentation site builds without a warning, and every code block in it runs.

Blocks fenced as ``python`` run with Python, blocks fenced as ``bash`` or ``sh`` with bash (-e, -o
pipefail), in the order of their page, in one scratch folder per page that sees the repository's
``examples``, ``tests`` and ``docs`` folders, so that they write nothing into the checkout. Commands shown but not meant to run
here (a server, a cluster address, an install, a file the reader must bring) are fenced as ``console``
or ``text``, and Python shown but not run (it needs such a file, or takes minutes and is run by the
test suite elsewhere) as ``py``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
RUNNABLE = {"python": "python", "bash": "bash", "sh": "bash"}
FENCE = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```\s*$", re.MULTILINE | re.DOTALL)


def _site_pages() -> list[Path]:
    """The markdown pages of the site's navigation (mkdocs.yml)."""
    text = (ROOT / "mkdocs.yml").read_text()
    nav = text[text.index("\nnav:") :]
    return [DOCS / name for name in re.findall(r":\s*([\w./-]+\.md)\s*$", nav, flags=re.MULTILINE)]


def _blocks() -> list[tuple[str, int, str, str]]:
    found = []
    for page in _site_pages():
        for k, match in enumerate(FENCE.finditer(page.read_text())):
            language = match.group(1).lower()
            if language in RUNNABLE:
                found.append((page.relative_to(DOCS).as_posix(), k, RUNNABLE[language], match.group(2)))
    return found


BLOCKS = _blocks()


def test_every_page_of_the_nav_exists():
    missing = [p for p in _site_pages() if not p.is_file()]
    assert missing == []
    assert len(_site_pages()) >= 15


@pytest.mark.slow
def test_site_builds_with_warnings_as_errors(tmp_path):
    pytest.importorskip("mkdocs")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (tmp_path / "site" / "index.html").is_file()
    api = (tmp_path / "site" / "reference" / "api" / "index.html").read_text()
    assert "load_scenario" in api and "RunResult" in api  # the API reference comes from the docstrings


_SCRATCH: dict[str, Path] = {}


@pytest.fixture
def scratch(page: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    # the blocks of one page run in order in one folder: a later block may read what an earlier wrote
    if page not in _SCRATCH:
        folder = tmp_path_factory.mktemp("docs")
        for name in ("examples", "tests", "docs", "benchmarks", "scripts"):
            (folder / name).symlink_to(ROOT / name, target_is_directory=True)
        _SCRATCH[page] = folder
    return _SCRATCH[page]


@pytest.mark.slow
@pytest.mark.parametrize(("page", "index", "runner", "code"), BLOCKS, ids=[f"{b[0]}#{b[1]}" for b in BLOCKS])
def test_code_block_runs(page, index, runner, code, scratch):
    if runner == "python":
        command = [sys.executable, "-c", code]
    else:
        command = ["bash", "-e", "-o", "pipefail", "-c", code]
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    proc = subprocess.run(command, cwd=scratch, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, (
        f"{page} block {index}:\n{code}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    )
