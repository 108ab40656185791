"""The multi-point model weighs every vehicle with the route's gravity (``Route.gravity_mps2``), not a
constant (issue 13): on a constant grade the gradient work is exactly sum_i m_i g r dx_i."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from mpcases import freight_train, level_route

from trainsim.model import GradientSection
from trainsim.multipoint import MultiPointSettings, build_multipoint_train, run_multipoint_fastest

GRADE_PERMILLE = 5.0


@pytest.mark.parametrize("g", [9.80665, 9.78, 9.83])
def test_gradient_work_is_the_weight_with_the_routes_gravity_times_the_rise(g):
    train = freight_train(5)
    route = dataclasses.replace(
        level_route(3_000.0), gradients=(GradientSection(0.0, 3_000.0, GRADE_PERMILLE),), gravity_mps2=g
    )
    result = run_multipoint_fastest(train, route, MultiPointSettings())
    assert result.status == "ok", result.warnings
    mp = build_multipoint_train(train, MultiPointSettings())
    rise_m = (result.position_m[-1] - result.position_m[0]) * GRADE_PERMILLE / 1000.0  # per vehicle
    analytic_j = float(np.sum(mp.mass_kg * g * rise_m))
    # with 9.81 in the kernel this was off by (9.81 - g) / g: 1.4e-4 at 9.80665, 3e-3 at 9.78
    assert result.energy.gradient_j == pytest.approx(analytic_j, rel=1e-9)
