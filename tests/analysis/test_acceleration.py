"""Source 001's power-limited acceleration analysis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trainsim.analysis.acceleration import (
    AccelerationAnalysis,
    acceleration_analysis,
    available_power_w,
    balancing_speed_mps,
    speed_increment_mps,
)
from trainsim.errors import InputError
from trainsim.model import Braking, EffortCurve, Quadratic, ResistanceTerm, Train
from trainsim.physics import resistance as res

KMH = 1 / 3.6


def make_train(resistance: tuple[ResistanceTerm, ...], mass_kg: float, rho: float = 1.1) -> Train:
    return Train(
        name="test",
        mass_kg=mass_kg,
        rotating_mass_factor=rho,
        length_m=200.0,
        max_speed_mps=40.0,
        traction=EffortCurve.power_limited(1.0e6, 200e3),
        braking=Braking(deceleration_mps2=0.5),
        resistance=resistance,
    )


def cubic_train() -> Train:
    # R(v) = 100 v^2 [N]: eta P = R(v) v = 100 v^3 has a closed-form root
    return make_train((ResistanceTerm("cubic", Quadratic(0.0, 0.0, 100.0)),), mass_kg=100_000.0)


def bb60000_train() -> Train:
    # Source 001's convoy: a BB 60000 (72 t, 4 axles; mass assumed) and 12 four-axle carriages (40 t assumed)
    terms = (
        ResistanceTerm("BB 60000", res.rav_locomotive_bb60000(72_000.0, 4)),
        ResistanceTerm("12 carriages", res.rav_carriage_4axle(12 * 40_000.0)),
    )
    return make_train(terms, mass_kg=72_000.0 + 12 * 40_000.0)


def test_available_power() -> None:
    # 0.8 * 1 MW - 100 * 10^2 * 10 = 800000 - 100000 = 700000 W
    train = cubic_train()
    assert available_power_w(10.0, 1.0e6, 0.8, train.running_resistance_n) == pytest.approx(700_000.0)
    # at standstill the whole wheel power is available
    assert available_power_w(0.0, 1.0e6, 0.8, train.running_resistance_n) == pytest.approx(800_000.0)


def test_speed_increment_hand_computed() -> None:
    # v = 10 m/s, dt = 1 s, k M = 1.1 * 100 t = 110000 kg, P_avail = 700000 W:
    # sqrt(100 + 2 * 700000 / 110000) - 10 = sqrt(112.727273) - 10 = 0.617310 m/s
    train = cubic_train()
    dv = speed_increment_mps(10.0, 1.0, 1.0e6, 0.8, train.running_resistance_n, 100_000.0, 1.1)
    assert dv == pytest.approx(math.sqrt(100 + 2 * 700_000 / 110_000) - 10)
    assert dv == pytest.approx(0.617310, abs=1e-6)


def test_speed_increment_from_standstill() -> None:
    # v = 0: sqrt(2 * 800000 * 2 s / 110000) = sqrt(29.0909) = 5.393599 m/s
    train = cubic_train()
    dv = speed_increment_mps(0.0, 2.0, 1.0e6, 0.8, train.running_resistance_n, 100_000.0)
    assert dv == pytest.approx(5.393599, abs=1e-6)


def test_energy_balance_over_a_step() -> None:
    # 1/2 k M ((v + dv)^2 - v^2) must equal P_avail dt at each speed
    train = cubic_train()
    v = np.array([0.0, 5.0, 15.0, 19.0, 21.0])
    p = available_power_w(v, 1.0e6, 0.8, train.running_resistance_n)
    dv = speed_increment_mps(v, 0.5, 1.0e6, 0.8, train.running_resistance_n, 100_000.0, 1.1)
    np.testing.assert_allclose(0.5 * 110_000.0 * ((v + dv) ** 2 - v**2), p * 0.5, rtol=1e-10, atol=1e-6)


def test_negative_radicand_gives_nan() -> None:
    # v = 40 m/s: P_avail = 800000 - 100 * 40^3 = -5.6 MW; 1600 - 2 * 5.6e6 * 20 / 110000 = -436 < 0
    train = cubic_train()
    dv = speed_increment_mps(np.array([10.0, 40.0]), 20.0, 1.0e6, 0.8, train.running_resistance_n, 100_000.0)
    assert np.isfinite(dv[0])
    assert np.isnan(dv[1])


def test_balancing_speed_closed_form() -> None:
    # 100 v^3 = 800000 -> v^3 = 8000 -> v = 20 m/s (72 km/h)
    train = cubic_train()
    assert balancing_speed_mps(1.0e6, 0.8, train.running_resistance_n) == pytest.approx(20.0, rel=1e-9)


def test_balancing_speed_none_without_resistance() -> None:
    def zero(v: object) -> float:
        return 0.0

    assert balancing_speed_mps(1.0e6, 0.8, zero) is None


def test_analysis_of_source_001_convoy() -> None:
    train = bb60000_train()
    result = acceleration_analysis(train, nominal_power_w=1.0e6, efficiency=0.8)
    assert isinstance(result, AccelerationAnalysis)
    assert result.mass_factor == 1.1  # the train's rotating mass factor
    assert result.speed_mps.shape == result.available_power_w.shape == result.delta_v_mps.shape == (101,)
    # the balancing speed solves eta P = R(v) v: cross-check with the cubic's real positive root
    law = train.resistance_law
    roots = np.roots([law.c2, law.c1, law.c0, -0.8e6])
    expected = max(r.real for r in roots if abs(r.imag) < 1e-9 and r.real > 0)
    assert result.balancing_speed_mps == pytest.approx(expected, rel=1e-9)
    # resistance at 100 km/h: loco 4708 N + carriages 12*(480 + 360 + 1760) = 31200 N -> 35908 N,
    # 35908 * 27.78 = 997 kW > 800 kW, so the 1 MW loco cannot reach 100 km/h with this load
    assert train.running_resistance_n(100 * KMH) == pytest.approx(35_908.0)
    assert result.balancing_speed_mps < 100 * KMH
    # dv is positive below the balancing speed and decreases with speed
    below = result.speed_mps < result.balancing_speed_mps
    assert np.all(result.delta_v_mps[below] > 0)
    assert np.all(np.diff(result.delta_v_mps[below]) < 0)


def test_analysis_custom_speeds_and_mass_factor() -> None:
    train = cubic_train()
    result = acceleration_analysis(train, 1.0e6, 0.8, dt_s=1.0, speeds_mps=[10.0], mass_factor=1.1)
    assert result.delta_v_mps[0] == pytest.approx(0.617310, abs=1e-6)
    assert result.mean_acceleration_mps2[0] == pytest.approx(0.617310, abs=1e-6)
    assert result.balancing_speed_mps == pytest.approx(20.0)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"nominal_power_w": 0.0, "efficiency": 0.8},
        {"nominal_power_w": 1e6, "efficiency": 1.5},
        {"nominal_power_w": 1e6, "efficiency": 0.8, "dt_s": 0.0},
        {"nominal_power_w": 1e6, "efficiency": 0.8, "mass_factor": 0.9},
        {"nominal_power_w": 1e6, "efficiency": 0.8, "speeds_mps": [-1.0, 2.0]},
    ],
)
def test_invalid_inputs(kwargs: dict[str, object]) -> None:
    with pytest.raises(InputError):
        acceleration_analysis(cubic_train(), **kwargs)  # type: ignore[arg-type]
