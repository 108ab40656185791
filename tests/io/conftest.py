"""Fixtures of the io tests: where the examples and the shared TrainRuns.jl data are."""

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
    """TrainRuns.jl 1.0.4 test data (shared/data/trainruns next to the repository, or
    $TRAINSIM_SHARED/data/trainruns)."""
    shared = Path(os.environ.get("TRAINSIM_SHARED", REPO.parent / "shared"))
    path = shared / "data" / "trainruns"
    if not path.is_dir():
        pytest.skip(f"shared TrainRuns.jl data not found at {path}")
    return path


@pytest.fixture(scope="session")
def railtoolkit_schema_dir() -> Path:
    """railtoolkit/schema docs and examples (shared/data/railtoolkit-schema)."""
    shared = Path(os.environ.get("TRAINSIM_SHARED", REPO.parent / "shared"))
    path = shared / "data" / "railtoolkit-schema"
    if not path.is_dir():
        pytest.skip(f"shared railtoolkit schema data not found at {path}")
    return path
