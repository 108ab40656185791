"""Signalling of a line from railML 2 and 3 (issue 17): signals, train detection points, switches and
station tracks along the path of a route, for the operations layer (:mod:`trainsim.operations.line`).

The path is the route's (:mod:`trainsim.io.railml_reader`: a timetable train's, or the operational
points given); positions are route positions [m], the coordinate of the route's stations. An element
off the path is not read (counted in the notes).

railML 2 (``infrastructure/tracks/track``)
    * ``ocsElements/signals/signal@pos,@dir,@type,@function,@name``;
    * ``ocsElements/trainDetectionElements/trainDetector@pos`` (an axle counter, or a detector) and
      ``trackCircuitBorder@pos``;
    * ``trackTopology/connections/switch@pos,@name``, the speed over its diverging branch from
      ``switch/connection@maxSpeed`` [km/h];
    * station tracks: the tracks an ocp is placed on (``crossSection@ocpRef``).

railML 3 (``infrastructure/functionalInfrastructure``)
    * ``signalsIS/signalIS`` with ``spotLocation`` (``@applicationDirection`` normal, reverse) and
      ``isTrainMovementSignal@type,@function`` (or the same attributes on ``signalIS``);
    * ``trainDetectionElements/trainDetectionElement@type`` with ``spotLocation``;
    * ``switchesIS/switchIS`` with ``spotLocation``, the speed over its diverging branch from the
      ``leftBranch`` / ``rightBranch`` of ``@branchCourse`` (``@branchingSpeed``, ``@joiningSpeed``
      [km/h]);
    * station tracks: the netElements an operationalPoint has a ``spotLocation`` on.

The kind of a signal (trainsim's reading of the railML enumerations, :data:`SIGNAL_KINDS`): ``main``
(type main or combined), ``block`` (a main signal whose function is blocking / block / intermediate),
``distant`` (type distant or repeater). Other types (shunting...) are not read and noted.

Direction: ``up`` for a signal that governs trains running along the route's path, ``down`` for one
that faces the other way on the same tracks (single track).

Double track (``double_track=True``): the down path is the route's stations in reverse order through
the tracks that are not on the route's path (each station must lie on such a track). Signals, train
detection points and switches of the down path are mapped to route positions piecewise linearly
between the stations both paths pass (beyond the first and last, at the same scale: 1 m down is 1 m
back), so that the two tracks may differ in length and mileage. A signal of the down track that faces
along the down path is a ``down`` signal; one facing the other way (wrong-line running) is not read
and noted. Station tracks are then counted per direction: the tracks of a station on the up side
(not on the down path) and on the down side.

Tracks (:class:`TrackAt`, ``LineSignalling.tracks``): railML 2 ``tracks/track@type,@mainDir``; railML 3
``functionalInfrastructure/tracks/track@type,@mainDirection`` with the netElements of its
``linearLocation/associatedNetElement`` (``@keepsOrientation`` false turns the direction round). Each
is given with its extent along a path and its main direction relative to the route (``up``, ``down``,
``both`` or None). In railML 3 a station's tracks are the functional tracks its operational point lies
on (two netElements of one track count once); netElements outside every track count one each.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
from lxml import etree

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.io import railml_common as rc
from trainsim.io.railml_common import attr_float, child, children, label, local
from trainsim.io.railml_reader import Dialect, Reader

__all__ = [
    "SIGNAL_KINDS",
    "DetectionPoint",
    "LineSignalling",
    "SignalAt",
    "StationTracks",
    "SwitchAt",
    "TrackAt",
    "read_signalling",
]

Direction = Literal["up", "down"]
SignalKind = Literal["main", "distant", "block"]

#: railML signal type -> trainsim's kind (a main signal with a :data:`BLOCK_FUNCTIONS` function is
#: ``block``). Types not listed (shunting, other:...) are not read.
SIGNAL_KINDS: dict[str, SignalKind] = {
    "main": "main",
    "combined": "main",
    "distant": "distant",
    "repeater": "distant",
}
#: Signal functions that make a main signal an automatic block signal.
BLOCK_FUNCTIONS = frozenset({"blocking", "block", "intermediate"})


@dataclass(frozen=True)
class SignalAt:
    """A signal on the route: ``position_m`` route position [m], ``direction`` relative to the path."""

    name: str
    position_m: float
    direction: Direction
    kind: SignalKind
    source: str  #: element and line it was read from


@dataclass(frozen=True)
class DetectionPoint:
    """A train detection point (axle counter, track-circuit border) at ``position_m`` [m]."""

    name: str
    position_m: float
    kind: str  #: ``axle_counter``, ``track_circuit_border`` or ``detector``
    source: str
    path: Direction = "up"  #: read on the route's path (``up``) or on the down path of a double track


@dataclass(frozen=True)
class SwitchAt:
    """A switch on the route at ``position_m`` [m]."""

    name: str
    position_m: float
    source: str
    path: Direction = "up"  #: read on the route's path (``up``) or on the down path of a double track
    #: its clearance point [m] where the source gives it (spreadsheets; railML has none)
    clearance_m: float | None = None
    #: highest speed over its diverging branch [m/s] where the source gives it
    diverging_speed_mps: float | None = None


@dataclass(frozen=True)
class TrackAt:
    """A railML track along a path: ``start_m`` .. ``end_m`` route positions [m], its railML type and
    its main direction relative to the route (``up``, ``down``, ``both``, or None when not given)."""

    name: str
    kind: str | None
    main_direction: str | None
    start_m: float
    end_m: float
    path: Direction
    source: str


@dataclass(frozen=True)
class StationTracks:
    """A station of the route at ``position_m`` [m] with the number of tracks it lies on (on a double
    track read with its down path: the tracks on the up side, and ``down_tracks`` on the down side)."""

    name: str
    position_m: float
    tracks: int
    down_tracks: int | None = None


@dataclass
class LineSignalling:
    """What a railML file says about the signalling along one route path."""

    name: str
    start_m: float
    end_m: float
    stations: list[StationTracks]
    signals: list[SignalAt] = field(default_factory=list)
    detection_points: list[DetectionPoint] = field(default_factory=list)
    switches: list[SwitchAt] = field(default_factory=list)
    tracks: list[TrackAt] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def station_signals(self, direction: Direction = "up") -> list[dict[str, float | str | int]]:
        """Per station, in the form of the operation file's ``line.stations`` entries: ``name``,
        ``position_m``, ``tracks`` and, where the file has them, ``entry_signal_distance_m`` (from the
        last main signal before the station, after the previous station) and
        ``exit_signal_offset_m`` (to the first main signal at or after the stopping point, before the
        next station), in the running direction ``direction``."""
        sign = 1.0 if direction == "up" else -1.0
        mains = sorted(
            sign * s.position_m for s in self.signals if s.direction == direction and s.kind == "main"
        )
        ordered = sorted(self.stations, key=lambda st: sign * st.position_m)
        out: list[dict[str, float | str | int]] = []
        for k, st in enumerate(ordered):
            p = sign * st.position_m
            before = sign * ordered[k - 1].position_m if k > 0 else -float("inf")
            after = sign * ordered[k + 1].position_m if k + 1 < len(ordered) else float("inf")
            entry: dict[str, float | str | int] = {"name": st.name, "position_m": st.position_m}
            entry["tracks"] = st.tracks if direction == "up" or st.down_tracks is None else st.down_tracks
            home = [x for x in mains if before < x < p]
            if home and k > 0:
                entry["entry_signal_distance_m"] = p - home[-1]
            exits = [x for x in mains if p <= x < after]
            if exits and k + 1 < len(ordered):
                entry["exit_signal_offset_m"] = exits[0] - p
            out.append(entry)
        return out if direction == "up" else out[::-1]

    def block_signals_m(self) -> dict[Direction, list[float]]:
        """Block signals per direction, route positions [m]: the form of the operation file's
        ``line.block_signals_m``."""
        out: dict[Direction, list[float]] = {"up": [], "down": []}
        for s in self.signals:
            if s.kind == "block":
                out[s.direction].append(s.position_m)
        return {d: sorted(v) for d, v in out.items()}


# ---------------------------------------------------------------------- placing elements
@dataclass(frozen=True)
class _Placed:
    element: etree._Element
    edge: str
    pos: float
    directions: tuple[int, ...]


_DIRS_V2 = {"up": (1,), "down": (-1,)}
_DIRS_V3 = {"normal": (1,), "reverse": (-1,)}


def _below(el: etree._Element | None, names: Sequence[str]) -> list[etree._Element]:
    return [d for d in el.iter() if d is not el and local(d) in names] if el is not None else []


def _placed_v2(reader: Reader, container: str, names: Sequence[str]) -> list[_Placed]:
    """Elements named ``names`` below ``container`` of each track, at ``@pos`` in ``@dir``."""
    assert reader.topology is not None
    out: list[_Placed] = []
    for tid, track in reader.topology.net.elements.items():
        begin, end = reader.topology.net.extent[tid]
        holder = child(track, container)
        for el in _below(holder, names):
            reader.usage.use(el.getparent())
            pos = attr_float(el, "pos", reader.problems, required=True, what="position on the track [m]")
            if pos is None or not reader.within(el, pos, begin, end):
                continue
            reader.usage.use(el, deep=True)
            out.append(_Placed(el, tid, pos, _DIRS_V2.get(el.get("dir") or "", (1, -1))))
    return out


def _placed_v3(reader: Reader, names: Sequence[str]) -> list[_Placed]:
    """Elements named ``names`` below functionalInfrastructure, at their spotLocations."""
    from trainsim.io.railml3 import NetElements, Railml3

    topology = reader.topology
    assert isinstance(topology, NetElements) and isinstance(reader.d, Railml3)
    out: list[_Placed] = []
    for el in _below(reader.infra, names):
        reader.d.use_containers(el)
        reader.usage.use(el, deep=True)
        dirs = _DIRS_V3.get(
            next((s.get("applicationDirection") for s in children(el, "spotLocation")), ""), (1, -1)
        )
        places = reader.d.spot(el, topology.net, topology.measures, reader.d.lps_units())
        if not places:
            reader.problems.add(el, "no position on a netElement (spotLocation)")
        out.extend(_Placed(el, edge, pos, dirs) for edge, pos in places)
    return out


def _on_path(path: rc.RoutePath, item: _Placed) -> tuple[float, int] | None:
    """Route position [m] and the direction (+1 along the path, -1 against it) of a placed element."""
    for leg, s0 in zip(path.legs, path.offsets, strict=True):
        if leg.edge == item.edge and leg.covers(item.pos):
            return round(s0 + abs(item.pos - leg.start), 9), leg.direction
    return None


def _signal_kind(el: etree._Element, v3: bool) -> SignalKind | None:
    holder = child(el, "isTrainMovementSignal") if v3 else None
    kind = (holder.get("type") if holder is not None else None) or el.get("type")
    function = (holder.get("function") if holder is not None else None) or el.get("function")
    if kind is None and holder is not None:
        kind = "main"  # a train movement signal without type is a main signal
    found = SIGNAL_KINDS.get((kind or "").strip())
    if found == "main" and (function or "").strip() in BLOCK_FUNCTIONS:
        return "block"
    return found


def _name(reader: Reader, el: etree._Element) -> str:
    return reader.d.name(el, use=True) or el.get("id") or label(el)


def _source(el: etree._Element) -> str:
    return f"{label(el)} at line {el.sourceline}"


# ---------------------------------------------------------------------- double track
@dataclass
class _DownPath:
    """The down path of a double-track line and its mapping to route positions."""

    path: rc.RoutePath
    down_m: np.ndarray  #: station positions along the down path, increasing [m]
    up_m: np.ndarray  #: the same stations' route positions, decreasing [m]
    up_side: frozenset[str]  #: edges joined to the route's path without crossing the down path
    down_side: frozenset[str]  #: edges joined to the down path without crossing the route's path

    def route_position(self, down_m: float) -> float:
        """Route position of a down-path position: linear between the stations, at the same scale
        beyond them."""
        if down_m < self.down_m[0]:
            return float(self.up_m[0] + (self.down_m[0] - down_m))
        if down_m > self.down_m[-1]:
            return float(self.up_m[-1] - (down_m - self.down_m[-1]))
        return float(np.interp(down_m, self.down_m, self.up_m))


def _down_path(reader: Reader) -> _DownPath:
    """The route's stations in reverse order through the tracks that are not on its path."""
    assert reader.path is not None and reader.topology is not None
    file = str(reader.file)
    net = reader.topology.net
    up_edges = {leg.edge for leg in reader.path.legs}
    side = rc.Network()
    for edge, (begin, end) in net.extent.items():
        if edge not in up_edges:
            side.add_edge(edge, begin, end, net.elements[edge])
    for port in net.ports.values():
        if port.edge not in up_edges:
            side.add_port(port)
    stops: list[rc.Stop] = []
    for st in reversed(reader.stations):
        places = tuple((e, x) for e, x in reader.station_places[st.element] if e not in up_edges)
        if not places:
            raise InputError(
                f"double track: station '{st.name}' lies on no track besides the route's path, so the down "
                "track cannot be found",
                file=file,
                field="double_track",
                value=st.name,
                allowed="each station placed on both tracks (railML 2 crossSection@ocpRef, railML 3 "
                "spotLocation of the operational point)",
            )
        stops.append(rc.Stop(st.name, places, st.element))
    problems = rc.Problems(file)
    path = rc.route_path(side, stops, problems)
    if path is None:
        first = problems.items[0] if problems.items else None
        raise InputError(
            "double track: no down path through the tracks beside the route's path"
            + (f" ({first.text()})" if first is not None else ""),
            file=file,
            field="double_track",
            allowed="a second track joining the stations in reverse order",
        )
    down, up = [], []
    after = -np.inf
    for stop, st in zip(stops, reversed(reader.stations), strict=True):
        found = [x for e, q in stop.locations if (x := path.position(e, q, after)) is not None]
        after = min(found)
        down.append(after)
        up.append(st.position_m)
    if not (np.all(np.diff(down) > 0) and np.all(np.diff(up) < 0)):
        raise InputError(  # pragma: no cover - route_path visits the stops in order
            "double track: the stations do not lie in reverse order along the down path",
            file=file,
            field="double_track",
        )
    down_edges = {leg.edge for leg in path.legs}
    return _DownPath(
        path, np.array(down), np.array(up), _side(net, up_edges, down_edges), _side(net, down_edges, up_edges)
    )


