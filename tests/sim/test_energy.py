"""Energy accounting against hand computation: traction, regenerative blending, line energy,
auxiliaries, line current; line-resistance components in the trace."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.constants import KMH, KWH
from trainsim.constants import STANDARD_GRAVITY as G
from trainsim.model import Braking, Curve, EffortCurve, Electrical, LineResistanceSettings, Tunnel
from trainsim.sim.codes import BRAKE

F, B, M_KG, RHO = 200e3, 300e3, 300e3, 1.1
V = 100 * KMH
ETA_T, ETA_R, AUX_W = 0.9, 0.8, 50e3


def electric_train(regen_fraction: float | None):
    train = make_train(traction_n=F, braking_n=B, mass_kg=M_KG, rho=RHO)
    regen = EffortCurve.constant(F).scaled(regen_fraction) if regen_fraction else None
    return dataclasses.replace(
        train,
        braking=Braking(service_force=EffortCurve.constant(B), regenerative=regen),
        electrical=Electrical(
            line_voltage_v=3000.0,
            traction_efficiency=ETA_T,
            regenerative_efficiency=ETA_R,
            power_factor=1.0,
            auxiliary_power_w=AUX_W,
        ),
    )


def test_energy_figures_of_a_constant_force_run_with_regenerative_braking():
    result = trainsim.run_fastest(electric_train(0.8), make_route(length_m=8_000.0, limit_kmh=100.0))
    a, b = F / (M_KG * RHO), B / (M_KG * RHO)
    d_acc, d_brk = V**2 / (2 * a), V**2 / (2 * b)
    traction_work = F * d_acc
    regen_work = 0.8 * F * d_brk  # the electric brake takes 160 kN of the 300 kN demand
    e = result.energy_kwh
    assert e.traction * KWH == pytest.approx(traction_work, rel=1e-9)
    assert e.braking * KWH == pytest.approx(B * d_brk, rel=1e-9)
    assert e.regenerated * KWH == pytest.approx(regen_work * ETA_R, rel=1e-9)
    assert e.auxiliary * KWH == pytest.approx(AUX_W * result.total_time_s, rel=1e-9)
    assert e.net * KWH == pytest.approx(
        traction_work / ETA_T + AUX_W * result.total_time_s - regen_work * ETA_R
    )
    assert e.paper * KWH == pytest.approx(traction_work * ETA_T, rel=1e-9)
    tr = result.trace
    braking = tr.regime == BRAKE
    assert np.allclose(tr.regenerative_braking_force_n[braking], 0.8 * F)
    assert np.allclose(tr.friction_braking_force_n[braking], B - 0.8 * F)
    # peak current: full traction at the top speed, I = (F v / eta + P_aux) / U
    assert result.peak_current_a == pytest.approx((F * V / ETA_T + AUX_W) / 3000.0, rel=1e-9)
    assert result.peak_paper_current_a == pytest.approx(F * V * ETA_T / 3000.0, rel=1e-9)


def test_without_regeneration_nothing_returns_to_the_line():
    result = trainsim.run_fastest(electric_train(None), make_route(length_m=8_000.0))
    assert result.energy_kwh.regenerated == 0.0
    assert np.all(result.trace.regenerative_braking_force_n == 0.0)


def test_cumulative_energy_in_the_trace_ends_at_the_totals():
    result = trainsim.run_fastest(electric_train(0.8), make_route(length_m=8_000.0))
    tr = result.trace
    assert tr.traction_work_j[-1] == pytest.approx(result.energy_kwh.traction * KWH)
    assert tr.electrical_energy_j[-1] == pytest.approx(result.energy_kwh.net * KWH)
    assert sum(s.energy_kwh.net for s in result.sections) == pytest.approx(result.energy_kwh.net)


@pytest.mark.parametrize(
    ("formula", "per_mille"),
    [("roeckl", 650 / (500 - 55)), ("tbt1407", 600 / 500), ("french800", 800 / 500)],
)
def test_curve_resistance_in_the_trace(formula, per_mille):
    train = make_train(mass_kg=M_KG)
    route = dataclasses.replace(
        make_route(length_m=5_000.0),
        curves=(Curve(2000.0, 2600.0, 500.0),),
        line_resistance=LineResistanceSettings(curve_formula=formula, tunnel_formula="none"),
    )
    tr = trainsim.run_fastest(train, route).trace
    inside = (tr.position_m > 2000.0) & (tr.position_m < 2600.0)
    assert np.allclose(tr.curve_resistance_n[inside], per_mille / 1000 * M_KG * G)
    assert np.all(tr.curve_resistance_n[tr.position_m < 1999.0] == 0.0)


def test_tunnel_on_a_limiting_gradient_grows_with_speed_squared():
    train = make_train(mass_kg=M_KG)
    route = dataclasses.replace(
        make_route(length_m=6_000.0),
        tunnels=(Tunnel(1000.0, 3000.0, limiting_gradient=True),),
        line_resistance=LineResistanceSettings(curve_formula="none", tunnel_formula="wang"),
    )
    tr = trainsim.run_fastest(train, route).trace
    inside = (tr.position_m > 1000.0) & (tr.position_m < 3000.0)
    expected = 1.296e-9 * 2000.0 * M_KG * G * tr.speed_mps[inside] ** 2  # source 000, l_t = 2000 m
    assert np.allclose(tr.tunnel_resistance_n[inside], expected)
