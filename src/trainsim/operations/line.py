"""A signalled line: stations with their tracks, block sections, signals and the routes trains take.

Positions are in metres. A line has one coordinate (``0 .. length_m``, the "up" direction); a train in
the "down" direction runs from ``length_m`` towards 0 and sees the line in its own *running
coordinate* ``x = length_m - position``. Every route below is stored in the running coordinate of its
direction, so a train's trajectory and the routes it takes share one increasing position.

The model follows Pachl, *Railway Operation and Control* (4th ed., 2018), chapters 3-4, and UIC Code
406 (2nd ed., 2013):

* A **route** (block section, or an interlocking route through a station) starts at a main signal and
  ends at the next main signal plus the **overlap** beyond it (with train detection points given, up
  to the first one at least the overlap length beyond: ``overlap_end_m``). It is made of
  **resources** (train detection sections: a plain-line block, a station's switch zone, a platform
  track, a single-track section between two stations). Two trains conflict when they claim one
  resource at the same time.
* A resource is released when the rear of the train has cleared its end (**sectional release**), or
  when the rear has cleared the end of the whole route (**whole-route release**), plus the release time.
* Station layout (per direction, in running coordinates, ``p`` the stopping point of the head):
  entry (home) signal at ``p - entry_signal_distance_m``; its switch zone from there over
  ``switch_zone_m``; the platform tracks; exit (starting) signal at ``p + exit_signal_offset_m``; the
  exit switch zone from the exit signal over ``switch_zone_m``, whose end is the clearance point of the
  platform tracks.
* Double track: one track per direction, automatic block signals between stations every
  ``block_length_m`` at most (evenly spaced) or at given positions. Stations may have more than one
  track per direction (passing loops for overtaking).
* Single track: both directions share each section between two stations, which is one block (no
  intermediate block signals); stations have passing loops (two or more platform tracks shared by
  both directions). A train is given a single-track section only together with a platform track at
  the next station, which keeps trains from meeting head on between stations.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import Literal

import numpy as np

from trainsim.errors import InputError, Problem
from trainsim.model import SpeedLimit

Direction = Literal["up", "down"]
Separation = Literal["fixed_block", "etcs_l2", "moving_block"]
Release = Literal["sectional", "whole_route"]
Layout = Literal["double_track", "single_track"]
#: Most block sections (or moving-block sections) per direction: bounds memory and run time.
MAX_SECTIONS = 20_000


@dataclass(frozen=True)
class Signalling:
    """Train separation and the times of the blocking-time model (Pachl ch. 4; UIC 406).

    Attributes:
        system: ``fixed_block`` (lineside signals), ``etcs_l2`` (ETCS Level 2 on fixed virtual blocks:
            the approach starts at the indication point of the movement authority ending at the block
            marker) or ``moving_block`` (ETCS L3 / CBTC: the approach is the service braking distance
            plus ``safety_margin_m`` behind the rear of the train ahead).
        aspects: number of aspects of the fixed-block signals (2, 3 or 4). With 2 aspects every main
            signal has a distant signal ``distant_distance_m`` before it; with 3 (4) aspects the
            previous (second previous) main signal gives the warning.
        distant_distance_m: distance from a distant signal to its main signal (2 aspects) [m].
        sighting_distance_m: distance before the (distant) signal from which the driver must see its
            aspect [m].
        overlap_m: overlap beyond each main signal [m].
        setup_s: route setting (formation and locking) time [s].
        reaction_s: driver's sight and reaction time, besides the sighting distance [s]; for ETCS and
            moving block the time to issue and receive a movement authority [s].
        release_s: route release time [s].
        release: ``sectional`` or ``whole_route`` release.
        safety_margin_m: moving block: the margin kept behind the rear of the train ahead [m].
        moving_block_step_m: moving block: the length of the virtual sections the line is cut into to
            compute blocking times and headways [m]; the smaller, the closer to true moving block.
        standing_distance_m: how far before a signal showing stop a train comes to a stand [m].
    """

    system: Separation = "fixed_block"
    aspects: int = 3
    distant_distance_m: float = 1000.0
    sighting_distance_m: float = 200.0
    overlap_m: float = 50.0
    setup_s: float = 6.0
    reaction_s: float = 6.0
    release_s: float = 3.0
    release: Release = "sectional"
    safety_margin_m: float = 50.0
    moving_block_step_m: float = 50.0
    standing_distance_m: float = 10.0

    def __post_init__(self) -> None:
        problems = []
        if self.system not in ("fixed_block", "etcs_l2", "moving_block"):
            problems.append(
                Problem(
                    "unknown train separation",
                    field="signalling.system",
                    value=self.system,
                    allowed="fixed_block, etcs_l2, moving_block",
                )
            )
        if self.aspects not in (2, 3, 4):
            problems.append(
                Problem(
                    "unsupported number of aspects",
                    field="signalling.aspects",
                    value=self.aspects,
                    allowed="2, 3 or 4",
                )
            )
        if self.release not in ("sectional", "whole_route"):
            problems.append(
                Problem(
                    "unknown route release",
                    field="signalling.release",
                    value=self.release,
                    allowed="sectional, whole_route",
                )
            )
        for name in (
            "distant_distance_m",
            "sighting_distance_m",
            "overlap_m",
            "setup_s",
            "reaction_s",
            "release_s",
            "safety_margin_m",
            "standing_distance_m",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0 <= value <= 1e5):
                problems.append(
                    Problem(
                        "must be a finite number >= 0",
                        field=f"signalling.{name}",
                        value=value,
                        allowed="0 .. 100000",
                    )
                )
        if not (np.isfinite(self.moving_block_step_m) and 1 <= self.moving_block_step_m <= 5000):
            problems.append(
                Problem(
                    "invalid moving-block step",
                    field="signalling.moving_block_step_m",
                    value=self.moving_block_step_m,
                    allowed="1 .. 5000 m",
                )
            )
        if problems:
            raise InputError.from_problems(problems)


@dataclass(frozen=True)
class StationLayout:
    """A station of the line with its tracks.

    Attributes:
        name: station name.
        position_m: stopping point of the head in the up direction [m]; a down train stops with its
            head at the same point.
        tracks: platform tracks per direction (double track) or shared by both directions (single
            track). Single track needs at least 2 where trains meet, 1 is a halt without loop.
        entry_signal_distance_m: from the entry signal to the stopping point [m].
        exit_signal_offset_m: from the stopping point to the exit signal [m].
        switch_zone_m: length of the switch zone behind the entry signal and beyond the exit signal
            (its end is the clearance point) [m].
    """

    name: str
    position_m: float
    tracks: int = 1
    entry_signal_distance_m: float = 400.0
    exit_signal_offset_m: float = 20.0
    switch_zone_m: float = 100.0


@dataclass(frozen=True)
class SwitchLayout:
    """A switch of a station's track layout, in line positions [m].

    Attributes:
        name: its name (for messages).
        position_m: line position of the switch (its blade tip, where its two tracks join) [m].
        clearance_m: line position of its clearance (fouling) point on the side of its two tracks,
            between the switch and the station's stopping point [m]: a train on one of the two tracks
            beyond it no longer fouls the other. None: the nearest train detection point on that side.
        diverging_speed_mps: highest speed over its diverging branch [m/s]; None: line speed. A
            train routed to a platform track over the diverging branch keeps to it from the blade
            tip to the clearance point (entry side; from the clearance point to the blade tip on the
            exit side) until its rear has cleared that span (``Route.speed_limits``).
        diverging_tracks: the platform tracks of its station (1 .. ``tracks``) reached over its
            diverging branch; None: every track but track 1, the through track of the standard layout.
    """

    name: str
    position_m: float
    clearance_m: float | None = None
    diverging_speed_mps: float | None = None
    diverging_tracks: tuple[int, ...] | None = None


@dataclass(frozen=True)
class TrackLayout:
    """What is given of one track, in line positions [m]: the track of one direction of a double-track
    line (key ``up`` or ``down`` of ``build_line``'s ``tracks``) or the single track (key ``both``).

    Attributes:
        detection_points_m: train detection points (axle counters, track-circuit borders) [m]. They cut
            the open line's blocks into track sections released one by one (sectional release), a
            switch is released at the first one at or beyond its clearance point (entry) or its blade
            tip (exit), and a signal's overlap runs to one (``overlap_end_m``). Moving block does not
            use them (trains are released by their position reports: a switch at its clearance point
            or blade tip, a single-track section as a whole), except as clearance points not given.
        switches: the stations' switches; each belongs to the station on whose entry side (between the
            entry signal and the stopping point) or exit side (beyond the exit signal, before the next
            signal) it lies.
        station_signals_m: per station name, the line positions of its entry (home) and exit
            (starting) signal on this track [m], instead of the station's ``entry_signal_distance_m``
            and ``exit_signal_offset_m``.
    """

    detection_points_m: tuple[float, ...] = ()
    switches: tuple[SwitchLayout, ...] = ()
    station_signals_m: Mapping[str, tuple[float, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class Resource:
    """A resource a route claims: a train detection section named ``name`` whose end, in the running
    coordinate of the route's direction, is ``end_m`` [m] (the train releases it once its rear has
    passed that point)."""

    name: str
    end_m: float


@dataclass(frozen=True)
class Route:
    """A route from a main signal at ``start_m`` to the next main signal at ``end_m`` plus ``overlap_m``
    (running coordinate of its direction) [m], claiming ``resources``.

    ``track`` is the platform track the route leads to (for routes into a station), ``station`` the
    station it enters or leaves; ``reserve_next`` says the route is only given together with the
    next route (a single-track section together with a track at the next station).
    ``speed_limits`` (routes into a platform track) are the ceilings of the diverging switches the
    train runs over into and out of that track (running coordinate): a train given the route keeps
    to them (the core holds a limit until the rear has passed its end).
    """

    name: str
    signal: str
    start_m: float
    end_m: float
    overlap_m: float
    resources: tuple[Resource, ...]
    station: str | None = None
    track: int | None = None
    reserve_next: bool = False
    speed_limits: tuple[SpeedLimit, ...] = ()


@dataclass(frozen=True)
class RouteStep:
    """One step of a direction's path: the routes from one signal, one per alternative track."""

    start_m: float
    end_m: float
    alternatives: tuple[Route, ...]
    station: str | None = None
    kind: Literal["block", "entry", "exit"] = "block"


