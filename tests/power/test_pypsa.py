"""Independent cross-check of the DC solver with PyPSA's Newton-Raphson power flow.

PyPSA 1.4's power flow for sub-networks of carrier DC fails ("Non-AC networks not supported for
Y"), so the same DC circuit is given to its AC power flow with zero reactance and zero reactive
power: with a real admittance matrix and real injections its equations are exactly the DC ones
(all angles stay 0). The return is ideal on both sides (rail resistance 0: rails = reference),
since PyPSA's loads are bus-to-ground; the substations share one no-load voltage E, so they are one
slack bus at E behind one line of resistance R_i each (equal-voltage Thevenin sources in parallel
share their source node). Loads and regenerated power are constant-power, without limitation.
"""

from __future__ import annotations

import logging
import os
import warnings
from itertools import pairwise

import numpy as np
import pytest
from powercases import NO_LIMITS

from trainsim.power import Connection, Gap, Network, StepLoads, Substation, Track, solve_step, solver

E_V = 850.0
R_C = 0.03e-3  # contact line + return lumped [ohm/m]


def _pypsa():
    try:
        import pypsa
    except ImportError:
        if os.environ.get("CI") == "true":
            pytest.fail(
                "PyPSA is not installed: install the test extra (pip install -e '.[test]' with pypsa)"
            )
        pytest.skip("PyPSA is not installed (pip install pypsa): the independent cross-check cannot run")
    return pypsa


def _case():
    tracks = (Track("A", 0.0, 9000.0, R_C, 0.0), Track("B", 0.0, 9000.0, R_C, 0.0))
    subs = (
        Substation("S1", 0.0, ("A", "B"), E_V, 0.025, reversible=True),
        Substation("S2", 4500.0, ("A", "B"), E_V, 0.04, reversible=True),
        Substation("S3", 9000.0, ("A", "B"), E_V, 0.03, reversible=True),
    )
    net = Network(
        "pypsa check",
        "dc",
        NO_LIMITS,
        tracks,
        subs,
        (Connection("PP", 2200.0, ("A", "B")),),
        (Gap("SI", "B", 6000.0, 6000.0),),  # B beyond 6 km fed from S3 only
        contact_leakage_s=1e-13,
    )
    trains = [
        ("A", 1000.0, 2.5e6),
        ("A", 3100.0, -1.2e6),
        ("A", 7700.0, 3.0e6),
        ("B", 2200.0, 1.0e6),
        ("B", 5200.5, 2.0e6),
        ("B", 8000.0, 0.8e6),
    ]
    return net, trains


def _pypsa_voltages(pypsa, trains):
    """Build the same circuit in PyPSA by hand (nodes at every substation, post and train)."""
    n = pypsa.Network()
    v_nom_kv = E_V / 1000
    n.add("Bus", "E", v_nom=v_nom_kv)
    n.add("Generator", "grid", bus="E", control="Slack")
    points = {"A": {0.0, 2200.0, 4500.0, 9000.0}, "B": {0.0, 2200.0, 4500.0, 9000.0}}
    for tr, x, _ in trains:
        points[tr].add(x)
    bus = {}
    shared = {0.0: "S1", 2200.0: "PP", 4500.0: "S2"}
    for tr, xs in points.items():
        for x in xs:
            name = shared.get(x, "S3" if x == 9000.0 else f"{tr}{x}")
            bus[tr, x] = name
            if name not in n.buses.index:
                n.add("Bus", name, v_nom=v_nom_kv)
    for tr, xs in points.items():
        xs = sorted(xs)
        for x0, x1 in pairwise(xs):
            if tr == "B" and x0 < 6000.0 <= x1:
                continue  # section insulator
            n.add(
                "Line",
                f"{tr}{x0}-{x1}",
                bus0=bus[tr, x0],
                bus1=bus[tr, x1],
                r=R_C * (x1 - x0),
                x=0.0,
                s_nom=1e3,
            )
    for name, r in (("S1", 0.025), ("S2", 0.04), ("S3", 0.03)):
        n.add("Line", f"int-{name}", bus0="E", bus1=name, r=r, x=0.0, s_nom=1e3)
    for k, (tr, x, p) in enumerate(trains):
        n.add("Load", f"T{k}", bus=bus[tr, x], p_set=p / 1e6, q_set=0.0)
    n.pf(x_tol=1e-13)
    vm = n.buses_t.v_mag_pu.iloc[0]
    va = n.buses_t.v_ang.iloc[0]
    assert np.max(np.abs(va)) < 1e-12
    return np.array([vm[bus[tr, x]] * E_V for tr, x, _ in trains])


