"""One time step of the DC network against closed-form solutions; rectifier states; bad input."""

from __future__ import annotations

import numpy as np
import pytest
from powercases import NO_LIMITS, two_substations

from trainsim.errors import InputError
from trainsim.power import Connection, Gap, Network, StepLoads, Substation, Track, solve_step, standard_limits
from trainsim.power.limits import regen_acceptance, traction_availability


def _loads(track, x, traction, regen=None, aux=None) -> StepLoads:
    x = np.atleast_1d(np.asarray(x, dtype=float))
    n = len(x)
    zeros = np.zeros(n)
    return StepLoads(
        np.full(n, track) if np.isscalar(track) else np.asarray(track),
        x,
        np.atleast_1d(np.asarray(traction, dtype=float)),
        zeros if regen is None else np.atleast_1d(np.asarray(regen, dtype=float)),
        zeros if aux is None else np.atleast_1d(np.asarray(aux, dtype=float)),
        zeros,
    )


def closed_form_voltage(e1, r1, e2, r2, r_loop_per_m, length, x, p):
    """Constant-power load P between two Thevenin sources over a resistive line: the Thevenin
    equivalent seen by the train (E_th, R_th), then U = (E_th + sqrt(E_th^2 - 4 R_th P)) / 2, the
    high-voltage root of U (E_th - U) / R_th = P."""
    ra = r1 + r_loop_per_m * x
    rb = r2 + r_loop_per_m * (length - x)
    e_th = (e1 * rb + e2 * ra) / (ra + rb)
    r_th = ra * rb / (ra + rb)
    return (e_th + np.sqrt(e_th**2 - 4 * r_th * p)) / 2, e_th, r_th


@pytest.mark.parametrize(("x", "p"), [(1500.0, 3e6), (10.0, 1e6), (3999.9, 4e6), (2000.0, -2e6)])
def test_one_train_between_two_substations_closed_form(x, p):
    net = two_substations()
    traction, regen = (p, 0.0) if p > 0 else (0.0, -p)
    sol = solve_step(net, _loads(0, x, traction, regen), np.ones(2, dtype=bool))
    u, _, _ = closed_form_voltage(835.0, 0.03, 825.0, 0.05, 0.035e-3, 4000.0, x, p)
    assert sol.converged
    assert sol.train_voltage_v[0] == pytest.approx(u, rel=1e-9)
    assert sol.train_power_w[0] == pytest.approx(p, rel=1e-12)
    # substation currents from the two branches of the closed form
    i1 = (835.0 - u) / (0.03 + 0.035e-3 * x)
    i2 = (825.0 - u) / (0.05 + 0.035e-3 * (4000.0 - x))
    assert sol.substation_current_a == pytest.approx([i1, i2], rel=1e-8, abs=1e-6)
    # power balance at the step: sources = train + losses
    assert np.sum(sol.substation_source_w) == pytest.approx(
        sol.train_power_w[0] + sol.line_loss_w + sol.substation_loss_w, rel=1e-8
    )


def test_non_reversible_substation_never_takes_power():
    """A regenerating train next to S2: S2 (a diode rectifier) blocks and takes nothing; S1 is
    then the only path; with reversible substations S2 takes power back."""
    p = 1.5e6
    blocked = solve_step(
        two_substations(e1=800.0, e2=800.0, reversible=False), _loads(0, 3900.0, 0.0, p), np.ones(2, bool)
    )
    assert blocked.converged
    assert not blocked.substation_on.any()  # S1 too is beyond its no-load voltage: the train curtails
    assert np.all(blocked.substation_power_w >= -1e-9)
    # with an auxiliary load at S1's end both can be seen: S1 supplies nothing, S2 nothing
    rev = solve_step(
        two_substations(e1=800.0, e2=800.0, reversible=True), _loads(0, 3900.0, 0.0, p), np.ones(2, bool)
    )
    assert rev.substation_power_w[1] < -1e5  # taken back
    u, _, _ = closed_form_voltage(800.0, 0.03, 800.0, 0.05, 0.035e-3, 4000.0, 3900.0, -p)
    assert rev.train_voltage_v[0] == pytest.approx(u, rel=1e-9)


