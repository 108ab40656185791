"""The compiled DC solver parts (trainsim.power._solver_c, trainsim.power._rail_c) against independent
computations: the residual against a network assembled by hand as a dense matrix, the compiled Newton
against the closed form of one constant-power train fed from two sources (Thevenin equivalent), the
diode rounding against its defining formulas, the band solver against LAPACK, the stray current
against the numpy form; errors name the argument; importing the solver loads no numba."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from trainsim.power import _rail_c, _solver_c
from trainsim.power.rail import segment_leakage_a

I64 = np.int64


def _random_network(rng, n=7, m=3):
    """Branches (some to earth), two reversible sources, two diodes, m trains (some with an earthed
    rail), potentials around 750 V on the contact nodes."""
    a = np.array([0, 1, 2, 3, 4, 5, 6, 0, 3, 6], I64)
    b = np.array([1, 2, 3, 4, 5, 6, -1, -1, 5, 2], I64)
    y = rng.uniform(1.0, 50.0, len(a))
    sp, sn = np.array([0, 4], I64), np.array([-1, 5], I64)
    ys, e = np.array([30.0, 20.0]), np.array([850.0, 840.0])
    dp, dn = np.array([2, 6], I64), np.array([-1, 3], I64)
    dy, de = np.array([25.0, 40.0]), np.array([845.0, 835.0])
    tc, tr = rng.integers(0, n, m).astype(I64), np.array([-1, 5, 3][:m], I64)
    tw, aw, rw = rng.uniform(0, 2e6, m), np.full(m, 5e4), rng.uniform(0, 1e6, m)
    v = rng.uniform(600.0, 950.0, n)
    return a, b, y, sp, sn, ys, e, dp, dn, de, dy, tc, tr, tw, aw, rw, v


LIMITS = {"u_floor": 0.75, "min1_v": 500.0, "full_v": 600.0, "regen_full_v": 850.0, "regen_zero_v": 900.0}


def _reference_residual(a, b, y, sp, sn, ys, e, dp, dn, de, dy, tc, tr, tw, aw, rw, v, delta, share):
    """G V - J + I_trains + I_diodes from a dense conductance matrix built entry by entry."""
    n = len(v)
    g = np.zeros((n, n))
    j = np.zeros(n)

    def branch(p, q, cond):
        if p >= 0:
            g[p, p] += cond
        if q >= 0:
            g[q, q] += cond
        if p >= 0 and q >= 0:
            g[p, q] -= cond
            g[q, p] -= cond

    for p, q, cond in zip(a, b, y, strict=True):
        branch(p, q, cond)
    for p, q, cond, src in zip(sp, sn, ys, e, strict=True):
        branch(p, q, cond)
        # a Norton source E / R_i into p, out of q
        if p >= 0:
            j[p] += cond * src
        if q >= 0:
            j[q] -= cond * src
    f = g @ v - j
    pot = lambda node: v[node] if node >= 0 else 0.0  # noqa: E731
    lim = LIMITS
    for k in range(len(tc)):
        u = max(pot(tc[k]) - pot(tr[k]), lim["u_floor"])
        av = min(max((u - lim["min1_v"]) / (lim["full_v"] - lim["min1_v"]), 0.0), 1.0)
        rv = min(max((lim["regen_zero_v"] - u) / (lim["regen_zero_v"] - lim["regen_full_v"]), 0.0), 1.0)
        i = (tw[k] * av + aw[k] - rw[k] * rv) / u
        if tc[k] >= 0:
            f[tc[k]] += i
        if tr[k] >= 0:
            f[tr[k]] -= i
    for k in range(len(dp)):
        x = de[k] - (pot(dp[k]) - pot(dn[k]))
        fwd = x if x >= delta else (0.0 if x <= -delta else (x + delta) ** 2 / (4 * delta))
        i = (fwd + share * (x - fwd)) * dy[k]
        if dn[k] >= 0:
            f[dn[k]] += i
        if dp[k] >= 0:
            f[dp[k]] -= i
    return f


@pytest.mark.parametrize("share", [0.0, 0.1])
def test_residual_against_a_hand_assembled_network(share):
    rng = np.random.default_rng(14)
    for _ in range(5):
        a, b, y, sp, sn, ys, e, dp, dn, de, dy, tc, tr, tw, aw, rw, v = _random_network(rng)
        # one diode inside its rounding, one blocked: every branch of the rounding is used
        v[2] = de[0] + 0.003
        delta = 7.5e-3
        f, uu, p = _solver_c.dc_residual_full(
            v, a, b, y, sp, sn, ys, e, dp, dn, de, dy, tc, tr, tw, aw, rw, *LIMITS.values(), delta, share
        )
        ref = _reference_residual(a, b, y, sp, sn, ys, e, dp, dn, de, dy, tc, tr, tw, aw, rw, v, delta, share)
        scale = np.max(np.abs(ys * e))
        np.testing.assert_allclose(f, ref, rtol=0, atol=1e-12 * scale)
        assert len(uu) == len(p) == len(tc) and np.all(uu >= LIMITS["u_floor"])


def _two_feeds(diode: bool, power_w: float):
    """Two sources (E1, r1), (E2, r2) feeding one train through contact segments R1, R2 (ideal
    return, earth = rail): nodes 0 (source 1), 1 (train), 2 (source 2)."""
    e1, e2, r1, r2, rl1, rl2 = 850.0, 840.0, 0.03, 0.05, 0.04, 0.06
    a, b, y = np.array([0, 1], I64), np.array([1, 2], I64), np.array([1 / rl1, 1 / rl2])
    none_i, none_f = np.empty(0, I64), np.empty(0)
    sources = (np.array([0, 2], I64), np.array([-1, -1], I64), np.array([1 / r1, 1 / r2]), np.array([e1, e2]))
    linear = (none_i, none_i, none_f, none_f) if diode else sources
    diodes = sources if diode else (none_i, none_i, none_f, none_f)
    ra, rb = r1 + rl1, r2 + rl2
    e_th = (e1 / ra + e2 / rb) / (1 / ra + 1 / rb)
    r_th = 1 / (1 / ra + 1 / rb)
    # constant power P at u: u (E_th - u) / R_th = P, the upper root
    u = (e_th + math.sqrt(e_th**2 - 4 * r_th * power_w)) / 2
    args = (
        a, b, y, *linear, *diodes[:2], diodes[3], diodes[2], np.array([1], I64), np.array([-1], I64),
        np.array([power_w]), np.zeros(1), np.zeros(1),
    )  # fmt: skip
    return args, u


@pytest.mark.parametrize("diode", [False, True])
def test_newton_against_the_closed_form_of_one_train(diode):
    """A train taking 2 MW (full traction above 600 V): its voltage is the upper root of
    u (E_th - u) / R_th = P; with diode rectifiers that both conduct (well beyond the rounding) the
    same."""
    args, u_exact = _two_feeds(diode, 2e6)
    v0 = np.full(3, 845.0)
    place = np.array([0, 1, 2], I64)
    lim = (0.75, 500.0, 600.0, 850.0, 900.0)
    v, its, converged, singular = _solver_c.newton_dc_dense(
        v0, place, *args, *lim, 7.5e-3, 0.0, False, 60, 1e-10, 1e-9, 225.0
    )
    assert converged and not singular and 1 <= its <= 10
    assert v[1] == pytest.approx(u_exact, rel=1e-12)
    # the unknowns in another order: the same solution
    v2, _, converged2, _ = _solver_c.newton_dc_dense(
        v0, np.array([2, 0, 1], I64), *args, *lim, 7.5e-3, 0.0, False, 60, 1e-10, 1e-9, 225.0
    )
    assert converged2 and v2 == pytest.approx(v, rel=1e-13)


def test_newton_reports_a_singular_jacobian():
    """A node joined to nothing: no pivot in its column, reported rather than raised."""
    args, _ = _two_feeds(False, 1e6)
    v0 = np.array([845.0, 845.0, 845.0, 0.0])
    lim = (0.75, 500.0, 600.0, 850.0, 900.0)
    _, _, converged, singular = _solver_c.newton_dc_dense(
        v0, np.arange(4, dtype=I64), *args, *lim, 7.5e-3, 0.0, False, 60, 7.5e-8, 1e-6, 225.0
    )
    assert singular and not converged


def test_diode_rounding_against_its_definition():
    delta = 7.5e-3
    for x in (-1.0, -delta, -delta / 2, 0.0, delta / 3, delta, 2.0):
        inner = (x + delta) ** 2 / (4 * delta)
        want = x if x >= delta else (0.0 if x <= -delta else inner)
        slope = 1.0 if x >= delta else (0.0 if x <= -delta else (x + delta) / (2 * delta))
        assert _solver_c.diode_forward_scalar(x, delta) == want
        assert _solver_c.diode_forward_slope_scalar(x, delta) == slope
    # value and slope continuous at both ends of the rounding
    assert _solver_c.diode_forward_scalar(delta * (1 - 1e-12), delta) == pytest.approx(delta, rel=1e-9)
    assert _solver_c.diode_forward_slope_scalar(delta * (1 - 1e-12), delta) == pytest.approx(1.0, rel=1e-9)
    assert _solver_c.diode_forward_scalar(-delta * (1 - 1e-9), delta) == pytest.approx(0.0, abs=1e-15)


def test_band_solver_and_stamping_against_numpy():
    rng = np.random.default_rng(3)
    for n, w in ((1, 0), (6, 1), (50, 4), (90, 7)):
        a = rng.integers(0, n, 3 * n).astype(I64)
        b = np.clip(a + rng.integers(-w, w + 1, 3 * n), -1, n - 1).astype(I64)
        y = rng.uniform(0.1, 10.0, 3 * n)
        jac = np.zeros((n, n))
        _solver_c.stamp_dense(jac, a, b, y)
        ref = np.zeros((n, n))
        for p, q, c in zip(a, b, y, strict=True):
            ref[p, p] += c
            if q >= 0:
                ref[q, q] += c
                ref[p, q] -= c
                ref[q, p] -= c
        np.testing.assert_allclose(jac, ref, rtol=1e-14, atol=1e-12)
        wb = _solver_c.half_bandwidth(((a, b),))
        assert wb <= w
        # the stamps plus random entries within the band, zero pivots where rows must be exchanged
        i, j = np.indices((n, n))
        jac = jac + np.where(np.abs(i - j) <= wb, rng.normal(size=(n, n)), 0.0)
        if n > 1:
            jac[np.arange(0, n, 3), np.arange(0, n, 3)] = 0.0
        rhs = rng.normal(size=n)
        ref_x = np.linalg.solve(jac, rhs)
        x, singular = _solver_c.band_solve(jac.copy(), rhs.copy(), wb)
        assert not singular
        np.testing.assert_allclose(x, ref_x, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref_x)))
    _, singular = _solver_c.band_solve(np.diag([1.0, 0.0, 2.0]), np.ones(3), 0)
    assert singular


def test_stray_current_against_the_numpy_form():
    rng = np.random.default_rng(9)
    k = 200
    va, vb = rng.normal(0, 20, k), rng.normal(0, 20, k)
    length = rng.uniform(0.05, 3000.0, k)
    r, g = np.full(k, 0.015e-3), rng.choice([0.0, 1e-7, 1e-4], k)
    got = _rail_c.segment_leakage_total_a(va, vb, length, r, g)
    assert got == pytest.approx(math.fsum(segment_leakage_a(va, vb, length, r, g)), rel=1e-12)
    assert _rail_c.segment_leakage_total_a(va[:0], vb[:0], length[:0], r[:0], g[:0]) == 0.0


def test_bad_input_names_the_argument():
    args, _ = _two_feeds(False, 1e6)
    lim = (0.75, 500.0, 600.0, 850.0, 900.0, 7.5e-3, 0.0)
    with pytest.raises(ValueError, match=r"^a\[1\]: node 7, need -1 \(earth\) or 0 \.\. 2"):
        _solver_c.dc_residual_full(np.zeros(3), np.array([0, 7], I64), *args[1:], *lim)
    with pytest.raises(ValueError, match=r"^y: length 1, need the length of a \(2\)"):
        _solver_c.dc_residual_full(np.zeros(3), args[0], args[1], np.ones(1), *args[3:], *lim)
    with pytest.raises(ValueError, match=r"^place\[0\]: 5, need a place 0 \.\. 2"):
        _solver_c.newton_dc_dense(np.zeros(3), np.array([5, 0, 1]), *args, *lim, False, 60, 1e-8, 1e-6, 225.0)
    with pytest.raises(ValueError, match=r"^mat: need a writable C-contiguous square float64"):
        _solver_c.band_solve(np.ones((2, 3)), np.ones(2), 1)
    with pytest.raises(ValueError, match=r"^tc: need a 1-D array of integers"):
        _solver_c.dc_residual_full(np.zeros(3), *args[:11], np.array([0.5]), *args[12:], *lim)
    with pytest.raises(ValueError, match=r"^length_m: length 1, need the length of va_v \(2\)"):
        _rail_c.segment_leakage_total_a(np.ones(2), np.ones(2), np.ones(1), np.ones(2), np.ones(2))
    with pytest.raises(ZeroDivisionError, match="track 0's contact or rail resistance is 0"):
        _solver_c.assemble_dc_kernel(
            2, np.array([0], I64), np.array([5.0]), np.array([0.0, 10.0]), np.array([0, 2], I64),
            np.array([0, 1], I64), np.array([-1, -1], I64), np.empty(0), np.empty(0), np.array([0, 0], I64),
            np.array([0.0]), np.array([0.0]), np.array([0.0]), 1e-9, True, 1e-9,
        )  # fmt: skip


def test_the_solver_loads_no_numba():
    code = "import sys, trainsim.power.solver, trainsim.power.rail; print('numba' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "False"
