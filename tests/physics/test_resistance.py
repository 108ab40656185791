"""Running-resistance families: published / hand-computed values, SI conversion, registry."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.model.laws import Quadratic
from trainsim.physics import resistance as res

G = 9.80665  # the default gravity (constants.STANDARD_GRAVITY)
KMH = 1 / 3.6
SPEEDS_MPS = np.array([0.0, 5.0, 12.5, 22.2, 27.7778, 44.0])


# ---------------------------------------------------------------- published / hand-computed values
def test_davis_is_si_as_given() -> None:
    # 1000 + 20 * 10 + 5 * 100 = 1700 N
    assert res.davis(1000.0, 20.0, 5.0)(10.0) == pytest.approx(1700.0)


def test_davis_kn_kmh_source_002_table_2() -> None:
    # Source 002 table 2 at 80 km/h: 2.43 + 0.02997*80 + 0.00078*80^2 = 2.43 + 2.3976 + 4.992 = 9.8196 kN
    law = res.davis_kn_kmh(2.43, 0.02997, 0.00078)
    force = law(80 * KMH)
    assert force == pytest.approx(9819.6, rel=1e-9)
    # 288.2 t (4 x 49.8 + 2 x 44.5): 9819.6 / (288200 * 9.80665) * 1000 = 3.474 N/kN, a usual metro value
    assert force / (288_200 * G) * 1000 == pytest.approx(3.4744, abs=1e-3)


def test_per_mass_source_000() -> None:
    # R_b = m (a1 + a2 v^2) = 200000 * (0.01 + 1e-5 * 20^2) = 200000 * 0.014 = 2800 N
    assert res.per_mass(200_000.0, 0.01, 1e-5)(20.0) == pytest.approx(2800.0)


def test_specific_n_per_kn() -> None:
    # w0 = 0.85 + 0.005*60 + 0.000125*60^2 = 0.85 + 0.3 + 0.45 = 1.6 N/kN
    # force = 1.6 * 5e6 kg * 9.81 / 1000 = 78480 N
    law = res.specific_n_per_kn(5.0e6, 0.85, 0.005, 0.000125, gravity_mps2=9.81)
    assert law(60 * KMH) == pytest.approx(78_480.0)
    # the default is the standard gravity 9.80665
    assert res.specific_n_per_kn(5.0e6, 0.85, 0.005, 0.000125)(60 * KMH) == pytest.approx(78_453.2)


def test_specific_unit_weight_dimension() -> None:
    # 1 N/kN on 1000 kg is 1/1000 of 1000 kg * 9.80665 m/s^2 = 9.80665 N, at any speed
    law = res.specific_n_per_kn(1000.0, 1.0, 0.0, 0.0)
    np.testing.assert_allclose(law(SPEEDS_MPS), 9.80665)


def test_rav_in_newton_with_kmh() -> None:
    # 988 + 7.2 * 100 + 0.3 * 100^2 = 988 + 720 + 3000 = 4708 N at 100 km/h
    assert res.rav(988.0, 7.2, 0.3)(100 * KMH) == pytest.approx(4708.0)


def test_rav_locomotive_bb60000_source_001() -> None:
    # 72 t, 4 axles, 100 km/h: 6.5*72 + 130*4 + 0.1*72*100 + 0.3*100^2 = 468 + 520 + 720 + 3000 = 4708 N
    force = res.rav_locomotive_bb60000(72_000.0, 4)(100 * KMH)
    assert force == pytest.approx(4708.0)
    # 4708 / (72000 * 9.81) * 1000 = 6.67 N/kN: plausible for a locomotive, so N with M in t holds
    assert 3.0 < force / (72_000 * G) * 1000 < 10.0


def test_rav_carriage_4axle_source_001() -> None:
    # 40 t at 100 km/h: 12*40 + 0.09*40*100 + 0.0044*40*100^2 = 480 + 360 + 1760 = 2600 N
    assert res.rav_carriage_4axle(40_000.0)(100 * KMH) == pytest.approx(2600.0)
    # at standstill 12 N/t = 1.2 daN/t = 1.22 N/kN, the classic French wagon starting value
    assert res.rav_carriage_4axle(40_000.0)(0.0) == pytest.approx(480.0)


def test_strahl() -> None:
    # 1000 t, f0 = 1.5, f2 = 2.5 per mille at v = v00 = 100 km/h: 1e6 * 9.81 * (1.5 + 2.5) / 1000 = 39240 N
    assert res.strahl(1.0e6, 1.5, 2.5, gravity_mps2=9.81)(100 * KMH) == pytest.approx(39_240.0)
    # at 50 km/h: 9810 * (1.5 + 2.5 * 0.25) = 9810 * 2.125 = 20846.25 N
    assert res.strahl(1.0e6, 1.5, 2.5, gravity_mps2=9.81)(50 * KMH) == pytest.approx(20_846.25)


def test_sauthoff() -> None:
    # 400 t, f0=1.0, f1=0.5, f2=1.5 per mille at 85 km/h: (85 + 15)/100 = 1
    # 1.0 + 0.5 * 0.85 + 1.5 * 1 = 2.925 per mille -> 400000 * 9.81 * 2.925e-3 = 11477.7 N
    assert res.sauthoff(400_000.0, 1.0, 0.5, 1.5, gravity_mps2=9.81)(85 * KMH) == pytest.approx(11_477.7)


def test_sauthoff_head_wind_allowance_at_standstill() -> None:
    # v = 0: f0 + f2 (15/100)^2 = 1.0 + 1.5 * 0.0225 = 1.03375 per mille -> 3924 * 1.03375 = 4056.435 N
    assert res.sauthoff(400_000.0, 1.0, 0.5, 1.5, gravity_mps2=9.81)(0.0) == pytest.approx(4056.435)


def test_wende_traction_unit() -> None:
    # 80 t, 60 t on driven axles, f_td0 = 2.5, f_tc0 = 1.5, f_t2 = 0.5 per mille, 85 km/h ((85+15)/100 = 1):
    # 2.5e-3*60000*9.81 + 1.5e-3*20000*9.81 + 0.5e-3*80000*9.81*1 = 1471.5 + 294.3 + 392.4 = 2158.2 N
    assert res.wende_traction_unit(80_000.0, 60_000.0, 2.5, 1.5, 0.5, gravity_mps2=9.81)(
        85 * KMH
    ) == pytest.approx(2158.2)


def test_altrios() -> None:
    # 100 t, 4 axles, 50 N/axle, rolling 5e-4, davis_b 1e-4 s/m, cd_area 5 m^2 at 20 m/s; W = 981000 N
    # 4*50 + 5e-4*981000 + 1e-4*20*981000 + 1.225*5*20^2 = 200 + 490.5 + 1962 + 2450 = 5102.5 N
    assert res.altrios(100_000.0, 4, 50.0, 5e-4, 1e-4, 5.0, gravity_mps2=9.81)(20.0) == pytest.approx(5102.5)


def test_altrios_drag_area_lumps_the_half() -> None:
    # ALTRIOS reading: F_air = rho cd_area v^2 (no 1/2): 1.225 * 10 * 30^2 = 11025 N
    law = res.altrios(1.0, 1, 0.0, 0.0, 0.0, 10.0)
    assert law(30.0) - law(0.0) == pytest.approx(11_025.0)


# ---------------------------------------------------------------- consistency between families
def test_davis_kn_kmh_is_rav_times_1000() -> None:
    a = res.davis_kn_kmh(2.43, 0.02997, 0.00078)
    b = res.rav(2430.0, 29.97, 0.78)
    np.testing.assert_allclose(a(SPEEDS_MPS), b(SPEEDS_MPS))


def test_strahl_equals_specific_with_v00() -> None:
    # f2 (V/100)^2 per mille = f2/10000 V^2 N/kN
    a = res.strahl(300_000.0, 1.2, 3.0)
    b = res.specific_n_per_kn(300_000.0, 1.2, 0.0, 3.0 / 100**2)
    np.testing.assert_allclose(a(SPEEDS_MPS), b(SPEEDS_MPS))


def test_wende_all_driven_is_a_sauthoff_without_linear_term() -> None:
    a = res.wende_traction_unit(84_000.0, 84_000.0, 2.0, 9.9, 0.6)
    b = res.sauthoff(84_000.0, 2.0, 0.0, 0.6)
    np.testing.assert_allclose(a(SPEEDS_MPS), b(SPEEDS_MPS))


def test_rav_loco_scales_with_axles() -> None:
    # each axle adds 130 N at every speed
    six, four = res.rav_locomotive_bb60000(80_000.0, 6), res.rav_locomotive_bb60000(80_000.0, 4)
    np.testing.assert_allclose(six(SPEEDS_MPS) - four(SPEEDS_MPS), 260.0)


# ---------------------------------------------------------------- Quadratic vs direct formula
def _kmh(v: np.ndarray) -> np.ndarray:
    return v * 3.6


CASES: list[tuple[str, Quadratic, Callable[[np.ndarray], np.ndarray]]] = [
    ("davis", res.davis(1200.0, 35.0, 6.5), lambda v: 1200 + 35 * v + 6.5 * v**2),
    (
        "davis_kn_kmh",
        res.davis_kn_kmh(2.43, 0.02997, 0.00078),
        lambda v: 1000 * (2.43 + 0.02997 * _kmh(v) + 0.00078 * _kmh(v) ** 2),
    ),
    ("per_mass", res.per_mass(150_000.0, 0.012, 2e-5), lambda v: 150_000 * (0.012 + 2e-5 * v**2)),
    (
        "specific_n_per_kn",
        res.specific_n_per_kn(2.0e6, 0.9, 0.004, 0.0002),
        lambda v: (0.9 + 0.004 * _kmh(v) + 0.0002 * _kmh(v) ** 2) * 2.0e6 * G / 1000,
    ),
    ("rav", res.rav(900.0, 8.0, 0.25), lambda v: 900 + 8 * _kmh(v) + 0.25 * _kmh(v) ** 2),
    (
        "rav_locomotive_bb60000",
        res.rav_locomotive_bb60000(72_000.0, 4),
        lambda v: 6.5 * 72 + 130 * 4 + 0.1 * 72 * _kmh(v) + 0.3 * _kmh(v) ** 2,
    ),
    (
        "rav_carriage_4axle",
        res.rav_carriage_4axle(42_500.0),
        lambda v: 12 * 42.5 + 0.09 * 42.5 * _kmh(v) + 0.0044 * 42.5 * _kmh(v) ** 2,
    ),
    (
        "strahl",
        res.strahl(900_000.0, 1.4, 4.0),
        lambda v: 900_000 * G * (1.4 + 4.0 * (_kmh(v) / 100) ** 2) / 1000,
    ),
    (
        "sauthoff",
        res.sauthoff(350_000.0, 1.2, 0.3, 2.2),
        lambda v: 350_000 * G * (1.2 + 0.3 * _kmh(v) / 100 + 2.2 * ((_kmh(v) + 15) / 100) ** 2) / 1000,
    ),
    (
        "wende",
        res.wende_traction_unit(86_000.0, 60_000.0, 2.5, 1.4, 0.7),
        lambda v: G / 1000 * (2.5 * 60_000 + 1.4 * 26_000 + 0.7 * 86_000 * ((_kmh(v) + 15) / 100) ** 2),
    ),
    (
        "altrios",
        res.altrios(120_000.0, 4, 60.0, 4e-4, 1.5e-4, 6.0),
        lambda v: 4 * 60 + 4e-4 * 120_000 * G + 1.5e-4 * v * 120_000 * G + 1.225 * 6.0 * v**2,
    ),
]


@pytest.mark.parametrize(("name", "law", "direct"), CASES, ids=[c[0] for c in CASES])
def test_quadratic_matches_direct_formula(
    name: str, law: Quadratic, direct: Callable[[np.ndarray], np.ndarray]
) -> None:
    assert isinstance(law, Quadratic)
    np.testing.assert_allclose(law(SPEEDS_MPS), direct(SPEEDS_MPS), rtol=1e-12, atol=1e-9)


def test_every_family_is_tested_against_its_formula() -> None:
    assert {c[0] for c in CASES} == set(res.RESISTANCE_FAMILIES)


# ---------------------------------------------------------------- registry and validation
def test_registry_names_and_functions() -> None:
    expected = {
        "davis": res.davis,
        "davis_kn_kmh": res.davis_kn_kmh,
        "per_mass": res.per_mass,
        "specific_n_per_kn": res.specific_n_per_kn,
        "rav": res.rav,
        "rav_locomotive_bb60000": res.rav_locomotive_bb60000,
        "rav_carriage_4axle": res.rav_carriage_4axle,
        "strahl": res.strahl,
        "sauthoff": res.sauthoff,
        "wende": res.wende_traction_unit,
        "altrios": res.altrios,
    }
    assert expected == res.RESISTANCE_FAMILIES


@pytest.mark.parametrize(
    "call",
    [
        lambda: res.strahl(0.0, 1.0, 1.0),
        lambda: res.per_mass(-5.0, 0.01, 0.0),
        lambda: res.rav_locomotive_bb60000(72_000.0, 0),
        lambda: res.wende_traction_unit(80_000.0, 90_000.0, 2.5, 1.5, 0.5),
        lambda: res.wende_traction_unit(80_000.0, 0.0, 2.5, 1.5, 0.5),
        lambda: res.altrios(float("nan"), 4, 1.0, 1.0, 1.0, 1.0),
    ],
)
def test_invalid_masses_and_axles_raise(call: Callable[[], Quadratic]) -> None:
    with pytest.raises(InputError):
        call()
