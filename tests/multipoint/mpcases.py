"""Small multi-point trains and routes built in Python for the tests."""

from __future__ import annotations

from trainsim.constants import KMH, TONNE
from trainsim.model import (
    Braking,
    Curve,
    EffortCurve,
    Electrical,
    GradientSection,
    LineResistanceSettings,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
    Vehicle,
)


def freight_train(
    wagons: int = 20,
    *,
    locos: int = 1,
    loco_t: float = 120.0,
    wagon_t: float = 80.0,
    loco_m: float = 20.0,
    wagon_m: float = 14.0,
    traction_kn_per_loco: float = 400.0,
    power_kw_per_loco: float = 5000.0,
    brake_n_per_kg: float = 0.45,
    rho: float = 1.05,
    a1_n_per_kg: float = 0.012,
    a2_n_s2_per_kg_m2: float = 2.6e-5,
    regen_fraction: float | None = None,
    electrical: bool = False,
) -> Train:
    """Locomotives first, then wagons; per-mass running resistance (source 000) split by vehicle type."""
    loco = Vehicle("Loco", loco_t * TONNE, loco_m, axles=6, rotating_mass_factor=rho, powered=True)
    wagon = Vehicle("Wagon", wagon_t * TONNE, wagon_m, axles=4, rotating_mass_factor=rho)
    vehicles = (loco,) * locos + (wagon,) * wagons
    mass = sum(v.total_mass_kg for v in vehicles)
    traction = EffortCurve.power_limited(
        power_kw_per_loco * 1e3 * locos, traction_kn_per_loco * 1e3 * locos, label="test locos"
    )
    service = EffortCurve.constant(brake_n_per_kg * mass * 0.75)
    regen = traction.scaled(regen_fraction) if regen_fraction else None
    return Train(
        name=f"{locos} locos + {wagons} wagons",
        mass_kg=mass,
        rotating_mass_factor=rho,
        length_m=sum(v.length_m for v in vehicles),
        max_speed_mps=100 * KMH,
        traction=traction,
        braking=Braking(service_force=service, regenerative=regen),
        resistance=(
            ResistanceTerm(
                f"per_mass: {locos} x Loco",
                Quadratic(
                    locos * loco.total_mass_kg * a1_n_per_kg,
                    0,
                    locos * loco.total_mass_kg * a2_n_s2_per_kg_m2,
                ),
            ),
            ResistanceTerm(
                f"per_mass: {wagons} x Wagon",
                Quadratic(
                    wagons * wagon.total_mass_kg * a1_n_per_kg,
                    0,
                    wagons * wagon.total_mass_kg * a2_n_s2_per_kg_m2,
                ),
            ),
        ),
        electrical=Electrical(25e3, 0.85, 0.8, 0.95, 50e3) if electrical else None,
        vehicles=vehicles,
    )


def hilly_route(
    length_m: float = 8_000.0,
    *,
    stop_at: float | None = 4_000.0,
    dwell_s: float = 30.0,
    apply_over: str = "train_length",
    limit_kmh: float = 80.0,
    curves: bool = True,
) -> Route:
    """Grades up and down, two curves, a lower limit, an optional intermediate stop."""
    stations = [Station("A", 0.0)]
    if stop_at is not None:
        stations.append(Station("B", stop_at, dwell_s))
    stations.append(Station("C", length_m))
    L = length_m
    grads = (
        GradientSection(0.1 * L, 0.3 * L, 5.0),
        GradientSection(0.3 * L, 0.45 * L, -4.0),
        GradientSection(0.6 * L, 0.8 * L, 3.0),
        GradientSection(0.8 * L, 0.9 * L, -6.0),
    )
    return Route(
        name="hilly test line",
        start_m=0.0,
        end_m=L,
        stations=tuple(stations),
        speed_limits=(
            SpeedLimit(0.0, 0.55 * L, limit_kmh * KMH),
            SpeedLimit(0.55 * L, 0.65 * L, 0.75 * limit_kmh * KMH),
            SpeedLimit(0.65 * L, L, limit_kmh * KMH),
        ),
        gradients=grads,
        curves=(Curve(0.2 * L, 0.25 * L, 600.0), Curve(0.7 * L, 0.75 * L, 400.0)) if curves else (),
        line_resistance=LineResistanceSettings(
            curve_formula="roeckl" if curves else "none", tunnel_formula="none", apply_over=apply_over
        ),
    )


def level_route(length_m: float = 20_000.0, limit_kmh: float = 120.0) -> Route:
    return Route(
        name="level",
        start_m=0.0,
        end_m=length_m,
        stations=(Station("A", 0.0), Station("B", length_m)),
        speed_limits=(SpeedLimit(0.0, length_m, limit_kmh * KMH),),
        line_resistance=LineResistanceSettings(curve_formula="none", tunnel_formula="none"),
    )
