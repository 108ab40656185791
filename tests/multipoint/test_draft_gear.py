"""Friction draft gears (issue 13): the loading and unloading branches of a wedge-type gear, the energy
they dissipate per cycle against the hysteresis loop's area, the energy balance with friction, and
in-train forces that settle after a start as in measured trains."""

from __future__ import annotations

import numpy as np
import pytest
from mpcases import freight_train, level_route

from trainsim.multipoint import CouplerModel, MultiPointSession, MultiPointSettings, build_multipoint_train
from trainsim.multipoint import kernel as mpk
from trainsim.multipoint.model import FREIGHT_FRICTION_RATIO, FREIGHT_LOADING_STIFFNESS_N_PER_M

K = 8.4e6


def gear(mu: float, vf: float = 0.005, c: float = 0.0, slack_m: float = 0.0) -> CouplerModel:
    return CouplerModel(
        draft_stiffness_n_per_m=K,
        buff_stiffness_n_per_m=K,
        draft_damping_n_s_per_m=c,
        buff_damping_n_s_per_m=c,
        slack_m=slack_m,
        friction_ratio=mu,
        friction_velocity_mps=vf,
    )


def force(cp: np.ndarray, delta: float, rate: float) -> float:
    spring, dissipative, _, _ = mpk.coupler_force(delta, rate, cp)
    return spring + dissipative


def test_defaults_are_the_mt2_gear():
    c = CouplerModel()
    assert c.friction_ratio == pytest.approx(2 / 3) == FREIGHT_FRICTION_RATIO
    # absorptivity of a full cycle 2 mu / (1 + mu): the MT-2's 80 %
    assert 2 * c.friction_ratio / (1 + c.friction_ratio) == pytest.approx(0.8)
    # the loading branch keeps the documented secant stiffness 2.27 MN / 2 x 83 mm
    assert (1 + c.friction_ratio) * c.draft_stiffness_n_per_m == pytest.approx(
        FREIGHT_LOADING_STIFFNESS_N_PER_M
    )
    assert c.draft_damping_n_s_per_m == 0.0
    assert CouplerModel.stiff().friction_ratio == 0.0


@pytest.mark.parametrize("delta", [0.05, -0.05])
def test_loading_and_unloading_branches(delta):
    cp = gear(0.5).as_row()
    spring = K * delta
    loading = np.sign(delta) * 0.2  # travel growing, fast against the regularisation speed
    # (|spring| is rounded within 1 N for Newton's method)
    assert force(cp, delta, loading) == pytest.approx(1.5 * spring, abs=1.0)
    assert force(cp, delta, -loading) == pytest.approx(0.5 * spring, abs=1.0)
    assert force(cp, delta, 0.0) == pytest.approx(spring, rel=1e-9)  # at rest: the mean branch
    # the derivatives the Newton iterations use match finite differences
    for rate in (-0.004, 0.0, 0.003, 0.02):
        _, _, k, c = mpk.coupler_force(delta, rate, cp)
        h = 1e-7
        k_fd = (force(cp, delta + h, rate) - force(cp, delta - h, rate)) / (2 * h)
        c_fd = (force(cp, delta, rate + h) - force(cp, delta, rate - h)) / (2 * h)
        assert k == pytest.approx(k_fd, rel=1e-5)
        assert c == pytest.approx(c_fd, rel=1e-5)


@pytest.mark.parametrize("mu", [0.3, 2 / 3])
def test_energy_dissipated_per_cycle_is_the_hysteresis_loop_area(mu):
    """delta(t) = d0 + A sin(w t) in draft: the loop between the loading branch (1 + mu) k delta and the
    unloading branch (1 - mu) k delta encloses 2 mu k x (the area under k delta over the stroke) =
    2 mu k (2 A d0) = 4 mu k A d0; the work of the force over a cycle, by quadrature, is that area."""
    cp = gear(mu, vf=1e-4).as_row()
    d0, amp, omega = 0.05, 0.01, 2 * np.pi * 2.0
    t = np.linspace(0.0, 2 * np.pi / omega, 200_001)
    delta = d0 + amp * np.sin(omega * t)
    rate = amp * omega * np.cos(omega * t)
    f = np.array([force(cp, d, r) for d, r in zip(delta, rate, strict=True)])
    work = np.trapezoid(f * rate, t)
    area = 4 * mu * K * amp * d0
    # regularisation: the friction is not fully on while |rate| < a few v_f (1e-4 of 0.13 m/s)
    assert work == pytest.approx(area, rel=2e-3)
    # and the viscous part adds pi c w A^2 on top (independent terms)
    cpv = gear(mu, vf=1e-4, c=1e5).as_row()
    fv = np.array([force(cpv, d, r) for d, r in zip(delta, rate, strict=True)])
    assert np.trapezoid(fv * rate, t) == pytest.approx(area + np.pi * 1e5 * omega * amp**2, rel=2e-3)


