"""railML 3.x (3.1, 3.2): reading infrastructure, rolling stock and timetable, writing them back.

The element names are railML's (see the railML 3 documentation); the schemas and example files
are not shipped. Elements are found by their name wherever they sit below ``infrastructure``,
``rollingstock`` and ``timetable``, so both 3.1 and 3.2 layouts are read. How trainsim reads them:

Topology
    * ``netElement@length`` [m] (or, without it, the measures of its ``associatedPositioningSystem``
      at intrinsic coordinates 0 and 1); netElements that only aggregate others
      (``elementCollectionOrdered``/``Unordered``) are not part of the path.
    * ``netRelation@positionOnA,@positionOnB,@navigability`` with ``elementA@ref``, ``elementB@ref``
      join netElement ends (0 = begin, 1 = end; ``AB`` only from A to B, ``None`` not at all).
    * A linear positioning system (``linearPositioningSystem@units`` m or km) gives the route's
      origin: the measure of the first netElement's begin.

Locations
    * ``linearLocation/associatedNetElement@netElementRef`` with ``@posBegin``/``@posEnd`` [m from
      the netElement's begin], else ``@intrinsicCoordBegin``/``@intrinsicCoordEnd`` (x length), else
      ``linearCoordinateBegin``/``End@measure``; ``linearLocation@applicationDirection`` normal,
      reverse or both (absent: both).
    * ``spotLocation@netElementRef`` with ``@pos``, ``@intrinsicCoord`` or ``linearCoordinate``.

Functional infrastructure
    * ``speedSection@maxSpeed`` [km/h] (sections bound to a speed profile are not read);
      ``gradientCurve@gradient`` [per mille, positive uphill in the netElement's direction; with only
      ``@deltaGradient`` the mean over the curve is used]; ``horizontalCurve@radius`` [m, 0 =
      straight]; ``overCrossing@constructionType="tunnel"`` (``@type`` also accepted);
      ``electrificationSection`` with ``electrificationSystemRef`` -> ``electrificationSystem@voltage``
      [V] (or its own ``@voltage``; 0 = not electrified) and ``@ts:tractionShare`` (the share of
      tractive effort an electric train may use, 0 < share <= 1, default 1); ``operationalPoint``
      (``name@name``).
    * Overlapping sections of one kind that apply to the same direction are errors.

Rolling stock
    * ``vehicle@length,@speed,@tareWeight,@bruttoWeight,@nettoWeight,@numberOfDrivenAxles,
      @numberOfNonDrivenAxles,@rotatingMassFactor``; a vehicle with an ``engine`` is powered:
      ``tractiveEffort/valueTable`` (per vehicle), ``@maxTractiveEffort`` [N], ``@tractivePower`` [W]
      (without a table: power-limited traction at the wheel), ``brakeEffort/valueTable``
      (regenerative braking), ``@voltage`` [V]; ``brakes/decelerationTable/valueTable`` (service
      braking, force = deceleration x inertial mass; for a train the mass-weighted mean).
    * ``formation``: ``trainOrder@orderNumber,@vehicleRef`` (consecutive equal vehicles are counted),
      ``@speed``; ``trainBrakes@meanDeceleration`` (constant deceleration); running resistance
      from ``trainResistance`` (or ``trainDrivingResistance``): ``daviesFormulaFactors@constantFactorA,
      speedDependentFactorB,squareSpeedDependentFactorC,massDependent`` (N, N/(km/h), N/(km/h)^2), or
      a resistance curve ``valueTable`` fitted with A + B v + C v^2.

Timetable
    * ``baseItinerary/baseItineraryPoint@locationRef`` (operational points, in ``@sequence`` or
      document order) with ``times`` (scope ``operational``, ``scheduled``, ``commercial``, else the
      first) holding ``arrival@time`` and ``departure@time``: a point with both is a stop, dwell =
      departure - arrival; ``ts:dwell`` (xs:duration) and ``ts:stop`` say it where there are no times.
      A train id (any element id: operational train, variant, itinerary) is followed through its
      references to its base itinerary and formation.

trainsim's own attributes (``ts:``) carry what railML has no place for, as in railML 2.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from trainsim.constants import KMH, TONNE
from trainsim.errors import InputError
from trainsim.io import railml_common as rc
from trainsim.io.railml_common import (
    Content,
    Problems,
    Span,
    Usage,
    attr_bool,
    attr_float,
    child,
    children,
    descendants,
    fmt,
    label,
    local,
)
from trainsim.io.railml_reader import Dialect, Entry, Topology, read_railml
from trainsim.model import Route, Train

__all__ = ["NAMESPACES", "detect", "read_railml3", "write_railml3"]

NAMESPACES = {
    "3.1": "https://www.railml.org/schemas/3.1",
    "3.2": "https://www.railml.org/schemas/3.2",
}
SUPPORTED = ("3.1", "3.2")
_DIRECTIONS = {"normal": (1,), "reverse": (-1,), "both": (1, -1), None: (1, -1), "": (1, -1)}


def detect(root: etree._Element) -> str | None:
    """The railML 3 version of a document root, or None if it is not railML 3."""
    if local(root) != "railML":
        return None
    version = root.get("version")
    if version is None:
        ns = etree.QName(root).namespace or ""
        version = ns.rsplit("/", 1)[-1] if "railml.org/schemas/3" in ns else "3.x"
    return version if version.startswith("3") else None


class Railml3(Dialect):
    """What railML 3 names and places its own way (the rest of the reading:
    :mod:`trainsim.io.railml_reader`)."""

    family = "railML 3"
    root_tag = "railML"
    fallback_version = "3.x"
    read_as = "3.2"
    supported = SUPPORTED
    sections = ("infrastructure", "rollingstock", "timetable", "common")
    edge_figure = "netElements"
    points_word = "operational points"
    unplaced_point = "operational point '{ref}' has no position on a netElement (spotLocation)"
    stop_at_ends = False
    vehicle_family = None
    axles = ("numberOfDrivenAxles", "numberOfNonDrivenAxles")
    stock_in_containers = False
    no_formation_note = "no formation: no train read"
    unknown_vehicle = "reference to an unknown vehicle"
    empty_formation = "the formation lists no vehicle (trainOrder)"
    merge_repeats = True
    order_entries = True

    detect = staticmethod(detect)

    def name(self, el: etree._Element | None, use: bool = False) -> str:
        return _name(el, self.r.usage if use else None)

    # ------------------------------------------------------------------ topology
    def topology(self) -> Topology:
        net, origins, measures = self.network()
        return NetElements(self, net, origins, measures)

    def points(self) -> dict[str | None, etree._Element]:
        points = {op.get("id"): op for op in descendants(self.r.infra, "operationalPoint")}
        for op in points.values():
            self.use_containers(op)
        return points

    def lps_units(self) -> dict[str, float]:
        """Linear positioning systems: id -> metres per unit."""
        if hasattr(self, "_units"):
            return self._units
        out: dict[str, float] = {}
        self._units = out
        for lps in descendants(self.r.common, "linearPositioningSystem"):
            self.r.usage.use(lps, deep=True)
            self.r.usage.use(lps.getparent())
            self.r.usage.use(lps.getparent().getparent())
            unit = lps.get("units") or "m"
            factor = {"m": 1.0, "km": 1000.0}.get(unit.strip())
            if factor is None:
                self.r.problems.add(
                    lps, f"unknown unit '{unit}'", attribute="units", value=unit, allowed="m, km"
                )
                continue
            out[lps.get("id") or ""] = factor
        return out

    def network(self) -> tuple[rc.Network, dict[str, float], dict[str, tuple[float, str]]]:
        """netElements as edges, netRelations as ports; edge -> mileage origin [m]; edge -> (begin
        measure [m], positioning system id) for linear coordinates."""
        p = self.r.problems
        net = rc.Network()
        units = self.lps_units()
        p.raise_if_any()  # positions in an unknown unit: nothing else can be placed
        origins: dict[str, float] = {}
        measures: dict[str, tuple[float, str]] = {}
        topology = child(self.r.infra, "topology")
        self.r.usage.use(topology)
        container = child(topology, "netElements")
        self.r.usage.use(container)
        for ne in children(container, "netElement"):
            nid = ne.get("id")
            if (
                child(ne, "elementCollectionOrdered") is not None
                or child(ne, "elementCollectionUnordered") is not None
            ):
                self.r.usage.skip(ne, "aggregates other netElements (not a track of the path)")
                continue
            self.r.usage.use(ne, deep=True)
            coords: dict[float, tuple[float, str]] = {}
            for ic in descendants(ne, "intrinsicCoordinate"):
                x = rc.num(ic.get("intrinsicCoord"))
                lc = child(ic, "linearCoordinate")
                if x is None or lc is None:
                    continue
                ref = lc.get("positioningSystemRef") or ""
                measure = attr_float(lc, "measure", p)
                if measure is not None and ref in units:
                    coords[x] = (measure * units[ref], ref)
            length = attr_float(ne, "length", p, positive=True)
            if length is None and 0.0 in coords and 1.0 in coords:
                length = abs(coords[1.0][0] - coords[0.0][0])
            if length is None or length <= 0:
                if ne.get("length") is None:
                    p.add(
                        ne,
                        "missing length [m] (and no positioning measures at both ends)",
                        attribute="length",
                    )
                continue
            net.add_edge(nid or "", 0.0, length, ne)
            if 0.0 in coords:
                measures[nid or ""] = coords[0.0]
                if 1.0 not in coords or coords[1.0][0] >= coords[0.0][0]:
                    origins[nid or ""] = coords[0.0][0]
        relations = child(topology, "netRelations")
        self.r.usage.use(relations)
        for nr in children(relations, "netRelation"):
            self.r.usage.use(nr, deep=True)
            a_el, b_el = child(nr, "elementA"), child(nr, "elementB")
            a, b = (
                (a_el.get("ref") if a_el is not None else None),
                (b_el.get("ref") if b_el is not None else None),
            )
            pa, pb = rc.num(nr.get("positionOnA")), rc.num(nr.get("positionOnB"))
            if a not in net.extent or b not in net.extent:
                if a in net.extent or b in net.extent:
                    p.add(nr, "netRelation to an unknown netElement", value=(a, b))
                continue
            if pa not in (0.0, 1.0) or pb not in (0.0, 1.0):
                p.add(
                    nr,
                    "positionOnA and positionOnB must be 0 or 1",
                    value=(nr.get("positionOnA"), nr.get("positionOnB")),
                )
                continue
            nav = (nr.get("navigability") or "Both").lower()
            key = nr.get("id") or f"nr{nr.sourceline}"

            def port(
                edge: str, at: float, can_leave: bool, suffix: str, key: str = key, nr: etree._Element = nr
            ) -> rc.Port:
                # at the end (1) a train leaves moving up and arrives moving down; at the begin (0)
                # the other way round
                end = net.extent[edge][1]
                leave = ((1,) if at == 1.0 else (-1,)) if can_leave else ()
                arrive = (-1,) if at == 1.0 else (1,)
                partner = f"{key}:{'B' if suffix == 'A' else 'A'}"
                return rc.Port(f"{key}:{suffix}", edge, end if at == 1.0 else 0.0, leave, arrive, partner, nr)

            if nav == "none":
                continue
            net.add_port(port(a, pa, nav in ("both", "ab"), "A"))
            net.add_port(port(b, pb, nav in ("both", "ba"), "B"))
        return net, origins, measures

    # ------------------------------------------------------------------ locations
    def _linear(
        self,
        holder: etree._Element,
        net: rc.Network,
        measures: dict[str, tuple[float, str]],
        units: dict[str, float],
    ) -> list[tuple[str, float, float, tuple[int, ...]]]:
        """Extents ``(edge, a, b, directions)`` of an element's linear locations."""
        p = self.r.problems
        out = []
        locations = children(holder, "linearLocation")
        if not locations:
            p.add(holder, "no linearLocation: where is it?")
        for ll in locations:
            self.r.usage.use(ll, deep=True)
            dirs = _DIRECTIONS.get(ll.get("applicationDirection"), (1, -1))
            for ane in children(ll, "associatedNetElement"):
                edge = ane.get("netElementRef") or ""
                if edge not in net.extent:
                    p.add(ane, "unknown netElement", attribute="netElementRef", value=edge)
                    continue
                length = net.extent[edge][1]
                ends = []
                for which in ("Begin", "End"):
                    pos = attr_float(ane, f"pos{which}", p)
                    if pos is None:
                        x = attr_float(ane, f"intrinsicCoord{which}", p)
                        if x is not None:
                            if not 0 <= x <= 1:
                                p.add(
                                    ane,
                                    "intrinsic coordinate outside 0 .. 1",
                                    attribute=f"intrinsicCoord{which}",
                                    value=x,
                                )
                                continue
                            pos = x * length
                    if pos is None:
                        lc = child(ane, f"linearCoordinate{which}")
                        pos = self._measure(lc, edge, measures, units)
                    if pos is None:
                        p.add(
                            ane,
                            f"missing position of the {which.lower()} (pos{which}, intrinsicCoord{which} or "
                            f"linearCoordinate{which})",
                        )
                        continue
                    if not -rc.POSITION_TOLERANCE_M <= pos <= length + rc.POSITION_TOLERANCE_M:
                        p.add(ane, "position outside its netElement", value=pos, allowed=f"0 .. {length:g} m")
                        continue
                    ends.append(pos)
                if len(ends) == 2:
                    if abs(ends[1] - ends[0]) <= rc.POSITION_TOLERANCE_M:
                        p.add(ane, "the location has no length (begin = end)")
                        continue
                    out.append((edge, min(ends), max(ends), dirs))
        return out

    def _measure(
        self,
        lc: etree._Element | None,
        edge: str,
        measures: dict[str, tuple[float, str]],
        units: dict[str, float],
    ) -> float | None:
        if lc is None:
            return None
        measure = attr_float(lc, "measure", self.r.problems)
        ref = lc.get("positioningSystemRef") or ""
        if measure is None or edge not in measures or ref != measures[edge][1] or ref not in units:
            return None
        return measure * units[ref] - measures[edge][0]

    def spot(
        self,
        holder: etree._Element,
        net: rc.Network,
        measures: dict[str, tuple[float, str]],
        units: dict[str, float],
    ) -> list[tuple[str, float]]:
        p = self.r.problems
        out = []
        for sl in children(holder, "spotLocation"):
            self.r.usage.use(sl, deep=True)
            edge = sl.get("netElementRef") or ""
            if edge not in net.extent:
                p.add(sl, "unknown netElement", attribute="netElementRef", value=edge)
                continue
            length = net.extent[edge][1]
            pos = attr_float(sl, "pos", p)
            if pos is None:
                x = attr_float(sl, "intrinsicCoord", p)
                pos = None if x is None else x * length
            if pos is None:
                pos = self._measure(child(sl, "linearCoordinate"), edge, measures, units)
            if pos is None:
                p.add(sl, "missing position (pos, intrinsicCoord or linearCoordinate)")
                continue
            if not -rc.POSITION_TOLERANCE_M <= pos <= length + rc.POSITION_TOLERANCE_M:
                p.add(sl, "position outside its netElement", value=pos, allowed=f"0 .. {length:g} m")
                continue
            out.append((edge, pos))
        return out

    # ------------------------------------------------------------------ line data

    # ------------------------------------------------------------------ line data
    def line_data(self, topology: Topology) -> dict[str, list[Any]]:
        assert isinstance(topology, NetElements)
        data: dict[str, list[Any]] = dict(self._line_data(topology.net, topology.measures))
        data["speed_changes"] = []
        return data

    def _line_data(self, net: rc.Network, measures: dict[str, tuple[float, str]]) -> dict[str, list[Span]]:
        p = self.r.problems
        units = self.lps_units()
        data: dict[str, list[Span]] = {
            "speed": [],
            "gradient": [],
            "radius": [],
            "tunnel": [],
            "electrification": [],
        }
        fi = self.r.infra

        def spans(el: etree._Element, value: Any, kind: str) -> None:
            for edge, a, b, dirs in self._linear(el, net, measures, units):
                data[kind].append(Span(edge, a, b, value, el, dirs))

        for sec in descendants(fi, "speedSection"):
            self.use_containers(sec)
            if any("rofile" in a for a in sec.attrib) or any("rofile" in local(c) for c in sec):
                self.r.usage.skip(sec, "speed for a speed profile, not the line speed")
                continue
            self.r.usage.use(sec, deep=True)
            v = attr_float(sec, "maxSpeed", p, required=True, what="maximum speed [km/h]", positive=True)
            if v is not None:
                spans(sec, v, "speed")
        for gc in descendants(fi, "gradientCurve"):
            self.use_containers(gc)
            self.r.usage.use(gc, deep=True)
            g = attr_float(gc, "gradient", p)
            dg = attr_float(gc, "deltaGradient", p)
            if g is None and dg is None:
                p.add(gc, "missing gradient [per mille]", attribute="gradient")
                continue
            if dg is not None:
                self.r.content.notes.append(
                    f"{label(gc)} (line {gc.sourceline}): a changing gradient, its mean over the curve is "
                    "used"
                )
                g = (g or 0.0) + dg / 2.0 if g is not None else dg / 2.0
            spans(gc, g, "gradient")
        for hc in descendants(fi, "horizontalCurve"):
            self.use_containers(hc)
            r = attr_float(hc, "radius", p)
            if r is None:
                self.r.usage.skip(hc, f"no radius (curveType {hc.get('curveType')})")
                continue
            self.r.usage.use(hc, deep=True)
            spans(hc, abs(r), "radius")
        for oc in descendants(fi, "overCrossing"):
            self.use_containers(oc)
            kind = oc.get("constructionType") or oc.get("type") or ""
            if kind != "tunnel":
                self.r.usage.skip(oc, f"not a tunnel ({kind or 'no constructionType'})")
                continue
            self.r.usage.use(oc, deep=True)
            spans(oc, (rc.ext(oc, "limitingGradient") or "false").lower() == "true", "tunnel")
        systems = {s.get("id"): s for s in descendants(fi, "electrificationSystem")}
        for s in systems.values():
            self.use_containers(s)
            self.r.usage.use(s, deep=True)
        for es in descendants(fi, "electrificationSection"):
            self.use_containers(es)
            self.r.usage.use(es, deep=True)
            holder = es
            ref = child(es, "electrificationSystemRef")
            if ref is not None:
                holder = systems.get(ref.get("ref"))
                if holder is None:
                    p.add(
                        ref,
                        "reference to an unknown electrificationSystem",
                        attribute="ref",
                        value=ref.get("ref"),
                    )
                    continue
            voltage = attr_float(holder, "voltage", p, minimum=0)
            if voltage is None:
                if holder.get("voltage") is None:
                    p.add(holder, "missing line voltage [V] (0 = not electrified)", attribute="voltage")
                continue
            share = rc.traction_share(es, p)
            spans(es, voltage if share == 1.0 else (voltage, share), "electrification")
        return data

    def use_containers(self, el: etree._Element) -> None:
        parent = el.getparent()
        while parent is not None and parent is not self.r.infra:
            self.r.usage.use(parent)
            parent = parent.getparent()

    # ------------------------------------------------------------------ timetable

    # ------------------------------------------------------------------ timetable
    def timetable_path(
        self, train_id: str | None, points: dict[str | None, etree._Element]
    ) -> tuple[list[Entry], etree._Element | None, None, str] | None:
        p = self.r.problems
        entries: list[Entry] = []
        base, formation, tname = self.itinerary(train_id)
        if base is None:
            return None
        self.r.usage.use(base)
        for c in base.iterancestors():
            self.r.usage.use(c)
        bips = children(base, "baseItineraryPoint")
        # a sequence that is not a whole number is a problem named with its element, not sorted as 0
        bips.sort(key=lambda b: rc.attr_int(b, "sequence", self.r.problems))
        for k, bip in enumerate(bips):
            self.r.usage.use(bip)
            ref = bip.get("locationRef")
            if ref not in points:
                p.add(bip, "locationRef to an unknown operationalPoint", attribute="locationRef", value=ref)
                continue
            arr, dep = self._times(bip)
            dwell = rc.parse_duration(rc.ext(bip, "dwell"))
            stop_attr = rc.ext(bip, "stop")
            if dwell is None:
                dwell = (
                    (dep - arr + (86400.0 if dep < arr else 0.0))
                    if arr is not None and dep is not None
                    else 0.0
                )
            if stop_attr is not None:
                stop = stop_attr.lower() == "true"
            else:
                stop = (
                    k in (0, len(bips) - 1)
                    or (arr is not None and dep is not None)
                    or child(bip, "stopActivities") is not None
                )
            entries.append((ref, dwell if stop else 0.0, stop, bip))
            for c in bip:
                self.r.usage.use(c, deep=True)
        return entries, formation, None, tname

    def _follow(self, start: etree._Element, want: str, limit: int = 50) -> etree._Element | None:
        """The first element named ``want`` reached from ``start`` through reference attributes."""
        seen = set()
        queue = [start]
        while queue and len(seen) < limit:
            el = queue.pop(0)
            if id(el) in seen:
                continue
            seen.add(id(el))
            self.r.usage.use(el, deep=True)
            if local(el) == want:
                return el
            for d in el.iter():
                if d is not el and local(d) == want:
                    return d
                for k, v in d.attrib.items():
                    if (k.endswith("Ref") or k == "ref") and v in self.r.ids:
                        queue.append(self.r.ids[v])
        return None

    def itinerary(self, train_id: str | None) -> tuple[etree._Element | None, etree._Element | None, str]:
        """The base itinerary of the chosen train (by id or name; default: the first operational or
        commercial train, else the first base itinerary), its formation if referenced, its name."""
        tt = self.r.timetable
        if tt is None:
            return None, None, ""
        bases = descendants(tt, "baseItinerary")
        start = None
        if train_id is not None:
            start = self.r.ids.get(train_id)
            if start is None:
                named = [e for e in tt.iter() if local(e) and _name(e) == train_id]
                start = named[0] if named else None
            if start is None:
                trains = [
                    e.get("id") for e in tt.iter() if local(e) in ("operationalTrain", "commercialTrain")
                ]
                raise InputError(
                    "no element of that id or name in the timetable",
                    file=self.r.file,
                    field="train_id",
                    value=train_id,
                    allowed=", ".join(str(x) for x in [*trains, *(b.get("id") for b in bases)]),
                )
        else:
            trains = [e for e in tt.iter() if local(e) in ("operationalTrain", "commercialTrain")]
            if trains:
                start = trains[0]
                if len(trains) > 1:
                    self.r.content.notes.append(
                        f"{len(trains)} trains in the timetable: the first, {label(start)}, is read "
                        "(choose with --train-id)"
                    )
                for other in trains[1:]:
                    self.r.usage.skip(other, "another train")
        if start is not None:
            base = self._follow(start, "baseItinerary")
            if base is None:
                raise self.r.problems.error(
                    start, "no baseItinerary reached from this element through its references"
                )
            formation = self._follow(start, "formation")
            name = _name(start, self.r.usage) or start.get("id") or ""
            self.r.usage.use(start, deep=True)
        elif bases:
            base, formation = bases[0], None
            name = base.get("id") or ""
            if len(bases) > 1:
                self.r.content.notes.append(
                    f"{len(bases)} base itineraries: the first, {label(base)}, is the route "
                    "(choose with --train-id)"
                )
        else:
            return None, None, ""
        for other in bases:
            if other is not base:
                self.r.usage.skip(other, "another train's path")
        return base, formation, name

    def _times(self, point: etree._Element) -> tuple[float | None, float | None]:
        sets = children(point, "times")
        order = {"operational": 0, "scheduled": 1, "commercial": 2}
        sets.sort(key=lambda t: order.get(t.get("scope") or "", 3))
        for t in sets:
            self.r.usage.use(t, deep=True)
        if not sets:
            return None, None
        t = sets[0]
        out = []
        for which in ("arrival", "departure"):
            el = child(t, which)
            text = el.get("time") if el is not None else t.get(which)
            holder = el if el is not None else t
            days = rc.attr_int(
                holder, "dayOffset" if el is not None else f"{which}Day", self.r.problems, high=366
            )
            value = rc.parse_clock(text, days) if text is not None else None
            if text is not None and value is None:
                self.r.problems.add(el if el is not None else t, "not a time hh:mm:ss", value=text)
            out.append(value)
        return out[0], out[1]

    # ------------------------------------------------------------------ route

    # ------------------------------------------------------------------ rolling stock
    def vehicle_equipment(self, v: etree._Element, src: rc.VehicleSource) -> None:
        p = self.r.problems
        src.rotating_mass_factor = attr_float(v, "rotatingMassFactor", p, minimum=1.0)
        src.auxiliary_w = rc.num(rc.ext(v, "auxiliaryPower")) or 0.0
        engine = child(v, "engine")
        if engine is not None:
            self.r.usage.use(engine, deep=True)
            src.powered = True
            src.propulsion = engine
            src.max_effort_n = _attr_below(engine, "maxTractiveEffort", p)
            src.power_w = _attr_below(engine, "tractivePower", p)
            src.max_brake_power_w = _attr_below(engine, "maxBrakePower", p)
            vt = _table_below(engine, "tractiveEffort")
            if vt is not None:
                src.traction = rc.read_value_table(vt, p, y_dimensions=("force",), usage=self.r.usage)
            vt = _table_below(engine, "brakeEffort")
            if vt is not None:
                src.regenerative = rc.read_value_table(vt, p, y_dimensions=("force",), usage=self.r.usage)
        vt = _table_below(child(v, "brakes"), "decelerationTable")
        if vt is not None:
            self.r.usage.use(child(v, "brakes"), deep=True)
            src.deceleration = rc.read_value_table(vt, p, y_dimensions=("acceleration",), usage=self.r.usage)

    def formation_data(self, formation: etree._Element, form: rc.FormationSource) -> None:
        p = self.r.problems
        for tb in children(formation, "trainBrakes"):
            self.r.usage.use(tb, deep=True)
            mean = attr_float(tb, "meanDeceleration", p, positive=True)
            if mean is not None and form.mean_deceleration is None:
                form.mean_deceleration = (mean, tb)
        tr = next(
            (
                child(formation, n)
                for n in ("trainResistance", "trainDrivingResistance", "drivingResistance")
                if child(formation, n) is not None
            ),
            None,
        )
        if tr is None:
            return
        self.r.usage.use(tr, deep=True)
        if tr.get("tunnelFactor") is not None:
            form.notes.append(
                f"{label(tr)}: tunnelFactor not used (the tunnel resistance is the route's formula)"
            )
        factors = child(tr, "daviesFormulaFactors")
        if factors is not None:
            form.davis = (
                attr_float(factors, "constantFactorA", p, minimum=0) or 0.0,
                attr_float(factors, "speedDependentFactorB", p) or 0.0,
                attr_float(factors, "squareSpeedDependentFactorC", p, minimum=0) or 0.0,
                attr_bool(factors, "massDependent") is True,
                factors,
            )
            return
        vt = next(iter(descendants(tr, "valueTable")), None)
        if vt is not None:
            form.resistance_table = rc.read_value_table(
                vt, p, y_dimensions=("force", "ratio"), usage=self.r.usage
            )

    def electrical(self, form: rc.FormationSource) -> None:
        p = self.r.problems
        engine = rc.powered_propulsion(form)
        if engine is None:
            return
        voltage = _attr_below(engine, "voltage", p)
        eta = rc.num(rc.ext(engine, "tractionEfficiency"))
        if voltage is None or eta is None:
            return
        out: dict[str, Any] = {"line_voltage_v": voltage, "traction_efficiency": eta}
        pairs = (
            ("regenerative_efficiency", "regenerativeEfficiency"),
            ("power_factor", "powerFactor"),
            ("receptivity", "receptivity"),
        )
        rc.extension_numbers(engine, out, pairs)
        form.electrical = out


