"""Small networks and metro trains shared by the power tests."""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import trainsim
from trainsim.power import Connection, Network, Substation, Track, VoltageLimits, train_load_from_run

#: limits that never limit: traction full above 101 V, regeneration full up to 2 kV
NO_LIMITS = VoltageLimits(
    nominal_v=750, min2_v=100, min1_v=100, max1_v=2000, max2_v=2100, traction_full_v=101
)


def two_substations(
    length_m: float = 4000.0,
    contact_ohm_per_m: float = 0.02e-3,
    rail_ohm_per_m: float = 0.015e-3,
    e1: float = 835.0,
    e2: float = 825.0,
    r1: float = 0.03,
    r2: float = 0.05,
    reversible: bool = True,
    limits: VoltageLimits = NO_LIMITS,
) -> Network:
    """One track between two substations, no leakage to earth."""
    return Network(
        "two substations",
        "dc",
        limits,
        (Track("A", 0.0, length_m, contact_ohm_per_m, rail_ohm_per_m),),
        (
            Substation("S1", 0.0, ("A",), e1, r1, reversible=reversible),
            Substation("S2", length_m, ("A",), e2, r2, reversible=reversible),
        ),
        contact_leakage_s=1e-12,
    )


@lru_cache(maxsize=1)
def metro_run():
    """Source 002's metro (examples/metro_b) with regenerative braking at 0.8 of traction."""
    sc = trainsim.load_scenario("examples/metro_b/scenario.yaml")
    braking = dataclasses.replace(sc.train.braking, regenerative=sc.train.traction.scaled(0.8))
    train = dataclasses.replace(sc.train, braking=braking)
    return trainsim.run_fastest(train, sc.route, sc.settings), sc.route.end_m


def metro_network(reversible: bool, limits: VoltageLimits | None = None) -> Network:
    from trainsim.power import standard_limits

    _, length = metro_run()
    tracks = tuple(Track(t, 0.0, length, 0.02e-3, 0.015e-3, 0.1e-6) for t in ("up", "down"))
    subs = tuple(
        Substation(
            f"S{i}",
            x,
            ("up", "down"),
            850.0,
            0.03,
            rated_power_w=3e6,
            overload_power_w=4.5e6,
            reversible=reversible,
        )
        for i, x in enumerate([0.0, length / 2, length])
    )
    return Network(
        "metro",
        "dc",
        limits or standard_limits("dc_750"),
        tracks,
        subs,
        (Connection("pp", length / 4, ("up", "down")),),
    )


def metro_loads(n_per_direction: int = 3, headway_s: float = 180.0):
    run, length = metro_run()
    loads = []
    for k in range(n_per_direction):
        loads.append(
            train_load_from_run(
                run,
                id=f"up{k}",
                track="up",
                departure_s=headway_s * k,
                traction_efficiency=0.98,
                regenerative_efficiency=0.98,
                auxiliary_power_w=50e3,
            )
        )
        loads.append(
            train_load_from_run(
                run,
                id=f"down{k}",
                track="down",
                departure_s=headway_s * k + 60,
                origin_m=length,
                direction=-1,
                traction_efficiency=0.98,
                regenerative_efficiency=0.98,
                auxiliary_power_w=50e3,
            )
        )
    return loads
