"""Timetables for energy-efficient driving: what running time each section gets.

A timetable says, for each section between consecutive stops of a route, either its scheduled
running time, or a running-time supplement over the fastest run (a fraction or seconds), or it
gives one supplement for the whole line, which is then split between the sections so that every
section has the same marginal energy per second (the optimal split, Albrecht et al. 2016).
"""

from __future__ import annotations

import re
from typing import Any

from trainsim.errors import InputError
from trainsim.model import bounds
from trainsim.model.timetable import Journey, SectionSchedule, Timetable, TimingPoint

__all__ = [
    "Journey",
    "SectionSchedule",
    "Timetable",
    "TimingPoint",
    "line_supplement",
    "parse_supplement",
    "timetable_from_dict",
    "timetable_from_journey",
]


def parse_supplement(
    text: str | float, *, file: str | None = None, field: str = "supplement"
) -> SectionSchedule:
    """``"10%"`` or ``0.1``-style fraction given as percent string, or ``"30 s"``, as a schedule."""
    if isinstance(text, int | float):
        raise InputError(
            "give the supplement with its unit", file=file, field=field, value=text, allowed='"10%" or "30 s"'
        )
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*(%|s|min)\s*", str(text))
    if not m:
        raise InputError(
            "cannot read the supplement", file=file, field=field, value=text, allowed='"10%" or "30 s"'
        )
    value, unit = float(m.group(1)), m.group(2)
    if unit == "%":
        if not value <= 300:
            raise InputError("supplement too large", file=file, field=field, value=text, allowed="0 .. 300 %")
        return SectionSchedule(supplement_fraction=value / 100.0)
    factor = 60.0 if unit == "min" else 1.0
    if not bounds.BOUNDS["time"].contains(value * factor):  # "1e400 s" would be an infinite supplement
        raise InputError(
            "supplement too large",
            file=file,
            field=field,
            value=text,
            allowed=f"0 .. {bounds.BOUNDS['time'].high / factor:g} {unit}",
        )
    return SectionSchedule(supplement_s=value * factor)


def line_supplement(text: str) -> Timetable:
    """A timetable with one supplement for the whole line (split optimally)."""
    return Timetable(line=parse_supplement(text))


#: The keys of a ``trainsim/timetable`` document.
TIMETABLE_KEYS = ("schema", "version", "name", "description", "supplement", "sections")


def timetable_from_dict(data: Any, file: str = "<timetable>", n_sections: int | None = None) -> Timetable:
    """The :class:`Timetable` of a ``schema: trainsim/timetable`` document (already parsed).

    Either ``supplement: "10%"`` for the whole line, or ``sections:`` a list with, per section,
    ``running_time_s``, ``supplement`` ("8%" / "20 s"), or ``departure_s`` and ``arrival_s``. Times are
    numbers (not ``true``, text, NaN or inf) within the plausible range of a time
    (:mod:`trainsim.model.bounds`); ``n_sections`` is the route's number of sections between stops.
    """
    if not isinstance(data, dict) or data.get("schema") != "trainsim/timetable":
        raise InputError(
            "not a trainsim timetable",
            file=file,
            field="schema",
            value=data.get("schema") if isinstance(data, dict) else type(data).__name__,
            allowed="trainsim/timetable",
        )
    if data.get("version") != 1 or isinstance(data.get("version"), bool):
        raise InputError(
            "unsupported version", file=file, field="version", value=data.get("version"), allowed="1"
        )
    unknown = sorted(str(k) for k in set(data) - set(TIMETABLE_KEYS))
    if unknown:
        raise InputError(
            "unknown field", file=file, field=", ".join(unknown), allowed=", ".join(TIMETABLE_KEYS)
        )
    if "supplement" in data and "sections" in data:
        raise InputError("give either 'supplement' or 'sections', not both", file=file, field="supplement")
    if "supplement" in data:
        return Timetable(line=parse_supplement(data["supplement"], file=file), source=file)
    rows = data.get("sections")
    if not isinstance(rows, list) or not rows:
        raise InputError(
            "'sections' must be a non-empty list",
            file=file,
            field="sections",
            value=rows if not isinstance(rows, list) else None,
            allowed="a list with one schedule per section between stops",
        )
    if n_sections is not None and len(rows) != n_sections:
        raise InputError(
            "one schedule per section is needed",
            file=file,
            field="sections",
            value=len(rows),
            allowed=f"{n_sections} (the route's sections between stops)",
        )
    return Timetable(sections=tuple(_section(row, k, file) for k, row in enumerate(rows)), source=file)


