"""Domain objects of the simulation core: trains, routes and force laws, all in SI units."""

from trainsim.model.effort import EffortCurve
from trainsim.model.laws import Quadratic
from trainsim.model.route import (
    Curve,
    ElectrificationSection,
    GradientSection,
    LineResistanceSettings,
    Route,
    SpeedLimit,
    Station,
    Tunnel,
)
from trainsim.model.train import Braking, Electrical, ResistanceTerm, Train, Vehicle

__all__ = [
    "Braking",
    "Curve",
    "EffortCurve",
    "Electrical",
    "ElectrificationSection",
    "GradientSection",
    "LineResistanceSettings",
    "Quadratic",
    "ResistanceTerm",
    "Route",
    "SpeedLimit",
    "Station",
    "Train",
    "Tunnel",
    "Vehicle",
]
