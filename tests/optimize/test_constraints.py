"""Driving constraints: comfort acceleration and deceleration, a margin below the speed limits (every
strategy), and the kinematic acceleration and jerk limits of the reference."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.model import (
    Braking,
    EffortCurve,
    Electrical,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
)
from trainsim.model.timetable import SectionSchedule, Timetable
from trainsim.optimize.api import optimize
from trainsim.optimize.constraints import (
    DrivingConstraints,
    constrained_route,
    constrained_train,
    kinematic_limits,
)


def train() -> Train:
    traction = EffortCurve.power_limited(3.0e6, force_cap_n=250e3)
    return Train(
        name="constraint test train",
        mass_kg=300e3,
        rotating_mass_factor=1.08,
        length_m=100.0,
        max_speed_mps=160 * KMH,
        traction=traction,
        braking=Braking(service_force=EffortCurve.constant(300e3), regenerative=traction.scaled(0.8)),
        resistance=(ResistanceTerm("Davis", Quadratic(4000.0, 60.0, 8.0)),),
        electrical=Electrical(line_voltage_v=3000.0, traction_efficiency=0.9, regenerative_efficiency=0.8),
    )


def line(length: float = 5000.0) -> Route:
    return Route(
        name="level",
        start_m=0.0,
        end_m=length,
        stations=(Station("A", 0.0), Station("B", length)),
        speed_limits=(SpeedLimit(0.0, length, 120 * KMH),),
    )


def test_constraints_are_validated():
    with pytest.raises(InputError):
        DrivingConstraints(max_acceleration_mps2=0.0)
    with pytest.raises(InputError):
        DrivingConstraints(speed_margin_mps=float("nan"))
    with pytest.raises(InputError, match="margin"):
        constrained_route(line(), DrivingConstraints(speed_margin_mps=20.0))


def test_comfort_limits_and_speed_margin_hold_on_the_optimal_run():
    t, r = train(), line()
    dc = DrivingConstraints(max_acceleration_mps2=0.4, max_deceleration_mps2=0.5, speed_margin_mps=5 * KMH)
    ct = constrained_train(t, dc)
    assert ct.traction(0.0) == pytest.approx(0.4 * t.inertial_mass_kg)
    assert ct.braking.service_force(10.0) == pytest.approx(0.5 * t.inertial_mass_kg)
    free = optimize(t, r, Timetable(sections=(SectionSchedule(supplement_fraction=0.2),)))
    # the same running time for both (a supplement would be on the slower constrained fastest run)
    tt = Timetable(sections=(SectionSchedule(running_time_s=free.scheduled_running_time_s[0]),))
    res = optimize(t, r, tt, constraints=dc)
    tr = res.run.trace
    assert tr.speed_mps.max() <= 115 * KMH + 1e-6
    # traction capped at rho m a_max: on level track the resistance only lowers the acceleration
    assert kinematic_limits(tr.position_m, tr.speed_mps, DrivingConstraints(max_acceleration_mps2=0.4)) == []
    # braking capped at rho m d_max: the resistance adds at most R(v_max) / (rho m)
    extra = t.resistance_law(120 * KMH) / t.inertial_mass_kg
    assert (
        kinematic_limits(tr.position_m, tr.speed_mps, DrivingConstraints(max_deceleration_mps2=0.5 + extra))
        == []
    )
    assert abs(res.schedule_deviation_s[0]) <= 0.5
    assert res.run.energy_kwh.net >= free.run.energy_kwh.net - 1e-6  # constraints cost energy


@pytest.mark.slow
def test_reference_bounds_kinematic_acceleration_and_jerk():
    pytest.importorskip("casadi")
    from trainsim.optimize.reference import solve_reference

    t, r = train(), line(3000.0)
    dc = DrivingConstraints(max_acceleration_mps2=0.5, max_deceleration_mps2=0.6, max_jerk_mps3=0.3)
    tt = Timetable(sections=(SectionSchedule(supplement_fraction=0.2),))
    T = optimize(t, r, tt).scheduled_running_time_s[0]
    free = solve_reference(t, r, 0.0, 3000.0, T, intervals=300)
    ref = solve_reference(t, r, 0.0, 3000.0, T, intervals=300, constraints=dc)
    assert ref.status == "ok", ref.status
    h = np.diff(ref.s)
    acc = (ref.v[1:] ** 2 - ref.v[:-1] ** 2) / (2 * h)
    assert acc.max() <= 0.5 + 1e-6 and acc.min() >= -0.6 - 1e-6
    dt = np.diff(ref.time_s)
    jerk = np.diff(acc) / (0.5 * (dt[:-1] + dt[1:]))
    assert np.abs(jerk).max() <= 0.3 + 1e-6
    assert ref.energy_j >= free.energy_j
