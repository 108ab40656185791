"""Coupler capacities: read from the ``multi_point`` block, checked against every step's forces, warned
with coupling, vehicle, force, time and place (issue 13, "Long trains and studies")."""

from __future__ import annotations

import numpy as np
import pytest

import trainsim
from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.io.multipoint_spec import multipoint_settings_from_dict
from trainsim.model import LineResistanceSettings, Route, SpeedLimit, Station
from trainsim.multipoint import BrakePropagation, CouplerModel, MultiPointSettings, run_multipoint_fastest
from trainsim.multipoint.model import FREIGHT_CAPACITY_N


def level(length_m: float = 5_000.0, limit_kmh: float = 100.0) -> Route:
    return Route(
        name="level",
        start_m=0.0,
        end_m=length_m,
        stations=(Station("A", 0.0), Station("B", length_m)),
        speed_limits=(SpeedLimit(0.0, length_m, limit_kmh * KMH),),
        line_resistance=LineResistanceSettings(curve_formula="none", tunnel_formula="none"),
    )


@pytest.fixture(scope="module")
def heavy_haul():
    return trainsim.load_train("examples/heavy_haul/train.yaml")


#: the couplers of the issue's case: viscous dampers only (the model before the friction draft gears),
#: which let the rear run into the braked front hardest
VISCOUS = {
    "draft_stiffness_n_per_m": 1.4e7,
    "buff_stiffness_n_per_m": 1.4e7,
    "draft_damping_n_s_per_m": 3.7e5,
    "buff_damping_n_s_per_m": 3.7e5,
    "friction_ratio": 0.0,
}


def settings(speed_mps: float | None, **couplers) -> MultiPointSettings:
    return MultiPointSettings(
        couplers=CouplerModel(slack_m=0.025, **{**VISCOUS, **couplers}),
        locomotive_positions=(0, 1),
        traction_ramp_s=20,
        brake_propagation=BrakePropagation(speed_mps, "head", 3.0),
    )


@pytest.fixture(scope="module")
def slow_brakes(heavy_haul):
    """The heavy-haul train (10,700 t, 106 vehicles, all power at the head) braking from 100 km/h to a
    stop with the brake command travelling at 100 m/s: the rear runs into the braked front (viscous
    couplers, as in the issue)."""
    return run_multipoint_fastest(heavy_haul, level(), settings(100.0))


def test_default_capacity_is_the_documented_draft_gear_impedance():
    assert FREIGHT_CAPACITY_N == 2.27e6
    c = CouplerModel()
    assert c.draft_capacity_n == c.buff_capacity_n == 2.27e6
    assert CouplerModel.stiff().buff_capacity_n is None  # an idealised coupling has no rating


def test_buff_force_beyond_the_capacity_is_warned_with_coupling_time_and_place(slow_brakes):
    r = slow_brakes
    # regression: the case gave 3.57 MN buff, well past the 2.27 MN, without a word
    assert r.max_buff.force_n < -3.0e6
    over = r.capacity_exceedances
    assert over and all(e.mode in ("draft", "buff") for e in over)
    worst = over[0]
    # the worst is the train's largest buff force, at the same coupling, time and place
    assert worst.mode == "buff"
    assert worst.force_n == pytest.approx(r.max_buff.force_n, rel=1e-12)
    assert worst.coupler == r.max_buff.coupler and worst.time_s == pytest.approx(r.max_buff.time_s)
    assert worst.coupler_position_m == pytest.approx(r.max_buff.coupler_position_m)
    assert worst.behind_vehicle == r.vehicle_names[worst.coupler]
    text = [w for w in r.warnings if w.startswith("buff force above the coupler capacity")]
    assert len(text) == 1
    buff_over = [e for e in over if e.mode == "buff"]
    for part in (
        f"{abs(worst.force_n) / 1e6:.2f} MN at coupling {worst.coupler}",
        f"'{worst.behind_vehicle}'",
        f"t = {worst.time_s:.1f} s",
        f"coupling at {worst.coupler_position_m:.0f} m",
        "capacity 2.27 MN",
        f"and {len(buff_over) - 1} other couplings",
    ):
        assert part in text[0], (part, text[0])
    # every listed coupling really passed its capacity; the unlisted ones did not
    listed = {e.coupler for e in buff_over}
    nc = r.mptrain.n_vehicles - 1
    peaks = -np.min(r.coupler_force_n, axis=0)
    for k in range(nc):
        if peaks[k] > FREIGHT_CAPACITY_N:  # the recorded samples are a subset of the steps
            assert k in listed
    # the JSON summary carries them, status stays ok (documented: a finding of the run, not a failure)
    s = r.summary()
    assert s["status"] == "ok"
    assert s["multi_point"]["capacity_exceedances"][0]["force_kn"] == pytest.approx(worst.force_n / 1e3)
    assert s["multi_point"]["capacity_exceedances"][0]["capacity_kn"] == pytest.approx(2270.0)