def test_dc_solver_matches_pypsa_power_flow():
    pypsa = _pypsa()
    logging.getLogger("pypsa").setLevel(logging.ERROR)
    net, trains = _case()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        expected = _pypsa_voltages(pypsa, trains)
    p = np.array([t[2] for t in trains])
    loads = StepLoads(
        np.array([net.track_index(t[0]) for t in trains]),
        np.array([t[1] for t in trains]),
        np.maximum(p, 0.0),
        np.maximum(-p, 0.0),
        np.zeros(len(p)),
        np.zeros(len(p)),
    )
    sol = solve_step(net, loads, np.ones(3, dtype=bool))
    assert sol.converged
    assert np.max(np.abs(sol.train_voltage_v - expected)) < 1e-6


# ---- diode rectifiers blocked by a regenerating train, rails as their own branches --------------------
#
# The return is no longer ideal: every track's rails are a resistance of their own (R_R per metre, a
# different ratio to the contact line's, so that the circuit is not the lumped one above), joined
# between the tracks by a cross-bond where the contact lines are not, continuous under the section
# insulator, and earthed at the substations' negative busbars (``negative_earthed``), which are one bus
# of fixed potential in PyPSA (a slack of its own: the rails and the contact lines are two
# sub-networks there). A train is a load between its contact and rail buses, and PyPSA's loads are
# bus to ground: it is given as two constant-power loads, V_c I at its contact bus and -V_r I at its
# rail bus (potentials to PyPSA's ground), from trainsim's potentials and current (I = P / (V_c -
# V_r)); their sum is the train's power P = (V_c - V_r) I. PyPSA then solves its own
# circuit for those loads: if trainsim's potentials satisfy Kirchhoff's laws of that circuit, PyPSA
# finds them again (trainsim's solution is a fixed point of the split; an error in any branch, rail
# or contact, or a wrong rectifier would move PyPSA's voltages away by the error's effect). (Iterating
# the split on PyPSA's own voltages from V_r = 0 instead needs dozens of PyPSA power flows, minutes on
# the shared machine.) The diode rectifiers' states are taken from trainsim: each is a line from the
# common source E through R_i if trainsim found it conducting, and open if blocked.

R_R = 0.02e-3  # rails [ohm/m]
EARTH_V = 100.0  # PyPSA's potential of the earth [V] (see _pypsa_two_layer_voltages)
DIODE_R = {"S1": 0.025, "S2": 0.04, "S3": 0.03}
SUB_X = {"S1": 0.0, "S2": 4500.0, "S3": 9000.0}
PP_X, XB_X, SI_X = 2200.0, 6800.0, 6000.0
DIODE_TRAINS = [
    ("A", 1000.0, 0.9e6),
    ("A", 3100.0, 0.4e6),
    ("A", 7700.0, 0.5e6),
    ("B", 2900.0, 0.6e6),
    ("B", 5200.5, 0.3e6),
    ("B", 8000.0, -2.4e6),  # regenerating where track B is fed from S3 alone
]


def _diode_case(trains):
    tracks = (Track("A", 0.0, 9000.0, R_C, R_R), Track("B", 0.0, 9000.0, R_C, R_R))
    subs = tuple(Substation(k, SUB_X[k], ("A", "B"), E_V, r, reversible=False) for k, r in DIODE_R.items())
    return Network(
        "pypsa diode check",
        "dc",
        NO_LIMITS,
        tracks,
        subs,
        (Connection("PP", PP_X, ("A", "B")), Connection("XB", XB_X, ("A", "B"), "cross_bond")),
        (Gap("SI", "B", SI_X, SI_X),),
        negative_earthed=True,
        contact_leakage_s=1e-13,  # left out in PyPSA: it moves no voltage by 1e-9 V
    )


