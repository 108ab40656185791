"""The compiled exact energy integration (``sim/_energy_c.pyx``, Cython; issue 14) against independent
computations: scipy's solve_ivp on the same equations of motion at tight tolerance, quadrature of
closed-form forces for cruising and prescribed profiles, and the work-energy identity of whole runs.

(It replaced the numba ``energy.stretch_works`` after giving the same bits on every stretch of the
examples' and the TrainRuns.jl freight train's fastest runs and of the metro's optimal run.)"""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model import EffortCurve
from trainsim.model.scenario import RunSettings
from trainsim.sim import _energy_c, codes, energy
from trainsim.sim.energy import run_works, stretch_works
from trainsim.sim.fastest import run_fastest
from trainsim.sim.parameters import kink_speeds
from trainsim.sim.profile import line_resistance_profile, traction_availability

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = next(
    (
        d
        for d in (ROOT.parent / "shared" / "data" / "trainruns", ROOT / "tests" / "data" / "trainruns")
        if (d / "paths" / "realworld.yaml").exists()
    ),
    None,
)

# a 400 t train with quadratic running resistance (values of a freight locomotive's order)
M_KG = 400e3
RHO = 1.08
C0, C1, C2 = 6e3, 120.0, 9.0
G = 9.80665
# the line: two pieces with their own gradient, curve and tunnel laws (per unit mass, u from the piece's start)
LX = np.array([0.0, 900.0, 5000.0])
LAWS = {
    "g0": np.array([G * 0.004, G * 0.002]),
    "g1": np.array([0.0, G * -2e-6]),
    "c0": np.array([0.0, G * 0.0008]),
    "c1": np.array([0.0, G * 1e-7]),
    "k0": np.array([0.0, 1.5e-6]),
    "k1": np.array([0.0, 1e-10]),
    "available": np.array([1.0, 0.9]),
}
TRACTION = EffortCurve.power_limited(4.0e6, force_cap_n=320e3)  # kink at 12.5 m/s
BRAKE_N = 280e3
BRAKE = EffortCurve.constant(BRAKE_N)
REGEN = EffortCurve.power_limited(2.1e6, force_cap_n=1e9)  # min(braking, P/v): blending at 7.5 m/s


def _params(decel_mps2: float = 0.0) -> np.ndarray:
    """The kernel's parameter vector of the test train (service braking a force law unless a
    constant deceleration [m/s^2] is given)."""
    P = np.zeros(codes.N_PARAMS)
    P[codes.P_INERTIAL_MASS] = RHO * M_KG
    P[codes.P_MASS] = M_KG
    P[codes.P_R0], P[codes.P_R1], P[codes.P_R2] = C0, C1, C2
    P[codes.P_DECEL] = decel_mps2
    P[codes.P_BRAKE_FRACTION] = 1.0
    P[codes.P_TRACTION_SCALE] = 1.0
    return P


def _works(s, v, regime, level=None, regen=REGEN, decel_mps2=0.0):
    """stretch_works on the test line and train (points s [m], v [m/s], regime codes)."""
    s, v, regime = np.asarray(s, float), np.asarray(v, float), np.asarray(regime)
    level = np.ones(len(s)) if level is None else np.asarray(level, float)
    curves = (*TRACTION.as_arrays(), *BRAKE.as_arrays(), *regen.as_arrays())
    tk = kink_speeds(*TRACTION.as_arrays())
    rk = kink_speeds(*regen.as_arrays())
    # where the service braking force equals the regenerative capacity (both constant or P / v here)
    blend = [regen.power_cap_w / BRAKE_N] if np.isfinite(regen.power_cap_w) else []
    bk = np.unique(np.concatenate([kink_speeds(*BRAKE.as_arrays()), rk, blend]))
    laws = tuple(LAWS[k] for k in ("g0", "g1", "c0", "c1", "k0", "k1", "available"))
    return stretch_works(s, v, regime, level, LX, laws, _params(decel_mps2), curves, tk, bk, rk)


def _piece(x: float) -> int:
    return int(np.clip(np.searchsorted(LX, x, side="right") - 1, 0, len(LX) - 2))


def _line(x: float, v: float) -> tuple[float, float, float]:
    """Running, gradient and curve + tunnel resistance [N] at position x [m] and speed v [m/s]."""
    i = _piece(x)
    u = x - LX[i]
    running = C0 + C1 * v + C2 * v * v
    grad = M_KG * (LAWS["g0"][i] + LAWS["g1"][i] * u)
    ct = M_KG * ((LAWS["c0"][i] + LAWS["c1"][i] * u) + (LAWS["k0"][i] + LAWS["k1"][i] * u) * v * v)
    return running, grad, ct