@dataclass(frozen=True)
class DirectionPath:
    """The route steps of one direction, in running coordinates, with the stopping points of its
    stations and the main signals (for the aspect sequence)."""

    direction: Direction
    steps: tuple[RouteStep, ...]
    stop_m: dict[str, float]
    #: per station whose switches are given on both sides: the platform tracks' usable extent, from
    #: the clearance point of the entry switches to that of the exit switches (running coordinate) [m]
    platform_m: dict[str, tuple[float, float]] = field(default_factory=dict)

    def signal_positions(self) -> np.ndarray:
        """Positions of the main signals in running order [m]."""
        return np.array([s.start_m for s in self.steps])

    def track_speed_limits(self, station: str, track: int) -> tuple[SpeedLimit, ...]:
        """The diverging-switch ceilings of platform track ``track`` of ``station`` (running
        coordinate, ``Route.speed_limits`` of the route into it); empty for an unknown station or
        track."""
        for step in self.steps:
            if step.kind == "entry" and step.station == station:
                return next((r.speed_limits for r in step.alternatives if r.track == track), ())
        return ()


@dataclass(frozen=True)
class Line:
    """A signalled line: its length, layout, stations, signalling and the path of each direction."""

    name: str
    length_m: float
    layout: Layout
    stations: tuple[StationLayout, ...]
    signalling: Signalling
    paths: dict[str, DirectionPath] = field(default_factory=dict)
    tracks: Mapping[str, TrackLayout] = field(default_factory=dict)

    def running_position(self, direction: Direction, position_m: float) -> float:
        """The running coordinate of a line position for a direction [m]."""
        return position_m if direction == "up" else self.length_m - position_m

    def line_position(self, direction: Direction, running_m: float | np.ndarray) -> float | np.ndarray:
        """The line position of a running coordinate [m]."""
        return running_m if direction == "up" else self.length_m - running_m

    def station(self, name: str) -> StationLayout:
        """The station called ``name`` (InputError naming the known ones otherwise)."""
        for s in self.stations:
            if s.name == name:
                return s
        raise InputError(
            "unknown station", field="station", value=name, allowed=", ".join(s.name for s in self.stations)
        )

    def loop_problems(
        self, direction: Direction, origin: str, destination: str, train_length_m: float, where: str
    ) -> list[Problem]:
        """Stations from ``origin`` to ``destination`` (both included) where a train of
        ``train_length_m`` [m] standing at the stopping point would foul a switch: its rear must be
        beyond the clearance point of the entry switches and its head short of that of the exit
        switches, so the room is ``min(stop, exit clearance) - entry clearance`` (running coordinate)
        [m]. A train may stand at any of them (a stop, a meet on single track, being overtaken); only
        stations whose switches are given on both sides are checked."""
        path = self.paths[direction]
        lo, hi = path.stop_m.get(origin), path.stop_m.get(destination)
        if lo is None or hi is None:
            return []
        out = []
        for name, (a, b) in path.platform_m.items():
            p = path.stop_m[name]
            room = min(p, b) - a
            if lo - 1e-9 <= p <= hi + 1e-9 and room < train_length_m - 1e-9:
                out.append(
                    Problem(
                        f"the train does not fit on the platform tracks / passing loop at '{name}' ({direction}): "
                        f"standing at the stopping point it would foul a switch (loop {b - a:g} m between the "
                        f"clearance points, {room:g} m from the entry clearance point to the stopping point)",
                        field=f"{where}.train",
                        value=train_length_m,
                        allowed=f"a train of at most {room:g} m, or a longer loop",
                    )
                )
        return out