def test_diode_blocks_one_substation_only():
    """Train drawing near S1 (E1 = 835 V) and a regenerating train near S2 (E2 = 800 V): S2's
    busbar rises above 800 V, it blocks, and the regenerated power flows to the other train."""
    net = two_substations(e1=835.0, e2=800.0, reversible=False)
    sol = solve_step(net, _loads(0, [500.0, 3800.0], [3e6, 0.0], [0.0, 1e6]), np.ones(2, bool))
    assert sol.converged
    assert sol.substation_on.tolist() == [True, False]
    assert 0.0 <= sol.substation_power_w[1] < 0.1  # blocked: only the rounding current of the diode
    assert sol.substation_power_w[0] > 0
    # S2's busbar is above its no-load voltage (complementarity: blocked <=> U > E)
    assert sol.train_voltage_v[1] > 800.0


def test_traction_limitation_and_regen_curtailment_functions():
    lim = standard_limits("dc_750")
    assert (lim.min1_v, lim.nominal_v, lim.max1_v, lim.max2_v) == (500.0, 750.0, 900.0, 1000.0)
    assert traction_availability([400, 500, 587.5, 675, 800], 500, 675).tolist() == [0, 0, 0.5, 1, 1]
    assert regen_acceptance([850, 900, 950, 1000, 1100], 900, 1000).tolist() == [1, 1, 0.5, 0, 0]


def test_voltage_limited_train_draws_less_than_asked():
    """A weak line: the train asks 3 MW but its voltage falls into the EN 50388 ramp; the power it
    draws is a(U) x 3 MW and satisfies the line equation U (E_th - U) / R_th = P(U)."""
    lim = standard_limits("dc_750")
    net = two_substations(contact_ohm_per_m=0.2e-3, rail_ohm_per_m=0.1e-3, limits=lim)
    sol = solve_step(net, _loads(0, 2000.0, 3e6), np.ones(2, bool))
    u = sol.train_voltage_v[0]
    assert lim.min1_v < u < lim.traction_full_v
    share = (u - lim.min1_v) / (lim.traction_full_v - lim.min1_v)
    assert sol.traction_share[0] == pytest.approx(share, rel=1e-12)
    _, e_th, r_th = closed_form_voltage(835.0, 0.03, 825.0, 0.05, 0.3e-3, 4000.0, 2000.0, 0.0)
    assert u * (e_th - u) / r_th == pytest.approx(3e6 * share, rel=1e-8)
    # closed form: U (E_th - U) / R_th = P (U - Umin1) / (U_full - Umin1), a quadratic in U
    k = r_th * 3e6 / (lim.traction_full_v - lim.min1_v)
    expected = (e_th - k + np.sqrt((e_th - k) ** 2 + 4 * k * lim.min1_v)) / 2
    assert u == pytest.approx(expected, rel=1e-9)
    assert e_th**2 / (4 * r_th) < 3e6  # the line could not give the 3 MW at any voltage


def test_two_tracks_with_paralleling_post_and_section_insulator():
    """Paralleling post, cross-bond and a section insulator: the balance closes, and cutting
    track B at 2500 m makes its train at 3000 m lose the feed from S1 over B's own contact line
    (its voltage falls). The voltages themselves are checked against PyPSA in test_pypsa.py."""
    lim = NO_LIMITS
    tracks = (Track("A", 0, 4000, 0.02e-3, 0.015e-3), Track("B", 0, 4000, 0.02e-3, 0.015e-3))
    net = Network(
        "2 tracks",
        "dc",
        lim,
        tracks,
        (
            Substation("S1", 0, ("A", "B"), 835, 0.03),
            Substation("S2", 4000, ("A", "B"), 825, 0.05, reversible=True),
        ),
        (Connection("PP", 1000, ("A", "B")), Connection("CB", 2000, ("A", "B"), kind="cross_bond")),
        (Gap("SI", "B", 2500, 2500),),
        contact_leakage_s=1e-12,
    )
    sol = solve_step(net, _loads([0, 1], [1500.0, 3000.0], [2e6, 1e6]), np.ones(2, bool))
    assert sol.converged
    assert np.sum(sol.substation_source_w) == pytest.approx(
        np.sum(sol.train_power_w) + sol.line_loss_w + sol.substation_loss_w, rel=1e-9
    )
    uncut = Network(
        "2 tracks", "dc", lim, tracks, net.substations, net.connections, (), contact_leakage_s=1e-12
    )
    ref = solve_step(uncut, _loads([0, 1], [1500.0, 3000.0], [2e6, 1e6]), np.ones(2, bool))
    assert sol.train_voltage_v[1] < ref.train_voltage_v[1] - 1.0


