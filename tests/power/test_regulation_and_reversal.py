"""Substation regulation curves (closed form, kinks) and non-reversible AC substations."""

from __future__ import annotations

import numpy as np
import pytest
from powercases import NO_LIMITS

from trainsim.errors import InputError
from trainsim.power import Network, StepLoads, Substation, Track, VoltageLimits, solve_step, standard_limits
from trainsim.power.network import regulation_points
from trainsim.power.regulation import regulation_current_a, regulation_voltage_v

#: a rectifier's regulation: 10 mohm up to 2 kA, 20 mohm up to 6 kA, 40 mohm beyond
CURVE = ((0.0, 850.0), (2000.0, 830.0), (6000.0, 750.0), (9000.0, 630.0))
LOOP_OHM_PER_M = 0.01e-3
LENGTH_M = 2000.0


def _one_substation(reversible: bool = False, curve=CURVE) -> Network:
    e, r = regulation_points(list(curve))
    return Network(
        "regulated",
        "dc",
        NO_LIMITS,
        (Track("A", 0.0, LENGTH_M, LOOP_OHM_PER_M),),  # ideal return: the loop is the contact line
        (Substation("S", 0.0, ("A",), e, r, reversible=reversible, regulation=tuple(curve)),),
        contact_leakage_s=1e-12,
    )


def _loads(x, traction, regen=0.0) -> StepLoads:
    z = np.zeros(1)
    return StepLoads(np.array([0]), np.array([x]), np.array([traction]), np.array([regen]), z, z)


def closed_form(p_w: float, curve=CURVE, r_line: float = LOOP_OHM_PER_M * LENGTH_M) -> tuple[float, float]:
    """(I, U) of a constant-power load P at the end of a line R fed by a piecewise-linear source:
    on segment k the source is a_k - R_k I, so P = I (a_k - (R_k + R) I), the smaller root; the
    segment is the one whose current range holds that root."""
    pts = np.asarray(curve)
    for k in range(len(pts) - 1):
        (i0, u0), (i1, u1) = pts[k], pts[k + 1]
        r_k = -(u1 - u0) / (i1 - i0)
        a_k = u0 + r_k * i0
        disc = a_k**2 - 4 * (r_k + r_line) * p_w
        i = (a_k - np.sqrt(disc)) / (2 * (r_k + r_line))
        last = k == len(pts) - 2
        if (i0 - 1e-9 <= i <= i1 + 1e-9) or (last and i > i1) or (k == 0 and i < i0):
            return i, p_w / i
    raise AssertionError("no segment")


def test_curve_functions_and_inverse():
    ci, cu = np.array([q[0] for q in CURVE]), np.array([q[1] for q in CURVE])
    assert regulation_voltage_v(1000.0, ci, cu) == pytest.approx(840.0, rel=1e-15)
    assert regulation_voltage_v(10000.0, ci, cu) == pytest.approx(590.0, rel=1e-15)  # end extended
    assert regulation_voltage_v(-1000.0, ci, cu) == pytest.approx(860.0, rel=1e-15)
    for i in (-500.0, 0.0, 1999.0, 2000.0, 4500.0, 9000.0):
        back, slope = regulation_current_a(regulation_voltage_v(i, ci, cu), ci, cu)
        assert back == pytest.approx(i, abs=1e-9)
        assert slope < 0
    # at the kink the higher-current segment's slope is taken
    assert regulation_current_a(830.0, ci, cu)[1] == pytest.approx(-1 / 0.02)
    assert regulation_points(list(CURVE)) == (850.0, pytest.approx(0.01))