def test_the_integrator_accounts_for_the_friction_losses():
    """Two vehicles, a stretched coupling, no resistance: the energy the friction takes is the loss of
    kinetic + spring energy, and the integral of the recorded force over the recorded extension."""
    train = freight_train(1, locos=1, a1_n_per_kg=0.0, a2_n_s2_per_kg_m2=0.0, loco_t=100.0, wagon_t=60.0)
    h = 0.002
    mp = build_multipoint_train(
        train, MultiPointSettings(couplers=gear(0.4, vf=0.002), time_step_s=h, record_interval_s=h)
    )
    session = MultiPointSession(mp, level_route())
    x0 = np.array([0.0, -mp.length_m[0] - 0.02])  # 20 mm stretched: 168 kN
    session.set_state(x0 + 100.0, [0.0, 0.0])
    for _ in range(4):
        session.step(0.0, 0.5)
    r = session.result()
    e = r.energy
    stored = 0.5 * K * 0.02**2
    assert e.damper_j > 0.5 * stored  # most of it is gone within 2 s
    assert e.kinetic_change_j + e.spring_change_j + e.damper_j == pytest.approx(0.0, abs=1e-6 * stored)
    # independent: the recorded force minus its spring part, integrated over the recorded extension
    delta = r.position_m[:, 0] - mp.length_m[0] - r.position_m[:, 1]
    tension = r.coupler_force_n[:, 0]
    cp = mp.couplers[0].as_row()
    friction = tension - np.array([mpk.coupler_force(d, 0.0, cp)[0] for d in delta])
    assert np.trapezoid(friction, delta) == pytest.approx(e.damper_j, rel=1e-2)
    # the oscillation died: the coupling at rest near its unstretched length
    assert abs(tension[-1]) < 0.02 * tension[0]


def oscillation_percent(r, coupler: int, t0: float, t1: float) -> float:
    m = (r.time_s >= t0) & (r.time_s < t1)
    f = r.coupler_force_n[m, coupler]
    return 100 * (f.max() - f.min()) / 2 / abs(f.mean())


def test_forces_settle_after_a_start_as_in_measured_trains():
    """50 wagons with 25 mm slack start at half traction: with the former viscous-only couplers the
    force at mid-train still swings by more than 5 % after 100 s (the slowest mode barely damped); with
    the friction draft gears every force is steady to 0.1 % within 50 s, at the analytic share."""
    train = freight_train(50, locos=1)
    out = {}
    for name, couplers in (
        ("viscous", CouplerModel(slack_m=0.025, friction_ratio=0.0, draft_stiffness_n_per_m=1.4e7,
                                 buff_stiffness_n_per_m=1.4e7, draft_damping_n_s_per_m=3.7e5,
                                 buff_damping_n_s_per_m=3.7e5)),
        ("friction", CouplerModel(slack_m=0.025)),
    ):  # fmt: skip
        mp = build_multipoint_train(train, MultiPointSettings(couplers=couplers, record_interval_s=0.1))
        session = MultiPointSession(mp, level_route(50_000))
        for _ in range(12):
            session.step(0.5, 10.0)
        out[name] = session.result()
        assert out[name].energy.balance_error == pytest.approx(0.0, abs=1e-4)
    assert oscillation_percent(out["viscous"], 25, 100, 120) > 5.0
    for k in (0, 10, 25, 40):
        assert oscillation_percent(out["friction"], k, 50, 120) < 0.1
    # steady: the coupling behind vehicle k pulls the mass behind it at the train's acceleration
    r = out["friction"]
    mp = r.mptrain
    a = np.mean(r.acceleration_mps2[-1])
    for k in (0, 25):
        behind = slice(k + 1, None)
        res = sum(q.c0 + q.c2 * r.speed_mps[-1, i] ** 2 for i, q in enumerate(mp.resistance) if i > k)
        want = mp.inertial_mass_kg[behind].sum() * a + res
        assert r.coupler_force_n[-1, k] == pytest.approx(want, rel=1e-2)