def _traction_n(v: float) -> float:
    return min(320e3, 4.0e6 / max(v, 1e-3))


def _regen_n(v: float) -> float:
    return 2.1e6 / max(v, 1e-3)


def _rhs(mode: int, level: float):
    """dE/ds and the integrands of the works (traction, braking, regenerative, running, gradient,
    curve + tunnel) written from the equations, for scipy."""

    def f(x, y):
        v = np.sqrt(2.0 * max(y[0], 0.0))
        running, grad, ct = _line(x, v)
        ft = level * LAWS["available"][_piece(x)] * _traction_n(v) if mode == codes.TRACTION else 0.0
        fb = level * BRAKE_N if mode == codes.BRAKE else 0.0
        fr = min(fb, _regen_n(v))
        acc = (ft - fb - running - grad - ct) / (RHO * M_KG)
        return [acc, ft, fb, fr, running, grad, ct]

    return f


def _reference(mode: int, s0: float, s1: float, v0: float, level: float = 1.0) -> tuple[float, np.ndarray]:
    """End speed [m/s] and works [J] over [s0, s1] by DOP853 at rtol 1e-13, restarted at the line's
    breakpoints and at the speeds where a force has a kink (as any careful integration must be)."""
    kinks = {codes.TRACTION: [12.5], codes.BRAKE: [7.5]}.get(mode, [])
    y = np.array([0.5 * v0 * v0, 0, 0, 0, 0, 0, 0], float)
    cuts = [s0, *[x for x in LX if s0 < x < s1], s1]
    for a, b in itertools.pairwise(cuts):
        x = a
        while x < b:
            events = []
            for vk in kinks:

                def event(_x, yy, vk=vk):
                    return yy[0] - 0.5 * vk * vk

                event.terminal = True
                events.append(event)
            sol = solve_ivp(
                _rhs(mode, level), (x, b), y, method="DOP853", rtol=1e-13, atol=1e-9, events=events
            )
            y = sol.y[:, -1]
            x = sol.t[-1]
            if x < b:
                # crossed a kink: step past it with the next piece's law (no event at its start)
                kinks = [vk for vk in kinks if abs(0.5 * vk * vk - y[0]) > 1e-9 * y[0]]
    return float(np.sqrt(2.0 * max(y[0], 0.0))), y[1:]


def _assert_works(got: np.ndarray, want: np.ndarray, rel: float) -> None:
    scale = np.max(np.abs(want))
    assert np.all(np.abs(got - want) <= rel * scale), (got, want, np.abs(got - want) / scale)


def _recorded_points(mode: int, s0: float, s1: float, v0: float, level: float):
    """Points every ``RunSettings().max_step_m`` along the reference motion, as a run records them,
    with the reference works of each stretch between them."""
    s = np.linspace(s0, s1, int(np.ceil((s1 - s0) / RunSettings().max_step_m)) + 1)
    v = [v0]
    works = []
    for a, b in itertools.pairwise(s):
        vb, w = _reference(mode, a, b, v[-1], level)
        v.append(vb)
        works.append(w)
    return s, np.array(v), np.array(works)


@pytest.mark.parametrize(
    ("mode", "s0", "s1", "v0", "level"),
    [
        (codes.TRACTION, 0.0, 3500.0, 4.0, 1.0),  # force cap, then power cap; two line pieces
        (codes.TRACTION, 300.0, 2500.0, 9.0, 0.6),  # the driver's level, across the power kink
        (codes.COAST, 200.0, 2200.0, 22.0, 1.0),
        (codes.BRAKE, 400.0, 780.0, 24.0, 1.0),  # regenerative power cap, then blending at 7.5 m/s
    ],
)
def test_a_run_has_the_works_of_an_independent_integration(mode, s0, s1, v0, level):
    s, v, want = _recorded_points(mode, s0, s1, v0, level)
    assert v[-1] > 1.0
    n = len(s)
    works, v_end, off = _works(s, v, [mode] * n, [level] * n)
    assert not off.any()
    np.testing.assert_allclose(v_end, v[1:], rtol=1e-9)
    # a stretch that crosses a kink restarts there, located in the speed domain to about 1e-8 (the
    # differences measured: at most 5e-9 of a stretch's largest work, 2e-9 of a whole motion's)
    _assert_works(works.sum(axis=0), want.sum(axis=0), 1e-8)
    for k in range(n - 1):
        _assert_works(works[k], want[k], 1e-8)
    if mode == codes.BRAKE:
        assert 0.0 < want[:, 2].sum() < want[:, 1].sum()  # part of the braking is regenerative


