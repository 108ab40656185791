"""A signalled line: stations with their tracks, block sections, signals and the routes trains take.

Positions are in metres. A line has one coordinate (``0 .. length_m``, the "up" direction); a train in
the "down" direction runs from ``length_m`` towards 0 and sees the line in its own *running
coordinate* ``x = length_m - position``. Every route below is stored in the running coordinate of its
direction, so a train's trajectory and the routes it takes share one increasing position.

The model follows Pachl, *Railway Operation and Control* (4th ed., 2018), chapters 3-4, and UIC Code
406 (2nd ed., 2013):

* A **route** (block section, or an interlocking route through a station) starts at a main signal and
  ends at the next main signal plus the **overlap** beyond it. It is made of **resources** (train
  detection sections: a plain-line block, a station's switch zone, a platform track, a single-track
  section between two stations). Two trains conflict when they claim one resource at the same time.
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

from dataclasses import dataclass, field
from itertools import pairwise
from typing import Literal

import numpy as np

from trainsim.errors import InputError, Problem

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

    def signal_positions(self) -> np.ndarray:
        """Positions of the main signals in running order [m]."""
        return np.array([s.start_m for s in self.steps])


@dataclass(frozen=True)
class Line:
    """A signalled line: its length, layout, stations, signalling and the path of each direction."""

    name: str
    length_m: float
    layout: Layout
    stations: tuple[StationLayout, ...]
    signalling: Signalling
    paths: dict[str, DirectionPath] = field(default_factory=dict)

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

    Raises:
        InputError: stations off the line, out of order or too close; block signals off the open line.
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
    line = Line(name, float(length_m), layout, stations, signalling)
    paths = {}
    for direction in ("up", "down"):
        given = None
        if block_signals_m and direction in block_signals_m:
            given = sorted(line.running_position(direction, float(x)) for x in block_signals_m[direction])
        paths[direction] = _direction_path(line, direction, block_length_m, given)
    object.__setattr__(line, "paths", paths)
    return line


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
    used_given: set[int] = set()

    def track_res(st: StationLayout, k: int) -> str:
        return f"{st.name}/track{k}" if single else f"{st.name}/{tag}{k}"

    def zone_res(st: StationLayout, end: str) -> str:
        # single track: the switch zone at the line's west (low) or east (high) end, shared by both directions
        if single:
            side = ("W" if end == "entry" else "E") if direction == "up" else ("E" if end == "entry" else "W")
            return f"{st.name}/switch{side}"
        return f"{st.name}/{tag}-{end}-switch"

    for i, st in enumerate(ordered):
        p = line.running_position(direction, st.position_m)
        stop_m[st.name] = p
        entry = p - st.entry_signal_distance_m
        exit_ = p + st.exit_signal_offset_m
        zone_end = exit_ + st.switch_zone_m
        entry_zone_end = entry + st.switch_zone_m
        # route into the station: entry signal -> exit signal (+ overlap), one per platform track
        alts = []
        for k in range(1, st.tracks + 1):
            resources = (
                Resource(zone_res(st, "entry"), entry_zone_end),
                Resource(track_res(st, k), zone_end),
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
                )
            )
        steps.append(RouteStep(entry, exit_, tuple(alts), st.name, "entry"))
        if i == len(ordered) - 1:
            break
        nxt = ordered[i + 1]
        next_entry = line.running_position(direction, nxt.position_m) - nxt.entry_signal_distance_m
        # the open line from the exit signal to the next entry signal
        if single:
            section = _section_name(line, st, nxt)
            resources = (Resource(zone_res(st, "exit"), zone_end), Resource(section, next_entry))
            route = Route(
                f"{tag}:{st.name} exit -> {nxt.name}", f"{st.name} {tag} exit", exit_, next_entry, overlap, resources, st.name,
                reserve_next=True,
            )  # fmt: skip
            steps.append(RouteStep(exit_, next_entry, (route,), st.name, "exit"))
            continue
        if sig.system == "moving_block":
            inner = list(np.arange(exit_, next_entry - 1e-6, sig.moving_block_step_m)[1:])
        elif given is not None:
            inner = [x for x in given if zone_end < x < next_entry]
            used_given.update(j for j, x in enumerate(given) if zone_end < x < next_entry)
        else:
            n = max(1, int(np.ceil((next_entry - exit_) / block_length_m - 1e-9)))
            inner = list(exit_ + (next_entry - exit_) * np.arange(1, n) / n)
        bounds = [exit_, *inner, next_entry]
        for j, (a, b) in enumerate(pairwise(bounds)):
            resources = (
                (
                    Resource(zone_res(st, "exit"), zone_end),
                    Resource(f"{tag}:{st.name}-{nxt.name} block {j + 1}", b),
                )
                if j == 0
                else (Resource(f"{tag}:{st.name}-{nxt.name} block {j + 1}", b),)
            )
            name = f"{tag}:{st.name}-{nxt.name} block {j + 1}"
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
        off = [line.line_position(direction, x) for j, x in enumerate(given) if j not in used_given]
        raise InputError(
            "block signals must lie on the open line between two stations (beyond the exit switch zone, before the next entry signal)",
            field=f"line.block_signals_m.{direction}",
            value=off,
        )
    return DirectionPath(direction, tuple(steps), stop_m)


def _section_name(line: Line, a: StationLayout, b: StationLayout) -> str:
    lo, hi = (a, b) if a.position_m < b.position_m else (b, a)
    return f"{lo.name}-{hi.name}"
