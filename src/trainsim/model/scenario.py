"""A scenario: a train on a route with the settings of the run."""

from __future__ import annotations

from dataclasses import dataclass, field

from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.train import Train


@dataclass(frozen=True)
class RunSettings:
    """Numerical and driving settings of a run.

    Attributes:
        max_step_m: largest distance step of the integrator [m]; route breakpoints, speed-limit
            changes and regime switches are located exactly whatever the step.
        braking_fraction: share of the train's service braking force used by the driver [-];
            1.0 = full service braking.
        record_dwell: whether the trace holds dwell points at stops.
    """

    max_step_m: float = 20.0
    braking_fraction: float = 1.0
    record_dwell: bool = True

    def __post_init__(self) -> None:
        if not 0.01 <= self.max_step_m <= 1000:
            raise InputError(
                "invalid integration step",
                field="settings.max_step_m",
                value=self.max_step_m,
                allowed="0.01 .. 1000 m",
            )
        if not 0 < self.braking_fraction <= 1:
            raise InputError(
                "invalid braking fraction",
                field="settings.braking_fraction",
                value=self.braking_fraction,
                allowed="0 < x <= 1",
            )


@dataclass(frozen=True)
class Scenario:
    """A train, a route (whose stations say where it stops and for how long) and run settings.

    ``model`` is ``single_point`` or ``multi_point`` (every vehicle its own mass, couplers as
    springs; ``multi_point`` then holds that model's validated settings, see docs/MULTIPOINT.md).
    ``strategy`` is ``fastest`` or an energy-efficient strategy (``optimal``, ``lesov``,
    ``reference``) driven to ``timetable`` (a ``trainsim.optimize.timetable.Timetable``).
    """

    name: str
    train: Train
    route: Route
    settings: RunSettings = field(default_factory=RunSettings)
    model: str = "single_point"
    multi_point: object | None = None
    strategy: str = "fastest"
    timetable: object | None = None