def _quad(f, a: float, b: float, points) -> float:
    return quad(f, a, b, points=sorted(points) or None, epsabs=0.0, epsrel=1e-13, limit=200)[0]


def _need_works(need, parts, a: float, b: float, cap) -> np.ndarray:
    """Works of a motion needing the force ``need(x)`` (> 0 traction, < 0 braking) [J] by quadrature,
    split at the line's breakpoints and where the need changes sign or crosses the capacity."""
    grid = np.linspace(a, b, 4001)
    points = [x for x in LX if a < x < b]
    for f in (need, lambda x: -need(x) - cap(x)):
        y = np.array([f(x) for x in grid])
        for j in np.flatnonzero(y[:-1] * y[1:] < 0):
            points.append(brentq(f, grid[j], grid[j + 1], xtol=1e-13, rtol=1e-15))
    return np.array(
        [
            _quad(lambda x: max(need(x), 0.0), a, b, points),
            _quad(lambda x: max(-need(x), 0.0), a, b, points),
            _quad(lambda x: min(max(-need(x), 0.0), cap(x)), a, b, points),
            *(_quad(lambda x, j=j: parts(x)[j], a, b, points) for j in range(3)),
        ]
    )


def test_cruising_works_are_the_holding_force_integrated():
    """At constant speed the holding force is the resistance: on the second piece it changes sign
    (gradient falling along it) and its braking part exceeds the regenerative capacity in places."""
    v, a, b = 18.0, 950.0, 4900.0
    regen = EffortCurve.constant(4e3)

    def need(x):
        return sum(_line(x, v))

    assert need(a) > 0 > need(b)
    want = _need_works(need, lambda x: _line(x, v), a, b, lambda x: 4e3)
    works, v_end, off = _works([a, b], [v, v], [codes.CRUISE, codes.CRUISE], regen=regen)
    assert not off[0] and v_end[0] == v
    _assert_works(works[0], want, 1e-10)
    assert want[0] > 0 and want[1] > want[2] > 0


@pytest.mark.parametrize(("v0", "v1"), [(8.0, 21.0), (20.0, 3.0)])
def test_a_prescribed_profile_needs_the_forces_of_its_accelerations(v0, v1):
    """FOLLOW: v^2 linear over the stretch; the need M a + R is traction or braking by its sign."""
    a_, b_ = 100.0, 2600.0
    acc = (0.5 * v1 * v1 - 0.5 * v0 * v0) / (b_ - a_)

    def speed(x):
        return np.sqrt(2.0 * (0.5 * v0 * v0 + acc * (x - a_)))

    def need(x):
        return RHO * M_KG * acc + sum(_line(x, speed(x)))

    want = _need_works(need, lambda x: _line(x, speed(x)), a_, b_, lambda x: _regen_n(speed(x)))
    works, _, off = _works([a_, b_], [v0, v1], [codes.FOLLOW, codes.FOLLOW])
    assert not off[0]
    _assert_works(works[0], want, 1e-10)


def test_a_stretch_off_its_regime_is_integrated_as_its_recorded_motion():
    """Traction at level 0.6 recorded as if it reached the full-traction end speed: the stretch is
    flagged, its works are those of the recorded (prescribed) motion, and its integrated end speed
    is the regime's."""
    s0, s1, v0 = 300.0, 2500.0, 9.0
    v_full, _ = _reference(codes.TRACTION, s0, s1, v0, 1.0)
    v_part, _ = _reference(codes.TRACTION, s0, s1, v0, 0.6)
    works, v_end, off = _works([s0, s1], [v0, v_full], [codes.TRACTION] * 2, [0.6, 0.6])
    follow, _, _ = _works([s0, s1], [v0, v_full], [codes.FOLLOW] * 2)
    assert off[0]
    np.testing.assert_array_equal(works, follow)
    assert v_end[0] == pytest.approx(v_part, rel=1e-10)


