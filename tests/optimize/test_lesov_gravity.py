"""Source 004's method weighs the train with the route's gravity (``Route.gravity_mps2``), not 9.81
(issue 13): its specific forces are per kN of m g, and its predicted traction phase on a grade
follows the analytic gradient force m g r."""

from __future__ import annotations

import pytest

from trainsim.constants import KMH
from trainsim.model import GradientSection, LineResistanceSettings, Route, SpeedLimit, Station
from trainsim.optimize import lesov


def _train():
    import trainsim

    return trainsim.load_scenario("examples/metro_b/scenario.yaml").train


def _route(g: float, grade_permille: float) -> Route:
    return Route(
        name="grade",
        start_m=0.0,
        end_m=3_000.0,
        stations=(Station("A", 0.0), Station("B", 3_000.0)),
        speed_limits=(SpeedLimit(0.0, 3_000.0, 80 * KMH),),
        gradients=(GradientSection(0.0, 3_000.0, grade_permille),),
        line_resistance=LineResistanceSettings(curve_formula="none", tunnel_formula="none"),
        gravity_mps2=g,
    )


def test_specific_forces_are_per_kn_of_the_weight_with_the_given_gravity():
    train = _train()
    for g in (9.78, 9.80665, 9.81):
        assert lesov.specific_force_n_per_kn(train.mass_kg * g, train, g) == pytest.approx(1000.0)
        # the paper's "2": 3.6 x 60 g / (1000 rho) km/h per minute per N/kN
        assert lesov.zeta_kmh_per_min(train, g) == pytest.approx(0.216 * g / train.rotating_mass_factor)


def _traction_minutes(train, g: float, grade_permille: float, v_ss_kmh: float) -> float:
    """The paper's traction phase computed independently: dt = dV / a(V_c + dV/2) with the physical
    acceleration a = (F - R - m g r) / (rho m), summed over its speed steps [min]."""
    v, minutes = 0.0, 0.0
    while v < v_ss_kmh - 1e-9:
        dv = min(lesov.speed_step_kmh(v, v_ss_kmh), v_ss_kmh - v)
        vm = (v + 0.5 * dv) * KMH
        force = float(train.traction(vm)) - float(train.running_resistance_n(vm))
        a = (force - train.mass_kg * g * grade_permille / 1000.0) / (
            train.rotating_mass_factor * train.mass_kg
        )
        minutes += dv * KMH / a / 60.0
        v += dv
    return minutes


@pytest.mark.parametrize("grade_permille", [0.0, 20.0])
def test_the_traction_phase_follows_the_gradient_force_of_the_routes_gravity(grade_permille):
    train = _train()
    times = {}
    for g in (9.78, 9.83):
        route = _route(g, grade_permille)
        sw = lesov.switching_for_speed(train, route, 0.0, 3_000.0, 60.0)
        _, t_tr, _, _, _, v_top = lesov._phases(
            train, route, 0.0, 3_000.0, 60.0, lesov.zeta_kmh_per_min(train, g)
        )
        assert v_top == pytest.approx(60.0)
        assert t_tr == pytest.approx(_traction_minutes(train, g, grade_permille, 60.0), rel=1e-12)
        times[g] = sw.traction_end_m
    if grade_permille == 0.0:
        # on the level g cancels out of the paper's formulas (f_u and zeta both carry it)
        assert times[9.78] == pytest.approx(times[9.83], rel=1e-12)
    else:
        # uphill, a larger g is a larger gradient force: a longer traction phase
        assert times[9.83] > times[9.78] * (1.0 + 1e-4)
