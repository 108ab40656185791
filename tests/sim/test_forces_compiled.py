"""The compiled force laws (``sim/_forces.pxd``, Cython) against the laws written out in plain Python
here, operation for operation as documented (the numba kernel they replaced gave the same bits; it was
compared while both existed, commit 173df09)."""

import math

import numpy as np
import pytest

from trainsim.model.effort import POWER_CAP_MIN_SPEED_MPS
from trainsim.sim import _forces, codes


def _law(v: float, j: int, coefs: np.ndarray) -> float:
    f = coefs[j, 0] + coefs[j, 1] * v + coefs[j, 2] * v * v
    if coefs[j, 3] != 0.0:
        f += coefs[j, 3] / v if v > 0.0 else math.inf
    return f


def _power_floor(v: float) -> float:
    return v if v > POWER_CAP_MIN_SPEED_MPS else POWER_CAP_MIN_SPEED_MPS


def _effort(v: float, starts, coefs, fcap: float, pcap: float) -> float:
    """Maximum force [N]: the interval's law, the force cap, the power cap P / max(v, 1 mm/s) where
    F v exceeds it, then the clip at 0."""
    j = max(int(np.searchsorted(starts, v, side="right")) - 1, 0)
    f = min(_law(v, j, coefs), fcap)
    vp = _power_floor(v)
    if f * vp > pcap:
        f = pcap / vp
    return f if f > 0.0 else 0.0


def _effort_branch(v: float, vref: float, starts, coefs, fcap: float, pcap: float) -> float:
    """The branch (law, force cap, power cap or zero) that binds at vref, continued to v."""
    if vref < 0.0:
        return _effort(v, starts, coefs, fcap, pcap)
    j = max(int(np.searchsorted(starts, vref, side="right")) - 1, 0)
    candidates = [(_law(vref, j, coefs), 0), (fcap, 1), (pcap / _power_floor(vref), 2)]
    best, branch = candidates[0]
    for value, which in candidates[1:]:
        if value < best:
            best, branch = value, which
    if not best > 0.0:
        return 0.0
    if branch == 1:
        return fcap
    if branch == 2:
        return pcap / _power_floor(v)
    f = _law(v, j, coefs)
    return f if f > 0.0 else 0.0


def _speed_domain_steps(v_from: float, v_to: float, a_from: float, a_to: float) -> int:
    n = abs(v_to - v_from) / codes.SPEED_DOMAIN_STEP
    if a_from * a_to > 0.0:
        n = min(n, 8.0) + codes.SPEED_DOMAIN_STEPS_PER_LOG * abs(math.log(a_to / a_from))
    return min(max(math.ceil(n), codes.SPEED_DOMAIN_MIN_STEPS), codes.SPEED_DOMAIN_MAX_STEPS)


def test_the_power_cap_floor_is_the_models():
    assert _forces.power_cap_min_speed() == POWER_CAP_MIN_SPEED_MPS


def _random_curve(rng: np.random.Generator, n: int) -> tuple:
    starts = np.concatenate(([0.0], np.sort(rng.uniform(0.5, 40.0, n - 1))))
    coefs = np.column_stack(
        (
            rng.uniform(-5e4, 4e5, n),
            rng.uniform(-2e3, 2e3, n),
            rng.uniform(-50.0, 50.0, n),
            np.where(rng.random(n) < 0.3, rng.uniform(0.0, 5e6, n), 0.0),
        )
    )
    fcap = rng.choice([np.inf, rng.uniform(1e5, 4e5)])
    pcap = rng.choice([np.inf, rng.uniform(1e6, 8e6)])
    return starts, np.ascontiguousarray(coefs), float(fcap), float(pcap)


@pytest.mark.parametrize("seed", range(20))
def test_effort_and_its_branches_equal_the_laws_written_out(seed):
    rng = np.random.default_rng(seed)
    curve = _random_curve(rng, int(rng.integers(1, 12)))
    speeds = np.concatenate(([0.0, 1e-4, POWER_CAP_MIN_SPEED_MPS], curve[0], rng.uniform(0.0, 60.0, 200)))
    for v in speeds:
        assert _forces.effort_at(v, curve) == _effort(v, *curve)
        for vref in (-1.0, 0.0, v, *rng.uniform(0.0, 60.0, 3)):
            got = _forces.effort_branch_at(v, vref, curve)
            want = _effort_branch(v, vref, *curve)
            assert got == want or (np.isnan(got) and np.isnan(want)), (v, vref, got, want)


@pytest.mark.parametrize("seed", range(20))
def test_a_branch_chosen_once_gives_effort_branch_at_every_speed(seed):
    """sim/_energy_c chooses each curve's branch once per piece (``branch_at``) and evaluates it at
    every RK4 stage (``effort_on``): the same bits as choosing it at each (``effort_branch``), for
    every reference speed, NaN and no reference (-1) included."""
    rng = np.random.default_rng(100 + seed)
    curve = _random_curve(rng, int(rng.integers(1, 12)))
    speeds = np.concatenate(([0.0, 1e-4, POWER_CAP_MIN_SPEED_MPS], curve[0], rng.uniform(0.0, 60.0, 100)))
    for vref in (-1.0, 0.0, 1e-4, np.nan, *curve[0], *rng.uniform(0.0, 60.0, 10)):
        got = _forces.effort_on_at(speeds, vref, curve)
        for v, g in zip(speeds, got, strict=True):
            want = _forces.effort_branch_at(v, vref, curve)
            assert g == want or (np.isnan(g) and np.isnan(want)), (v, vref, g, want)


def test_a_malformed_curve_is_refused_with_its_shapes():
    with pytest.raises(ValueError, match=r"\(n,\) and \(n, 4\)"):
        _forces.effort_at(1.0, (np.zeros(2), np.zeros((3, 4)), 1.0, 1.0))


def test_the_compiled_codes_are_the_python_ones():
    compiled = _forces.compiled_codes()
    assert compiled == {name: getattr(codes, name) for name in compiled}


def test_speed_domain_steps_equal_the_rule_written_out():
    assert _forces.speed_domain_settings() == (
        codes.SPEED_DOMAIN_STEP,
        codes.SPEED_DOMAIN_MIN_STEPS,
        codes.SPEED_DOMAIN_STEPS_PER_LOG,
    )
    rng = np.random.default_rng(7)
    for _ in range(2000):
        v0, v1 = rng.uniform(0.0, 40.0, 2)
        a0, a1 = rng.uniform(-2.0, 2.0, 2) * rng.choice([1e-6, 1.0], 2)
        assert _forces.speed_domain_steps_of(v0, v1, a0, a1) == _speed_domain_steps(v0, v1, a0, a1)