def test_a_constant_deceleration_brakes_with_what_the_resistance_leaves():
    """Service braking given as a deceleration d: the brakes supply rho m d minus the resistance, so
    v^2 falls linearly (exactly, whatever the resistance) and the works follow by quadrature."""
    d, s0, s1, v0 = 0.5, 600.0, 1150.0, 25.0
    M = RHO * M_KG

    def speed(x):
        return np.sqrt(v0 * v0 - 2.0 * d * (x - s0))

    def need(x):
        return -M * d + sum(_line(x, speed(x)))

    v1 = speed(s1)
    want = _need_works(need, lambda x: _line(x, speed(x)), s0, s1, lambda x: _regen_n(speed(x)))
    s = np.linspace(s0, s1, 29)
    works, v_end, off = _works(s, speed(s), [codes.BRAKE] * 29, decel_mps2=d)
    assert not off.any()
    assert v_end[-1] == pytest.approx(v1, rel=1e-12)
    got = works.sum(axis=0)
    _assert_works(np.delete(got, 2), np.delete(want, 2), 1e-9)
    # min(braking, P/v) has a kink where they cross, at a speed that depends on the resistance: no
    # kink speed is given for it, so the sub-step that holds it is integrated across it (measured
    # 6e-6 relative; a known limit of the method, the same in the numba integration it replaced)
    assert got[2] == pytest.approx(want[2], rel=1e-5)
    assert 0.0 < want[2] < want[1]


def test_dwells_and_empty_stretches_have_no_works():
    works, v_end, off = _works(
        [0.0, 0.0, 500.0, 500.0, 500.0],
        [0.0, 0.0, 10.0, 10.0, 10.0],
        [codes.DWELL, codes.FOLLOW, codes.DWELL, codes.TRACTION, codes.TRACTION],
    )
    assert not works[[0, 2, 3]].any() and not off.any()
    assert list(v_end[[0, 2, 3]]) == [0.0, 10.0, 10.0]
    assert works[1, 0] > 0 and v_end[1] == pytest.approx(10.0, rel=1e-12)


@pytest.fixture(scope="module")
def fastest_runs() -> dict[str, tuple]:
    """(train, route, settings, trace) of the metro's fastest run and of the TrainRuns.jl freight
    train on realworld."""
    out = {}
    sc = trainsim.load_scenario(ROOT / "examples/metro_b/scenario.yaml")
    out["metro_b"] = (sc.train, sc.route, sc.settings)
    if TRAINRUNS is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            train = load_train(TRAINRUNS / "trains" / "freight.yaml")
        out["freight realworld"] = (
            train,
            load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="mass_point"),
            RunSettings(),
        )
    return {name: (*c, run_fastest(*c).trace) for name, c in out.items()}


@pytest.mark.parametrize("case", ["metro_b", "freight realworld"])
def test_the_works_of_every_stretch_of_a_run_balance_its_kinetic_energy(fastest_runs, case):
    """Work-energy identity per stretch: rho m (v_end^2 - v_start^2) / 2 = traction - braking -
    running - gradient - curve/tunnel, to rounding (RK4 is linear in its stages); cruising stretches
    hold their speed (the works cancel); every stretch follows its regime."""
    if case not in fastest_runs:
        pytest.skip("the TrainRuns.jl data is not on this machine")
    train, route, settings, tr = fastest_runs[case]
    train = train.at_gravity(route.gravity_mps2)
    works, v_end, off = run_works(
        train=train,
        route=route,
        settings=settings,
        profile=line_resistance_profile(route, train),
        available=traction_availability(route, train),
        s=tr.position_m,
        v=tr.speed_mps,
        regime=tr.regime,
        level=np.ones(len(tr)),
    )
    assert not off.any()
    M = train.inertial_mass_kg
    net = works[:, 0] - works[:, 1] - works[:, 3] - works[:, 4] - works[:, 5]
    scale = np.abs(works).sum(axis=1) + M * tr.speed_mps[:-1] ** 2
    moving = (tr.regime[:-1] != codes.DWELL) & (np.diff(tr.position_m) > 0)
    cruise = moving & (tr.regime[:-1] == codes.CRUISE)
    dynamic = moving & ~cruise
    kinetic = 0.5 * M * (v_end**2 - tr.speed_mps[:-1] ** 2)
    # a stretch ending at a stop integrates E a hair below 0 (the end speed is clipped at 0)
    stop = dynamic & (v_end == 0.0)
    assert np.all(np.abs(net - kinetic)[dynamic & ~stop] <= 1e-11 * scale[dynamic & ~stop])
    assert np.all(np.abs(net - kinetic)[stop] <= M * 1e-7) and stop.any()
    assert np.all(np.abs(net)[cruise] <= 1e-11 * scale[cruise])
    # and the integrated end speeds are the trace's (the kernel integrated the same motion)
    np.testing.assert_allclose(v_end[dynamic], tr.speed_mps[1:][dynamic], rtol=1e-6, atol=1e-5)
    assert dynamic.sum() > 100


