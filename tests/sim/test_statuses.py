"""Statuses that tell the truth for impossible physics (issue 13): each case with its status, its
message and its best feasible result."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.sim.result import STATUSES

DATA = Path(__file__).resolve().parents[1] / "data" / "trainruns"


def test_every_run_ends_at_standstill_at_its_stop_with_the_strip_model_and_a_fine_step():
    """The strip mass model on TrainRuns.jl's freight x realworld with 1.25 m steps ended 20 mm short
    of the final stop at 0.09 m/s with status ok: a stretch starting and ending at a kink speed was
    counted as -1 kinks, so the kink insertion wrote past its arrays and lost the last points."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = trainsim.load_train(DATA / "trains" / "freight.yaml")
        route = trainsim.load_route(DATA / "paths" / "realworld.yaml", mass_model="homogeneous_strip")
    r = trainsim.run_fastest(train, route, trainsim.RunSettings(max_step_m=1.25))
    assert r.status == "ok", r.warnings
    assert r.trace.position_m[-1] == route.stops[-1].position_m
    assert r.trace.speed_mps[-1] == 0.0
    assert abs(r.energy_balance["relative_error"]) < 1e-6


def test_a_run_that_does_not_end_at_its_stop_says_so():
    """The check behind every result: a trace that ends short of the last stop, or moving, is not ok."""
    from trainsim.sim.profile import line_resistance_profile, speed_ceiling
    from trainsim.sim.result import build_result

    train, route = make_train(), make_route(length_m=1000.0)
    s = np.array([0.0, 500.0, 999.9])
    v = np.array([0.0, 10.0, 0.5])
    r = build_result(
        train=train,
        route=route,
        settings=trainsim.RunSettings(),
        profile=line_resistance_profile(route, train),
        ceiling=speed_ceiling(route, train),
        s=s,
        v=v,
        t=np.array([0.0, 100.0, 120.0]),
        regime=np.array([0, 3, 4], dtype=np.int8),
        status="ok",
    )
    assert r.status == "did_not_reach_stop"
    assert "0.100 m short of B" in r.warnings[-1] and "1.800 km/h" in r.warnings[-1]
    assert r.status in STATUSES


def test_statuses_are_a_documented_vocabulary():
    assert {"ok", "stalled", "brake_limited", "did_not_reach_stop"} <= set(STATUSES)
    assert all(isinstance(text, str) and text for text in STATUSES.values())


def test_stall_on_a_grade_gives_the_best_feasible_run():
    train = make_train(traction_n=100e3, mass_kg=300e3)
    route = make_route(length_m=5000.0, gradient_permille=40.0)  # 118 kN of grade > 100 kN
    r = trainsim.run_fastest(train, route)
    assert r.status == "stalled"
    assert "stalls at 0.0 m" in r.warnings[0] and "100.0 kN" in r.warnings[0] and "117.7 kN" in r.warnings[0]
    assert r.trace.speed_mps[-1] == 0.0


def test_zero_speed_limit_is_refused_by_the_route():
    with pytest.raises(trainsim.InputError):
        make_route(limit_kmh=0.0)


def _metro():
    import dataclasses

    from trainsim.model import Braking, EffortCurve, GradientSection

    sc = trainsim.load_scenario(Path(__file__).resolve().parents[2] / "examples/metro_b/scenario.yaml")
    weak = dataclasses.replace(sc.train, braking=Braking(service_force=EffortCurve.constant(20e3)))
    return sc, weak, dataclasses, GradientSection


