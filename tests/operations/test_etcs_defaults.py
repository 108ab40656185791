"""The ETCS default values against SUBSET-026-3 A.3.1 (fixed values) and A.3.2 (national values'
defaults), and the conversion model's A.3.7 coefficients.

Cross-checked against an independent open-source on-board implementation (cesarBLG/ETCS, MPL-2.0:
EVC/Supervision/national_values.cpp, fixed_values.cpp and conversion_model.cpp), whose values are
restated here as numbers, not copied code. The A.3.8 freight build-up row is also pinned against the text of SUBSET-026-3 v4.0.0 (docs/ETCS.md).
"""

from __future__ import annotations

import pytest

from trainsim.constants import KMH
from trainsim.operations.etcs import (
    CONVERSION_AD_COEFFICIENTS,
    CONVERSION_BUILD_UP,
    CONVERSION_CT,
    EtcsNationalValues,
)

NV = EtcsNationalValues()


@pytest.mark.parametrize(
    ("clause", "name", "expected"),
    [
        # A.3.2: default values of the national values
        ("A.3.2 V_NVREL", "v_nvrel_mps", 40 * KMH),
        ("A.3.2 Q_NVSBTSMPERM", "q_nvsbtsmperm", True),
        ("A.3.2 Q_NVGUIPERM", "q_nvguiperm", False),
        ("A.3.2 Q_NVSBFBPERM", "q_nvsbfbperm", False),
        ("A.3.2 Q_NVINHSMICPERM", "q_nvinhsmicperm", False),
        ("A.3.2 M_NVAVADH", "m_nvavadh", 0.0),
        ("A.3.2 M_NVEBCL (1 - 1e-9, index 9)", "m_nvebcl", 9),
        ("A.3.2 M_NVKTINT", "kt_int", 1.1),
        ("A.3.2 A_NVP12", "a_nvp12_mps2", 0.0),
        ("A.3.2 A_NVP23", "a_nvp23_mps2", 0.0),
        ("A.3.2 A_NVMAXREDADH1", "a_nvmaxredadh1_mps2", 1.0),
        ("A.3.2 A_NVMAXREDADH2", "a_nvmaxredadh2_mps2", 0.7),
        ("A.3.2 A_NVMAXREDADH3", "a_nvmaxredadh3_mps2", 0.7),
        # A.3.1: fixed values
        ("A.3.1 dV_ebi_min", "dv_ebi_min_mps", 7.5 * KMH),
        ("A.3.1 dV_ebi_max", "dv_ebi_max_mps", 15 * KMH),
        ("A.3.1 V_ebi_min", "v_ebi_min_mps", 110 * KMH),
        ("A.3.1 V_ebi_max", "v_ebi_max_mps", 210 * KMH),
        ("A.3.1 dV_sbi_min", "dv_sbi_min_mps", 5.5 * KMH),
        ("A.3.1 dV_sbi_max", "dv_sbi_max_mps", 10 * KMH),
        ("A.3.1 V_sbi_min", "v_sbi_min_mps", 110 * KMH),
        ("A.3.1 V_sbi_max", "v_sbi_max_mps", 210 * KMH),
        ("A.3.1 dV_warning_min", "dv_warning_min_mps", 4 * KMH),
        ("A.3.1 dV_warning_max", "dv_warning_max_mps", 5 * KMH),
        ("A.3.1 V_warning_min", "v_warning_min_mps", 110 * KMH),
        ("A.3.1 V_warning_max", "v_warning_max_mps", 140 * KMH),
        ("A.3.1 T_warning", "t_warning_s", 2.0),
        ("A.3.1 T_driver", "t_driver_s", 4.0),
        ("A.3.1 M_rotating_max", "m_rotating_max_percent", 15.0),
        ("A.3.1 M_rotating_min", "m_rotating_min_percent", 2.0),
    ],
)
def test_default_value(clause: str, name: str, expected: object) -> None:
    assert getattr(NV, name) == pytest.approx(expected), clause


@pytest.mark.parametrize(
    ("clause", "name"),
    [
        ("A.3.2 Kv_int (freight)", "kv_int_freight"),
        ("A.3.2 Kv_int (passenger, set a)", "kv_int_passenger_a"),
        ("A.3.2 Kv_int (passenger, set b)", "kv_int_passenger_b"),
    ],
)
def test_default_kv_int_is_one_step_of_0_7(clause: str, name: str) -> None:
    fn = getattr(NV, name)
    assert list(fn.values) == [0.7], clause


def test_default_kr_int_is_one_step_of_0_9() -> None:
    assert list(NV.kr_int.values) == [0.9], "A.3.2 Kr_int"


def test_conversion_model_coefficients() -> None:
    # A.3.7: AD_n(lambda) coefficients (a0, a1, a2, a3), n = 1..5
    assert CONVERSION_AD_COEFFICIENTS == (
        (0.0663, 4.72e-3, 6.10e-5, -6.30e-7),
        (0.1300, 5.14e-3, -4.54e-6, 2.73e-7),
        (0.0479, 5.81e-3, -6.76e-6, 5.58e-8),
        (0.0480, 5.52e-3, -3.85e-6, 3.00e-8),
        (0.0559, 5.06e-3, 1.66e-6, 3.23e-9),
    )
    # A.3.8.1-3 / A.3.9.1-3: build-up times up to 900 m and for passenger trains
    assert CONVERSION_BUILD_UP["emergency"]["passenger_p"][0][1] == (2.30, 0.0, 0.17)
    assert CONVERSION_BUILD_UP["emergency"]["freight_g"][0][1] == (12.0, 0.0, 0.05)
    assert CONVERSION_BUILD_UP["service"]["passenger_p"][0][1] == (3.00, 1.50, 0.10)
    assert CONVERSION_BUILD_UP["service"]["freight_p"][1][1] == (10.50, 0.32, 0.18)
    # A.3.8.4-5: Ct
    assert CONVERSION_CT == {"passenger_p": 0.20, "freight_p": 0.20, "freight_g": 0.16}
    # A.3.8.2 / A.3.8.3 above 900 m, read in SUBSET-026-3 v4.0.0: a = -0.40, b = 1.60, c = 0.03 for
    # freight trains in P and in G alike (cesarBLG/ETCS has a = -0.5 for P, against the text)
    assert CONVERSION_BUILD_UP["emergency"]["freight_p"][1][1] == (-0.40, 1.60, 0.03)
    assert CONVERSION_BUILD_UP["emergency"]["freight_g"][1][1] == (-0.40, 1.60, 0.03)
    assert CONVERSION_BUILD_UP["emergency"]["freight_p"][0][1] == (2.30, 0.0, 0.17)
    assert CONVERSION_BUILD_UP["service"]["freight_g"][0][1] == (3.00, 2.77, 0.0)