class NetElements(Topology):
    """railML 3 netElements; operational points placed by their ``spotLocation``."""

    def __init__(
        self,
        dialect: Railml3,
        net: rc.Network,
        origins: dict[str, float],
        measures: dict[str, tuple[float, str]],
    ) -> None:
        super().__init__(net, origins)
        self.dialect = dialect
        self.measures = measures  #: edge -> (begin measure [m], positioning system id)

    def locate(self, point: etree._Element, ref: str) -> list[tuple[str, float]]:
        return self.dialect.spot(point, self.net, self.measures, self.dialect.lps_units())


def _name(el: etree._Element | None, usage: Usage | None = None) -> str:
    """railML 3 names: a ``name`` child with ``@name``, else the ``@name`` attribute."""
    if el is None:
        return ""
    n = child(el, "name")
    if n is not None and n.get("name"):
        if usage is not None:
            usage.use(n)
        return n.get("name") or ""
    return el.get("name") or ""


def _attr_below(el: etree._Element, name: str, problems: Problems) -> float | None:
    for d in el.iter():
        if d.get(name) is not None:
            return attr_float(d, name, problems, positive=True)
    return None


def _table_below(el: etree._Element | None, container: str) -> etree._Element | None:
    for d in descendants(el, container):
        vt = child(d, "valueTable")
        if vt is not None:
            return vt
    return None


