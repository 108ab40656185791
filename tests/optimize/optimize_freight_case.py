"""The freight example's section 2 as the optimal strategy's solver sees it, at a given step: the case of
the departure-root and final-phase tests (issue 13)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import trainsim
from trainsim.optimize.api import _solvers
from trainsim.optimize.optimal import SectionSolver

ROOT = Path(__file__).resolve().parents[2]
#: A holding speed near the one that meets the freight example's 10 % line supplement [m/s].
FREIGHT_V = 21.79205


def freight_section_2(step_m: float) -> SectionSolver:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario = trainsim.load_scenario(ROOT / "examples" / "freight_000" / "scenario.yaml")
    settings = dataclasses.replace(scenario.settings, max_step_m=step_m)
    return _solvers(scenario.train, scenario.route, settings)[1]