def _station_problems(
    line_length_m: float, stations: tuple[StationLayout, ...], layout: Layout
) -> list[Problem]:
    problems: list[Problem] = []
    names = [s.name for s in stations]
    for i, s in enumerate(stations):
        where = f"stations[{i}]"
        if names.count(s.name) > 1:
            problems.append(Problem("station names must be unique", field=f"{where}.name", value=s.name))
        if not (np.isfinite(s.position_m) and 0 <= s.position_m <= line_length_m):
            problems.append(
                Problem(
                    "station lies off the line",
                    field=f"{where}.position_m",
                    value=s.position_m,
                    allowed=f"0 .. {line_length_m:g} m",
                )
            )
        if not 1 <= s.tracks <= 8:
            problems.append(
                Problem(
                    "invalid number of platform tracks",
                    field=f"{where}.tracks",
                    value=s.tracks,
                    allowed="1 .. 8",
                )
            )
        for name in ("entry_signal_distance_m", "exit_signal_offset_m", "switch_zone_m"):
            value = getattr(s, name)
            if not (np.isfinite(value) and 0 < value < 10_000):
                problems.append(
                    Problem(
                        "invalid station geometry",
                        field=f"{where}.{name}",
                        value=value,
                        allowed="0 < x < 10000 m",
                    )
                )
    if len(stations) < 2:
        problems.append(
            Problem(
                "a line needs at least two stations", field="stations", value=names, allowed=">= 2 stations"
            )
        )
    positions = [s.position_m for s in stations]
    if any(b <= a for a, b in pairwise(positions)):
        problems.append(Problem("stations must be in increasing position", field="stations", value=positions))
    if problems:
        return problems
    for a, b in pairwise(stations):
        # the exit zone of one station and the entry zone of the next must not overlap, in either direction
        need_up = a.exit_signal_offset_m + a.switch_zone_m + b.entry_signal_distance_m
        need_down = b.exit_signal_offset_m + b.switch_zone_m + a.entry_signal_distance_m
        gap = b.position_m - a.position_m
        if gap <= max(need_up, need_down):
            problems.append(
                Problem(
                    f"stations '{a.name}' and '{b.name}' are too close for their signal and switch zones",
                    field="stations.position_m",
                    value=gap,
                    allowed=f"> {max(need_up, need_down):g} m (exit offset + switch zone + entry signal distance)",
                )
            )
    return problems


