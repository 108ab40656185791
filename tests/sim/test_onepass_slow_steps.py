"""Accelerating steps near standstill in the speed domain (issue 14, ``sim/_kernel_c.pyx``,
``speed_domain_step``): checked against the closed form of a constant force, against scipy's DOP853 in
the time domain with speed-dependent resistance and a gradient that changes along the step, and on
whole runs against the distance domain's sub-steps it replaces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from test_onepass_kinks import CASES

from trainsim.sim import _kernel_c, codes

M = 400_000.0  # [kg]


def _params(r0=0.0, r1=0.0, r2=0.0, rho=1.06):
    P = np.zeros(codes.N_PARAMS)
    P[codes.P_INERTIAL_MASS] = rho * M
    P[codes.P_MASS] = M
    P[codes.P_R0], P[codes.P_R1], P[codes.P_R2] = r0, r1, r2
    P[codes.P_BRAKE_FRACTION] = 1.0
    P[codes.P_TRACTION_SCALE] = 1.0
    return P


def _curves(c0, c1=0.0, c2=0.0):
    """A traction curve of one law c0 + c1 v + c2 v^2 [N], no caps; no braking curves."""
    trac = (np.zeros(1), np.array([[c0, c1, c2, 0.0]]), math.inf, math.inf)
    none = (np.zeros(1), np.zeros((1, 4)), 0.0, 0.0)
    return (*trac, *none, *none)


def test_a_constant_force_gives_the_closed_form():
    # a = (F - R0) / (rho m), constant: v1^2 = v0^2 + 2 a h, t = (v1 - v0) / a
    P = _params(r0=8_000.0)
    F = 200_000.0
    a = (F - 8_000.0) / P[codes.P_INERTIAL_MASS]
    for v0, h in ((0.05, 0.01), (0.3, 5.0), (1.0, 20.0)):
        E, dt, used = _kernel_c.rk4_energy_time_slow_of(
            0.5 * v0 * v0, 0.0, h, codes.TRACTION, (0.0, 0.0, 0.0, 0.0), P, _curves(F)
        )
        assert used, (v0, h)
        v1 = math.sqrt(v0 * v0 + 2.0 * a * h)
        assert pytest.approx(0.5 * v1 * v1, rel=1e-13) == E
        assert pytest.approx((v1 - v0) / a, rel=1e-12) == dt


@pytest.mark.parametrize("v0,h", [(0.2, 0.05), (0.5, 2.0), (1.5, 20.0), (0.5, 20.0)])
def test_speed_dependent_forces_and_a_changing_gradient_agree_with_dop853(v0, h):
    P = _params(r0=6_000.0, r1=150.0, r2=9.0)
    curves = _curves(300_000.0, -2_000.0, -40.0)
    line = (0.004, 2e-4, 1e-5, 1e-7)  # [N/kg], [N/kg/m], [1/m], [1/m^2]

    def accel(v, s):
        res = 6_000.0 + 150.0 * v + 9.0 * v * v + M * ((0.004 + 2e-4 * s) + (1e-5 + 1e-7 * s) * v * v)
        return (300_000.0 - 2_000.0 * v - 40.0 * v * v - res) / P[codes.P_INERTIAL_MASS]

    def rhs(_t, y):
        return [y[1], accel(y[1], y[0])]

    def reached(_t, y):
        return y[0] - h

    reached.terminal = True
    ref = solve_ivp(rhs, (0.0, 1e4), [0.0, v0], method="DOP853", rtol=1e-13, atol=1e-15, events=reached)
    t_ref, v_ref = ref.t_events[0][0], ref.y_events[0][0][1]
    args = (0.5 * v0 * v0, 0.0, h, codes.TRACTION, line, P, curves)
    E, dt, used = _kernel_c.rk4_energy_time_slow_of(*args)
    assert used
    # measured: 1e-13 (5 cm) to 1.1e-9 (20 m from 0.5 m/s, a whole grid step)
    assert pytest.approx(v_ref, rel=2e-9) == math.sqrt(2.0 * E)
    assert pytest.approx(t_ref, rel=2e-9) == dt
    # the distance domain's time over the same step is the less accurate (7e-10 to 6e-7 here)
    _, dt_distance = _kernel_c.rk4_energy_time_of(*args)
    assert abs(dt - t_ref) < abs(dt_distance - t_ref)


def test_a_step_that_stops_accelerating_falls_back_to_the_distance_domain():
    # the traction falls below the resistance on the way: the speed domain is singular there
    P = _params(r0=10_000.0, r1=40_000.0)
    curves = _curves(60_000.0)
    args = (0.5 * 0.5**2, 0.0, 20.0, codes.TRACTION, (0.0, 0.0, 0.0, 0.0), P, curves)
    E, dt, used = _kernel_c.rk4_energy_time_slow_of(*args)
    assert not used
    assert (E, dt) == _kernel_c.rk4_energy_time_of(*args)


def test_fast_steps_are_not_changed():
    P = _params(r0=8_000.0, r1=100.0)
    args = (0.5 * 20.0**2, 0.0, 20.0, codes.TRACTION, (0.0, 0.0, 0.0, 0.0), P, _curves(200_000.0))
    E, dt, used = _kernel_c.rk4_energy_time_slow_of(*args)
    assert not used
    assert (E, dt) == _kernel_c.rk4_energy_time_of(*args)


@pytest.mark.parametrize("name", ["metro_b", "trainruns freight realworld"])
def test_runs_keep_their_running_times_within_1e_9(name):
    seg = CASES[name]()
    n_max = 4 * len(seg.track.x) + 64
    s0, v0, t0, m0, st0 = seg.run(n_max, kink_points=True)
    s1, v1, t1, m1, st1 = seg.run(n_max, kink_points=True, slow_steps=True)
    assert st0 == st1 and len(s0) == len(s1)
    np.testing.assert_array_equal(m0, m1)
    np.testing.assert_allclose(s1, s0, rtol=1e-12, atol=1e-9)
    stops = np.flatnonzero(m0 == codes.DWELL)
    np.testing.assert_allclose(t1[stops], t0[stops], rtol=1e-9)
    np.testing.assert_allclose(v1, v0, rtol=1e-7, atol=1e-7)
    assert not np.array_equal(t1, t0), "the speed domain must have been used"


def _braking_curves(c0, c1=0.0):
    """No traction; a service braking curve of one law c0 + c1 v [N], no caps."""
    none = (np.zeros(1), np.zeros((1, 4)), 0.0, 0.0)
    brake = (np.zeros(1), np.array([[c0, c1, 0.0, 0.0]]), math.inf, math.inf)
    return (*none, *brake, *none)


def test_a_constant_deceleration_backwards_from_near_standstill_gives_the_closed_form():
    # the braking curve to a stop, integrated backwards from it: E grows by a h with h < 0
    P = _params(r0=2_000.0)
    P[codes.P_DECEL] = 0.6
    for v0, h in ((0.05, -0.01), (0.4, -5.0), (1.0, -20.0)):
        E, used = _kernel_c.rk4_energy_slow_of(
            0.5 * v0 * v0, 20.0, h, codes.BRAKE, (0.0, 0.0, 0.0, 0.0), P, _braking_curves(0.0)
        )
        assert used, (v0, h)
        assert pytest.approx(0.5 * v0 * v0 - 0.6 * h, rel=1e-13) == E


@pytest.mark.parametrize("v0,h", [(0.3, -0.1), (0.6, -5.0), (1.0, -20.0), (4.0, 12.0)])
def test_braking_forces_backwards_and_forwards_agree_with_dop853(v0, h):
    # a braking force growing with speed against a rising gradient; forwards (h > 0) it slows down
    # to no less than half its speed (nearer standstill the distance domain keeps the step)
    P = _params(r0=5_000.0, r1=120.0, r2=8.0)
    curves = _braking_curves(180_000.0, 3_000.0)
    line = (0.003, 1e-4, 0.0, 0.0)

    def accel(v, s):
        res = 5_000.0 + 120.0 * v + 8.0 * v * v + M * (0.003 + 1e-4 * (20.0 + s))
        return -(180_000.0 + 3_000.0 * v + res) / P[codes.P_INERTIAL_MASS]

    # dE/ds = a(v, s) from s = 0 to h, the reference by DOP853 in the distance domain away from v = 0
    ref = solve_ivp(
        lambda s, y: [accel(math.sqrt(2.0 * y[0]), s)], (0.0, h), [0.5 * v0 * v0], method="DOP853",
        rtol=1e-13, atol=1e-16,
    )  # fmt: skip
    E, used = _kernel_c.rk4_energy_slow_of(0.5 * v0 * v0, 20.0, h, codes.BRAKE, line, P, curves)
    assert used
    assert pytest.approx(ref.y[0][-1], rel=2e-9) == E


def test_a_step_braking_to_standstill_stays_in_the_distance_domain():
    P = _params(r0=5_000.0)
    curves = _braking_curves(180_000.0)
    a = -(185_000.0) / P[codes.P_INERTIAL_MASS]
    v0 = 0.5
    h = 0.9 * v0 * v0 / (2.0 * -a)  # ends at a third of the speed
    args = (0.5 * v0 * v0, 0.0, h, codes.BRAKE, (0.0, 0.0, 0.0, 0.0), P, curves)
    E, used = _kernel_c.rk4_energy_slow_of(*args)
    assert not used
    assert _kernel_c.rk4_energy_of(*args) == E