def _time(row: dict[str, Any], key: str, field: str, file: str) -> float:
    return bounds.check(row[key], "time", field=f"{field}.{key}", file=file, unit="s")


def _section(row: Any, k: int, file: str) -> SectionSchedule:
    field = f"sections[{k}]"
    if not isinstance(row, dict):
        raise InputError("expected a mapping", file=file, field=field, value=row)
    keys = set(row) - {"from", "to"}
    if keys == {"running_time_s"}:
        value = _time(row, "running_time_s", field, file)
        if value <= 0:
            raise InputError(
                "must be > 0", file=file, field=f"{field}.running_time_s", value=value, allowed="> 0 s"
            )
        return SectionSchedule(running_time_s=value)
    if keys == {"supplement"}:
        return parse_supplement(row["supplement"], file=file, field=f"{field}.supplement")
    if keys == {"departure_s", "arrival_s"}:
        dep, arr = _time(row, "departure_s", field, file), _time(row, "arrival_s", field, file)
        if arr <= dep:
            raise InputError(
                "arrival must be after departure",
                file=file,
                field=f"{field}.arrival_s",
                value=arr,
                allowed=f"> the departure_s, {dep:g} s",
            )
        return SectionSchedule(running_time_s=arr - dep)
    raise InputError(
        "a section needs running_time_s, or supplement, or departure_s and arrival_s",
        file=file,
        field=field,
        value=sorted(str(key) for key in keys),
    )


def timetable_from_journey(journey, route):  # (Journey, Route) -> (Route, Timetable)
    """A TTOBench journey as a route with the journey's stops and a per-section timetable.

    Each section gets the longest time its windows allow (depart at the earliest, arrive at the
    latest), which is what saves most energy; an intermediate stop dwells from the latest arrival
    to the earliest departure. The passing points go into the timetable's ``timing_points`` with
    their times from the departure of their section: the reference enforces them, every strategy's
    result reports the windows it misses (``OptimizationResult.timing_points``).
    """
    import dataclasses

    from trainsim.model.route import Station

    stops = [p for p in journey.points if p.is_stop]
    merged: list[list] = []  # [position, arrival latest, departure earliest]
    for p in stops:
        if merged and abs(merged[-1][0] - p.position_m) < 1e-6:
            merged[-1][2] = p.earliest_s
        else:
            merged.append([p.position_m, p.latest_s, p.earliest_s])
    stations = []
    for k, (pos, arr, dep) in enumerate(merged):
        dwell = 0.0 if k in (0, len(merged) - 1) else max(0.0, (dep or 0.0) - (arr or 0.0))
        stations.append(Station(f"{pos:.0f} m", pos, dwell))
    sections = []
    for k in range(len(merged) - 1):
        dep = merged[k][2] if merged[k][2] is not None else merged[k][1]
        arr = merged[k + 1][1]
        if dep is None or arr is None or arr <= dep:
            raise InputError(
                "a journey section needs a departure time and a later arrival time",
                file=journey.name,
                field=f"timing points (section {k + 1})",
                value=(dep, arr),
            )
        sections.append(SectionSchedule(running_time_s=float(arr - dep)))
    new_route = dataclasses.replace(route, stations=tuple(stations))
    # passing points with their times from the departure of the section they lie in
    points = []
    for p in journey.passing_points:
        k = max((i for i in range(len(merged) - 1) if merged[i][0] <= p.position_m), default=0)
        dep = merged[k][2] if merged[k][2] is not None else (merged[k][1] or 0.0)
        shift = [None if x is None else x - dep for x in (p.earliest_s, p.latest_s)]
        if shift[0] is not None:
            shift[0] = max(shift[0], 0.0)  # an earliest time before the departure constrains nothing
        if shift[1] is not None and shift[1] < 0.0:
            raise InputError(
                "a passing point's window closes before its section departs",
                file=journey.name,
                field=f"timing point {p.label}",
                value=(p.earliest_s, p.latest_s),
                allowed=f">= the section's departure at {dep:g} s",
            )
        points.append(dataclasses.replace(p, earliest_s=shift[0], latest_s=shift[1]))
    return new_route, Timetable(sections=tuple(sections), source=journey.name, timing_points=tuple(points))
