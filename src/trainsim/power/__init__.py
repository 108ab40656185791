"""Traction power supply: DC and AC networks with many trains (docs/POWER.md).

Layers: :mod:`limits` (EN 50163 data, EN 50388-style train behaviour), :mod:`network` (tracks,
substations, connections, gaps), :mod:`solver` (one time step: sparse nodal analysis, Newton,
rectifier states), :mod:`regulation` (substation regulation curves), :mod:`rail` (leaking return
rails, stray current), :mod:`onboard` (on-board storage), :mod:`simulation` (many trains over time,
results, compact traces for a whole day), :mod:`day` (a timetable's whole day), :mod:`synchronise`
(departures shifted to save substation energy), :mod:`stretches` (runs joined per stretch between stops), :mod:`study` (trains from runs,
voltage-limited traction fed back into the runs). The file reader (:mod:`trainsim.io.power_file`) and plots
(:mod:`plots`) sit on top and are not imported here.
"""

from __future__ import annotations

from trainsim.power.limits import EN50163, VoltageLimits, standard_limits
from trainsim.power.network import Connection, Gap, Network, Storage, Substation, Track
from trainsim.power.onboard import OnboardStorage
from trainsim.power.simulation import (
    CompactPowerResult,
    PowerResult,
    TrainLoad,
    simulate,
    train_load_from_run,
)
from trainsim.power.solver import StepLoads, StepSolution, solve_step

__all__ = [
    "EN50163",
    "CompactPowerResult",
    "Connection",
    "Gap",
    "Network",
    "OnboardStorage",
    "PowerResult",
    "StepLoads",
    "StepSolution",
    "Storage",
    "Substation",
    "Track",
    "TrainLoad",
    "VoltageLimits",
    "simulate",
    "solve_step",
    "standard_limits",
    "train_load_from_run",
]