def _side(net: rc.Network, start: set[str], stop: set[str]) -> frozenset[str]:
    """The edges reached from ``start`` through the ports without entering ``stop``: the tracks on one
    side of a double-track line (its passing loops), to count a station's tracks per direction."""
    seen, todo = set(start), list(start)
    while todo:
        for port in net.by_edge.get(todo.pop(), []):
            other = net.ports.get(port.partner or "")
            if other is not None and other.edge not in seen and other.edge not in stop:
                seen.add(other.edge)
                todo.append(other.edge)
    return frozenset(seen)


# ---------------------------------------------------------------------- tracks
_MAIN_V2 = {"up": 1, "down": -1, "both": 0}
_MAIN_V3 = {"normal": 1, "reverse": -1, "both": 0}


def _railml_tracks(reader: Reader, v3: bool) -> list[tuple[etree._Element, dict[str, int]]]:
    """Each railML track with its edges: edge -> main direction in edge coordinates (+1, -1, 0 both,
    2 not given). railML 2: every track is its own edge."""
    out: list[tuple[etree._Element, dict[str, int]]] = []
    assert reader.topology is not None
    if not v3:
        for tid, track in reader.topology.net.elements.items():
            out.append((track, {tid: _MAIN_V2.get((track.get("mainDir") or "").strip(), 2)}))
        return out
    holder = child(child(reader.infra, "functionalInfrastructure"), "tracks")
    for track in children(holder, "track"):
        reader.usage.use(holder)
        reader.usage.use(track, deep=True)
        main = _MAIN_V3.get((track.get("mainDirection") or "").strip(), 2)
        edges: dict[str, int] = {}
        for loc in children(track, "linearLocation"):
            for assoc in children(loc, "associatedNetElement"):
                ref = assoc.get("netElementRef")
                if ref not in reader.topology.net.extent:
                    reader.problems.add(
                        assoc, "a track on an unknown netElement", attribute="netElementRef", value=ref
                    )
                    continue
                flip = -1 if (assoc.get("keepsOrientation") or "").strip() == "false" else 1
                edges[ref] = main * flip if main in (1, -1) else main
        if not edges:
            reader.problems.add(track, "a track needs its netElements (linearLocation/associatedNetElement)")
        out.append((track, edges))
    return out