def read_railml3(
    path: str | Path,
    *,
    train_id: str | None = None,
    formation_id: str | None = None,
    ocps: Sequence[str] | None = None,
    line_resistance: dict[str, str] | None = None,
    rotating_mass_factor: float | None = None,
    require_line_resistance: bool = True,
    tree: etree._ElementTree | None = None,
) -> Content:
    """Read a railML 3 file: its train (formation) and route, as trainsim YAML mappings. The
    options are those of :func:`trainsim.io.railml2.read_railml2`."""
    options = {k: v for k, v in locals().items() if k != "path"}
    return read_railml(path, Railml3, **options)


def load_train_railml3(path: str | Path, **options: Any) -> Train:
    """The train of a railML 3 file."""
    return rc.build_train(read_railml3(path, **options))


def load_route_railml3(path: str | Path, **options: Any) -> Route:
    """The route of a railML 3 file."""
    return rc.build_route(read_railml3(path, **options))


# ====================================================================== writing
class _Writer(rc.ElementWriter):
    family = "railML 3"
    value_tag = "value"

    def __init__(self, version: str) -> None:
        super().__init__(version, NAMESPACES)

    def linear(
        self, parent: etree._Element, ident: str, a: float, b: float, length: float, direction: str = "both"
    ) -> None:
        ll = self.el(parent, "linearLocation", id=f"{ident}_lloc", applicationDirection=direction)
        self.el(
            ll,
            "associatedNetElement",
            netElementRef="ne1",
            keepsOrientation=True,
            intrinsicCoordBegin=a / length,
            intrinsicCoordEnd=b / length,
            posBegin=a,
            posEnd=b,
        )

    def infrastructure(self, root: etree._Element, route: Route) -> None:
        lr = route.line_resistance
        length = route.end_m - route.start_m
        rel = route.start_m
        common = self.el(root, "common", id="co")
        positioning = self.el(common, "positioning")
        lpss = self.el(positioning, "linearPositioningSystems")
        self.el(
            lpss,
            "linearPositioningSystem",
            id="lps1",
            units="m",
            startMeasure=route.start_m,
            endMeasure=route.end_m,
            linearReferencingMethod="absolute",
        )
        infra = self.el(
            root,
            "infrastructure",
            id="is",
            ts_curveFormula=lr.curve_formula,
            ts_tunnelFormula=lr.tunnel_formula,
            ts_gradientFormula=lr.gradient_formula,
            ts_applyOver=lr.apply_over,
        )
        self.el(infra, "name", name=route.name, language="en")
        topology = self.el(infra, "topology")
        nes = self.el(topology, "netElements")
        ne = self.el(nes, "netElement", id="ne1", length=length)
        aps = self.el(ne, "associatedPositioningSystem", id="ne1_aps")
        for k, (x, m) in enumerate(((0, route.start_m), (1, route.end_m))):
            ic = self.el(aps, "intrinsicCoordinate", id=f"ne1_ic{k}", intrinsicCoord=x)
            self.el(ic, "linearCoordinate", positioningSystemRef="lps1", measure=m)
        self.el(topology, "netRelations")
        fi = self.el(infra, "functionalInfrastructure")
        if route.electrification:
            elec = self.el(fi, "electrifications")
            systems = self.el(elec, "electrificationSystems")
            voltages = sorted({e.voltage_v for e in route.electrification})
            for k, u in enumerate(voltages):
                self.el(systems, "electrificationSystem", id=f"esys{k + 1}", voltage=u)
            sections = self.el(elec, "electrificationSections")
            for k, e in enumerate(route.electrification):
                share = e.traction_share if e.traction_share != 1.0 else None
                es = self.el(sections, "electrificationSection", id=f"es{k + 1}", ts_tractionShare=share)
                self.linear(es, f"es{k + 1}", e.start_m - rel, e.end_m - rel, length)
                self.el(es, "electrificationSystemRef", ref=f"esys{voltages.index(e.voltage_v) + 1}")
        if route.gradients:
            gcs = self.el(fi, "gradientCurves")
            for k, g in enumerate(route.gradients):
                gc = self.el(
                    gcs,
                    "gradientCurve",
                    id=f"gc{k + 1}",
                    curveType="straight",
                    gradient=g.gradient_permille,
                    length=g.end_m - g.start_m,
                )
                self.linear(gc, f"gc{k + 1}", g.start_m - rel, g.end_m - rel, length)
            # the level parts between gradient curves are written as level curves: a gap would
            # keep the gradient before it when read back
            cursor = route.start_m
            k = len(route.gradients)
            for g in [*route.gradients, None]:
                a = cursor
                b = g.start_m if g is not None else route.end_m
                if b - a > rc.POSITION_TOLERANCE_M:
                    k += 1
                    gc = self.el(
                        gcs, "gradientCurve", id=f"gc{k}", curveType="straight", gradient=0.0, length=b - a
                    )
                    self.linear(gc, f"gc{k}", a - rel, b - rel, length)
                if g is not None:
                    cursor = g.end_m
        if route.curves:
            hcs = self.el(fi, "horizontalCurves")
            for k, cv in enumerate(route.curves):
                hc = self.el(
                    hcs,
                    "horizontalCurve",
                    id=f"hc{k + 1}",
                    curveType="arc",
                    radius=cv.radius_m,
                    length=cv.end_m - cv.start_m,
                )
                self.linear(hc, f"hc{k + 1}", cv.start_m - rel, cv.end_m - rel, length)
        ops = self.el(fi, "operationalPoints")
        for k, st in enumerate(route.stations):
            op = self.el(ops, "operationalPoint", id=f"op{k + 1}")
            self.el(op, "name", name=st.name, language="en")
            self.el(
                op,
                "spotLocation",
                id=f"op{k + 1}_sloc",
                netElementRef="ne1",
                applicationDirection="both",
                intrinsicCoord=(st.position_m - rel) / length,
                pos=st.position_m - rel,
            )
        if route.tunnels:
            ocs = self.el(fi, "overCrossings")
            for k, t in enumerate(route.tunnels):
                oc = self.el(
                    ocs,
                    "overCrossing",
                    id=f"tn{k + 1}",
                    constructionType="tunnel",
                    ts_limitingGradient=True if t.limiting_gradient else None,
                )
                self.linear(oc, f"tn{k + 1}", t.start_m - rel, t.end_m - rel, length)
        speeds = self.el(fi, "speeds")
        for k, lim in enumerate(route.speed_limits):
            sec = self.el(speeds, "speedSection", id=f"sps{k + 1}", maxSpeed=lim.limit_mps / KMH)
            self.linear(sec, f"sps{k + 1}", lim.start_m - rel, lim.end_m - rel, length, "normal")

    def rollingstock(self, root: etree._Element, train: Train) -> None:
        rs = self.el(root, "rollingstock", id="rs")
        vehicles_el = self.el(rs, "vehicles")
        groups = rc.vehicle_groups(train)
        powered_names = {v.name for v, _ in groups if v.powered} or {groups[0][0].name}
        n_powered = sum(n for v, n in groups if v.name in powered_names)
        n_total = sum(n for _, n in groups)
        tables = rc.written_tables(train, groups, self.notes)
        xi, speeds, forces = tables.xi, tables.speeds, tables.forces
        fcap, pcap = tables.force_cap_n, tables.power_cap_w
        r_speeds, r_forces = tables.regen_speeds, tables.regen_forces
        regen = train.braking.regenerative
        braking = train.braking
        if braking.service_force is not None:
            b_speeds, b_forces, _, _, b_exact = rc.effort_table(braking.service_force, train.max_speed_mps)
            if not b_exact or len(b_speeds) == 0:
                b_speeds, b_forces = rc.sampled(braking.service_force, train.max_speed_mps)
                self.notes.append("braking: the curve is not a table; written sampled")
        elec = train.electrical
        for k, (v, _n) in enumerate(groups):
            vid = f"veh{k + 1}"
            powered = v.name in powered_names
            veh = self.el(
                vehicles_el,
                "vehicle",
                id=vid,
                length=v.length_m,
                bruttoWeight=(v.mass_kg + v.load_kg) / TONNE,
                tareWeight=v.mass_kg / TONNE,
                nettoWeight=v.load_kg / TONNE,
                numberOfDrivenAxles=v.axles if v.axles and powered else None,
                numberOfNonDrivenAxles=v.axles if v.axles and not powered else None,
                rotatingMassFactor=xi,
                ts_auxiliaryPower=(elec.auxiliary_power_w / n_total)
                if elec and elec.auxiliary_power_w
                else None,
            )
            self.el(veh, "name", name=v.name, language="en")
            if braking.service_force is not None:
                brakes = self.el(veh, "brakes")
                dt = self.el(brakes, "decelerationTable")
                self.value_table(dt, "deceleration", "m/s^2", b_speeds, b_forces / train.inertial_mass_kg)
            if powered:
                engine = self.el(
                    veh,
                    "engine",
                    ts_tractionEfficiency=elec.traction_efficiency if elec else None,
                    ts_regenerativeEfficiency=elec.regenerative_efficiency if elec else None,
                    ts_powerFactor=elec.power_factor if elec else None,
                    ts_receptivity=elec.receptivity if elec else None,
                )
                mode = self.el(
                    engine,
                    "powerMode",
                    mode="electric" if elec else "diesel",
                    isPrimaryMode=True,
                    voltage=elec.line_voltage_v if elec else None,
                )
                data = self.el(mode, "tractionData")
                self.el(
                    data,
                    "info",
                    maxTractiveEffort=(fcap / n_powered) if math.isfinite(fcap) else None,
                    tractivePower=(pcap if len(speeds) == 0 else float(np.max(speeds * forces))) / n_powered,
                )
                if len(speeds):
                    details = self.el(data, "details")
                    te = self.el(details, "tractiveEffort")
                    self.value_table(te, "tractiveEffort", "N", speeds, forces / n_powered)
                if regen is not None:
                    be = self.el(data, "brakeEffort")
                    self.value_table(be, "brakeEffort", "N", r_speeds, r_forces / n_powered)
                    if math.isfinite(regen.power_cap_w):
                        be.set("maxBrakePower", fmt(regen.power_cap_w / n_powered))
        formations = self.el(rs, "formations")
        form = self.el(
            formations, "formation", id="f1", speed=train.max_speed_mps / KMH, length=train.length_m
        )
        self.el(form, "name", name=train.name, language="en")
        order = 0
        for k, (_v, n) in enumerate(groups):
            for _ in range(n):
                order += 1
                self.el(form, "trainOrder", orderNumber=order, vehicleRef=f"veh{k + 1}", orientation="normal")
        if braking.deceleration_mps2 is not None:
            self.el(form, "trainBrakes", meanDeceleration=braking.deceleration_mps2)
        law = train.resistance_law
        tr = self.el(form, "trainResistance")
        self.el(
            tr,
            "daviesFormulaFactors",
            constantFactorA=law.c0,
            speedDependentFactorB=law.c1 * KMH,
            squareSpeedDependentFactorC=law.c2 * KMH**2,
            massDependent=False,
        )

    def timetable(
        self, root: etree._Element, route: Route, times: Sequence[tuple[float, float]] | None
    ) -> None:
        tt = self.el(root, "timetable", id="tt")
        bases = self.el(tt, "baseItineraries")
        base = self.el(bases, "baseItinerary", id="bi1")
        n = len(route.stations)
        for k, st in enumerate(route.stations):
            stop = st.stop or k in (0, n - 1)
            bip = self.el(
                base,
                "baseItineraryPoint",
                id=f"bip{k + 1}",
                locationRef=f"op{k + 1}",
                sequence=k + 1,
                ts_stop=stop,
                ts_dwell=rc.format_duration(st.dwell_s) if stop and 0 < k < n - 1 else None,
            )
            if times is not None:
                arr, dep = times[k]
                t = self.el(bip, "times", scope="calculated")
                if k > 0:
                    text, day = rc.format_clock(arr)
                    self.el(t, "arrival", time=text, dayOffset=day if day else None)
                if k < n - 1:
                    text, day = rc.format_clock(dep)
                    self.el(t, "departure", time=text, dayOffset=day if day else None)
                    sections = self.el(bip, "followupSections")
                    section = self.el(sections, "followupSection")
                    self.el(section, "minimalTime", runTime=rc.format_duration(times[k + 1][0] - dep))


def write_railml3(
    path: str | Path,
    *,
    train: Train | None = None,
    route: Route | None = None,
    times: Sequence[tuple[float, float]] | None = None,
    version: str = "3.2",
) -> list[str]:
    """Write a train and/or a route as a railML 3 file (one netElement, one formation, one base
    itinerary whose points are the route's stations). Returns notes on what was not written
    exactly. ``times``: as in :func:`trainsim.io.railml2.write_railml2`."""
    w = _Writer(version)
    root = w.el(None, "railML", version=version)
    if route is not None:
        w.infrastructure(root, route)
    if train is not None:
        w.rollingstock(root, train)
    if route is not None:
        w.timetable(root, route, times)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    etree.ElementTree(root).write(str(out), xml_declaration=True, encoding="UTF-8", pretty_print=True)
    return w.notes
