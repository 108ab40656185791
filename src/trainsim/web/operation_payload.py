"""The answer body of an operation run (issue 17): the train graph (operated and planned paths, the
operated blocking-time stairs, the planned timetable's conflicts), the delay per station and the
headway over the line, as JSON-ready values. Times in s after midnight, line positions in m."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from trainsim.operations.blocking import BlockingTime, Headway
from trainsim.operations.line import Line
from trainsim.operations.simulate import OperationResult

__all__ = ["headway_profile", "operation_body"]


def _finite(x: float | None, digits: int = 3) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), digits)


def _path(line: Line, direction: Any, trajectory: Any, max_points: int) -> dict[str, list[float]]:
    """A trajectory as line position over time, at most ``max_points`` points (first and last kept)."""
    n = len(trajectory.time_s)
    keep = np.unique(np.linspace(0, n - 1, min(max_points, n)).round().astype(int)) if n else np.arange(0)
    position = np.asarray(line.line_position(direction, trajectory.position_m[keep]), dtype=float)
    return {
        "time_s": np.round(trajectory.time_s[keep], 1).tolist(),
        "position_m": np.round(position, 1).tolist(),
    }


def headway_profile(
    leader: Sequence[BlockingTime], follower: Sequence[BlockingTime], planned_headway_s: float
) -> tuple[list[float], list[float]]:
    """The headway each resource shared by two consecutive trains needs [s], over the resource's middle
    on the line [m], sorted by position: ``end_leader - start_follower + planned_headway`` (Pachl
    section 4.2.3; a resource a train blocks twice counts from its first start to its last end). Its
    highest point is the pair's minimum headway (``trainsim.operations.blocking.minimum_headway``)."""

    def spans(times: Sequence[BlockingTime]) -> dict[str, tuple[float, float, float]]:
        out: dict[str, tuple[float, float, float]] = {}
        for b in times:
            mid = 0.5 * (b.from_m + b.to_m)
            if b.resource in out:
                start, end, mid = out[b.resource]
                out[b.resource] = (min(start, b.start_s), max(end, b.end_s), mid)
            else:
                out[b.resource] = (b.start_s, b.end_s, mid)
        return out

    lead, follow = spans(leader), spans(follower)
    points = sorted(
        (mid, lead[name][1] - start + planned_headway_s)
        for name, (start, _end, mid) in follow.items()
        if name in lead
    )
    return [round(p, 1) for p, _ in points], [round(h, 3) for _, h in points]


def _conflicts(result: OperationResult) -> list[dict[str, Any]]:
    """The planned timetable's conflicts, each with the extent of the resource on the line (the second
    train's planned blocking time of it, as the command line's train graph draws it)."""
    planned = {(b.train, b.resource): b for b in result.planned_blocking}
    out = []
    for c in result.conflicts:
        b = planned.get((c.second, c.resource))
        lo, hi = (None, None) if b is None else sorted((b.from_m, b.to_m))
        out.append({**c.to_dict(), "from_m": _finite(lo, 1), "to_m": _finite(hi, 1)})
    return out


def _headways(result: OperationResult, limit: int = 400) -> list[dict[str, Any]]:
    by_train: dict[str, list[BlockingTime]] = {}
    for b in result.planned_blocking:
        by_train.setdefault(b.train, []).append(b)
    out = []
    h: Headway
    for h in result.headways[:limit]:
        x, y = headway_profile(by_train.get(h.leader, []), by_train.get(h.follower, []), h.planned_headway_s)
        out.append({**h.to_dict(), "position_m": x, "headway_s": y})
    return out


def operation_body(
    name: str, title: str, line: Line, result: OperationResult, max_points: int = 400
) -> dict[str, Any]:
    """Everything the page shows of an operation run (see docs/WEB.md, "Line in operation")."""
    trains = []
    for t in result.trains:
        operated = t.trajectory is not None
        shown = t.trajectory if operated else t.planned_trajectory
        path = _path(line, t.direction, shown, max_points)
        planned = _path(line, t.direction, t.planned_trajectory, max_points)
        trains.append(
            {
                "id": t.id,
                "direction": str(t.direction),
                "status": t.status,
                "delay_s": _finite(t.delay_s),
                "operated": operated,
                "time_s": path["time_s"],
                "position_m": path["position_m"],
                "planned_time_s": planned["time_s"],
                "planned_position_m": planned["position_m"],
                "stops": [s.to_dict() for s in t.stops],
                "warnings": list(t.warnings),
            }
        )
    return {
        "name": name,
        "title": title,
        "status": result.status,
        "warnings": list(result.warnings),
        "deadlock": list(result.deadlock),
        "signalling": line.signalling.system,
        "line_length_m": line.length_m,
        "stations": [{"name": s.name, "position_m": s.position_m} for s in line.stations],
        "trains": trains,
        "blocking": [
            {
                "train": b.train,
                "start_s": b.start_s,
                "end_s": b.end_s,
                "from_m": b.from_m,
                "to_m": b.to_m,
                "block": b.route,
                "resource": b.resource,
            }
            for b in result.blocking
        ],
        "conflicts": _conflicts(result),
        "headways": _headways(result),
        "total_delay_s": _finite(sum(t.delay_s for t in result.trains if math.isfinite(t.delay_s))),
    }