def _tracks_on(path: rc.RoutePath, which: Direction, tracks, reader: Reader) -> list[TrackAt]:
    out: list[TrackAt] = []
    for track, edges in tracks:
        spans = [
            (
                s0,
                s0 + leg.length,
                edges[leg.edge] * leg.direction if edges[leg.edge] in (1, -1) else edges[leg.edge],
            )
            for leg, s0 in zip(path.legs, path.offsets, strict=True)
            if leg.edge in edges
        ]
        if not spans:
            continue
        along = {m for _a, _b, m in spans}
        if along <= {1} or along <= {-1}:
            up_along = next(iter(along)) == (1 if which == "up" else -1)
            main: str | None = "up" if up_along else "down"
        else:
            main = "both" if along == {0} else None
        kind = (track.get("type") or track.get("trackType") or "").strip() or None
        start, end = min(a for a, _b, _m in spans), max(b for _a, b, _m in spans)
        out.append(TrackAt(_name(reader, track), kind, main, start, end, which, _source(track)))
    return out


def _station_track_count(places, tracks, v3: bool) -> int:
    """Distinct tracks at the places of a station: railML 3 functional tracks (a netElement outside
    every track counts alone), railML 2 tracks."""
    edges = {e for e, _x in places}
    if not v3 or not tracks:
        return len(edges)
    owner = {e: i for i, (_t, es) in enumerate(tracks) for e in es}
    return len({owner.get(e, e) for e in edges})


