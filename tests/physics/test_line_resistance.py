"""Line resistances as ratios of the weight: gradients, curves, tunnels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.physics import line_resistance as lr

G = 9.80665  # the default gravity (constants.STANDARD_GRAVITY)


# ---------------------------------------------------------------- gradient
def test_gradient_small_angle_source_002_eq_5() -> None:
    # i = 10 per mille -> 10 N/kN -> ratio 0.01; downhill negative
    assert lr.gradient_ratio(10.0) == pytest.approx(0.01)
    assert lr.gradient_ratio(-35.0, "small_angle") == pytest.approx(-0.035)


def test_gradient_exact_source_000() -> None:
    # sin(atan(0.01)) = 0.01 / sqrt(1 + 0.01^2) = 0.009999500037
    assert lr.gradient_ratio(10.0, "exact") == pytest.approx(0.01 / math.sqrt(1.0001), rel=1e-12)
    # 40 per mille: 0.04 / sqrt(1.0016) = 0.039968; 0.08 % below the small-angle value
    assert lr.gradient_ratio(40.0, "exact") == pytest.approx(0.039968038, rel=1e-8)


def test_gradient_vectorised() -> None:
    out = lr.gradient_ratio(np.array([0.0, 5.0, -5.0]))
    np.testing.assert_allclose(out, [0.0, 0.005, -0.005])


def test_gradient_unknown_formula() -> None:
    with pytest.raises(InputError, match="small_angle"):
        lr.gradient_ratio(1.0, "sine")


# ---------------------------------------------------------------- curves
def test_roeckl_large_and_small_radius() -> None:
    # R = 1000 m: 650 / (1000 - 55) = 0.687831 per mille
    assert lr.curve_ratio(1000.0, "roeckl") == pytest.approx(650 / 945 / 1000)
    # R = 250 m: 500 / (250 - 30) = 2.272727 per mille
    assert lr.curve_ratio(250.0, "roeckl") == pytest.approx(500 / 220 / 1000)
    # R = 300 m belongs to the large-radius branch: 650 / 245 = 2.653061 per mille
    assert lr.curve_ratio(300.0, "roeckl") == pytest.approx(650 / 245 / 1000)


def test_wang_source_000_is_roeckl_in_kn_per_t() -> None:
    # R = 1000 m: 6.3 kN/t / 9.81 / (1000 - 55) = 6.7958e-4 (0.680 per mille vs Roeckl's 0.688)
    assert lr.curve_ratio(1000.0, "wang") == pytest.approx(6.3 / G / 945)
    # R = 250 m: 4.91 / 9.81 / (250 - 30) = 2.2751e-3; 4.91/9.81 = 500.5, Roeckl's 500
    assert lr.curve_ratio(250.0, "wang") == pytest.approx(4.91 / G / 220)
    assert lr.curve_ratio(250.0, "wang") == pytest.approx(
        lr.curve_ratio(250.0, "roeckl"), rel=1.5e-3
    )  # 500.7 vs 500


def test_wang_dimension_kn_per_tonne() -> None:
    # 6.3 m/(r-55) kN for m = 100 t, r = 655 m: 6.3 * 100 / 600 = 1.05 kN = ratio * 100 t * 9.81 kN/t
    ratio = lr.curve_ratio(655.0, "wang")
    assert ratio * 100 * G == pytest.approx(1.05)


def test_tbt1407_and_french800() -> None:
    # 600 / 600 = 1 per mille; 800 / 800 = 1 per mille
    assert lr.curve_ratio(600.0, "tbt1407") == pytest.approx(1e-3)
    assert lr.curve_ratio(800.0, "french800") == pytest.approx(1e-3)
    # small radius is fine for these: 600 / 40 = 15 per mille
    assert lr.curve_ratio(40.0, "tbt1407") == pytest.approx(0.015)


def test_curve_none() -> None:
    assert lr.curve_ratio(20.0, "none") == 0.0


def test_curve_vectorised_mixed_branches() -> None:
    out = lr.curve_ratio(np.array([250.0, 300.0, 1055.0]), "roeckl")
    # 500/220, 650/245, 650/1000 per mille
    np.testing.assert_allclose(out, np.array([500 / 220, 650 / 245, 0.65]) / 1000)


@pytest.mark.parametrize(
    ("radius", "formula", "allowed"),
    [
        (30.0, "roeckl", "R > 30 m"),
        (25.0, "wang", "R > 30 m"),
        (0.0, "tbt1407", "R > 0 m"),
        (-100.0, "french800", "R > 0 m"),
        (float("nan"), "roeckl", "R > 30 m"),
    ],
)
def test_curve_radius_at_or_below_pole(radius: float, formula: str, allowed: str) -> None:
    with pytest.raises(InputError) as info:
        lr.curve_ratio(radius, formula)
    assert info.value.field == "curves.radius"
    assert info.value.allowed == allowed
    assert info.value.value == radius or math.isnan(radius)


def test_curve_unknown_formula_lists_known_ones() -> None:
    with pytest.raises(InputError) as info:
        lr.curve_ratio(500.0, "davis")
    assert info.value.field == "line_resistance.curve_formula"
    for name in lr.CURVE_FORMULAS:
        assert name in info.value.allowed


def test_curve_radius_from_angle_source_002_eq_6() -> None:
    # R = (360 / 2 pi) * 100 m / 10 deg = 57.29578 * 10 = 572.9578 m
    assert lr.curve_radius_from_angle(100.0, 10.0) == pytest.approx(572.957795, rel=1e-9)


def test_curve_ratio_tbt1407_from_angle_source_002_eq_6() -> None:
    # 10.5 * 10 deg / 100 m = 1.05 N/kN
    assert lr.curve_ratio_tbt1407_from_angle(100.0, 10.0) == pytest.approx(1.05e-3)
    # vs 600 / R = 600 / 572.9578 = 1.04720 N/kN: 10.5 is 10.472 rounded (+0.27 %)
    via_radius = lr.curve_ratio(lr.curve_radius_from_angle(100.0, 10.0), "tbt1407")
    assert via_radius == pytest.approx(1.0472e-3, rel=1e-4)
    assert lr.curve_ratio_tbt1407_from_angle(100.0, 10.0) / via_radius == pytest.approx(1.0027, abs=1e-4)


def test_curve_geometry_must_be_positive() -> None:
    with pytest.raises(InputError):
        lr.curve_radius_from_angle(100.0, 0.0)
    with pytest.raises(InputError):
        lr.curve_ratio_tbt1407_from_angle(-1.0, 5.0)


# ---------------------------------------------------------------- tunnels
def test_tunnel_wang_without_limiting_gradient() -> None:
    # 1.3e-7 * 2000 m = 2.6e-4 (0.26 per mille), speed-independent
    assert lr.tunnel_ratio(2000.0, "wang") == pytest.approx((2.6e-4, 0.0))


def test_tunnel_wang_limiting_gradient_1_permille_at_100_kmh() -> None:
    const, coef = lr.tunnel_ratio(1000.0, "wang", limiting_gradient=True)
    assert const == 0.0
    # 1.296e-9 * 1000 m * (100/3.6 m/s)^2 = 1.296e-6 * 771.605 = 1.0e-3: 1 per mille
    assert coef * (100 / 3.6) ** 2 == pytest.approx(1.0e-3, rel=1e-12)
    # unit check: coefficient [s^2/m^2] times v^2 [m^2/s^2] is dimensionless
    assert coef == pytest.approx(1.296e-6)


def test_tunnel_tbt1407_source_002_eq_7() -> None:
    # w_s = 0.00013 * 2000 = 0.26 N/kN -> 2.6e-4; the same law as Wang's first one
    assert lr.tunnel_ratio(2000.0, "tbt1407") == pytest.approx((2.6e-4, 0.0))
    assert lr.tunnel_ratio(2000.0, "tbt1407", True) == lr.tunnel_ratio(2000.0, "tbt1407", False)


def test_tunnel_none_and_errors() -> None:
    assert lr.tunnel_ratio(5000.0, "none", True) == (0.0, 0.0)
    with pytest.raises(InputError) as info:
        lr.tunnel_ratio(1000.0, "french")
    assert info.value.field == "line_resistance.tunnel_formula"
    with pytest.raises(InputError):
        lr.tunnel_ratio(-1.0, "wang")


def test_registries_match_route_literals() -> None:
    assert set(lr.CURVE_FORMULAS) == {"roeckl", "wang", "tbt1407", "french800", "none"}
    assert set(lr.TUNNEL_FORMULAS) == {"wang", "tbt1407", "none"}
    assert set(lr.GRADIENT_FORMULAS) == {"small_angle", "exact"}