def _bad(**changes):
    base = dict(
        name="n",
        system="dc",
        limits=standard_limits("dc_750"),
        tracks=(Track("A", 0, 1000, 0.02e-3, 0.015e-3),),
        substations=(Substation("S1", 0, ("A",), 850, 0.03),),
    )
    base.update(changes)
    return Network(**base)


def test_bad_networks_are_input_errors():
    with pytest.raises(InputError, match="contact_resistance_ohm_per_km"):
        _bad(tracks=(Track("A", 0, 1000, -0.02e-3, 0.015e-3),))
    with pytest.raises(InputError, match="disconnected network"):
        _bad(gaps=(Gap("SI", "A", 500, 500),))
    with pytest.raises(InputError, match="position off track"):
        _bad(substations=(Substation("S1", 2000, ("A",), 850, 0.03),))
    with pytest.raises(InputError, match="unknown track"):
        _bad(substations=(Substation("S1", 0, ("X",), 850, 0.03),))
    with pytest.raises(InputError, match="internal_resistance_ohm"):
        _bad(substations=(Substation("S1", 0, ("A",), 850, 0.0),))
    with pytest.raises(InputError, match="unknown supply system"):
        standard_limits("dc_900")


def test_ac_train_between_two_substations_against_an_independent_solve():
    """AC: one train (P, Q) between two substations with complex impedances; the pantograph voltage
    from the fixed-point iteration equals the root of U = E_th - Z_th conj(S / U) found by scipy's
    fsolve on its real and imaginary parts (the Thevenin equivalent built by hand)."""
    from scipy.optimize import fsolve

    from trainsim.power import VoltageLimits

    lim = VoltageLimits(
        nominal_v=25e3, min2_v=1e3, min1_v=1e3, max1_v=4e4, max2_v=4.1e4, traction_full_v=1001.0
    )
    z_line = complex(0.19e-3, 0.41e-3)  # ohm/m
    z1, z2 = complex(0.25, 3.0), complex(0.3, 2.5)
    e1, e2 = 27500.0, 27000.0
    net = Network(
        "ac",
        "ac",
        lim,
        (Track("A", 0.0, 40000.0, z_line.real, 0.0, 0.0, z_line.imag),),
        (
            Substation("S1", 0.0, ("A",), e1, z1.real, z1.imag),
            Substation("S2", 40000.0, ("A",), e2, z2.real, z2.imag),
        ),
        contact_leakage_s=1e-15,
    )
    x, p, pf = 15000.0, 8e6, 0.95
    tan_phi = np.sqrt(1 - pf**2) / pf
    loads = StepLoads(
        np.array([0]), np.array([x]), np.array([p]), np.zeros(1), np.zeros(1), np.array([tan_phi])
    )
    sol = solve_step(net, loads)
    za, zb = z1 + z_line * x, z2 + z_line * (40000.0 - x)
    e_th = (e1 * zb + e2 * za) / (za + zb)
    z_th = za * zb / (za + zb)
    s = p * (1 + 1j * tan_phi)

    def residual(w):
        u = complex(w[0], w[1])
        r = u - (e_th - z_th * np.conj(s / u))
        return [r.real, r.imag]

    root = fsolve(residual, [e_th.real, e_th.imag], xtol=1e-14)
    assert sol.converged
    assert sol.train_voltage_v[0] == pytest.approx(abs(complex(*root)), rel=1e-9)
    assert np.sum(sol.substation_source_w) == pytest.approx(
        p + sol.line_loss_w + sol.substation_loss_w, rel=1e-8
    )