def test_metro_with_20_kn_of_brakes_on_a_40_permille_descent_is_brake_limited():
    """Gravity pulls 113 kN on the 288 t metro; its 20 kN of brakes cannot hold it. The run used to
    'move' at 0.0 km/h for thousands of seconds with status ok; now it stops before the descent and
    says where and by how much."""
    sc, weak, dataclasses, GradientSection = _metro()
    route = dataclasses.replace(sc.route, gradients=(GradientSection(1000.0, 3000.0, -40.0),))
    r = trainsim.run_fastest(weak, route, sc.settings)
    assert r.status == "brake_limited"
    msg = r.warnings[0]
    assert "cannot hold the train" in msg and "from 1000.0 m" in msg and "-40.0 per mille" in msg
    assert "20.0 kN" in msg and "by 90.6 kN" in msg
    assert any("implausible brakes" in w for w in r.warnings)
    # the best feasible run: to a standstill at the start of the descent
    assert r.trace.position_m[-1] == pytest.approx(1000.0) and r.trace.speed_mps[-1] == 0.0
    assert r.max_speed_kmh > 30.0 and r.sections[-1].to_station == "(brake-limited at 1000 m)"
    assert abs(r.energy_balance["relative_error"]) < 1e-6
    assert r.summary()["status"] == "brake_limited"
    # on a descent everywhere it cannot even stand: the result stays at the first stop
    everywhere = dataclasses.replace(sc.route, gradients=(GradientSection(0.0, sc.route.end_m, -40.0),))
    r = trainsim.run_fastest(weak, everywhere, sc.settings)
    assert r.status == "brake_limited" and "at standstill from 0.0 m" in r.warnings[0]
    assert r.distance_m == 0.0 and r.running_time_s == 0.0


def test_a_traction_table_of_zeros_stalls_and_says_why():
    import dataclasses

    from trainsim.model import EffortCurve, Electrical

    train = make_train(traction=EffortCurve.from_table([0.0, 10.0, 20.0], [0.0, 0.0, 0.0]))
    train = dataclasses.replace(train, electrical=Electrical(line_voltage_v=1500.0))
    r = trainsim.run_fastest(train, make_route(length_m=5000.0))
    assert r.status == "stalled"
    assert "no tractive effort at any speed" in r.warnings[0] and "not electrified" not in r.warnings[0]


@pytest.mark.parametrize("efficiency", [1e-308, 1e-12])
def test_a_powerless_train_stalls_at_standstill(efficiency):
    """Power-limited traction with an absurd efficiency: the power cap eta P / v is below the
    resistance at any speed it could reach; it used to creep on the force cap of the first step."""
    from trainsim.model import EffortCurve, Quadratic

    traction = EffortCurve.power_limited(1e6, 200e3, efficiency=efficiency)
    train = make_train(traction=traction, resistance=Quadratic(3000.0, 30.0, 5.0))
    r = trainsim.run_fastest(train, make_route(length_m=5000.0))
    assert r.status == "stalled"
    assert "0.0 kN, is below the 3.0 kN" in r.warnings[0]
    assert not any("internal consistency" in w for w in r.warnings)


def test_a_weak_power_creeps_with_a_plausibility_warning():
    """eta = 0.001 of 1 MW is 1 kW at the wheel: against 3 kN the train creeps at about 0.33 m/s, a
    real (if absurd) run: status ok, with a warning, and no consistency failure."""
    from trainsim.model import EffortCurve, Quadratic

    traction = EffortCurve.power_limited(1e6, 200e3, efficiency=0.001)
    train = make_train(traction=traction, resistance=Quadratic(3000.0, 30.0, 5.0))
    r = trainsim.run_fastest(train, make_route(length_m=5000.0))
    assert r.status == "ok"
    assert any(w.startswith("implausibly slow run: A - B averages 1.19 km/h") for w in r.warnings)
    assert r.running_time_s == pytest.approx(15071, rel=1e-3)


def test_a_train_without_brakes_and_a_creeping_limit_get_plausibility_warnings():
    from trainsim.model import Braking, EffortCurve, Quadratic

    no_brakes = make_train(
        braking=Braking(service_force=EffortCurve.constant(0.0)), resistance=Quadratic(3e3)
    )
    r = trainsim.run_fastest(no_brakes, make_route(length_m=3000.0))
    assert any("implausible brakes" in w and "0 m/s^2" in w for w in r.warnings)
    r = trainsim.run_fastest(make_train(), make_route(length_m=500.0, limit_kmh=0.001))
    assert any("implausible speed limit: 0.001 km/h" in w for w in r.warnings)
    assert any("implausibly slow run" in w for w in r.warnings)