def _pypsa_two_layer_voltages(pypsa, trains, conducting, vc, vr):
    """Contact and rail potentials at ``trains`` in PyPSA with the rails as their own branches, each
    train's power split between its buses from the contact and rail potentials ``vc``, ``vr`` [V]
    (see above)."""
    n = pypsa.Network()
    v_nom_kv = E_V / 1000
    # PyPSA's potentials are to its own ground: the earthed negatives are a bus "earth" at EARTH_V and
    # every potential is shifted by as much, so that every bus stays positive (a rail near a
    # regenerating train is negative against earth; PyPSA's flat start would find another root there)
    n.add("Bus", "E", v_nom=v_nom_kv, v_mag_pu_set=(E_V + EARTH_V) / E_V)
    n.add("Generator", "grid", bus="E", control="Slack")
    n.add("Bus", "earth", v_nom=v_nom_kv, v_mag_pu_set=EARTH_V / E_V)
    n.add("Generator", "earthing", bus="earth", control="Slack")
    fixed = {0.0, PP_X, SUB_X["S2"], XB_X, 9000.0}
    points = {"A": set(fixed), "B": set(fixed)}
    for tr, x, _ in trains:
        points[tr].add(x)
    sub_at = {x: k for k, x in SUB_X.items()}
    contact, rail = {}, {}
    for tr, xs in points.items():
        for x in xs:
            contact[tr, x] = f"{sub_at[x]}c" if x in sub_at else ("PPc" if x == PP_X else f"{tr}{x}c")
            # rails: earthed at the substations' negatives, joined between the tracks by the cross-bond
            rail[tr, x] = "earth" if x in sub_at else ("XBr" if x == XB_X else f"{tr}{x}r")
    for name in {*contact.values(), *rail.values()} - {"earth"}:
        n.add("Bus", name, v_nom=v_nom_kv)
    for tr, xs in points.items():
        for x0, x1 in pairwise(sorted(xs)):
            if not (tr == "B" and x0 < SI_X <= x1):  # the section insulator cuts the contact line only
                n.add("Line", f"{tr}{x0}-{x1}c", bus0=contact[tr, x0], bus1=contact[tr, x1],
                      r=R_C * (x1 - x0), x=0.0, s_nom=1e3)  # fmt: skip
            if rail[tr, x0] != rail[tr, x1]:
                n.add("Line", f"{tr}{x0}-{x1}r", bus0=rail[tr, x0], bus1=rail[tr, x1],
                      r=R_R * (x1 - x0), x=0.0, s_nom=1e3)  # fmt: skip
    for name, on in conducting.items():
        if on:  # a blocked rectifier is open
            n.add("Line", f"int-{name}", bus0="E", bus1=f"{name}c", r=DIODE_R[name], x=0.0, s_nom=1e3)
    i = np.array([t[2] for t in trains]) / (vc - vr)
    for k, (tr, x, _) in enumerate(trains):
        n.add("Load", f"T{k}c", bus=contact[tr, x], p_set=(vc[k] + EARTH_V) * i[k] / 1e6, q_set=0.0)
        if rail[tr, x] != "earth":
            n.add("Load", f"T{k}r", bus=rail[tr, x], p_set=-(vr[k] + EARTH_V) * i[k] / 1e6, q_set=0.0)
    n.pf(x_tol=1e-13)
    assert np.max(np.abs(n.buses_t.v_ang.iloc[0])) < 1e-12  # DC: every potential real
    v = n.buses_t.v_mag_pu.iloc[0] * E_V - EARTH_V
    new_c = np.array([v[contact[tr, x]] for tr, x, _ in trains])
    new_r = np.array([v[rail[tr, x]] for tr, x, _ in trains])
    return new_c, new_r


def test_diode_rectifiers_blocked_and_rails_as_branches_match_pypsa(monkeypatch):
    pypsa = _pypsa()
    # PyPSA's rectifier is ideal (a resistance or open); trainsim's rounds max(E - U, 0) over 1e-5 Un
    # (7.5 mV), which moves this case's voltages by 1.1 .. 1.7e-6 V (its conducting rectifiers give
    # ys d^2 / (4 (E - U)) more): compared with the rounding at 1e-10 Un, far from any switching point
    monkeypatch.setattr(solver, "DIODE_SMOOTHING_SHARE", 1e-10)
    logging.getLogger("pypsa").setLevel(logging.ERROR)
    net = _diode_case(DIODE_TRAINS)
    p = np.array([t[2] for t in DIODE_TRAINS])
    loads = StepLoads(
        np.array([net.track_index(t[0]) for t in DIODE_TRAINS]),
        np.array([t[1] for t in DIODE_TRAINS]),
        np.maximum(p, 0.0),
        np.maximum(-p, 0.0),
        np.zeros(len(p)),
        np.zeros(len(p)),
    )
    sol = solve_step(net, loads)
    assert sol.converged
    conducting = {s.id: bool(on) for s, on in zip(net.substations, sol.substation_on, strict=True)}
    # the case is what it claims: the regenerating train blocks some rectifier, others conduct
    assert not all(conducting.values()) and any(conducting.values())
    assert sol.regen_share[-1] == 1.0  # not curtailed: the line takes it all
    assert sol.return_loss_w > 0.0
    vc, vr = np.real(sol.guess.train_contact_v), np.real(sol.guess.train_rail_v)
    assert np.allclose(vc - vr, sol.train_voltage_v, rtol=0, atol=1e-9)
    assert np.max(np.abs(vr)) > 1.0  # the rails carry potentials of volts: not an ideal return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pypsa_c, pypsa_r = _pypsa_two_layer_voltages(pypsa, DIODE_TRAINS, conducting, vc, vr)
    assert np.max(np.abs(pypsa_c - vc)) < 1e-6
    assert np.max(np.abs(pypsa_r - vr)) < 1e-6
    assert np.max(np.abs((pypsa_c - pypsa_r) - sol.train_voltage_v)) < 1e-6
