"""Fixtures of the io tests: where the examples and the TrainRuns.jl test data are."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def examples_dir() -> Path:
    """The repository's examples/ folder."""
    return REPO / "examples"


@pytest.fixture(scope="session")
def trainruns_dir() -> Path:
    """TrainRuns.jl 1.0.4 test data: the repository's copy in tests/data/trainruns, else
    shared/data/trainruns next to the repository (or under $TRAINSIM_SHARED)."""
    shared = Path(os.environ.get("TRAINSIM_SHARED", REPO.parent / "shared"))
    for path in (REPO / "tests" / "data" / "trainruns", shared / "data" / "trainruns"):
        if (path / "trains" / "freight.yaml").is_file():
            return path
    pytest.skip("TrainRuns.jl test data not found (tests/data/trainruns or shared/data/trainruns)")