@pytest.mark.parametrize("reversible", [True, False])
@pytest.mark.parametrize(
    ("p_w", "segment"),
    [(0.8e6, 0), (1.58e6, "kink"), (3.0e6, 1), (3.9e6, 2)],
)
def test_regulated_substation_feeding_one_train_closed_form(p_w, segment, reversible):
    """Exact (1e-9) for a reversible substation; a diode rectifier's current is rounded over
    7.5 mV of R_1 I (solver.DIODE_SMOOTHING_SHARE), which moves the voltage by at most
    R_total d^2 / (4 R_1 I) (2e-6 V at 0.8 MW): 1e-8 there."""
    i, u = closed_form(p_w)
    if segment == "kink":
        assert i == pytest.approx(2000.0, rel=1e-12)  # 1.58 MW sits exactly on the first kink
    sol = solve_step(_one_substation(reversible), _loads(LENGTH_M, p_w))
    assert sol.converged
    assert sol.train_voltage_v[0] == pytest.approx(u, rel=1e-9 if reversible else 1e-8)
    assert sol.substation_current_a[0] == pytest.approx(i, rel=1e-8)
    # the busbar is on the curve: U_s = U(I)
    ci, cu = np.array([q[0] for q in CURVE]), np.array([q[1] for q in CURVE])
    u_bus = sol.substation_power_w[0] / sol.substation_current_a[0]
    assert u_bus == pytest.approx(regulation_voltage_v(i, ci, cu), rel=1e-9 if reversible else 1e-8)
    # balance: E I = train + line + substation losses
    assert sol.substation_source_w[0] == pytest.approx(
        sol.train_power_w[0] + sol.line_loss_w + sol.substation_loss_w, rel=1e-8
    )


def test_two_point_curve_equals_the_thevenin_source():
    """A curve of two points is a Thevenin source: same solution as E, R_i without a curve."""
    curve = ((0.0, 850.0), (5000.0, 800.0))
    with_curve = solve_step(_one_substation(curve=curve), _loads(1200.0, 2e6))
    plain = Network(
        "plain", "dc", NO_LIMITS, (Track("A", 0.0, LENGTH_M, LOOP_OHM_PER_M),),
        (Substation("S", 0.0, ("A",), 850.0, 0.01, reversible=False),), contact_leakage_s=1e-12,
    )  # fmt: skip
    without = solve_step(plain, _loads(1200.0, 2e6))
    assert with_curve.train_voltage_v[0] == pytest.approx(without.train_voltage_v[0], rel=1e-12)


def test_regulated_diode_never_takes_power_and_reversible_follows_the_curve_backwards():
    """A regenerating train: the diode rectifier with a curve blocks (the train curtails to what
    the line leakage and nothing else takes, so its voltage rises into the curtailment ramp);
    the reversible one takes the power back along the first segment extended (E + R_1 |I|)."""
    lim = standard_limits("dc_750")
    p = 1e6
    diode = solve_step(
        Network("d", "dc", lim, (Track("A", 0.0, LENGTH_M, LOOP_OHM_PER_M),),
                (Substation("S", 0.0, ("A",), 850.0, 0.01, reversible=False, regulation=CURVE),)),
        _loads(LENGTH_M, 0.0, p),
    )  # fmt: skip
    assert diode.converged
    assert diode.substation_power_w[0] >= 0.0
    assert diode.substation_power_w[0] < 1.0
    assert lim.regen_full_v < diode.train_voltage_v[0] < lim.regen_zero_v
    rev = solve_step(_one_substation(reversible=True), _loads(LENGTH_M, 0.0, p))
    # -P = I (a_0 - (R_1 + R) I) with I < 0 on the first segment extended
    r = 0.01 + LOOP_OHM_PER_M * LENGTH_M
    i = (850.0 - np.sqrt(850.0**2 + 4 * r * p)) / (2 * r)
    assert rev.converged
    assert rev.substation_current_a[0] == pytest.approx(i, rel=1e-8)
    assert rev.train_voltage_v[0] == pytest.approx(-p / i, rel=1e-9)