def build_line(
    name: str,
    length_m: float,
    layout: Layout,
    stations: tuple[StationLayout, ...],
    signalling: Signalling,
    block_length_m: float = 2000.0,
    block_signals_m: dict[str, list[float]] | None = None,
    tracks: Mapping[str, TrackLayout] | None = None,
) -> Line:
    """Build a line and the route steps of both directions.

    Args:
        name: line name.
        length_m: line length [m].
        layout: ``double_track`` or ``single_track``.
        stations: stations in increasing position.
        signalling: train separation and blocking-time settings.
        block_length_m: double track: longest block between two stations [m]; the open line between the
            exit zone of one station and the entry signal of the next is cut into equal blocks. For
            moving block the line is cut into ``signalling.moving_block_step_m`` sections instead.
        block_signals_m: double track: the block signals' line positions per direction (``up``,
            ``down``) instead of the automatic spacing [m]; each must lie on the open line between two
            stations.
        tracks: what is given of the tracks (``up`` and ``down`` on double track, ``both`` on single
            track): train detection points, the stations' switches with their clearance points, and a
            track's own station signals. Where they are not given, the standard layout above.

    Raises:
        InputError: stations off the line, out of order or too close; block signals off the open line;
            a switch or detection point off the line or in no station, a clearance point on the wrong
            side of its switch or beyond the next signal, station signals on the wrong side.
    """
    problems: list[Problem] = []
    if not (np.isfinite(length_m) and length_m > 0):
        problems.append(
            Problem("the line length must be > 0", field="line.length_m", value=length_m, allowed="> 0 m")
        )
    if layout not in ("double_track", "single_track"):
        problems.append(
            Problem("unknown layout", field="line.layout", value=layout, allowed="double_track, single_track")
        )
    if not (np.isfinite(block_length_m) and 100 <= block_length_m <= 1e5):
        problems.append(
            Problem(
                "invalid block length",
                field="line.block_length_m",
                value=block_length_m,
                allowed="100 .. 100000 m",
            )
        )
    if problems:
        raise InputError.from_problems(problems)
    stations = tuple(stations)
    problems = _station_problems(length_m, stations, layout)
    if layout == "single_track" and block_signals_m:
        problems.append(
            Problem(
                "single track has one block between stations; block signals are for double track",
                field="line.block_signals_m",
                value=block_signals_m,
            )
        )
    if problems:
        raise InputError.from_problems(problems)
    step = signalling.moving_block_step_m if signalling.system == "moving_block" else block_length_m
    if length_m / step > MAX_SECTIONS:
        field_name = (
            "signalling.moving_block_step_m" if signalling.system == "moving_block" else "line.block_length_m"
        )
        raise InputError(
            f"the line would be cut into more than {MAX_SECTIONS} sections per direction",
            field=field_name,
            value=step,
            allowed=f">= {length_m / MAX_SECTIONS:g} m on this {length_m:g} m line",
        )
    line = Line(name, float(length_m), layout, stations, signalling, tracks=dict(tracks or {}))
    problems = _track_problems(line, line.tracks)
    if problems:
        raise InputError.from_problems(problems)
    paths = {}
    for direction in ("up", "down"):
        given = None
        if block_signals_m and direction in block_signals_m:
            given = sorted(line.running_position(direction, float(x)) for x in block_signals_m[direction])
        paths[direction] = _direction_path(line, direction, block_length_m, given)
    object.__setattr__(line, "paths", paths)
    return line


def _track_key(line: Line, direction: Direction) -> str:
    return "both" if line.layout == "single_track" else direction