# ---------------------------------------------------------------------- reading
def read_signalling(
    path: str | Path,
    *,
    train_id: str | None = None,
    ocps: Sequence[str] | None = None,
    double_track: bool = False,
    tree: etree._ElementTree | None = None,
) -> LineSignalling:
    """The signals, train detection points, switches, tracks and station tracks of a railML 2 or 3
    file along the path of a timetable train (``train_id``, default the first) or through the
    operational points ``ocps``; with ``double_track`` also along the down track (module docstring).

    Raises:
        InputError naming the element and its line for every problem found (a signal off its track,
        a route that cannot be read, a down track that cannot be found).
    """
    from trainsim.io import railml2, railml3

    tree = tree if tree is not None else rc.parse_xml(path)
    root = tree.getroot()
    dialect: type[Dialect] | None = next(
        (d for d in (railml2.Railml2, railml3.Railml3) if d.detect(root)), None
    )
    if dialect is None:
        raise InputError("not a railML 2 or 3 file (root element 'railml' or 'railML')", file=str(path))
    reader = Reader(path, tree, dialect)
    route, _, _ = reader.route(
        train_id=train_id, ocps=ocps, line_resistance=None, require_line_resistance=False
    )
    if route is None or reader.path is None:
        raise InputError(
            "no route: the file has no timetable; give the operational points of the path",
            file=str(path),
            field="ocps",
        )
    v3 = dialect is railml3.Railml3
    if v3:
        signals = _placed_v3(reader, ("signalIS",))
        detectors = _placed_v3(reader, ("trainDetectionElement",))
        switches = _placed_v3(reader, ("switchIS",))
    else:
        signals = _placed_v2(reader, "ocsElements", ("signal",))
        detectors = _placed_v2(reader, "ocsElements", ("trainDetector", "trackCircuitBorder"))
        switches = _placed_v2(reader, "trackTopology", ("switch",))
    tracks = _railml_tracks(reader, v3)
    reader.problems.raise_if_any()
    down = _down_path(reader) if double_track else None
    stations = []
    for st in reader.stations:
        places = reader.station_places[st.element]
        if down is None:
            stations.append(StationTracks(st.name, st.position_m, _station_track_count(places, tracks, v3)))
            continue
        up_side = [(e, x) for e, x in places if e in down.up_side]
        down_side = [(e, x) for e, x in places if e in down.down_side]
        stations.append(
            StationTracks(
                st.name, st.position_m, _station_track_count(up_side, tracks, v3),
                _station_track_count(down_side, tracks, v3),
            )
        )  # fmt: skip
    out = LineSignalling(
        name=str(route["name"]), start_m=reader.path.start_m, end_m=reader.path.end_m, stations=stations
    )
    out.tracks = _tracks_on(reader.path, "up", tracks, reader)
    if down is not None:
        out.tracks += [
            replace(t, start_m=down.route_position(t.end_m), end_m=down.route_position(t.start_m))
            for t in _tracks_on(down.path, "down", tracks, reader)
        ]

    def where(item: _Placed) -> tuple[float, int, Direction] | None:
        """Route position, direction relative to the path it lies on (+1 along), and that path."""
        found = _on_path(reader.path, item)
        if found is not None:
            return found[0], found[1], "up"
        if down is None:
            return None
        found = _on_path(down.path, item)
        if found is None:
            return None
        pos = down.route_position(found[0])
        if not out.start_m - 1e-6 <= pos <= out.end_m + 1e-6:
            out.notes.append(f"{_source(item.element)}: on the down track beyond the route's ends, not read")
            return None
        return round(pos, 9), found[1], "down"

    off_path: dict[str, int] = {}
    for item in signals:
        place = where(item)
        kind = _signal_kind(item.element, v3)
        if kind is None:
            reader.usage.skip(item.element, "not a main, block or distant signal")
            out.notes.append(f"{_source(item.element)}: not a main, block or distant signal, not read")
            continue
        if place is None:
            off_path["signals"] = off_path.get("signals", 0) + 1
            continue
        pos, leg_dir, which = place
        if len(item.directions) != 1:
            reader.problems.add(
                item.element, "a signal needs its direction", attribute="dir" if not v3 else None
            )
            continue
        along = item.directions[0] == leg_dir
        if which == "down" and not along:
            out.notes.append(
                f"{_source(item.element)}: faces the up direction on the down track (wrong-line), not read"
            )
            continue
        direction: Direction = "down" if which == "down" or not along else "up"
        out.signals.append(SignalAt(_name(reader, item.element), pos, direction, kind, _source(item.element)))
    for item in detectors:
        place = where(item)
        if place is None:
            off_path["train detection points"] = off_path.get("train detection points", 0) + 1
            continue
        out.detection_points.append(
            DetectionPoint(
                _name(reader, item.element),
                place[0],
                _detector_kind(item.element),
                _source(item.element),
                place[2],
            )
        )
    for item in switches:
        place = where(item)
        if place is None:
            off_path["switches"] = off_path.get("switches", 0) + 1
            continue
        speed = _diverging_speed_mps(item.element, v3, reader.problems)
        out.switches.append(
            SwitchAt(_name(reader, item.element), place[0], _source(item.element), place[2], None, speed)
        )
    reader.problems.raise_if_any()
    out.signals.sort(key=lambda s: (s.direction != "up", s.position_m))
    out.detection_points.sort(key=lambda d: (d.path != "up", d.position_m))
    out.switches.sort(key=lambda s: (s.path != "up", s.position_m))
    out.tracks.sort(key=lambda t: (t.path != "up", t.start_m))
    out.notes += [f"{what} not on the route's path, not read: {n}" for what, n in off_path.items()]
    return out