def test_an_implausible_efficiency_gets_a_plausibility_warning():
    """Traction efficiency 0.001 gave a net energy of 80,773 kWh and 4.9 MA on the metro example with
    status ok and no warning (issue 13)."""
    from dataclasses import replace

    from trainsim.model import Electrical

    base = make_train()
    r = trainsim.run_fastest(
        replace(base, electrical=Electrical(line_voltage_v=1500.0)), make_route(length_m=3000.0)
    )
    assert not any("efficiency" in w for w in r.warnings)
    weak = replace(base, electrical=Electrical(line_voltage_v=1500.0, traction_efficiency=0.001))
    r = trainsim.run_fastest(weak, make_route(length_m=3000.0))
    assert any(w.startswith("implausible traction efficiency: 0.001") for w in r.warnings)
    # 0.5 is the threshold; a regenerative efficiency of 0 (no regeneration) is plausible
    edge = Electrical(line_voltage_v=1500.0, traction_efficiency=0.5, regenerative_efficiency=0.0)
    r = trainsim.run_fastest(replace(base, electrical=edge), make_route(length_m=3000.0))
    assert not any("efficiency" in w for w in r.warnings), r.warnings
    low_pf = Electrical(line_voltage_v=1500.0, power_factor=0.3)
    r = trainsim.run_fastest(replace(base, electrical=low_pf), make_route(length_m=3000.0))
    assert any(w.startswith("implausible power factor: 0.3 (usual: 0.6 to 1)") for w in r.warnings)


def test_an_overflowing_efficiency_is_a_status_not_a_null_figure_with_ok():
    """Traction efficiency 1e-308 gave an infinite net energy (null in JSON), numpy's overflow warning
    on stderr and status ok (issue 13). Readers refuse it; through the API the run says not_finite,
    names the figure and emits no numpy warning. A power factor of 1e-308 overflows the current alone."""
    import warnings as pywarnings
    from dataclasses import replace

    from trainsim.model import Electrical

    base, route = make_train(), make_route(length_m=3000.0)
    for kwargs, figure in (
        ({"traction_efficiency": 1e-308}, "the net energy"),
        ({"power_factor": 1e-308}, "the peak current"),
    ):
        train = replace(base, electrical=Electrical(line_voltage_v=1500.0, **kwargs))
        for trace in (True, False):
            with pywarnings.catch_warnings():
                pywarnings.simplefilter("error")  # numpy's RuntimeWarning must not be the only sign
                r = trainsim.run_fastest(train, route, trace=trace)
            assert r.status == "not_finite" and r.status in STATUSES
            assert any(figure in w and "not finite" in w for w in r.warnings), r.warnings
            assert r.summary()["status"] == "not_finite"
    # the same train with a plausible efficiency is ok: the check is not a blanket refusal
    r = trainsim.run_fastest(replace(base, electrical=Electrical(line_voltage_v=1500.0)), route)
    assert r.status == "ok" and np.isfinite(r.energy_kwh.net) and np.isfinite(r.peak_current_a)


def test_a_train_without_electrics_has_no_current_and_is_still_ok():
    """No electrical data: the peak current is NaN by design ("none"), not an overflow."""
    r = trainsim.run_fastest(make_train(), make_route(length_m=3000.0))
    assert make_train().electrical is None and np.isnan(r.peak_current_a)
    assert r.status == "ok", r.warnings


def test_an_absurd_dwell_is_refused_with_the_allowed_range():
    with pytest.raises(trainsim.InputError) as err:
        make_route(stations=[("A", 0.0, 0.0), ("B", 5000.0, 1e308), ("C", 10000.0, 0.0)])
    assert "stations.dwell" in str(err.value.field) and "<= 1e+06 s" in str(err.value.allowed)