def _track_problems(line: Line, tracks: Mapping[str, TrackLayout]) -> list[Problem]:
    """Checks of ``tracks`` that do not depend on a direction: keys, positions on the line, stations."""
    problems: list[Problem] = []
    allowed = ("both",) if line.layout == "single_track" else ("up", "down")
    names = {s.name for s in line.stations}
    for key, track in tracks.items():
        where = f"line.tracks.{key}"
        if key not in allowed:
            problems.append(
                Problem(
                    f"unknown track for a {line.layout.replace('_', ' ')} line",
                    field=where,
                    value=key,
                    allowed=", ".join(allowed),
                )
            )
            continue
        for k, x in enumerate(track.detection_points_m):
            if not (np.isfinite(x) and 0 <= x <= line.length_m):
                problems.append(
                    Problem(
                        "train detection point off the line",
                        field=f"{where}.detection_points_m[{k}]",
                        value=x,
                        allowed=f"0 .. {line.length_m:g} m",
                    )
                )
        seen: set[str] = set()
        for k, sw in enumerate(track.switches):
            if sw.name in seen:
                problems.append(
                    Problem("switch names must be unique", field=f"{where}.switches[{k}].name", value=sw.name)
                )
            seen.add(sw.name)
            v = sw.diverging_speed_mps
            if v is not None and not (np.isfinite(v) and 0 < v <= 150):
                problems.append(
                    Problem(
                        f"switch '{sw.name}': invalid diverging speed",
                        field=f"{where}.switches[{k}].diverging_speed_mps",
                        value=v,
                        allowed="0 < v <= 150 m/s (540 km/h), or none for line speed",
                    )
                )
            for attr in ("position_m", "clearance_m"):
                x = getattr(sw, attr)
                if x is not None and not (np.isfinite(x) and 0 <= x <= line.length_m):
                    problems.append(
                        Problem(
                            f"switch '{sw.name}' off the line",
                            field=f"{where}.switches[{k}].{attr}",
                            value=x,
                            allowed=f"0 .. {line.length_m:g} m",
                        )
                    )
        for name, pair in track.station_signals_m.items():
            if name not in names:
                problems.append(
                    Problem(
                        "unknown station",
                        field=f"{where}.station_signals_m.{name}",
                        value=name,
                        allowed=", ".join(sorted(names)),
                    )
                )
            elif len(pair) != 2 or not all(np.isfinite(x) and 0 <= x <= line.length_m for x in pair):
                problems.append(
                    Problem(
                        "station signals off the line",
                        field=f"{where}.station_signals_m.{name}",
                        value=list(pair),
                        allowed=f"[entry signal, exit signal], line positions 0 .. {line.length_m:g} m",
                    )
                )
    return problems


@dataclass
class _StationSides:
    """A station in the running coordinate of one direction [m]: stopping point, signals, where its
    entry and exit switch zones end (their release points) and the clearance points of its platforms."""

    p: float
    entry: float
    exit: float
    entry_zone_end: float
    exit_zone_end: float
    platform_lo: float | None = None
    platform_hi: float | None = None
    #: the diverging switches: (span start, span end, speed [m/s], platform tracks over the branch)
    diverging: list[tuple[float, float, float, tuple[int, ...]]] = field(default_factory=list)


def _clearance_line_m(
    sw: SwitchLayout, stop_line_m: float, dets_line: list[float], where: str, problems: list[Problem]
) -> float | None:
    """The clearance point of a switch (line position) [m]: given, or the nearest detection point
    between the switch and the station's stopping point."""
    side = 1.0 if stop_line_m > sw.position_m else -1.0
    lo, hi = sorted((sw.position_m, stop_line_m))
    if sw.clearance_m is not None:
        if not lo < sw.clearance_m < hi:
            problems.append(
                Problem(
                    f"the clearance point of switch '{sw.name}' must lie between the switch and the station's "
                    "stopping point (on the side of its two tracks)",
                    field=f"{where}.clearance_m",
                    value=sw.clearance_m,
                    allowed=f"{lo:g} < x < {hi:g} m",
                )
            )
            return None
        return float(sw.clearance_m)
    inside = [d for d in dets_line if lo < d < hi]
    if not inside:
        problems.append(
            Problem(
                f"switch '{sw.name}' needs its clearance point: give clearance_m, or a train detection point "
                "between the switch and the station's stopping point",
                field=f"{where}.clearance_m",
                value=None,
                allowed=f"a line position {lo:g} < x < {hi:g} m",
            )
        )
        return None
    return min(inside) if side > 0 else max(inside)


