"""A run without its trace (batch mode) gives the same summary figures as one with it."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

import trainsim
from trainsim.model.scenario import RunSettings
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


def _cases():
    yield trainsim.load_scenario(EXAMPLES / "metro_b" / "scenario.yaml")  # electric: peak current
    yield trainsim.load_scenario(EXAMPLES / "freight_000" / "scenario.yaml")


@pytest.mark.parametrize("scenario", list(_cases()), ids=["metro_b", "freight_000"])
def test_summary_without_trace_is_identical(scenario):
    full = run_fastest(scenario.train, scenario.route, scenario.settings)
    bare = run_fastest(scenario.train, scenario.route, scenario.settings, trace=False)
    assert bare.trace is None
    assert bare.summary() == full.summary()


def test_trainruns_summary_without_trace_is_identical():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml")
    route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="mass_point")
    full = run_fastest(train, route, RunSettings())
    bare = run_fastest(train, route, RunSettings(), trace=False)
    assert bare.summary() == full.summary()
    with pytest.raises(ValueError, match="without its trace"):
        bare.to_dataframe()
