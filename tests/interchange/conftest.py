"""Fixtures of the interchange tests: the hand-written test line and train (data/)."""

from __future__ import annotations

import pytest
from interchange_cases import DATA

import trainsim


@pytest.fixture(scope="session")
def yaml_train():
    return trainsim.load_train(DATA / "testline_train.yaml")


@pytest.fixture(scope="session")
def yaml_route():
    return trainsim.load_route(DATA / "testline_route.yaml")