def _station_sides(
    line: Line, direction: Direction, ordered: list[StationLayout], problems: list[Problem]
) -> tuple[list[_StationSides], list[float]]:
    """The stations of a direction with their signals and switch zones (running coordinate) [m], and
    the direction's detection points (running coordinate, sorted)."""
    key = _track_key(line, direction)
    track = line.tracks.get(key, TrackLayout())
    where = f"line.tracks.{key}"
    rp = line.running_position
    single = line.layout == "single_track"
    sides = []
    for st in ordered:
        p = rp(direction, st.position_m)
        entry, exit_ = p - st.entry_signal_distance_m, p + st.exit_signal_offset_m
        given = track.station_signals_m.get(st.name)
        if given is not None and len(given) == 2:
            e, x = rp(direction, float(given[0])), rp(direction, float(given[1]))
            if not e < p < x:
                problems.append(
                    Problem(
                        f"station '{st.name}': the entry signal must stand before the stopping point and the exit "
                        f"signal beyond it, in the {direction} direction",
                        field=f"{where}.station_signals_m.{st.name}",
                        value=list(given),
                        allowed=f"entry before, exit after the stopping point {st.position_m:g} m "
                        f"({'increasing' if direction == 'up' else 'decreasing'} positions)",
                    )
                )
            else:
                entry, exit_ = e, x
        sides.append(_StationSides(p, entry, exit_, entry + st.switch_zone_m, exit_ + st.switch_zone_m))
    dets_line = sorted(float(x) for x in track.detection_points_m)
    # moving block separates and releases by the trains' own position reports, not by track-side
    # detection: the points only stand for clearance points not given
    moving = line.signalling.system == "moving_block"
    dets = [] if moving else sorted(rp(direction, x) for x in dets_line)
    entry_sw: list[list[tuple[float, float]]] = [[] for _ in ordered]  # (clearance, release) per station
    exit_sw: list[list[tuple[float, float]]] = [[] for _ in ordered]
    for k, sw in enumerate(track.switches):
        field_sw = f"{where}.switches[{k}]"
        if not (np.isfinite(sw.position_m) and 0 <= sw.position_m <= line.length_m):
            continue  # reported by _track_problems
        x = rp(direction, sw.position_m)
        # a switch belongs to the nearest station; in each direction it must lie on that station's entry
        # side (protected by its entry signal) or exit side (before the next main signal)
        i = int(np.argmin([abs(sd.p - x) for sd in sides]))
        sd = sides[i]
        nxt = sides[i + 1].entry if i + 1 < len(sides) else line.length_m
        home = "entry" if sd.entry < x < sd.p else "exit" if sd.exit < x < nxt else None
        if home is None:
            problems.append(
                Problem(
                    f"switch '{sw.name}' lies outside its station '{ordered[i].name}' in the {direction} "
                    "direction: a switch must lie between the entry signal and the stopping point, or beyond "
                    "the exit signal before the next signal",
                    field=f"{field_sw}.position_m",
                    value=sw.position_m,
                    allowed=f"{_span(line, direction, sd.entry, sd.p)} or {_span(line, direction, sd.exit, nxt)}",
                )
            )
            continue
        side = home
        clear_line = _clearance_line_m(sw, ordered[i].position_m, dets_line, field_sw, problems)
        if clear_line is None:
            continue
        c = rp(direction, clear_line)
        if sw.diverging_speed_mps is not None:
            n_tracks = ordered[i].tracks
            over = sw.diverging_tracks if sw.diverging_tracks is not None else tuple(range(2, n_tracks + 1))
            bad = [k for k in over if not 1 <= k <= n_tracks]
            if bad and single and direction == "down":
                continue  # the same switches as up, reported once
            if bad:
                problems.append(
                    Problem(
                        f"switch '{sw.name}': diverging tracks that station '{ordered[i].name}' does not have",
                        field=f"{field_sw}.diverging_tracks",
                        value=list(over),
                        allowed=f"track numbers 1 .. {n_tracks}",
                    )
                )
                continue
            # a train runs over the branch from the blade tip to the clearance point on the way in, the
            # other way round on the way out
            lo, hi = (x, c) if side == "entry" else (c, x)
            sd.diverging.append((lo, hi, float(sw.diverging_speed_mps), tuple(over)))
        if side == "entry":
            # released when the rear has cleared the clearance point, or the border of the switch's
            # detection section beyond it (Pachl 3.3.4: sectional release)
            release = next((d for d in dets if c - 1e-9 <= d < sides[i].exit), c)
            if c >= sides[i].exit:
                problems.append(
                    Problem(
                        f"the clearance point of switch '{sw.name}' lies beyond the next signal (the exit signal "
                        f"of '{ordered[i].name}')",
                        field=f"{field_sw}.clearance_m",
                        value=clear_line,
                        allowed=f"before {line.line_position(direction, sides[i].exit):g} m in the {direction} "
                        "direction",
                    )
                )
                continue
            entry_sw[i].append((c, release))
        else:
            nxt = sides[i + 1].entry if i + 1 < len(sides) else line.length_m
            # a train leaving over the switch fouls it until its rear has passed the blade tip, or the
            # border of the switch's detection section beyond it
            release = next((d for d in dets if x - 1e-9 <= d < nxt), x)
            exit_sw[i].append((c, release))
    for i, sd in enumerate(sides):
        if entry_sw[i]:
            sd.entry_zone_end = max(r for _c, r in entry_sw[i])
            sd.platform_lo = max(c for c, _r in entry_sw[i])
        if exit_sw[i]:
            sd.exit_zone_end = max(r for _c, r in exit_sw[i])
            sd.platform_hi = min(c for c, _r in exit_sw[i])
    for i, st in enumerate(ordered):
        # a passing loop / platform track joined to the line at one end only is not connected: a train
        # could not run through it (intermediate stations; a terminus may be a stub)
        ends = (bool(entry_sw[i]), bool(exit_sw[i]))
        if 0 < i < len(ordered) - 1 and st.tracks >= 2 and ends[0] != ends[1]:
            if single and direction == "down":
                continue  # the same switches as up, reported once
            missing = "entry" if not ends[0] else "exit"
            problems.append(
                Problem(
                    f"the platform tracks of '{st.name}' are not connected at their {missing} end in the "
                    f"{direction} direction: switches are given at one end only",
                    field=f"{where}.switches",
                    value=[sw.name for sw in track.switches],
                    allowed=f"the switches of both ends of '{st.name}', or none (the standard layout)",
                )
            )
    for i, (a, b) in enumerate(pairwise(sides)):
        if a.exit_zone_end >= b.entry:
            problems.append(
                Problem(
                    f"stations '{ordered[i].name}' and '{ordered[i + 1].name}': the exit switch zone (or the "
                    f"clearance / detection point behind the exit switch) reaches beyond the next signal in "
                    f"the {direction} direction",
                    field=f"{where}.switches" if exit_sw[i] else "stations",
                    value=line.line_position(direction, a.exit_zone_end),
                    allowed=f"before the entry signal of '{ordered[i + 1].name}' at "
                    f"{line.line_position(direction, b.entry):g} m",
                )
            )
    return sides, dets