@pytest.mark.parametrize(
    ("curve", "words"),
    [
        (((0.0, 850.0), (2000.0, 850.0)), "strictly decrease"),
        (((100.0, 850.0), (2000.0, 800.0)), "current 0"),
        (((0.0, 850.0),), "at least two"),
    ],
)
def test_bad_regulation_curves_are_input_errors(curve, words):
    with pytest.raises(InputError, match=words):
        Network(
            "bad", "dc", NO_LIMITS, (Track("A", 0.0, LENGTH_M, LOOP_OHM_PER_M),),
            (Substation("S", 0.0, ("A",), 850.0, 0.01, regulation=curve),),
        )  # fmt: skip


def test_regulation_must_agree_with_e_and_r():
    with pytest.raises(InputError, match="disagrees"):
        Network(
            "bad", "dc", NO_LIMITS, (Track("A", 0.0, LENGTH_M, LOOP_OHM_PER_M),),
            (Substation("S", 0.0, ("A",), 840.0, 0.01, regulation=CURVE),),
        )  # fmt: skip


# ---- AC: the reversible flag ------------------------------------------------------------------
AC_LIMITS = VoltageLimits(
    nominal_v=25e3, min2_v=1e3, min1_v=1e3, max1_v=4e4, max2_v=4.1e4, traction_full_v=1001.0
)


def _ac(reversible: bool) -> Network:
    z_line = complex(0.19e-3, 0.41e-3)
    return Network(
        "ac", "ac", AC_LIMITS, (Track("A", 0.0, 40000.0, z_line.real, 0.0, 0.0, z_line.imag),),
        (
            Substation("S1", 0.0, ("A",), 27500.0, 0.25, 3.0, reversible=reversible),
            Substation("S2", 40000.0, ("A",), 27500.0, 0.3, 2.5, reversible=reversible),
        ),
        contact_leakage_s=1e-15,
    )  # fmt: skip


def _ac_loads(x, traction, regen) -> StepLoads:
    n = len(x)
    return StepLoads(np.zeros(n, dtype=np.int64), np.asarray(x, float), np.asarray(traction, float),
                     np.asarray(regen, float), np.zeros(n), np.zeros(n))  # fmt: skip


def test_ac_non_reversible_substation_never_takes_power():
    """A train drawing 4 MW near S1 and one regenerating 3 MW near S2: a reversible S2 takes
    power back; a non-reversible S2 opens (no current), the regenerated power goes to the other
    train, and the solution is that of the same network without S2."""
    loads = _ac_loads([2000.0, 38000.0], [4e6, 0.0], [0.0, 3e6])
    rev = solve_step(_ac(True), loads)
    assert rev.converged and rev.substation_power_w[1] < -1e5
    non = solve_step(_ac(False), loads)
    assert non.converged
    assert non.substation_on.tolist() == [True, False]
    assert non.substation_power_w[1] == 0.0 and non.substation_current_a[1] == 0.0
    assert np.all(non.substation_power_w >= 0.0)
    # S1 alone: the same circuit with S2 removed
    z_line = complex(0.19e-3, 0.41e-3)
    alone = Network(
        "ac1", "ac", AC_LIMITS, (Track("A", 0.0, 40000.0, z_line.real, 0.0, 0.0, z_line.imag),),
        (Substation("S1", 0.0, ("A",), 27500.0, 0.25, 3.0, reversible=False),), contact_leakage_s=1e-15,
    )  # fmt: skip
    ref = solve_step(alone, loads)
    assert non.train_voltage_v == pytest.approx(ref.train_voltage_v, rel=1e-9)
    assert non.substation_power_w[0] == pytest.approx(ref.substation_power_w[0], rel=1e-9)
    assert np.sum(non.substation_source_w) == pytest.approx(
        np.sum(non.train_power_w) + non.line_loss_w + non.substation_loss_w, rel=1e-8
    )


def test_ac_non_reversible_substations_both_deliver_when_loaded():
    loads = _ac_loads([15000.0], [8e6], [0.0])
    a, b = solve_step(_ac(True), loads), solve_step(_ac(False), loads)
    assert b.substation_on.all()
    assert b.train_voltage_v == pytest.approx(a.train_voltage_v, rel=1e-12)
