"""Timetable data types: section schedules, line supplements and timing points (SI: m, s, m/s).

A timetable says, for each section between consecutive stops of a route, either its scheduled
running time or a running-time supplement over the fastest run (a fraction or seconds), or it
gives one supplement for the whole line. Timing points add time windows (earliest and latest
passing time, from the start of the journey) and speed windows at positions of the line, as in
TTOBench journeys and as planners use them.

Readers and the strategies that use these types live in ``trainsim.optimize`` and ``trainsim.io``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from trainsim.errors import InputError


@dataclass(frozen=True)
class SectionSchedule:
    """The schedule of one section: exactly one of the three fields is set.

    Attributes:
        running_time_s: scheduled running time [s].
        supplement_fraction: supplement over the fastest run as a fraction (0.1 = 10 %) [-].
        supplement_s: supplement over the fastest run [s].
    """

    running_time_s: float | None = None
    supplement_fraction: float | None = None
    supplement_s: float | None = None

    def target_s(self, fastest_s: float) -> float:
        """Scheduled running time [s] given the section's fastest running time [s]."""
        if self.running_time_s is not None:
            return self.running_time_s
        if self.supplement_fraction is not None:
            return fastest_s * (1.0 + self.supplement_fraction)
        return fastest_s + (self.supplement_s or 0.0)


@dataclass(frozen=True)
class Timetable:
    """Per-section schedules (one per section, in order), or one line supplement.

    Attributes:
        sections: one schedule per section between consecutive stops, or empty.
        line: a supplement for the whole line, split optimally between sections.
        source: where it came from (file name), for messages.
        timing_points: passing points with time and speed windows [m, s, m/s]; their times are
            from the departure of the section (between two stops) they lie in.
    """

    sections: tuple[SectionSchedule, ...] = ()
    line: SectionSchedule | None = None
    source: str = ""
    timing_points: tuple[TimingPoint, ...] = ()

    def __post_init__(self) -> None:
        if (self.line is None) == (not self.sections):
            raise InputError(
                "a timetable gives either one schedule per section or one line supplement",
                file=self.source or None,
                field="timetable",
            )


def _check_window(lo: float | None, hi: float | None, what: str, where: str, unit: str) -> None:
    for name, x in (("lower", lo), ("upper", hi)):
        if x is not None and not (isinstance(x, int | float) and math.isfinite(x) and x >= 0.0):
            raise InputError(
                f"the {name} {what} of a timing point must be a finite number >= 0",
                field=f"{where}.{name} {what}",
                value=x,
                allowed=f">= 0 [{unit}] or null",
            )
    if lo is not None and hi is not None and lo > hi:
        raise InputError(
            f"the lower {what} of a timing point is above its upper {what}",
            field=where,
            value=(lo, hi),
            allowed=f"lower <= upper [{unit}]",
        )


@dataclass(frozen=True)
class TimingPoint:
    """A timing point: a position with a time window and a speed window, None where unconstrained.

    Attributes:
        position_m: position on the line [m].
        earliest_s: earliest passing (or departure) time from the start of the journey [s].
        latest_s: latest passing (or arrival) time from the start of the journey [s].
        min_speed_mps: lowest allowed speed at the point [m/s].
        max_speed_mps: highest allowed speed at the point [m/s].
        name: a label for messages.
    """

    position_m: float
    earliest_s: float | None = None
    latest_s: float | None = None
    min_speed_mps: float | None = None
    max_speed_mps: float | None = None
    name: str = ""

    def __post_init__(self) -> None:
        where = self.name or f"timing point at {self.position_m} m"
        if not (isinstance(self.position_m, int | float) and math.isfinite(self.position_m)):
            raise InputError(
                "a timing point needs a finite position", field=where, value=self.position_m, allowed="[m]"
            )
        _check_window(self.earliest_s, self.latest_s, "time constraint", where, "s")
        _check_window(self.min_speed_mps, self.max_speed_mps, "speed constraint", where, "m/s")

    @property
    def is_stop(self) -> bool:
        """Both speed bounds 0: a stopping point."""
        return self.min_speed_mps == 0.0 and self.max_speed_mps == 0.0

    @property
    def label(self) -> str:
        """The name, or the position when it has none."""
        return self.name or f"{self.position_m:.0f} m"


@dataclass(frozen=True)
class Journey:
    """A journey: ordered timing points on a track (TTOBench), stopping points delimit sections.

    Attributes:
        name: the journey's identifier.
        track_id: the identifier of the track it runs on.
        points: the timing points in order of position.
        notes: what was assumed when reading it.
    """

    name: str
    track_id: str
    points: tuple[TimingPoint, ...]
    notes: tuple[str, ...] = field(default=())

    @property
    def passing_points(self) -> tuple[TimingPoint, ...]:
        """The timing points that are not stopping points."""
        return tuple(p for p in self.points if not p.is_stop)