def test_the_compiled_settings_are_the_modules():
    got = _energy_c.integration_settings()
    for name in (
        "MAX_SUBSTEP_M",
        "LENGTH_SCALE_FRACTION",
        "MIN_SUBSTEP_M",
        "MAX_SUBSTEPS",
        "KINK_MARGIN_MPS",
        "OFF_REGIME_SPEED_MPS",
        "OFF_REGIME_RELATIVE",
        "N_WORKS",
    ):
        assert got[name] == getattr(energy, name), name
    assert got["N_WORKS"] == len(energy.WORK_NAMES)
    assert got["POSITION_TOLERANCE"] == codes.POSITION_TOLERANCE
    x, w = np.polynomial.legendre.leggauss(5)
    np.testing.assert_allclose(got["GL_X"], 0.5 * x + 0.5, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got["GL_W"], 0.5 * w, rtol=0, atol=1e-15)


def test_bad_arguments_are_refused_with_what_is_allowed():
    s, v, regime = np.array([0.0, 100.0, 200.0]), np.array([0.0, 5.0, 7.0]), np.zeros(3, int)
    curves = (*TRACTION.as_arrays(), *BRAKE.as_arrays(), *REGEN.as_arrays())
    laws = tuple(LAWS[k] for k in ("g0", "g1", "c0", "c1", "k0", "k1", "available"))
    ok = [s, v, regime, np.ones(3), LX, laws, _params(), curves, np.zeros(0), np.zeros(0), np.zeros(0)]

    def call(**changes):
        args = list(ok)
        for j, value in changes.items():
            args[int(j[1:])] = value
        return stretch_works(*args)

    assert call()[0].shape == (2, 6)
    with pytest.raises(ValueError, match="v has 2 values, needs 3"):
        call(a1=v[:2])
    with pytest.raises(ValueError, match=r"regime codes must be 0\.\.6"):
        call(a2=np.array([0, 9, 0]))
    with pytest.raises(ValueError, match="tk must be sorted increasing"):
        call(a8=np.array([2.0, 1.0]))
    with pytest.raises(ValueError, match="laws must be"):
        call(a5=laws[:6])
    with pytest.raises(ValueError, match="laws g1 has 1 values, needs 2"):
        call(a5=(laws[0], laws[1][:1], *laws[2:]))
    with pytest.raises(ValueError, match="lx must be at least 2 breakpoints sorted increasing"):
        call(a4=LX[::-1])
    with pytest.raises(ValueError, match="inertial mass"):
        call(a6=np.zeros(codes.N_PARAMS))
    with pytest.raises(ValueError, match="curves must be the 12-tuple"):
        call(a7=curves[:8])
    with pytest.raises(ValueError, match=r"\(n,\) and \(n, 4\)"):
        call(a7=(np.zeros(2), np.zeros((3, 4)), 1.0, 1.0, *curves[4:]))
    with pytest.raises(ValueError, match="s has 0 values, needs at least 1"):
        call(a0=np.zeros(0), a1=np.zeros(0), a2=np.zeros(0, int), a3=np.zeros(0))
    with pytest.raises(ValueError, match="s must be 1-d"):
        call(a0=np.zeros((3, 1)))
    with pytest.raises(ValueError, match="regime must be an array of integers, got <U1"):
        call(a2=np.array(["a", "b", "c"]))
    # arrays of another dtype or layout are converted: the same works
    converted = call(
        a0=list(s), a1=v.astype(np.float32), a2=regime.astype(np.int8), a3=np.repeat(np.ones(3), 2)[::2]
    )
    for got, want in zip(converted, call(), strict=True):
        np.testing.assert_array_equal(got, want)
    works, v_end, off = call(a0=np.zeros(1), a1=np.zeros(1), a2=np.zeros(1, int), a3=np.ones(1))
    assert works.shape == (0, 6) and v_end.shape == (0,) and off.dtype == np.bool_
