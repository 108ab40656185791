"""The coupler law (slack, draft/buff asymmetry, solid stage, damping, stored energy) and the building of
the multi-point train from a single-point train (masses, resistance split, locomotives, brake delays)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from mpcases import freight_train

from trainsim.constants import TONNE
from trainsim.errors import InputError
from trainsim.model import Quadratic, ResistanceTerm
from trainsim.multipoint import (
    BrakePropagation,
    CouplerModel,
    Locomotive,
    MultiPointSettings,
    build_multipoint_train,
    split_resistance,
)
from trainsim.multipoint import kernel as mpk

COUPLER = CouplerModel(
    draft_stiffness_n_per_m=1.0e7,
    buff_stiffness_n_per_m=2.0e7,
    draft_damping_n_s_per_m=1.0e5,
    buff_damping_n_s_per_m=3.0e5,
    slack_m=0.02,
    draft_travel_m=0.08,
    buff_travel_m=0.05,
    solid_stiffness_n_per_m=2.0e8,
    smoothing_m=0.001,
    friction_ratio=0.0,  # the viscous law alone (the gears' friction: test_draft_gear.py)
)


def force(delta, rate=0.0, c=COUPLER):
    s, d, _, _ = mpk.coupler_force(delta, rate, c.as_row())
    return s + d


def test_no_force_inside_the_slack():
    for delta in (-0.0089, -0.005, 0.0, 0.004, 0.0089):
        assert force(delta, rate=0.3) == 0.0


def test_draft_and_buff_stiffness_beyond_the_slack():
    # beyond the rounding zone the law is linear with the draft / buff stiffness
    assert force(0.01 + 0.03) == pytest.approx(1.0e7 * 0.03, rel=1e-12)
    assert force(-0.01 - 0.03) == pytest.approx(-2.0e7 * 0.03, rel=1e-12)
    # solid beyond the travel: slope 2e8
    assert force(0.01 + 0.08 + 0.01) == pytest.approx(1.0e7 * 0.09 + 2.0e8 * 0.01 - 1.0e7 * 0.01, rel=1e-12)
    assert force(-0.01 - 0.05 - 0.01) == pytest.approx(-(2.0e7 * 0.06 + 1.8e8 * 0.01), rel=1e-12)


def test_damping_in_draft_and_buff_only_when_engaged():
    assert force(0.03, 0.1) - force(0.03, 0.0) == pytest.approx(1.0e5 * 0.1)
    assert force(-0.03, -0.1) - force(-0.03, 0.0) == pytest.approx(-3.0e5 * 0.1)
    assert force(0.0, 1.0) == 0.0


def test_force_is_continuous_and_its_slopes_match_finite_differences():
    deltas = np.linspace(-0.09, 0.12, 4001)
    f = np.array([force(d, 0.05) for d in deltas])
    assert np.max(np.abs(np.diff(f))) < 2.0e8 * (deltas[1] - deltas[0]) * 1.01 + 1e-9
    row = COUPLER.as_row()
    for delta in (-0.0605, -0.0101, -0.0095, 0.0, 0.0097, 0.0102, 0.02, 0.0905):
        for rate in (-0.2, 0.0, 0.3):
            _, _, k, c = mpk.coupler_force(delta, rate, row)
            e = 1e-7
            k_fd = (force(delta + e, rate) - force(delta - e, rate)) / (2 * e)
            c_fd = (force(delta, rate + e) - force(delta, rate - e)) / (2 * e)
            assert k == pytest.approx(k_fd, rel=1e-5, abs=1.0)
            assert c == pytest.approx(c_fd, rel=1e-6, abs=1e-3)


def test_stored_energy_is_the_integral_of_the_spring_force():
    row = COUPLER.as_row()
    deltas = np.linspace(-0.08, 0.11, 20001)
    spring = np.array([mpk.coupler_force(d, 0.0, row)[0] for d in deltas])
    energy = np.array([mpk.coupler_energy(d, row) for d in deltas])
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (spring[1:] + spring[:-1]) * np.diff(deltas))])
    zero = np.argmin(np.abs(deltas))
    assert np.allclose(energy - energy[zero], integral - integral[zero], rtol=1e-6, atol=1e-3)
    assert mpk.coupler_energy(0.0, row) == 0.0


@pytest.mark.parametrize(
    "field, value",
    [
        ("draft_stiffness_n_per_m", -1.0),
        ("slack_m", -0.01),
        ("draft_travel_m", 0.0),
        ("solid_stiffness_n_per_m", 1.0e6),  # below the gear stiffness
        ("smoothing_m", 0.01),  # not small against a 20 mm slack
    ],
)
def test_invalid_coupler_data_is_an_input_error(field, value):
    with pytest.raises(InputError) as err:
        dataclasses.replace(COUPLER, **{field: value})
    assert field in str(err.value)


# ------------------------------------------------------------------------------------ the train
def test_masses_lengths_and_inertia_add_up():
    train = freight_train(20, locos=2)
    mp = build_multipoint_train(train)
    assert mp.n_vehicles == 22
    assert mp.mass_kg.sum() == pytest.approx(train.mass_kg)
    assert mp.inertial_mass_kg.sum() == pytest.approx(train.inertial_mass_kg)
    assert mp.length_m.sum() == pytest.approx(train.length_m)
    assert mp.brake_share.sum() == pytest.approx(1.0)
    assert mp.regen_share.sum() == pytest.approx(1.0)


def test_resistance_terms_of_a_vehicle_type_go_to_its_vehicles():
    train = freight_train(10, locos=2, loco_t=120, wagon_t=80, a1_n_per_kg=0.01, a2_n_s2_per_kg_m2=0.0)
    laws, notes = split_resistance(train, train.vehicles)
    assert not notes
    assert laws[0].c0 == pytest.approx(120 * TONNE * 0.01)
    assert laws[5].c0 == pytest.approx(80 * TONNE * 0.01)
    total = train.resistance_law
    assert sum(q.c0 for q in laws) == pytest.approx(total.c0)


def test_whole_train_terms_are_split_by_mass():
    train = freight_train(4, locos=1, loco_t=100, wagon_t=50)
    train = dataclasses.replace(
        train, resistance=(ResistanceTerm("davis (whole train)", Quadratic(3000, 30, 6)),)
    )
    laws, notes = split_resistance(train, train.vehicles)
    assert notes and "by mass" in notes[0]
    assert laws[0].c2 == pytest.approx(6 * 100 / 300)
    assert laws[1].c0 == pytest.approx(3000 * 50 / 300)


def test_locomotive_positions_place_the_powered_vehicles():
    train = freight_train(20, locos=2)
    mp = build_multipoint_train(train, MultiPointSettings(locomotive_positions=(0, 11)))
    assert [v.powered for v in mp.vehicles].count(True) == 2
    assert mp.vehicles[0].powered and mp.vehicles[11].powered
    assert list(mp.locomotive_indices) == [0, 11]
    assert mp.regen_share[11] == pytest.approx(0.5)
    with pytest.raises(InputError, match="one position per powered vehicle"):
        build_multipoint_train(train, MultiPointSettings(locomotive_positions=(0,)))
    with pytest.raises(InputError, match="distinct"):
        build_multipoint_train(train, MultiPointSettings(locomotive_positions=(0, 0)))


def test_locomotive_shares_and_own_curves():
    train = freight_train(10, locos=2)
    mp = build_multipoint_train(
        train, MultiPointSettings(locomotives=(Locomotive(0, 0.7), Locomotive(1, 0.3)))
    )
    assert mp.traction_curves[0](5.0) == pytest.approx(0.7 * train.traction(5.0))
    with pytest.raises(InputError, match="add up to 1"):
        build_multipoint_train(
            train, MultiPointSettings(locomotives=(Locomotive(0, 0.7), Locomotive(1, 0.7)))
        )


def test_brake_delays_from_the_head_or_from_every_locomotive():
    train = freight_train(20, locos=2, loco_m=20.0, wagon_m=14.0)
    prop = BrakePropagation(speed_mps=250.0, source="head")
    head = build_multipoint_train(
        train, MultiPointSettings(brake_propagation=prop, locomotive_positions=(0, 11))
    )
    rear_centre = train.length_m - 7.0
    assert head.brake_delay_s[0] == 0.0
    assert head.brake_delay_s[-1] == pytest.approx((rear_centre - 10.0) / 250.0)
    dp = build_multipoint_train(
        train,
        MultiPointSettings(
            brake_propagation=dataclasses.replace(prop, source="locomotives"), locomotive_positions=(0, 11)
        ),
    )
    assert dp.brake_delay_s[11] == 0.0
    assert dp.brake_delay_s.max() < 0.6 * head.brake_delay_s.max()


def test_a_train_without_formation_or_power_is_refused():
    train = freight_train(5)
    with pytest.raises(InputError, match="formation"):
        build_multipoint_train(dataclasses.replace(train, vehicles=()))
    unpowered = tuple(dataclasses.replace(v, powered=False) for v in train.vehicles)
    with pytest.raises(InputError, match="which vehicles pull"):
        build_multipoint_train(dataclasses.replace(train, vehicles=unpowered))
