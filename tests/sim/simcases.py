"""Small trains and routes built in Python for analytic tests of the simulator."""

from __future__ import annotations

from trainsim.constants import KMH
from trainsim.model import (
    Braking,
    EffortCurve,
    GradientSection,
    LineResistanceSettings,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
)


def make_train(
    *,
    traction_n: float = 200e3,
    braking_n: float = 300e3,
    resistance: Quadratic | None = None,
    mass_kg: float = 300e3,
    rho: float = 1.1,
    length_m: float = 100.0,
    vmax_kmh: float = 300.0,
    traction: EffortCurve | None = None,
    braking: Braking | None = None,
) -> Train:
    return Train(
        name="test train",
        mass_kg=mass_kg,
        rotating_mass_factor=rho,
        length_m=length_m,
        max_speed_mps=vmax_kmh * KMH,
        traction=traction or EffortCurve.constant(traction_n),
        braking=braking or Braking(service_force=EffortCurve.constant(braking_n)),
        resistance=(ResistanceTerm("test", resistance or Quadratic(0.0)),),
    )


def make_route(
    length_m: float = 10_000.0,
    limit_kmh: float = 100.0,
    gradient_permille: float = 0.0,
    limits: list[tuple[float, float, float]] | None = None,
    stations: list[tuple[str, float, float]] | None = None,
    apply_over: str = "head",
) -> Route:
    limits = limits or [(0.0, length_m, limit_kmh)]
    stations = stations or [("A", 0.0, 0.0), ("B", length_m, 0.0)]
    grads = (GradientSection(0.0, length_m, gradient_permille),) if gradient_permille else ()
    return Route(
        name="test route",
        start_m=0.0,
        end_m=length_m,
        stations=tuple(Station(n, p, d) for n, p, d in stations),
        speed_limits=tuple(SpeedLimit(a, b, v * KMH) for a, b, v in limits),
        gradients=grads,
        line_resistance=LineResistanceSettings(
            curve_formula="none", tunnel_formula="none", apply_over=apply_over
        ),
    )
