"""A line in operation: signals, blocking times, headways, conflicts and delays for many trains.

Built on the public single-train API (``trainsim.run_fastest``); the core knows nothing of it.
See docs/OPERATIONS.md. The simulation itself is ``trainsim.operations.simulate.simulate`` (not
re-exported here: the name would hide the module).
"""

from trainsim.operations.blocking import (
    BlockingTime,
    CapacityConsumption,
    Headway,
    Trajectory,
    blocking_times,
    compression,
    minimum_headway,
)
from trainsim.operations.line import Line, Signalling, StationLayout, build_line
from trainsim.operations.simulate import OperationResult, ScheduledStop, TrainService

__all__ = [
    "BlockingTime",
    "CapacityConsumption",
    "Headway",
    "Line",
    "OperationResult",
    "ScheduledStop",
    "Signalling",
    "StationLayout",
    "TrainService",
    "Trajectory",
    "blocking_times",
    "build_line",
    "compression",
    "minimum_headway",
]