def _diverging_speed_mps(el: etree._Element, v3: bool, problems: rc.Problems) -> float | None:
    """The speed over a switch's diverging branch [m/s] (module docstring), None when not given.

    railML 2: ``connection@maxSpeed`` [km/h] of the switch's connections (the branch leaving the
    switch's own track, which continues straight); the lowest where there are several. railML 3: the
    ``leftBranch`` or ``rightBranch`` named by ``@branchCourse`` (without it, the slower of the two),
    the lower of its ``@branchingSpeed`` (facing) and ``@joiningSpeed`` (trailing) [km/h]: the model
    holds one diverging speed per switch for both directions.
    """
    if not v3:
        branches = list(children(el, "connection"))
        names = ("maxSpeed",)
    else:
        course = (el.get("branchCourse") or "").strip()
        wanted = ("leftBranch", "rightBranch") if course not in ("left", "right") else (f"{course}Branch",)
        branches = [b for name in wanted for b in children(el, name)]
        names = ("branchingSpeed", "joiningSpeed")
    speeds = [
        v
        for b in branches
        for name in names
        if (v := attr_float(b, name, problems, what="speed [km/h]", positive=True)) is not None
    ]
    return min(speeds) * KMH if speeds else None


def _detector_kind(el: etree._Element) -> str:
    if local(el) == "trackCircuitBorder":
        return "track_circuit_border"
    kind = (el.get("type") or el.get("detectionObject") or "").strip()
    if kind in ("axleCounter", "axleCounting") or el.get("axleCounting") == "true":
        return "axle_counter"
    if kind == "trackCircuitBorder":
        return "track_circuit_border"
    return "detector"