def _span(line: Line, direction: Direction, a: float, b: float) -> str:
    lo, hi = sorted((float(line.line_position(direction, a)), float(line.line_position(direction, b))))
    return f"{lo:g} .. {hi:g} m"


def _parts(lo: float, hi: float, end: float, cuts: list[float]) -> list[tuple[int, float]]:
    """The cells of ``lo .. hi`` cut at ``cuts`` (all sorted, running coordinate) that a route over
    ``lo .. end`` crosses: (cell index, where the route leaves it) [m]."""
    bounds = [lo, *[d for d in cuts if lo < d < hi], hi]
    return [(k, min(b, end)) for k, (a, b) in enumerate(pairwise(bounds)) if a < end]


def _direction_path(
    line: Line, direction: Direction, block_length_m: float, given: list[float] | None
) -> DirectionPath:
    sig = line.signalling
    ordered = list(line.stations) if direction == "up" else list(reversed(line.stations))
    single = line.layout == "single_track"
    tag = "U" if direction == "up" else "D"
    overlap = 0.0 if sig.system == "moving_block" else sig.overlap_m
    steps: list[RouteStep] = []
    stop_m: dict[str, float] = {}
    platform_m: dict[str, tuple[float, float]] = {}
    used_given: set[int] = set()
    open_line: list[tuple[float, float]] = []  # (exit switch zone end, next entry signal) [m]
    problems: list[Problem] = []
    sides, dets = _station_sides(line, direction, ordered, problems)
    if problems:
        raise InputError.from_problems(problems)

    def track_res(st: StationLayout, k: int) -> str:
        return f"{st.name}/track{k}" if single else f"{st.name}/{tag}{k}"

    def zone_res(st: StationLayout, end: str) -> str:
        # single track: the switch zone at the line's west (low) or east (high) end, shared by both directions
        if single:
            side = ("W" if end == "entry" else "E") if direction == "up" else ("E" if end == "entry" else "W")
            return f"{st.name}/switch{side}"
        return f"{st.name}/{tag}-{end}-switch"

    for i, st in enumerate(ordered):
        sd = sides[i]
        p, entry, exit_ = sd.p, sd.entry, sd.exit
        stop_m[st.name] = p
        zone_end = sd.exit_zone_end
        entry_zone_end = sd.entry_zone_end
        if sd.platform_lo is not None and sd.platform_hi is not None:
            platform_m[st.name] = (sd.platform_lo, sd.platform_hi)
        # the platform track is held until the rear has left it over the exit switches (at their
        # clearance point, where given), and at least over the route's overlap
        track_end = zone_end if sd.platform_hi is None else max(sd.platform_hi, exit_)
        # route into the station: entry signal -> exit signal (+ overlap), one per platform track
        alts = []
        for k in range(1, st.tracks + 1):
            resources = (
                Resource(zone_res(st, "entry"), entry_zone_end),
                Resource(track_res(st, k), track_end),
            )
            alts.append(
                Route(
                    f"{tag}:{st.name} entry -> track {k}",
                    f"{st.name} {tag} entry",
                    entry,
                    exit_,
                    overlap,
                    resources,
                    st.name,
                    k,
                    speed_limits=tuple(
                        SpeedLimit(a, b, v) for a, b, v, over in sorted(sd.diverging) if k in over
                    ),
                )
            )
        steps.append(RouteStep(entry, exit_, tuple(alts), st.name, "entry"))
        if i == len(ordered) - 1:
            break
        nxt = ordered[i + 1]
        next_entry = sides[i + 1].entry
        # the open line from the exit signal to the next entry signal
        if single:
            section = _section_name(line, st, nxt)
            # cut at the detection points between the two stopping points, in line positions so that both
            # directions name the same cells alike (numbered from the line's low end)
            cells = _parts(p, sides[i + 1].p, next_entry, dets)
            n_cells = len([d for d in dets if p < d < sides[i + 1].p]) + 1
            parts = [(k if direction == "up" else n_cells - 1 - k, end) for k, end in cells if end > zone_end]
            sec = tuple(Resource(section if n_cells == 1 else f"{section}/{k + 1}", end) for k, end in parts)
            resources = (Resource(zone_res(st, "exit"), zone_end), *sec)
            route = Route(
                f"{tag}:{st.name} exit -> {nxt.name}", f"{st.name} {tag} exit", exit_, next_entry, overlap, resources, st.name,
                reserve_next=True,
            )  # fmt: skip
            steps.append(RouteStep(exit_, next_entry, (route,), st.name, "exit"))
            continue
        if sig.system == "moving_block":
            inner = list(np.arange(exit_, next_entry - 1e-6, sig.moving_block_step_m)[1:])
        elif given is not None:
            open_line.append((zone_end, next_entry))
            inner = [x for x in given if zone_end < x < next_entry]
            used_given.update(j for j, x in enumerate(given) if zone_end < x < next_entry)
        else:
            n = max(1, int(np.ceil((next_entry - exit_) / block_length_m - 1e-9)))
            inner = list(exit_ + (next_entry - exit_) * np.arange(1, n) / n)
            if inner and zone_end >= inner[0] and line.tracks.get(direction, TrackLayout()).switches:
                raise InputError(
                    f"the clearance / detection point behind the exit switch of '{st.name}' lies beyond the "
                    f"next signal (the first automatic block signal, {direction} direction)",
                    field=f"line.tracks.{direction}.switches",
                    value=line.line_position(direction, zone_end),
                    allowed=f"before {line.line_position(direction, inner[0]):g} m, or a longer block_length_m",
                )
        bounds = [exit_, *inner, next_entry]
        for j, (a, b) in enumerate(pairwise(bounds)):
            name = f"{tag}:{st.name}-{nxt.name} block {j + 1}"
            # train detection points inside the block cut it into track sections, each released when
            # the rear has passed its end (the open line beyond the exit switch zone)
            start = zone_end if j == 0 else a
            cuts = [] if sig.system == "moving_block" else [d for d in dets if start < d < b]
            blocks = (
                (Resource(name, b),)
                if not cuts
                else tuple(Resource(f"{name}/{k + 1}", end) for k, end in enumerate([*cuts, b]))
            )
            resources = (Resource(zone_res(st, "exit"), zone_end), *blocks) if j == 0 else blocks
            steps.append(
                RouteStep(
                    a,
                    b,
                    (Route(name, f"{name} signal", a, b, overlap, resources, st.name if j == 0 else None),),
                    st.name if j == 0 else None,
                    "exit" if j == 0 else "block",
                )
            )
    if given is not None and len(used_given) != len(given):
        # the first value off the open line (in running order; the file's list may be in the other) and
        # the ranges allowed, in the file's line positions
        j = min(k for k in range(len(given)) if k not in used_given)
        spans = sorted(sorted(line.line_position(direction, x) for x in ab) for ab in open_line)
        raise InputError(
            "block signals must lie on the open line between two stations (beyond the exit switch zone, "
            "before the next entry signal)",
            field=f"line.block_signals_m.{direction}",
            value=line.line_position(direction, given[j]),
            allowed="between " + ", ".join(f"{a:g} and {b:g} m" for a, b in spans) + " (exclusive)",
        )
    if dets and overlap > 0 and sig.system != "moving_block":
        steps = _overlaps_to_detection(steps, overlap, dets)
    return DirectionPath(direction, tuple(steps), stop_m, platform_m)


