"""Signalling of a line from railML 2 and 3 (issue 17): signals, train detection points, switches and
station tracks along the path of a route, for the operations layer (:mod:`trainsim.operations.line`).

The path is the route's (:mod:`trainsim.io.railml_reader`: a timetable train's, or the operational
points given); positions are route positions [m], the coordinate of the route's stations. An element
off the path is not read (counted in the notes).

railML 2 (``infrastructure/tracks/track``)
    * ``ocsElements/signals/signal@pos,@dir,@type,@function,@name``;
    * ``ocsElements/trainDetectionElements/trainDetector@pos`` (an axle counter, or a detector) and
      ``trackCircuitBorder@pos``;
    * ``trackTopology/connections/switch@pos,@name``;
    * station tracks: the tracks an ocp is placed on (``crossSection@ocpRef``).

railML 3 (``infrastructure/functionalInfrastructure``)
    * ``signalsIS/signalIS`` with ``spotLocation`` (``@applicationDirection`` normal, reverse) and
      ``isTrainMovementSignal@type,@function`` (or the same attributes on ``signalIS``);
    * ``trainDetectionElements/trainDetectionElement@type`` with ``spotLocation``;
    * ``switchesIS/switchIS`` with ``spotLocation``;
    * station tracks: the netElements an operationalPoint has a ``spotLocation`` on.

The kind of a signal (trainsim's reading of the railML enumerations, :data:`SIGNAL_KINDS`): ``main``
(type main or combined), ``block`` (a main signal whose function is blocking / block / intermediate),
``distant`` (type distant or repeater). Other types (shunting...) are not read and noted.

Direction: ``up`` for a signal that governs trains running along the route's path, ``down`` for one
that faces the other way on the same tracks (single track). For the other track of a double-track
line, read the path of a train in the other direction.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from lxml import etree

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


@dataclass(frozen=True)
class SwitchAt:
    """A switch on the route at ``position_m`` [m]."""

    name: str
    position_m: float
    source: str


@dataclass(frozen=True)
class StationTracks:
    """A station of the route at ``position_m`` [m] with the number of tracks it lies on."""

    name: str
    position_m: float
    tracks: int


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
            entry["tracks"] = st.tracks
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
        dirs = _DIRS_V3.get(next((s.get("applicationDirection") for s in children(el, "spotLocation")), ""), (1, -1))
        places = reader.d.spot(el, topology.net, topology.measures, reader.d.lps_units())
        if not places:
            reader.problems.add(el, "no position on a netElement (spotLocation)")
        out.extend(_Placed(el, edge, pos, dirs) for edge, pos in places)
    return out


def _on_path(reader: Reader, item: _Placed) -> tuple[float, int] | None:
    """Route position [m] and the direction (+1 along the path, -1 against it) of a placed element."""
    path = reader.path
    assert path is not None
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


# ---------------------------------------------------------------------- reading
def read_signalling(
    path: str | Path,
    *,
    train_id: str | None = None,
    ocps: Sequence[str] | None = None,
    tree: etree._ElementTree | None = None,
) -> LineSignalling:
    """The signals, train detection points, switches and station tracks of a railML 2 or 3 file along
    the path of a timetable train (``train_id``, default the first) or through the operational
    points ``ocps``.

    Raises:
        InputError naming the element and its line for every problem found (a signal off its track,
        a route that cannot be read).
    """
    from trainsim.io import railml2, railml3

    tree = tree if tree is not None else rc.parse_xml(path)
    root = tree.getroot()
    dialect: type[Dialect] | None = next((d for d in (railml2.Railml2, railml3.Railml3) if d.detect(root)), None)
    if dialect is None:
        raise InputError("not a railML 2 or 3 file (root element 'railml' or 'railML')", file=str(path))
    reader = Reader(path, tree, dialect)
    route, _, _ = reader.route(train_id=train_id, ocps=ocps, line_resistance=None, require_line_resistance=False)
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
    reader.problems.raise_if_any()
    out = LineSignalling(
        name=str(route["name"]),
        start_m=reader.path.start_m,
        end_m=reader.path.end_m,
        stations=[
            StationTracks(st.name, st.position_m, len({e for e, _ in reader.station_places[st.element]}))
            for st in reader.stations
        ],
    )
    off_path: dict[str, int] = {}
    for item in signals:
        where = _on_path(reader, item)
        kind = _signal_kind(item.element, v3)
        if kind is None:
            reader.usage.skip(item.element, "not a main, block or distant signal")
            out.notes.append(f"{_source(item.element)}: not a main, block or distant signal, not read")
            continue
        if where is None:
            off_path["signals"] = off_path.get("signals", 0) + 1
            continue
        pos, leg_dir = where
        if len(item.directions) != 1:
            reader.problems.add(item.element, "a signal needs its direction", attribute="dir" if not v3 else None)
            continue
        direction: Direction = "up" if item.directions[0] == leg_dir else "down"
        out.signals.append(SignalAt(_name(reader, item.element), pos, direction, kind, _source(item.element)))
    for item in detectors:
        where = _on_path(reader, item)
        if where is None:
            off_path["train detection points"] = off_path.get("train detection points", 0) + 1
            continue
        out.detection_points.append(
            DetectionPoint(_name(reader, item.element), where[0], _detector_kind(item.element), _source(item.element))
        )
    for item in switches:
        where = _on_path(reader, item)
        if where is None:
            off_path["switches"] = off_path.get("switches", 0) + 1
            continue
        out.switches.append(SwitchAt(_name(reader, item.element), where[0], _source(item.element)))
    reader.problems.raise_if_any()
    out.signals.sort(key=lambda s: (s.direction != "up", s.position_m))
    out.detection_points.sort(key=lambda d: d.position_m)
    out.switches.sort(key=lambda s: s.position_m)
    out.notes += [f"{what} not on the route's path, not read: {n}" for what, n in off_path.items()]
    return out


def _detector_kind(el: etree._Element) -> str:
    if local(el) == "trackCircuitBorder":
        return "track_circuit_border"
    kind = (el.get("type") or el.get("detectionObject") or "").strip()
    if kind in ("axleCounter", "axleCounting") or el.get("axleCounting") == "true":
        return "axle_counter"
    if kind == "trackCircuitBorder":
        return "track_circuit_border"
    return "detector"