def test_per_coupling_peaks_bound_the_recorded_forces(slow_brakes):
    """The kernel's per-coupling extremes are taken at every step: they bound every recorded force and
    their maximum is the train's extreme."""
    r = slow_brakes
    nc = r.mptrain.n_vehicles - 1
    per_buff = {e.coupler: e.force_n for e in r.capacity_exceedances if e.mode == "buff"}
    recorded_min = np.min(r.coupler_force_n, axis=0)
    for k, f in per_buff.items():
        assert f <= recorded_min[k] + 1e-6
    assert min(per_buff.values()) == pytest.approx(r.max_buff.force_n)
    assert len(recorded_min) == nc


def test_friction_draft_gears_keep_the_same_case_below_the_capacity(heavy_haul):
    # the default couplers (friction draft gears) absorb the run-in: no capacity warning
    r = run_multipoint_fastest(
        heavy_haul,
        level(),
        MultiPointSettings(
            couplers=CouplerModel(slack_m=0.025),
            locomotive_positions=(0, 1),
            traction_ramp_s=20,
            brake_propagation=BrakePropagation(100.0, "head", 3.0),
        ),
    )
    assert r.status == "ok" and not r.capacity_exceedances
    assert -FREIGHT_CAPACITY_N < r.max_buff.force_n < -1.0e6


def test_no_warning_below_the_capacity_or_without_one(heavy_haul, slow_brakes):
    # instantaneous brakes: the train stays below 2.27 MN
    quick = run_multipoint_fastest(heavy_haul, level(), settings(None))
    assert quick.max_buff.force_n > -FREIGHT_CAPACITY_N and quick.max_draft.force_n < FREIGHT_CAPACITY_N
    assert not quick.capacity_exceedances
    assert not any("capacity" in w for w in quick.warnings)
    # the same slow brakes with stronger gears (5 MN) or no rating: no capacity warning, same motion
    for caps in ({"buff_capacity_n": 5e6}, {"buff_capacity_n": None}):
        r = run_multipoint_fastest(heavy_haul, level(), settings(100.0, **caps))
        assert not [e for e in r.capacity_exceedances if e.mode == "buff"]
        assert r.max_buff.force_n == slow_brakes.max_buff.force_n


def test_capacities_in_the_multi_point_block():
    spec = multipoint_settings_from_dict(
        {
            "couplers": {"draft_capacity_kn": 2500, "buff_capacity_kn": 2000},
            "coupler_overrides": [{"coupler": 0, "buff_capacity_kn": None}, {"coupler": 1, "slack_m": 0}],
        }
    )
    s = spec.build()
    assert s.couplers.draft_capacity_n == 2.5e6 and s.couplers.buff_capacity_n == 2.0e6
    assert s.coupler_overrides[0].buff_capacity_n is None
    assert s.coupler_overrides[0].draft_capacity_n == 2.5e6  # from the couplers block
    assert s.coupler_overrides[1].buff_capacity_n == 2.0e6
    default = multipoint_settings_from_dict({}).build()
    assert default.couplers.buff_capacity_n == FREIGHT_CAPACITY_N


@pytest.mark.parametrize("value", [0, -5, "lots", 1e9, True])
def test_a_bad_capacity_is_an_input_error_naming_the_field(value):
    with pytest.raises(InputError) as err:
        multipoint_settings_from_dict({"couplers": {"buff_capacity_kn": value}}, "s.yaml")
    assert "multi_point.couplers.buff_capacity_kn" in str(err.value)
