"""The multi-point model's braking at a command against the single-point model's braking forces."""

from __future__ import annotations

import numpy as np
import pytest
from mpcases import freight_train, level_route

from trainsim.model.scenario import RunSettings
from trainsim.multipoint import MultiPointSettings, SpeedProfile, build_multipoint_train, follow_profile
from trainsim.multipoint import kernel as mpk
from trainsim.multipoint.simulate import _Compiled
from trainsim.sim.codes import BRAKE, CRUISE, DWELL, REGEN, TRACTION

KMH = 1 / 3.6


@pytest.fixture(scope="module")
def compiled():
    # source 004's train: electric brake 0.8 x traction (640 kN up to 45 km/h), service brake 486 kN
    train = freight_train(15, locos=2, regen_fraction=0.8, electrical=True)
    mp = build_multipoint_train(train, MultiPointSettings())
    return _Compiled(mp, level_route(), RunSettings(braking_fraction=0.9))


def braking_forces(c, v_mps, command, regime):
    """(electric, friction) braking of the whole train [N], every vehicle at v_mps, the command in
    force at every brake (no delay), blended as the controller and the session blend."""
    n = c.mp.n_vehicles
    xm = 10_000.0 - np.concatenate([[0.0], np.cumsum(c.mp.length_m[:-1])])
    w = np.full(n, v_mps)
    cmd = np.array([-command, 1.0, command, regime], dtype=float)
    level = np.full(n, -command)
    parts = np.zeros((n, 7))
    mpk.vehicle_forces(
        xm, w, w.copy(), c.VP, c.SP, cmd, np.zeros(n), level, level, c.bank, c.prof, c.avail,
        np.zeros(n, dtype=np.int64), np.empty(n), np.empty(n), True, parts,
    )  # fmt: skip
    return parts[:, 1].sum(), parts[:, 2].sum()


@pytest.mark.parametrize("speed_kmh", [15.0, 30.0, 45.0, 70.0, 90.0])
def test_regenerative_regime_brakes_with_the_electric_brake_curve_as_the_single_point_model(
    compiled, speed_kmh
):
    # single-point REGEN: the regenerative curve alone, whatever the service brake (sim.kernel); here
    # from the train's own curves, 0.8 x min(800 kN, 10 MW / v) against 0.9 x 486 kN
    v = speed_kmh * KMH
    regen = 0.8 * min(800e3, 10e6 / v)
    assert float(compiled.mp.train.braking.regenerative(v)) == pytest.approx(regen)
    service = 0.9 * 0.45 * 0.75 * compiled.mp.train.mass_kg
    # the controller's full-regenerative-braking command in this regime
    full = -min(1.0, regen / max(service, regen))
    electric, friction = braking_forces(compiled, v, full, REGEN)
    assert electric == pytest.approx(regen, rel=1e-9)
    assert friction == pytest.approx(0.0, abs=1e-6)
    # the strongest command never exceeds what the train's brakes allow: the larger of the two
    electric, friction = braking_forces(compiled, v, -1.0, REGEN)
    assert electric + friction == pytest.approx(max(service, regen), rel=1e-9)
    assert electric <= regen * (1 + 1e-12) and friction <= service * (1 + 1e-12)


@pytest.mark.parametrize("speed_kmh", [15.0, 45.0, 90.0])
@pytest.mark.parametrize("command", [-1.0, -0.4])
def test_service_braking_is_the_service_curve_blended_as_the_single_point_model(compiled, speed_kmh, command):
    # single-point BRAKE (and DrivingSession): that share of the service curve, the electric brake
    # supplying what it can
    v = speed_kmh * KMH
    regen = 0.8 * min(800e3, 10e6 / v)
    demand = -command * 0.9 * 0.45 * 0.75 * compiled.mp.train.mass_kg
    electric, friction = braking_forces(compiled, v, command, BRAKE)
    assert electric + friction == pytest.approx(demand, rel=1e-9)
    assert electric == pytest.approx(min(demand, regen), rel=1e-9)


def _reference_with_regenerative_braking(train, stop_m):
    """Source 004's driving to a stop, integrated here from the train's data alone: full traction
    to 40 km/h, cruising, then the electric brake's curve (REGEN, 640 kN at these speeds, stronger
    than the 486 kN service brake) down to V_mech = 10 km/h, then the service brake to rest."""
    m = train.mass_kg
    inertial = train.rotating_mass_factor * m
    s = np.linspace(0.0, stop_m, 6001)
    ds = s[1] - s[0]

    def resistance(v):
        return m * (0.012 + 2.6e-5 * v * v)

    def integrate(force, start_v, backwards):
        # v^2 / 2 over position by the midpoint rule, 0.25 m steps (far finer than the stop window)
        e = np.empty_like(s)
        e[0] = 0.5 * start_v**2
        for k in range(len(s) - 1):
            v = np.sqrt(2 * e[k])
            a_half = force(v) / inertial
            vm = np.sqrt(max(2 * (e[k] + 0.5 * ds * a_half), 0.0))
            e[k + 1] = max(e[k] + ds * force(vm) / inertial, 0.0)
        return np.sqrt(2 * e)[::-1] if backwards else np.sqrt(2 * e)

    v_cruise, v_mech = 40 * KMH, 10 * KMH
    traction = integrate(lambda v: min(800e3, 10e6 / max(v, 1e-3)) - resistance(v), 0.0, False)
    service = 0.45 * 0.75 * m

    def braking_backwards(v):
        brake = service if v < v_mech else 0.8 * min(800e3, 10e6 / max(v, 1e-3))
        return brake + resistance(v)

    braking = integrate(braking_backwards, 0.0, True)
    v = np.minimum(np.minimum(traction, v_cruise), braking)
    regime = np.where(
        braking <= np.minimum(traction, v_cruise),
        np.where(braking > v_mech, REGEN, BRAKE),
        np.where(traction < v_cruise, TRACTION, CRUISE),
    ).astype(np.int8)
    regime[-1] = DWELL
    return SpeedProfile(s, v, regime), service


def test_follower_of_a_regenerative_braking_run_stops_at_the_stop():
    # with the command topping out at the service brake the follower ran past this stop at 18 km/h
    train = freight_train(15, locos=2, regen_fraction=0.8, electrical=True)
    route = level_route(1_500.0, limit_kmh=60.0)
    profile, service = _reference_with_regenerative_braking(train, 1_500.0)
    regen = profile.regime == REGEN
    assert service < 0.8 * 800e3 and np.ptp(profile.position_m[regen]) > 100.0
    result = follow_profile(train, route, profile, MultiPointSettings())
    assert result.status == "ok", result.warnings
    assert result.run.trace.position_m[-1] == pytest.approx(1_500.0, abs=2.0)
    # the electric brake did the braking above V_mech: its work is about the 640 kN over that stretch
    # (the rest is the service brake's, which the electric brake also supplies at 486 kN)
    stretch = np.ptp(profile.position_m[regen])
    rest = 1_500.0 - profile.position_m[regen].max()
    regenerated_j = 640e3 * stretch + service * rest
    assert result.energy_kwh.regenerated * 3.6e6 == pytest.approx(
        regenerated_j * train.electrical.regenerative_efficiency * train.electrical.receptivity, rel=0.05
    )
