"""Electrical power and current: physical and source 002 conventions."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.physics import electrical as el


def test_mechanical_power() -> None:
    # 100 kN * 20 m/s = 2 MW
    assert el.mechanical_power_w(100e3, 20.0) == pytest.approx(2.0e6)


def test_traction_and_regenerated_line_power() -> None:
    # traction: 2 MW / 0.8 = 2.5 MW drawn; regeneration: 2 MW * 0.8 = 1.6 MW returned
    assert el.traction_line_power_w(100e3, 20.0, 0.8) == pytest.approx(2.5e6)
    assert el.regenerated_line_power_w(100e3, 20.0, 0.8) == pytest.approx(1.6e6)
    assert el.regenerated_line_power_w(100e3, 20.0, 0.0) == 0.0


def test_paper_power_multiplies_by_eta_in_traction() -> None:
    # source 002 eq. 14: P = F V eta = 2 MW * 0.98 = 1.96 MW; physical 2 MW / 0.98 = 2.0408 MW
    assert el.paper_power_w(100e3, 20.0, 0.98) == pytest.approx(1.96e6)
    assert el.traction_line_power_w(100e3, 20.0, 0.98) == pytest.approx(2.040816e6, rel=1e-6)


def test_line_current_source_002_eq_15() -> None:
    # I = P / (U cos phi) = 1.6 MW / (1000 V * 0.95) = 1684.21 A
    assert el.line_current_a(1.6e6, 1000.0, 0.95) == pytest.approx(1684.2105, rel=1e-7)
    # unit power factor: 1.5 MW / 1500 V = 1000 A
    assert el.line_current_a(1.5e6, 1500.0) == pytest.approx(1000.0)


def test_source_002_peak_current_reproduced_with_paper_convention() -> None:
    # Source 002 table 3 per motor car, x 4 motor cars; F V is largest on the 50-60 km/h segment:
    # F(V) = 83.75 - 1.375 (V - 50) kN, F V max at V = 152.5 / 2.75 = 55.4545 km/h, F = 76.25 kN x 4 = 305 kN
    speed_kmh = np.linspace(0.0, 80.0, 80_001)
    force_n = 4 * 1e3 * np.interp(speed_kmh, [0, 42, 50, 60, 70, 80], [93.25, 93.25, 83.75, 70, 59.5, 45])
    speed_mps = speed_kmh / 3.6
    paper = el.line_current_a(el.paper_power_w(force_n, speed_mps, 0.98), 1000.0, 0.95)
    physical = el.line_current_a(el.traction_line_power_w(force_n, speed_mps, 0.98), 1000.0, 0.95)
    # 305 kN * 15.404 m/s = 4.6982 MW; * 0.98 / 950 = 4846.6 A vs the published peak 4863 A (-0.3 %)
    assert paper.max() == pytest.approx(4846.6, abs=0.5)
    assert paper.max() == pytest.approx(4863.0, rel=0.005)
    # the physical convention gives 4.6982 MW / 0.98 / 950 = 5046.4 A (+3.8 %)
    assert physical.max() == pytest.approx(5046.4, abs=0.5)


def test_vectorised_shapes() -> None:
    f = np.array([0.0, 50e3, 100e3])
    v = np.array([0.0, 10.0, 20.0])
    out = el.traction_line_power_w(f, v, 0.9)
    assert isinstance(out, np.ndarray)
    np.testing.assert_allclose(out, [0.0, 5e5 / 0.9, 2e6 / 0.9])
    assert isinstance(el.mechanical_power_w(1.0, 2.0), float)


@pytest.mark.parametrize(
    "call",
    [
        lambda: el.traction_line_power_w(1.0, 1.0, 0.0),
        lambda: el.traction_line_power_w(1.0, 1.0, 1.2),
        lambda: el.paper_power_w(1.0, 1.0, -0.5),
        lambda: el.regenerated_line_power_w(1.0, 1.0, 1.01),
        lambda: el.line_current_a(1.0, 0.0, 0.95),
        lambda: el.line_current_a(1.0, 750.0, 0.0),
    ],
)
def test_invalid_inputs(call: Callable[[], object]) -> None:
    with pytest.raises(InputError):
        call()