def _overlaps_to_detection(steps: list[RouteStep], overlap_m: float, dets: list[float]) -> list[RouteStep]:
    """The routes with their overlaps run to a train detection point (``overlap_end_m``), but not
    beyond the first section of the next route, where the overlap lies: a train that stops in the
    next route (at a platform, the station's entry switches cleared) has cleared its overlap before it
    stands. Without the bound, a train standing at a platform short of the first detection point
    would hold the section behind it until it leaves (interlockings release such an overlap by a
    timer once the train stands)."""
    out = []
    for k, step in enumerate(steps):
        nxt = steps[k + 1].alternatives if k + 1 < len(steps) else ()
        bound = min((r.resources[0].end_m for r in nxt if r.resources), default=np.inf)
        alts = []
        for r in step.alternatives:
            end = min(overlap_end_m(r.end_m, overlap_m, dets), max(r.end_m + overlap_m, bound))
            alts.append(replace(r, overlap_m=end - r.end_m))
        out.append(replace(step, alternatives=tuple(alts)))
    return out


def overlap_end_m(signal_m: float, overlap_m: float, detection_m: list[float] | tuple[float, ...]) -> float:
    """Where the overlap of a main signal at ``signal_m`` ends (running coordinate) [m].

    The overlap is a track section beyond the signal, so it ends at a train detection point: the first
    one at least ``overlap_m`` beyond the signal (``detection_m`` sorted, running coordinate), and it
    is released with that section, when the train's rear has cleared that point (issue 17; Pachl,
    *Railway Operation and Control*, 4th ed. 2018, ch. 3: an overlap is a stretch of track beyond
    the signal kept clear, released with its train detection section). Without a detection point
    that far (or with no overlap), the overlap ends ``overlap_m`` beyond the signal.
    """
    if overlap_m <= 0:
        return signal_m
    want = signal_m + overlap_m
    i = bisect_left(detection_m, want - 1e-9)
    return float(detection_m[i]) if i < len(detection_m) else want


def _section_name(line: Line, a: StationLayout, b: StationLayout) -> str:
    lo, hi = (a, b) if a.position_m < b.position_m else (b, a)
    return f"{lo.name}-{hi.name}"
