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

from trainsim.power import Connection, Gap, Network, StepLoads, Substation, Track, solve_step

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
