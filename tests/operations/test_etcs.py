"""ETCS braking curves and supervision limits (SUBSET-026-3 3.13) against hand-computed values.

Every expected value below is computed here from the clauses' formulas written out by hand, not with
the module's own equation functions.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from trainsim.constants import KMH
from trainsim.errors import InfeasibleError, InputError
from trainsim.model.route import GradientSection, Route, SpeedLimit, Station
from trainsim.operations.etcs import (
    CONVERSION_AD_COEFFICIENTS,
    EtcsNationalValues,
    EtcsTrainData,
    StepFunction,
    a_gradient_mps2,
    basic_deceleration,
    ceiling_offset_mps,
    compensated_gradient_profile,
    conversion_build_up_time_s,
    conversion_kto,
    conversion_v_lim_mps,
    kv_int_passenger,
    moving_block_ceiling,
    supervision_curves,
)

G = 9.81  # SUBSET-026-3 3.13.4.3.2


def train(**changes) -> EtcsTrainData:
    base = dict(
        a_brake_emergency=1.0,
        a_brake_service=0.8,
        t_brake_emergency_s=3.0,
        t_brake_service_s=4.0,
        t_traction_cut_off_s=1.0,
        length_m=0.0,
        max_speed_mps=200 * KMH,
    )
    base.update(changes)
    return EtcsTrainData(**base)


NV = EtcsNationalValues()


# ---------------------------------------------------------------------------------------- data, laws


def test_step_function_follows_the_clause_steps():
    # 3.13.2.2.3.1.3: AD_0 for 0 <= V <= V1, AD_1 for V1 < V <= V2, the last step open ended
    fn = StepFunction.from_kmh([50, 100], [0.7, 0.9, 0.8])
    v1, v2 = 50 * KMH, 100 * KMH
    assert fn(0.0) == 0.7 and fn(v1) == 0.7 and fn(v1 + 1e-9) == 0.9
    assert fn(v2) == 0.9 and fn(v2 + 1e-9) == 0.8 and fn(1e3) == 0.8
    assert list(fn(np.array([0.0, v1, v2, 200.0]))) == [0.7, 0.7, 0.9, 0.8]


def test_ceiling_offsets_follow_3_13_9_2_3():
    # dV = dV_min up to V_min, then dV_min + C (V - V_min), C = (dV_max - dV_min)/(V_max - V_min), <= dV_max
    def dv(v_kmh, dmin, dmax, vmin, vmax):
        return ceiling_offset_mps(v_kmh * KMH, dmin * KMH, dmax * KMH, vmin * KMH, vmax * KMH) / KMH

    assert dv(100, 7.5, 15, 110, 210) == pytest.approx(7.5, abs=1e-12)
    assert dv(160, 7.5, 15, 110, 210) == pytest.approx(7.5 + 7.5 * 50 / 100, abs=1e-12)
    assert dv(300, 7.5, 15, 110, 210) == pytest.approx(15.0, abs=1e-12)
    assert dv(160, 5.5, 10, 110, 210) == pytest.approx(5.5 + 4.5 * 0.5, abs=1e-12)
    assert dv(125, 4, 5, 110, 140) == pytest.approx(4.5, abs=1e-12)


def test_fixed_and_national_defaults_are_subset_026_values():
    assert NV.t_driver_s == 4.0 and NV.t_warning_s == 2.0
    assert NV.dv_ebi_min_mps == pytest.approx(7.5 / 3.6) and NV.dv_ebi_max_mps == pytest.approx(15 / 3.6)
    assert NV.v_ebi_min_mps == pytest.approx(110 / 3.6) and NV.v_ebi_max_mps == pytest.approx(210 / 3.6)
    assert NV.dv_sbi_min_mps == pytest.approx(5.5 / 3.6) and NV.dv_warning_max_mps == pytest.approx(5 / 3.6)
    assert NV.m_rotating_max_percent == 15 and NV.m_rotating_min_percent == 2
    assert NV.v_nvrel_mps == pytest.approx(40 / 3.6) and NV.m_nvavadh == 0 and NV.m_nvebcl == 9
    assert not NV.q_nvinhsmicperm and not NV.q_nvguiperm


def test_gradient_acceleration_against_figure_35():
    # 3.13.4.3.2, and the compensated values printed in SUBSET-026-3 Figure 35 (rounded there)
    assert a_gradient_mps2(-9.0) == pytest.approx(-0.0865, abs=2e-4)
    assert a_gradient_mps2(-8.0) == pytest.approx(-0.0769, abs=2e-4)
    assert a_gradient_mps2(7.0) == pytest.approx(0.05965, abs=2e-4)
    assert a_gradient_mps2(10.0) == pytest.approx(G * 10 / 1150, rel=1e-12)
    assert a_gradient_mps2(-10.0) == pytest.approx(G * -10 / 1020, rel=1e-12)
    assert a_gradient_mps2(10.0, m_rotating_nom_percent=5.0) == pytest.approx(G * 10 / 1050, rel=1e-12)


def test_gradient_is_compensated_over_the_train_length():
    # 3.13.4.2.1: the lowest gradient between the fictive rear (d - L) and front (d)
    breaks, grads = compensated_gradient_profile(([0.0, 1000.0, 1200.0], [0.0, -10.0, 5.0]), 300.0)

    def at(x):
        return grads[np.searchsorted(breaks, x, side="right")]

    assert at(999.0) == 0.0
    assert at(1100.0) == -10.0
    assert at(1499.0) == -10.0  # rear still on the -10 section
    assert at(1501.0) == 5.0
    assert at(-50.0) == 0.0  # outside the profile: level (3.13.4.1.3 b)


# ------------------------------------------------------------------------------------ braking curves


def test_ebd_and_sbd_are_parabolas_on_level_track():
    c = supervision_curves(train(), NV, None, eoa_position_m=3000.0, svl_position_m=3200.0)
    s = np.array([2000.0, 2500.0, 2900.0, 2999.0, 3100.0, 3199.999])
    assert np.allclose(c.ebd(s), np.sqrt(2 * 1.0 * (3200.0 - s)), rtol=1e-9, atol=0)
    s_sbd = s[s < 3000]
    assert np.allclose(c.sbd(s_sbd), np.sqrt(2 * 0.8 * (3000.0 - s_sbd)), rtol=1e-9, atol=0)
    assert c.ebd(3200.0) == 0.0 and c.ebd(4000.0) == 0.0 and c.sbd(3000.0) == 0.0


def test_safe_deceleration_uses_the_correction_factors():
    # 3.13.6.2.1.4: A_brake_safe = Kdry (Kwet + M_NVAVADH (1 - Kwet)) A_brake_emergency
    t = train(kdry_rst={9: 0.8, 5: 0.95}, kwet_rst=0.9)
    nv = EtcsNationalValues(m_nvavadh=0.5)
    c = supervision_curves(t, nv, None, eoa_position_m=1000.0)
    a = 0.8 * (0.9 + 0.5 * 0.1) * 1.0
    s = np.array([0.0, 500.0, 999.0])
    assert np.allclose(c.ebd(s), np.sqrt(2 * a * (1000.0 - s)), rtol=1e-9, atol=0)
    c5 = supervision_curves(t, EtcsNationalValues(m_nvebcl=5), None, eoa_position_m=1000.0)
    assert c5.ebd(0.0) == pytest.approx(math.sqrt(2 * 0.95 * 0.9 * 1000.0), rel=1e-12)
    with pytest.raises(InputError, match="M_NVEBCL"):
        supervision_curves(t, EtcsNationalValues(m_nvebcl=3), None, eoa_position_m=1000.0)


def test_step_deceleration_gives_joined_parabolas():
    # A = 0.7 up to 20 m/s, 1.0 above: below 20 m/s v^2 = 1.4 (SvL - s); above, from the joint
    t = train(a_brake_emergency=StepFunction((0.7, 1.0), (20.0,)))
    c = supervision_curves(t, NV, None, eoa_position_m=5000.0)
    joint = 5000.0 - 20.0**2 / (2 * 0.7)
    s_low = np.array([4800.0, 4900.0, 4990.0])
    s_high = np.array([joint - 1.0, joint - 500.0, joint - 1500.0])
    assert np.allclose(c.ebd(s_low), np.sqrt(1.4 * (5000.0 - s_low)), rtol=1e-9, atol=0)
    assert np.allclose(c.ebd(s_high), np.sqrt(400.0 + 2.0 * (joint - s_high)), rtol=1e-9, atol=0)
    assert c.ebd(joint) == pytest.approx(20.0, rel=1e-12)


def test_downhill_gradient_lengthens_braking_and_uphill_shortens_it():
    level = supervision_curves(train(), NV, None, eoa_position_m=5000.0)
    down = supervision_curves(train(), NV, ([0.0], [-8.0]), eoa_position_m=5000.0)
    up = supervision_curves(train(), NV, ([0.0], [8.0]), eoa_position_m=5000.0)
    s = np.array([3000.0, 4000.0, 4900.0])
    a_down = 1.0 + G * -8.0 / 1020  # M_rotating_min downhill
    a_up = 1.0 + G * 8.0 / 1150  # M_rotating_max uphill
    assert np.allclose(down.ebd(s), np.sqrt(2 * a_down * (5000.0 - s)), rtol=1e-9, atol=0)
    assert np.allclose(up.ebd(s), np.sqrt(2 * a_up * (5000.0 - s)), rtol=1e-9, atol=0)
    assert np.all(down.ebd(s) < level.ebd(s)) and np.all(up.ebd(s) > level.ebd(s))
    # the braking distance from 150 km/h: downhill longer, uphill shorter
    v = 150 * KMH
    d_level = 5000.0 - level.limit_position_m("ebi", v)
    assert 5000.0 - down.limit_position_m("ebi", v) > d_level > 5000.0 - up.limit_position_m("ebi", v)


def test_gradient_change_with_train_length_compensation():
    # level up to 4000 m, then 10 per mille uphill; a 400 m train feels the uphill only when its rear is
    # on it: from 4400 m on (front position)
    t = train(length_m=400.0)
    c = supervision_curves(t, NV, ([0.0, 4000.0], [0.0, 10.0]), eoa_position_m=5000.0)
    a_up = 1.0 + G * 10 / 1150
    assert c.ebd(4500.0) == pytest.approx(math.sqrt(2 * a_up * 500.0), rel=1e-12)
    v_joint2 = 2 * a_up * 600.0  # speed^2 at 4400 m
    assert c.ebd(4200.0) == pytest.approx(math.sqrt(v_joint2 + 2 * 1.0 * 200.0), rel=1e-12)


def test_steep_downhill_beyond_the_brakes_is_reported():
    with pytest.raises(InfeasibleError, match="cannot brake"):
        supervision_curves(train(a_brake_emergency=0.3), NV, ([0.0], [-40.0]), eoa_position_m=5000.0)


# -------------------------------------------------------------------------------- supervision limits


def _hand_limits(v, *, a_e, a_s, t_be, t_bs, t_tco, a_est, v_ura, eoa, svl, tco=True):
    """Locations of EBI, SBI, W, P, I for an EoA/SvL on level track, from 3.13.9.3 written out."""
    t_traction = max(t_tco - (2.0 + t_bs), 0.0) if tco else t_tco
    t_berem = max(t_be - t_traction, 0.0)
    dv0, dv1, dv2 = v_ura, max(a_est, 0.0) * t_traction, min(max(a_est, 0.0), 0.4) * t_berem
    v_bec = max(v + dv0 + dv1, 0.0) + dv2
    d_bec = max(v + dv0 + dv1 / 2, 0.0) * t_traction + (max(v + dv0 + dv1, 0.0) + dv2 / 2) * t_berem
    d_ebi = (svl - v_bec**2 / (2 * a_e)) - d_bec
    d_sbi2 = d_ebi - v * t_bs
    d_sbi1 = (eoa - v**2 / (2 * a_s)) - v * t_bs
    t_ind = max(0.8 * t_bs, 5.0) + 4.0
    d_p = min(d_sbi1 - 4.0 * v, min(d_sbi2 - 4.0 * v, svl))
    return {
        "ebi": d_ebi,
        "sbi": min(d_sbi1, d_sbi2),
        "warning": min(d_sbi1, d_sbi2) - 2.0 * v,
        "permitted": d_p,
        "indication": d_p - t_ind * v,
    }


@pytest.mark.parametrize("tco", [True, False])
def test_supervision_limit_locations_against_hand_computation(tco):
    params = dict(
        a_e=1.0, a_s=0.8, t_be=3.0, t_bs=4.0, t_tco=7.0, a_est=0.3, v_ura=0.5, eoa=5000.0, svl=5100.0
    )
    t = train(
        t_traction_cut_off_s=7.0,
        speed_under_reading_mps=0.5,
        traction_cut_off_implemented=tco,
    )
    c = supervision_curves(
        t, NV, None, eoa_position_m=5000.0, svl_position_m=5100.0, estimated_acceleration_mps2=0.3
    )
    for v in (10.0, 25.0, 40.0, 55.0):
        expected = _hand_limits(v, tco=tco, **params)
        for kind, d in expected.items():
            assert c.limit_position_m(kind, v) == pytest.approx(d, abs=1e-9), (kind, v)
    assert c.times["t_traction"] == (1.0 if tco else 7.0)
    assert c.times["t_indication"] == 9.0


def test_sbi2_governs_when_the_overlap_is_short():
    # SvL 10 m beyond the EoA: the EBD-derived SBI2 comes before the SBD-derived SBI1
    c = supervision_curves(train(a_brake_service=1.0), NV, None, eoa_position_m=5000.0, svl_position_m=5010.0)
    v = 30.0
    d_sbi2 = 5010.0 - v**2 / 2 - v * 3.0 - v * 4.0  # T_traction = 0, T_berem = T_be = 3 s
    assert c.limit_position_m("sbi", v) == pytest.approx(d_sbi2, abs=1e-9)
    assert c.limit_position_m("sbi", v) < 5000.0 - v**2 / 2 - v * 4.0


def test_speed_limits_invert_the_locations_and_are_ordered():
    c = supervision_curves(
        train(speed_under_reading_ratio=0.01), NV, ([0.0, 2000.0], [3.0, -6.0]), 5000.0, 5150.0
    )
    v = np.linspace(5.0, 50.0, 37)
    d = {kind: c.limit_position_m(kind, v) for kind in ("ebi", "sbi", "warning", "permitted", "indication")}
    assert np.all(d["indication"] <= d["permitted"]) and np.all(d["permitted"] <= d["warning"])
    assert np.all(d["warning"] <= d["sbi"]) and np.all(d["sbi"] <= d["ebi"])
    for kind, where in d.items():
        back = getattr(c, kind)(where)
        check = (where < c.release_start_m) & (back < c.v_mrsp(where))
        assert np.max(np.abs(back[check] - v[check])) < 1e-9, kind
    s = np.linspace(0.0, c.release_start_m - 1.0, 301)
    ebi, sbi, w, p, i = (getattr(c, k)(s) for k in ("ebi", "sbi", "warning", "permitted", "indication"))
    assert np.all(i <= p) and np.all(p <= w) and np.all(w <= sbi) and np.all(sbi <= ebi)
    assert np.all(np.diff(p) <= 1e-12)  # non-increasing toward the EoA


def test_ceiling_limits_far_from_the_target():
    c = supervision_curves(train(), NV, None, 20000.0, mrsp=([0.0, 5000.0], [160 * KMH, 80 * KMH]))
    assert c.permitted(1000.0) == pytest.approx(160 * KMH)
    assert c.warning(1000.0) == pytest.approx((160 + 5) * KMH)  # above V_warning_max: dV_warning_max
    assert c.sbi(1000.0) == pytest.approx((160 + 5.5 + 4.5 * 0.5) * KMH)
    assert c.ebi(1000.0) == pytest.approx((160 + 7.5 + 7.5 * 0.5) * KMH)
    assert c.ebi(8000.0) == pytest.approx((80 + 7.5) * KMH)  # after the decrease: its ceiling
    # the decrease is a target: its EBD passes V_target + dV_ebi(V_target) at 5000 m (3.13.8.3.1)
    assert c.ebd(5000.0) == pytest.approx(87.5 * KMH, rel=1e-12)
    assert c.permitted(4999.0) == pytest.approx(80 * KMH)  # P does not go beyond the target
    assert c.permitted(4000.0) > 80 * KMH
    assert c.indication_point_m(70 * KMH) > 20000.0 - 600.0  # below the decrease's speed: only the EoA


def test_speed_decrease_target():
    c = supervision_curves(train(), NV, None, eoa_position_m=3000.0, target_speed_mps=80 * KMH)
    assert c.ebd(3000.0) == pytest.approx(87.5 * KMH, rel=1e-12)
    v_t = 80 * KMH
    # EBI for V: V_bec = V, D_bec = 3 V (T_traction = 0, T_berem = 3 s, no V_ura, A_est = 0)
    v = 40.0
    foot_ebd = 3000.0 + (87.5 * KMH) ** 2 / 2 - v**2 / 2
    assert c.limit_position_m("ebi", v) == pytest.approx(foot_ebd - 3 * v, abs=1e-9)
    assert c.permitted(5000.0) == pytest.approx(v_t)
    assert math.isinf(c.indication_point_m(v_t - 1.0))
    with pytest.raises(InputError, match="no SvL"):
        supervision_curves(train(), NV, None, 3000.0, svl_position_m=3100.0, target_speed_mps=10.0)


def test_guidance_curve_with_kn_and_in_the_permitted_speed():
    # 3.13.6.4.3: A_normal_service = A_bns + A_gradient - Kn+ grad/1000 uphill; GUI foot at the EoA
    t = train(a_brake_normal_service=0.5, kn_plus=0.5)
    nv = EtcsNationalValues(q_nvguiperm=True)
    c = supervision_curves(t, nv, ([0.0], [10.0]), eoa_position_m=5000.0)
    a = 0.5 + G * 10 / 1150 - 0.5 * 10 / 1000
    s = np.array([3000.0, 4500.0, 4999.0])
    assert np.allclose(c.guidance(s), np.sqrt(2 * a * (5000.0 - s)), rtol=1e-9, atol=0)
    v = 30.0
    assert c.limit_position_m("permitted", v) == pytest.approx(5000.0 - v**2 / (2 * a), abs=1e-9)
    off = supervision_curves(t, NV, ([0.0], [10.0]), eoa_position_m=5000.0)
    assert off.limit_position_m("permitted", v) > c.limit_position_m("permitted", v)


def test_conversion_model_uses_integrated_correction_factors():
    t = train(conversion_model_used=True, brake_position="freight_g", kdry_rst=0.5)
    c = supervision_curves(t, NV, None, eoa_position_m=2000.0)
    assert c.ebd(1000.0) == pytest.approx(math.sqrt(2 * 0.7 * 0.9 * 1.0 * 1000.0), rel=1e-12)
    assert c.times["t_be"] == pytest.approx(1.1 * 3.0)
    # 3.13.6.2.1.8.1: passenger sets interpolated between A_P12 and A_P23
    assert kv_int_passenger(0.9, 0.6, 0.8, 0.8, 1.0) == pytest.approx(0.7)
    assert kv_int_passenger(0.7, 0.6, 0.8, 0.8, 1.0) == pytest.approx(0.6)
    assert kv_int_passenger(1.2, 0.6, 0.8, 0.8, 1.0) == pytest.approx(0.8)


# ------------------------------------------------------------------------------------- release speed


def test_calculated_release_speed_and_its_monitoring():
    # 3.13.9.4.8.2 on level track, A = 1, no V_ura: V = V_EBD(EoA + V T) with T = T_traction_cut_off +
    # max(T_be - T_traction_cut_off, 0) = 3 s: V^2 = 2 (D - 3 V), V = -3 + sqrt(9 + 2 D)
    c = supervision_curves(train(), NV, None, eoa_position_m=5000.0, svl_position_m=5100.0)
    v_rel = -3.0 + math.sqrt(9.0 + 200.0)
    assert c.release_speed_mps == pytest.approx(v_rel, abs=1e-9)
    # start of release speed monitoring: the more restrictive of SBI1 and SBI2 for V_release
    d_sbi1 = 5000.0 - v_rel**2 / 1.6 - 4 * v_rel
    d_sbi2 = 5100.0 - v_rel**2 / 2 - 3 * v_rel - 4 * v_rel
    assert c.release_start_m == pytest.approx(min(d_sbi1, d_sbi2), abs=1e-9)
    s = np.array([c.release_start_m + 1.0, 4999.0])
    assert np.allclose(c.ebi(s), v_rel) and np.allclose(c.permitted(s), v_rel)
    assert c.ebi(5000.5) == 0.0 and c.permitted(5000.5) == 0.0  # trip location = EoA


def test_release_speed_variants():
    national = supervision_curves(train(), NV, None, 5000.0, 5100.0, release_speed="national")
    assert national.release_speed_mps == pytest.approx(40 * KMH)
    given = supervision_curves(train(), NV, None, 5000.0, 5100.0, release_speed=5.0)
    assert given.release_speed_mps == 5.0
    no_overlap = supervision_curves(train(), NV, None, 5000.0)
    assert no_overlap.release_speed_mps == 0.0 and no_overlap.release_start_m is None
    # 3.13.9.4.9: not above the MRSP near the EoA
    capped = supervision_curves(
        train(), NV, None, 5000.0, 5100.0, mrsp=([0.0, 4500.0], [100 * KMH, 30 * KMH])
    )
    assert capped.release_speed_mps == pytest.approx(30 * KMH)


def test_moving_block_ceiling_toward_the_rear_of_the_train_ahead():
    c = moving_block_ceiling(train(), NV, None, rear_of_train_ahead_m=2000.0, safety_margin_m=50.0)
    assert c.eoa_position_m == 1950.0 == c.svl_position_m and c.release_speed_mps == 0.0
    assert c.permitted(1950.0) == 0.0
    v = 20.0
    d_sbi2 = 1950.0 - v**2 / 2 - 3 * v - 4 * v
    d_sbi1 = 1950.0 - v**2 / 1.6 - 4 * v
    assert c.limit_position_m("permitted", v) == pytest.approx(min(d_sbi1, d_sbi2) - 4 * v, abs=1e-9)
    assert c.indication_point_m(v) == pytest.approx(min(d_sbi1, d_sbi2) - 4 * v - 9 * v, abs=1e-9)


def test_route_as_gradient_profile_and_mrsp():
    route = Route(
        name="r",
        start_m=0.0,
        end_m=6000.0,
        stations=(Station("A", 0.0), Station("B", 6000.0)),
        speed_limits=(SpeedLimit(0.0, 3000.0, 120 * KMH), SpeedLimit(3000.0, 6000.0, 60 * KMH)),
        gradients=(GradientSection(1000.0, 6000.0, -5.0),),
    )
    c = supervision_curves(train(), NV, route, 5500.0, mrsp=route)
    pair = supervision_curves(
        train(), NV, ([1000.0, 6000.0], [-5.0, 0.0]), 5500.0, mrsp=([0.0, 3000.0], [120 * KMH, 60 * KMH])
    )
    s = np.linspace(0.0, 5600.0, 57)
    for kind in ("ebd", "ebi", "permitted", "indication"):
        assert np.allclose(getattr(c, kind)(s), getattr(pair, kind)(s), rtol=1e-12, atol=1e-12)


# ------------------------------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"a_brake_emergency": -1.0}, "a_brake_emergency"),
        ({"kwet_rst": 1.5}, "kwet_rst"),
        ({"max_speed_mps": 0.0}, "max_speed_mps"),
        ({"t_brake_emergency_s": float("nan")}, "t_brake_emergency_s"),
        ({"brake_position": "fast"}, "brake_position"),
        ({"kdry_rst": {12: 0.9}}, "kdry_rst"),
    ],
)
def test_bad_train_data_is_an_input_error(changes, field):
    with pytest.raises(InputError) as info:
        train(**changes)
    assert info.value.field == field


def test_bad_step_functions_and_calls_are_input_errors():
    with pytest.raises(InputError, match="increasing"):
        StepFunction((1.0, 0.9, 0.8), (30.0, 20.0))
    with pytest.raises(InputError, match="one step limit fewer"):
        StepFunction((1.0, 0.9), ())
    with pytest.raises(InputError) as info:
        supervision_curves(train(), NV, None, 5000.0, svl_position_m=4000.0)
    assert info.value.field == "svl_position_m"
    with pytest.raises(InputError, match="gradient"):
        supervision_curves(train(), NV, ([0.0, 0.0], [1.0, 2.0]), 5000.0)
    with pytest.raises(InputError, match="gradient"):
        supervision_curves(train(), NV, "steep", 5000.0)
    with pytest.raises(InputError, match="release speed"):
        supervision_curves(train(), NV, None, 5000.0, release_speed="fast")
    with pytest.raises(InputError) as info:
        EtcsNationalValues(m_nvebcl=10)
    assert info.value.field == "m_nvebcl"
    with pytest.raises(InputError, match="safety margin"):
        moving_block_ceiling(train(), NV, None, 1000.0, -5.0)
    with pytest.raises(InputError, match="unknown supervision limit"):
        supervision_curves(train(), NV, None, 5000.0).limit_position_m("fast", 10.0)


def test_calculated_release_speed_honours_a_speed_decrease_before_the_svl():
    # 3.13.9.4.8: the EBI of a 20 km/h decrease at 5100 m (between the EoA and the SvL) also bounds it;
    # its EBD passes V_t + dV_ebi(V_t) = 27.5 km/h at 5100 m: V^2 = v1^2 + 2 (100 - 3 V)
    c = supervision_curves(train(), NV, None, 5000.0, 5200.0, mrsp=([0.0, 5100.0], [100 * KMH, 20 * KMH]))
    v1 = 27.5 * KMH
    expected = -3.0 + math.sqrt(9.0 + v1**2 + 200.0)
    assert c.release_speed_mps == pytest.approx(expected, abs=1e-9)
    alone = supervision_curves(train(), NV, None, 5000.0, 5200.0)
    assert alone.release_speed_mps == pytest.approx(-3.0 + math.sqrt(409.0), abs=1e-9)


def test_docs_example_runs_and_prints_what_the_docs_show(capsys):
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "ETCS.md").read_text(encoding="utf-8")
    blocks = text.split("```")
    code = next(b for b in blocks if b.startswith("python\n"))[len("python\n") :]
    shown = blocks[blocks.index(next(b for b in blocks if b.startswith("python\n"))) + 2].strip("\n")
    exec(compile(code, "docs/ETCS.md", "exec"), {})
    assert capsys.readouterr().out.strip("\n") == shown


def _fine_step_curve(a_of_v_s, s_target, v_target, s_query, ds=0.05):
    """Independent reference: march v^2 backwards from the target in steps of ds, the deceleration
    taken in the middle of each step (first order at the discontinuities)."""
    out = {}
    s, v2 = s_target, v_target**2
    for q in sorted(s_query, reverse=True):
        while s - ds > q:
            v2 += 2 * a_of_v_s(math.sqrt(v2), s - ds / 2) * ds
            s -= ds
        out[q] = math.sqrt(v2 + 2 * a_of_v_s(math.sqrt(v2), (s + q) / 2) * (s - q))
    return np.array([out[q] for q in s_query])


def test_ebd_and_guidance_against_a_fine_step_reference():
    sections = [(0.0, 0.0), (1500.0, -12.0), (2300.0, 6.0), (2600.0, -3.0), (3500.0, 0.0)]
    length = 350.0
    t = train(
        a_brake_emergency=StepFunction.from_kmh([60, 120], [1.2, 1.0, 0.85]),
        kdry_rst=StepFunction.from_kmh([60, 120], [0.9, 0.85, 0.8]),
        kwet_rst=0.9,
        a_brake_normal_service=0.6,
        kn_minus=StepFunction.from_kmh([80], [1.0, 2.0]),
        length_m=length,
    )
    nv = EtcsNationalValues(m_nvavadh=0.3)
    c = supervision_curves(t, nv, ([p for p, _ in sections], [g for _, g in sections]), 4000.0)

    def grad_under_train(s):  # lowest gradient between the rear and the front, by brute force
        starts = [p for p, _ in sections] + [math.inf]
        found = [0.0] if s - length < starts[0] else []
        for (p, g), nxt in zip(sections, starts[1:], strict=True):
            if p <= s and nxt > s - length:
                found.append(g)
        return min(found)

    def a_grad(g):
        return G * g / (1000 + 10 * (15 if g > 0 else 2))

    def a_safe(v, s):
        k = 0 if v <= 60 * KMH else (1 if v <= 120 * KMH else 2)
        a_e, kdry = (1.2, 1.0, 0.85)[k], (0.9, 0.85, 0.8)[k]
        return kdry * (0.9 + 0.3 * 0.1) * a_e + a_grad(grad_under_train(s))

    def a_normal(v, s):
        g = grad_under_train(s)
        kn = 0.0 if g >= 0 else (1.0 if v <= 80 * KMH else 2.0)
        return 0.6 + a_grad(g) - kn * g / 1000

    s = np.array([1200.0, 1900.0, 2450.0, 2800.0, 3300.0, 3900.0])
    assert np.allclose(c.ebd(s), _fine_step_curve(a_safe, 4000.0, 0.0, s), rtol=2e-5, atol=0)
    assert np.allclose(c.guidance(s), _fine_step_curve(a_normal, 4000.0, 0.0, s), rtol=2e-5, atol=0)


def test_limits_are_ordered_on_a_random_line():
    # invariants on a line with 60 gradient sections and 40 MRSP steps: no NaN, I <= P <= W <= SBI <= EBI,
    # P never above the MRSP, every limit 0 beyond the EoA's trip location
    rng = np.random.default_rng(17)
    mrsp_pos = np.concatenate([[0.0], np.cumsum(rng.uniform(200.0, 600.0, 39))])
    mrsp_v = rng.choice([60.0, 80.0, 100.0, 120.0, 160.0], 40) * KMH
    grad_pos = np.concatenate([[0.0], np.cumsum(rng.uniform(100.0, 500.0, 59))])
    grads = rng.uniform(-8.0, 8.0, 60)
    t = train(
        a_brake_emergency=StepFunction.from_kmh([100], [1.0, 0.9]),
        a_brake_service=0.7,
        length_m=400.0,
        max_speed_mps=160 * KMH,
        speed_under_reading_ratio=0.01,
    )
    eoa = float(mrsp_pos[-1]) + 300.0
    c = supervision_curves(
        t, NV, (grad_pos, grads), eoa, eoa + 120.0, mrsp=(mrsp_pos, mrsp_v), estimated_acceleration_mps2=0.2
    )
    s = np.linspace(0.0, eoa + 200.0, 4001)
    ebi, sbi, w, p, i = (getattr(c, k)(s) for k in ("ebi", "sbi", "warning", "permitted", "indication"))
    for limit in (ebi, sbi, w, p, i):
        assert not np.any(np.isnan(limit))
        assert np.all(limit[s >= eoa] == 0.0)
    tol = 1e-9
    assert (
        np.all(i <= p + tol) and np.all(p <= w + tol) and np.all(w <= sbi + tol) and np.all(sbi <= ebi + tol)
    )
    assert np.all(p <= c.v_mrsp(s) + tol)


# ------------------------------------------------------------------------- conversion model (lambda)


def test_conversion_v_lim_matches_an_independent_table():
    # V_lim = 16.85 lambda^0.428 km/h (A.3.7); an independent SPARK on-board tabulates it in cm/s,
    # rounded down: 2006 (lambda 30), 3359 (100), 4972 (250)
    for lam, cm_s in ((30, 2006), (100, 3359), (250, 4972)):
        assert math.floor(conversion_v_lim_mps(lam) * 100) == cm_s


def test_basic_deceleration_steps():
    def ad(n, lam):
        a0, a1, a2, a3 = CONVERSION_AD_COEFFICIENTS[n - 1]
        return a0 + a1 * lam + a2 * lam**2 + a3 * lam**3

    # lambda = 100: V_lim = 120.95 km/h, so AD_0 up to V_lim, then AD_3 (to 150), AD_4 (to 180), AD_5
    fn = basic_deceleration(100)
    assert fn.upper_limits == pytest.approx((16.85 * 100**0.428 * KMH, 150 * KMH, 180 * KMH))
    assert fn.values == pytest.approx((0.0075 * 100 + 0.076, ad(3, 100), ad(4, 100), ad(5, 100)))
    # lambda = 50: V_lim = 89.3 km/h, AD_1 up to 100 km/h
    fn = basic_deceleration(50)
    assert len(fn.values) == 6 and fn.values[1] == pytest.approx(ad(1, 50))
    assert fn.upper_limits[1] == pytest.approx(100 * KMH)
    assert ad(1, 50) == pytest.approx(0.0663 + 4.72e-3 * 50 + 6.1e-5 * 2500 - 6.3e-7 * 125000)


def test_conversion_build_up_times():
    # A.3.8 / A.3.9: a + b (L/100) + c (L/100)^2, L floored at 400 m where the clause says so
    assert conversion_build_up_time_s("emergency", "passenger_p", 300.0) == pytest.approx(2.3 + 0.17 * 16)
    assert conversion_build_up_time_s("service", "passenger_p", 300.0) == pytest.approx(3 + 1.5 * 3 + 0.1 * 9)
    assert conversion_build_up_time_s("emergency", "freight_g", 700.0) == pytest.approx(12 + 0.05 * 49)
    assert conversion_build_up_time_s("service", "freight_g", 300.0) == pytest.approx(3 + 2.77 * 4)
    assert conversion_build_up_time_s("emergency", "freight_p", 1200.0) == pytest.approx(
        -0.4 + 1.6 * 12 + 0.03 * 144
    )
    assert conversion_build_up_time_s("service", "freight_p", 1200.0) == pytest.approx(
        10.5 + 0.32 * 12 + 0.18 * 144
    )
    assert conversion_kto("freight_g") == 1.16 and conversion_kto("passenger_p") == 1.20


def test_lambda_train_curves():
    t = EtcsTrainData.from_brake_percentage(
        brake_percentage=120,
        brake_position="freight_p",
        length_m=600.0,
        max_speed_mps=100 * KMH,
        t_traction_cut_off_s=2.0,
    )
    assert t.conversion_model_used and t.a_brake_service == basic_deceleration(120)
    t_basic = 2.3 + 0.17 * 36
    c = supervision_curves(t, NV, None, eoa_position_m=3000.0)
    assert c.times["t_be"] == pytest.approx(1.1 * t_basic)  # Kt_int
    a0 = 0.7 * 0.9 * (0.0075 * 120 + 0.076)  # Kv_int Kr_int AD_0 below V_lim
    assert c.ebd(2950.0) == pytest.approx(math.sqrt(2 * a0 * 50.0), rel=1e-12)
    decrease = supervision_curves(t, NV, None, eoa_position_m=3000.0, target_speed_mps=40 * KMH)
    assert decrease.times["t_be"] == pytest.approx(1.1 * 1.2 * t_basic)  # kto for V_target > 0
    # a heavy service brake percentage is capped at 135 for A_brake_service
    heavy = EtcsTrainData.from_brake_percentage(180, "passenger_p", 200.0, 160 * KMH, 1.0)
    assert heavy.a_brake_service == basic_deceleration(135)


@pytest.mark.parametrize(
    ("args", "field"),
    [
        ((20, "freight_p", 500.0, 100 * KMH), "brake_percentage"),
        ((100, "passenger_p", 1000.0, 100 * KMH), "length_m"),
        ((100, "freight_g", 500.0, 220 * KMH), "max_speed_mps"),
        ((100, "express", 500.0, 100 * KMH), "brake_position"),
    ],
)
def test_conversion_model_outside_its_validity_is_an_input_error(args, field):
    with pytest.raises(InputError) as info:
        EtcsTrainData.from_brake_percentage(*args, t_traction_cut_off_s=1.0)
    assert info.value.field == field


def test_reduced_adhesion_limits_the_safe_deceleration():
    # 3.13.6.2.1.3: A_safe = MIN(A_brake_safe, A_MAXREDADH) + A_gradient where the adhesion is reduced
    strong = train(a_brake_emergency=1.2)
    everywhere = supervision_curves(strong, NV, None, 3000.0, reduced_adhesion=True)
    assert everywhere.ebd(2000.0) == pytest.approx(math.sqrt(2 * 0.7 * 1000.0), rel=1e-12)  # A_NVMAXREDADH2
    extra = train(a_brake_emergency=1.2, adhesion_independent_brake=True)
    assert supervision_curves(extra, NV, None, 3000.0, reduced_adhesion=True).ebd(2000.0) == pytest.approx(
        math.sqrt(2 * 1.0 * 1000.0), rel=1e-12
    )  # A_NVMAXREDADH1
    freight = train(a_brake_emergency=1.2, brake_position="freight_p")
    no_limit = EtcsNationalValues(a_nvmaxredadh3_mps2=None)
    assert supervision_curves(freight, no_limit, None, 3000.0, reduced_adhesion=True).ebd(
        2000.0
    ) == pytest.approx(math.sqrt(2 * 1.2 * 1000.0), rel=1e-12)
    # a trackside section 1000-2000 m acts up to 2000 m + the train length (3.13.5.3)
    t = train(a_brake_emergency=1.2, length_m=300.0)
    c = supervision_curves(t, NV, None, 3000.0, reduced_adhesion=[(1000.0, 2000.0)])
    v2_at_2300 = 2 * 1.2 * 700.0
    assert c.ebd(2300.0) == pytest.approx(math.sqrt(v2_at_2300), rel=1e-12)
    assert c.ebd(1500.0) == pytest.approx(math.sqrt(v2_at_2300 + 2 * 0.7 * 800.0), rel=1e-12)
    assert c.ebd(500.0) == pytest.approx(
        math.sqrt(v2_at_2300 + 2 * 0.7 * 1300.0 + 2 * 1.2 * 500.0), rel=1e-12
    )
    with pytest.raises(InputError, match="reduced adhesion"):
        supervision_curves(t, NV, None, 3000.0, reduced_adhesion=[(2000.0, 1000.0)])


def test_normal_service_model_chosen_by_the_service_deceleration_at_standstill():
    # 3.13.2.2.3.1.10: A_brake_service(0) = 0.8 lies between A_SB01 = 0.6 and A_SB12 = 0.9: model 1
    sets = (0.3, 0.45, 0.6)
    t = train(a_brake_normal_service_sets=sets, a_sb01_mps2=0.6, a_sb12_mps2=0.9)
    assert t.a_brake_normal_service == StepFunction.constant(0.45)
    assert train(
        a_brake_normal_service_sets=sets, a_sb01_mps2=0.8, a_sb12_mps2=0.9
    ).a_brake_normal_service.values == (0.3,)
    assert train(
        a_brake_normal_service_sets=sets, a_sb01_mps2=0.5, a_sb12_mps2=0.7
    ).a_brake_normal_service.values == (0.6,)
    c = supervision_curves(t, NV, None, 2000.0)
    assert c.guidance(1000.0) == pytest.approx(math.sqrt(2 * 0.45 * 1000.0), rel=1e-12)
    with pytest.raises(InputError) as info:
        train(a_brake_normal_service_sets=sets, a_sb01_mps2=0.6)
    assert info.value.field == "a_sb12_mps2"


def test_position_confidence_interval():
    c0 = supervision_curves(train(), NV, None, 5000.0, 5100.0, mrsp=([0.0, 3000.0], [160 * KMH, 80 * KMH]))
    c = supervision_curves(
        train(),
        NV,
        None,
        5000.0,
        5100.0,
        mrsp=([0.0, 3000.0], [160 * KMH, 80 * KMH]),
        position_confidence_m=20.0,
    )
    v = 20.0
    # EBD targets (the SvL) are supervised with the max safe front end, 20 m ahead of the estimated one
    assert c.limit_position_m("ebi", v) == pytest.approx(c0.limit_position_m("ebi", v) - 20.0, abs=1e-9)
    # the EoA with the estimated front end: SBI1 unchanged, so the SBI is the lower of the two
    d_sbi1 = 5000.0 - v**2 / 1.6 - 4 * v
    d_sbi2 = 5100.0 - v**2 / 2 - 3 * v - 4 * v - 20.0
    assert c.limit_position_m("sbi", v) == pytest.approx(min(d_sbi1, d_sbi2), abs=1e-9)
    # V_MRSP: the lowest speed between the min and max safe front ends
    assert c.v_mrsp(2985.0) == pytest.approx(80 * KMH) and c.v_mrsp(2975.0) == pytest.approx(160 * KMH)
    # release speed from d_tripEOA = EoA + 2 x 20 m: V^2 = 2 (60 - 3 V); trip when the min safe front
    # end passes the EoA
    assert c.release_speed_mps == pytest.approx(-3.0 + math.sqrt(9.0 + 120.0), abs=1e-9)
    assert c.ebi(5010.0) == pytest.approx(c.release_speed_mps) and c.ebi(5021.0) == 0.0
