"""railML 2.x (2.2 to 2.5): reading infrastructure, rolling stock and timetable, writing them back.

The element names are railML's (see the railML 2 documentation); the railML schemas and example
files are not shipped (their licence forbids redistribution). How trainsim reads them:

Infrastructure (``infrastructure``)
    * ``tracks/track``: ``trackTopology/trackBegin@pos`` and ``trackEnd@pos`` give the track's extent
      in metres (``pos`` is the distance along the track, ``absPos`` the mileage: positions are
      taken from ``pos``; the mileage of the first track's begin, when given, becomes the route's
      origin). Tracks are joined by ``connection@ref`` in ``trackBegin``/``trackEnd`` and in
      ``connections/switch`` (``orientation`` outgoing / incoming).
    * ``trackElements``: ``speedChanges/speedChange@pos,@vMax,@dir`` (km/h; ``vMax="end"`` ends a
      temporary restriction and restores the limit before it, as does the pre-2.3 virtual value
      999.9; a change applies to trains running in its ``dir``, both if absent; changes bound to
      a ``profileRef`` or a train category are not read), ``gradientChanges/gradientChange@pos,
      @slope`` (per mille, positive uphill in the track's direction; ``dir="down"`` gives it for
      the other direction), ``radiusChanges/radiusChange@pos,@radius`` (m, 0 = straight, sign =
      side), ``tunnels/tunnel@pos,@length`` (``dir="down"``: the tunnel extends towards decreasing
      positions), ``electrificationChanges/electrificationChange@pos,@type,@voltage``
      (``type="none"`` or voltage 0: not electrified). Each change applies from its position to the
      next change; positions before the first change of a track keep the value of the route before.
    * ``operationControlPoints/ocp`` (``@name``) are placed on tracks by
      ``trackTopology/crossSections/crossSection@ocpRef,@pos``.

Rolling stock (``rollingstock``)
    * ``formations/formation``: ``trainOrder/vehicleRef@vehicleRef,@vehicleCount,@orderNumber``,
      ``@speed`` [km/h], ``trainResistance@daviesFactorA,B,C`` (read as N, N/(km/h), N/(km/h)^2
      for the whole formation, per tonne with ``daviesMassDependent="true"``), ``@strahlFactor``
      (Strahl's freight-train law w = 2.5 + k (V/10)^2 per mille, read as such), or a
      ``valueTable`` of resistance over speed (fitted with a quadratic law);
      ``trainBrakes@meanDeceleration`` or ``trainBrakeOperation@meanDeceleration`` (a constant
      deceleration, TrainRuns.jl's braking model) or ``trainBrakeOperation/decelerationTable``
      (braking force = deceleration x inertial mass, read as the service braking).
    * ``vehicles/vehicle``: ``@length`` [m], ``@speed`` [km/h], ``@tareWeight`` (empty mass) and
      ``@bruttoWeight`` (with the load the train runs with) or ``@nettoWeight`` [t],
      ``@numberDrivenAxles`` + ``@numberNonDrivenAxles``, ``@vehicleFamilyRef`` (missing data taken
      from the family vehicle); ``wagon@rotationMassFactor`` or ``engine/propulsion@
      rotationMassFactor`` (or ``@additionalRotationMass`` [t]), ``wagon@auxiliaryPowerConsumption``
      [W]; a vehicle with ``engine/propulsion`` is powered: ``tractiveEffort/valueTable`` (per
      vehicle, units from ``xValueUnit``/``yValueUnit``), ``@maxTractEffort`` [N] (a cap),
      ``@power`` [W] (without a table: power-limited traction, the power read as the power at the
      wheel), ``brakeEffort/valueTable`` (regenerative braking force), ``@maxBrakePower`` [W],
      ``@voltage`` [V], ``@totalTractEfficiency``, ``@totalBrakeEfficiency``.

Timetable (``timetable``)
    * ``trains/train`` -> ``trainPartSequence/trainPartRef`` -> ``trainParts/trainPart``:
      ``formationTT@formationRef`` (the train's formation) and ``ocpsTT/ocpTT@ocpRef,@ocpType,
      @sequence`` (the route: every ocp in order; ``ocpType="pass"`` is not a stop). Dwell time:
      ``stopDescription/stopTimes@minimalTime``, else scheduled departure - arrival
      (``times@scope="scheduled"``, else the first ``times``).

Data railML has no place for are trainsim attributes in their own namespace (``ts:``, see
:data:`~trainsim.io.railml_common.EXTENSION_NS`): the line-resistance formulas
(``infrastructure@ts:curveFormula, ts:tunnelFormula, ts:gradientFormula, ts:applyOver``), the
power factor and the line receptivity (``propulsion@ts:powerFactor, ts:receptivity``), tunnels on a
ruling gradient (``tunnel@ts:limitingGradient``), the braking table kind
(``trainBrakeOperation@ts:tableIs``) and the share of tractive effort an electric train may use
(``electrificationChange@ts:tractionShare``, 0 < share <= 1, default 1). Without the formulas in
the file, they must be given.
"""

from __future__ import annotations

import itertools
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
    Span,
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

__all__ = [
    "NAMESPACES",
    "detect",
    "read_railml2",
    "write_railml2",
]

#: railML 2 namespace by version (the reader accepts any namespace; the writer uses these).
NAMESPACES = {
    "2.2": "http://www.railml.org/schemas/2013",
    "2.3": "http://www.railml.org/schemas/2016",
    "2.4": "https://www.railml.org/schemas/2018",
    "2.5": "https://www.railml.org/schemas/2021",
}
_VERSION_BY_NS = {ns: v for v, ns in NAMESPACES.items()}
SUPPORTED = ("2.2", "2.3", "2.4", "2.5")

#: The pre-2.3 way to end a temporary speed restriction: a "virtual" speed of 999.9 km/h.
_VIRTUAL_END_KMH = 999.9


def detect(root: etree._Element) -> str | None:
    """The railML 2 version of a document root, or None if it is not railML 2."""
    if local(root) != "railml":
        return None
    version = root.get("version")
    ns = etree.QName(root).namespace or ""
    if version is None:
        version = _VERSION_BY_NS.get(ns, "2.x")
    return version if version.startswith("2") else None


# ====================================================================== reading
class Railml2(Dialect):
    """What railML 2 names and places its own way (the rest of the reading:
    :mod:`trainsim.io.railml_reader`)."""

    family = "railML 2"
    root_tag = "railml"
    fallback_version = "2.x"
    read_as = "2.5"
    supported = SUPPORTED
    sections = ("infrastructure", "rollingstock", "timetable")
    edge_figure = "tracks"
    points_word = "ocps"
    unplaced_point = "operational point '{ref}' has no position on a track (no crossSection with its ocpRef)"
    stop_at_ends = True
    vehicle_family = "vehicleFamilyRef"
    axles = ("numberDrivenAxles", "numberNonDrivenAxles")
    stock_in_containers = True
    no_formation_note = "no formation: no train read (a formation lists the vehicles)"
    unknown_vehicle = "vehicleRef to an unknown vehicle"
    empty_formation = "the formation lists no vehicle (trainOrder/vehicleRef)"
    merge_repeats = False
    order_entries = False

    detect = staticmethod(detect)

    # ------------------------------------------------------------------ timetable
    def timetable_path(
        self, train_id: str | None, points: dict[str | None, etree._Element]
    ) -> tuple[list[Entry], None, str | None, str] | None:
        ocp_tts, formation_ref, tname = self.train_part_ocps(train_id)
        if not ocp_tts:
            return None
        entries: list[Entry] = []
        for o in ocp_tts:
            ref = o.get("ocpRef")
            if ref not in points:
                self.r.problems.add(o, "ocpRef to an unknown ocp", attribute="ocpRef", value=ref)
                continue
            dwell, stop = self.dwell(o)
            entries.append((ref, dwell, stop, o))
        return entries, None, formation_ref, tname

    def train_part_ocps(
        self, train_id: str | None
    ) -> tuple[list[etree._Element], etree._Element | None, str]:
        """The ocpTT elements of the chosen train in order, its formation reference, its name."""
        tt = self.r.timetable
        if tt is None:
            return [], None, ""
        parts = {p.get("id"): p for p in descendants(child(tt, "trainParts"), "trainPart")}
        trains = descendants(child(tt, "trains"), "train")
        chosen_parts: list[etree._Element] = []
        name = ""
        if train_id is not None:
            match = [t for t in trains if train_id in (t.get("id"), t.get("trainNumber"), t.get("name"))]
            if match:
                trains = match[:1]
            elif train_id in parts:
                chosen_parts = [parts[train_id]]
                name = parts[train_id].get("name") or train_id
            else:
                known = [t.get("id") for t in trains] + list(parts)
                raise InputError(
                    "no train or train part of that id, number or name in the timetable",
                    file=self.r.file,
                    field="train_id",
                    value=train_id,
                    allowed=", ".join(str(k) for k in known),
                )
        if not chosen_parts:
            if trains:
                if len(trains) > 1:
                    self.r.content.notes.append(
                        f"{len(trains)} trains in the timetable: the first, {label(trains[0])}, is read "
                        "(choose another with train_id / --train-id)"
                    )
                train = trains[0]
                self.r.usage.use(train, deep=True)
                name = train.get("name") or train.get("trainNumber") or train.get("id") or ""
                refs = []
                for seq in children(train, "trainPartSequence"):
                    order = rc.attr_int(seq, "sequence", self.r.problems)
                    refs += [(order, r.get("ref")) for r in children(seq, "trainPartRef")]
                for _, ref in sorted(refs, key=lambda x: x[0]):
                    if ref not in parts:
                        raise self.r.problems.error(train, "trainPartRef to an unknown trainPart", value=ref)
                    chosen_parts.append(parts[ref])
            elif parts:
                first = next(iter(parts.values()))
                if len(parts) > 1:
                    self.r.content.notes.append(
                        f"{len(parts)} train parts and no train: the first, {label(first)}, is read"
                    )
                chosen_parts = [first]
                name = first.get("name") or first.get("id") or ""
        ocps: list[etree._Element] = []
        formation_ref = None
        for part in chosen_parts:
            self.r.usage.use(part)
            ftt = child(part, "formationTT")
            if ftt is not None:
                self.r.usage.use(ftt)
                formation_ref = formation_ref or ftt.get("formationRef")
            container = child(part, "ocpsTT")
            self.r.usage.use(container)
            items = children(container, "ocpTT")
            # a sequence that is not a whole number is a problem named with its element (it was sorted
            # as 0, and the route then failed later with a message about the wrong thing)
            items.sort(key=lambda o: rc.attr_int(o, "sequence", self.r.problems))
            for o in items:
                # a train part starting where the previous one ended: the junction once
                if ocps and o.get("ocpRef") == ocps[-1].get("ocpRef"):
                    continue
                ocps.append(o)
        return ocps, formation_ref, name

    def dwell(self, ocp_tt: etree._Element) -> tuple[float, bool]:
        """Dwell time [s] and whether the train stops."""
        self.r.usage.use(ocp_tt)
        stop = ocp_tt.get("ocpType") != "pass"
        desc = child(ocp_tt, "stopDescription")
        minimal = None
        if desc is not None:
            self.r.usage.use(desc)
            for st in children(desc, "stopTimes"):
                self.r.usage.use(st)
                minimal = rc.parse_duration(st.get("minimalTime"))
                if st.get("minimalTime") is not None and minimal is None:
                    self.r.problems.add(
                        st, "not an xs:duration", attribute="minimalTime", value=st.get("minimalTime")
                    )
        if minimal is not None:
            return minimal, stop
        times = children(ocp_tt, "times")
        for t in times:
            self.r.usage.use(t)
        chosen = [t for t in times if t.get("scope") == "scheduled"] or times
        if chosen:
            t = chosen[0]
            self.r.usage.use(t)
            arr = rc.parse_clock(t.get("arrival"), rc.attr_int(t, "arrivalDay", self.r.problems, high=366))
            dep = rc.parse_clock(
                t.get("departure"), rc.attr_int(t, "departureDay", self.r.problems, high=366)
            )
            for attr, value in (("arrival", arr), ("departure", dep)):
                if t.get(attr) is not None and value is None:
                    self.r.problems.add(t, "not a time hh:mm:ss", attribute=attr, value=t.get(attr))
            if arr is not None and dep is not None:
                if dep < arr:
                    dep += 86400.0  # over midnight without a day offset
                return dep - arr, stop
        return 0.0, stop

    # ------------------------------------------------------------------ network

    # ------------------------------------------------------------------ network
    def topology(self) -> Topology:
        net, locations, origins = self.network()
        return _Tracks(net, origins, locations)

    def points(self) -> dict[str | None, etree._Element]:
        return {o.get("id"): o for o in descendants(child(self.r.infra, "operationControlPoints"), "ocp")}

    def network(self) -> tuple[rc.Network, dict[str, list[tuple[str, float]]], dict[str, float]]:
        """Tracks as edges, connections as ports; ocp id -> locations; track id -> mileage of its begin."""
        net = rc.Network()
        locations: dict[str, list[tuple[str, float]]] = {}
        origins: dict[str, float] = {}
        p = self.r.problems
        tracks_el = child(self.r.infra, "tracks")
        self.r.usage.use(tracks_el)
        for track in children(tracks_el, "track"):
            tid = track.get("id")
            if not tid:
                p.add(track, "a track needs an id", attribute="id")
                continue
            self.r.usage.use(track)
            topo = child(track, "trackTopology")
            self.r.usage.use(topo)
            begin_el, end_el = child(topo, "trackBegin"), child(topo, "trackEnd")
            if begin_el is None or end_el is None:
                p.add(track, "the track needs trackTopology/trackBegin and trackEnd")
                continue
            self.r.usage.use(begin_el, deep=True)
            self.r.usage.use(end_el, deep=True)
            begin = attr_float(begin_el, "pos", p, required=True, what="position of the track begin [m]")
            end = attr_float(end_el, "pos", p, required=True, what="position of the track end [m]")
            if begin is None or end is None:
                continue
            if end <= begin:
                p.add(
                    end_el,
                    "the track end must lie after its begin",
                    attribute="pos",
                    value=end,
                    allowed=f"> {begin:g}",
                )
                continue
            net.add_edge(tid, begin, end, track)
            abs_begin = attr_float(begin_el, "absPos", p)
            if abs_begin is not None and begin_el.get("absDir") != "falling":
                origins[tid] = abs_begin
            for end_node, leave, arrive, at in ((begin_el, (-1,), (1,), begin), (end_el, (1,), (-1,), end)):
                for conn in children(end_node, "connection"):
                    net.add_port(rc.Port(conn.get("id") or "", tid, at, leave, arrive, conn.get("ref"), conn))
            switches = [
                e
                for group in children(topo, "connections")
                for e in group
                if local(e) in ("switch", "crossing")
            ]
            for sw in switches:
                pos = attr_float(sw, "pos", p, required=True, what=f"position of the {local(sw)} [m]")
                if pos is None:
                    continue
                self.r.usage.use(sw, deep=True)
                self.r.usage.use(sw.getparent())
                for conn in children(sw, "connection"):
                    orientation = conn.get("orientation")
                    leave, arrive = {
                        "outgoing": ((1,), (-1,)),
                        "incoming": ((-1,), (1,)),
                    }.get(orientation or "", ((1, -1), (1, -1)))
                    net.add_port(
                        rc.Port(conn.get("id") or "", tid, pos, leave, arrive, conn.get("ref"), conn)
                    )
            for cs in children(child(topo, "crossSections"), "crossSection"):
                self.r.usage.use(cs.getparent())
                pos = attr_float(cs, "pos", p, required=True, what="position on the track [m]")
                ref = cs.get("ocpRef")
                if ref is None:
                    self.r.usage.skip(cs, "no ocpRef")
                    continue
                self.r.usage.use(cs)
                if pos is not None:
                    self.r.within(cs, pos, begin, end)
                    locations.setdefault(ref, []).append((tid, pos))
        return net, locations, origins

    def line_data(self, topology: Topology) -> dict[str, Any]:
        data = self._line_data(topology.net)
        data["speed_changes"] = data.pop("speed")
        data["speed"] = data.pop("speed_regions")
        return data

    def _line_data(self, net: rc.Network) -> dict[str, Any]:
        """Per track: direction-bound speed changes, and spans of speed (changes without direction),
        gradient, radius, tunnels, electrification."""
        p = self.r.problems
        speed: list[tuple[str, float, int, Any, etree._Element]] = []
        spans: dict[str, list[Span]] = {
            "gradient": [],
            "radius": [],
            "tunnel": [],
            "electrification": [],
            "speed_regions": [],
        }
        for tid, track in net.elements.items():
            begin, end = net.extent[tid]
            elements = child(track, "trackElements")
            if elements is None:
                continue
            self.r.usage.use(elements)
            # speed changes: bound to a direction (up, down: the limit from the change on, for trains
            # running that way), or without direction (the limit of the track from the change to the
            # next one, both ways)
            undirected: list[tuple[float, Any, etree._Element]] = []
            for sc in children(child(elements, "speedChanges"), "speedChange"):
                self.r.usage.use(sc.getparent())
                if sc.get("profileRef") or sc.get("trainCategory") or sc.get("etcsTrainCategory"):
                    self.r.usage.skip(sc, "speed for a speed profile / train category, not the line speed")
                    continue
                self.r.usage.use(sc, deep=True)
                pos = attr_float(sc, "pos", p, required=True, what="position on the track [m]")
                vmax_text = sc.get("vMax")
                if vmax_text is None:
                    p.add(sc, "missing speed (vMax, km/h or 'end')", attribute="vMax")
                    continue
                if vmax_text.strip() == "end":
                    value: Any = rc.END_OF_RESTRICTION
                else:
                    vmax = rc.num(vmax_text)
                    if vmax is None or vmax <= 0:
                        p.add(sc, "not a speed in km/h or 'end'", attribute="vMax", value=vmax_text)
                        continue
                    if abs(vmax - _VIRTUAL_END_KMH) < 1e-9:
                        self.r.content.notes.append(
                            f"{label(sc)} (line {sc.sourceline}): vMax 999.9 read as the end of a temporary "
                            "restriction (railML before 2.3)"
                        )
                        value = rc.END_OF_RESTRICTION
                    else:
                        value = vmax
                if pos is None or not self.r.within(sc, pos, begin, end):
                    continue
                direction = {"up": 1, "down": -1}.get(sc.get("dir") or "")
                if direction is None:
                    undirected.append((pos, value, sc))
                else:
                    speed.append((tid, pos, direction, value, sc))
            undirected.sort(key=lambda c: c[0])
            self._same_position(undirected, "speedChange")
            resolved: list[tuple[float, Any, etree._Element]] = []
            in_force: list[float] = []
            for pos, value, sc in undirected:
                if value == rc.END_OF_RESTRICTION:
                    if len(in_force) < 2:
                        p.add(
                            sc,
                            "end of a speed restriction ('end') with no restriction before it on this track",
                        )
                        continue
                    in_force.pop()
                else:
                    in_force.append(value)
                resolved.append((pos, in_force[-1], sc))
            spans["speed_regions"] += list(rc.regions(resolved, tid, end))
            # gradients, radii, electrification: changes along the track's direction -> spans
            for kind, container, item, attr in (
                ("gradient", "gradientChanges", "gradientChange", "slope"),
                ("radius", "radiusChanges", "radiusChange", "radius"),
            ):
                changes: list[tuple[float, Any, etree._Element]] = []
                for el in children(child(elements, container), item):
                    self.r.usage.use(el.getparent())
                    self.r.usage.use(el, deep=True)
                    pos = attr_float(el, "pos", p, required=True, what="position on the track [m]")
                    value = attr_float(
                        el,
                        attr,
                        p,
                        required=True,
                        what=f"{attr} ({'per mille' if kind == 'gradient' else 'm'})",
                    )
                    if pos is None or value is None or not self.r.within(el, pos, begin, end):
                        continue
                    if kind == "gradient" and el.get("dir") == "down":
                        value = -value  # slope given for trains running down
                    changes.append((pos, value, el))
                changes.sort(key=lambda c: c[0])
                self._same_position(changes, item)
                spans[kind] += list(rc.regions(changes, tid, end))
            changes = []
            for el in children(child(elements, "electrificationChanges"), "electrificationChange"):
                self.r.usage.use(el.getparent())
                self.r.usage.use(el, deep=True)
                pos = attr_float(el, "pos", p, required=True, what="position on the track [m]")
                voltage = attr_float(el, "voltage", p, minimum=0)
                kind_e = el.get("type")
                if kind_e == "none":
                    voltage = 0.0
                elif voltage is None:
                    if el.get("voltage") is None:
                        p.add(el, "missing line voltage [V] (or type='none')", attribute="voltage")
                    continue
                if pos is None or not self.r.within(el, pos, begin, end):
                    continue
                share = rc.traction_share(el, p)
                changes.append((pos, voltage if share == 1.0 else (voltage, share), el))
            changes.sort(key=lambda c: c[0])
            self._same_position(changes, "electrificationChange")
            spans["electrification"] += list(rc.regions(changes, tid, end))
            for el in children(child(elements, "tunnels"), "tunnel"):
                self.r.usage.use(el.getparent())
                self.r.usage.use(el, deep=True)
                pos = attr_float(el, "pos", p, required=True, what="position on the track [m]")
                length = attr_float(el, "length", p, required=True, what="tunnel length [m]", positive=True)
                if pos is None or length is None or not self.r.within(el, pos, begin, end):
                    continue
                a, b = (pos - length, pos) if el.get("dir") == "down" else (pos, pos + length)
                if not self.r.within(el, b if el.get("dir") != "down" else a, begin, end):
                    continue
                limiting = (rc.ext(el, "limitingGradient") or "false").lower() == "true"
                spans["tunnel"].append(Span(tid, a, b, limiting, el))
            for el in children(child(elements, "mileageChanges"), "mileageChange"):
                self.r.usage.skip(
                    el, "positions are read from pos (distance along the track), not the mileage"
                )
        return {"speed": speed, **spans}

    def _same_position(self, changes: Sequence[tuple[float, Any, etree._Element]], what: str) -> None:
        for (p0, v0, e0), (p1, v1, e1) in itertools.pairwise(changes):
            if abs(p1 - p0) <= rc.POSITION_TOLERANCE_M and v0 != v1:
                self.r.problems.add(
                    e1,
                    f"two {what} elements at the same position with different values; the other is "
                    f"{label(e0)} at line {e0.sourceline}",
                    attribute="pos",
                    value=p1,
                )

    # ------------------------------------------------------------------ rolling stock
    def vehicle_equipment(self, v: etree._Element, src: rc.VehicleSource) -> None:
        p = self.r.problems
        engine = child(v, "engine")
        propulsion = child(engine, "propulsion")
        wagon = child(v, "wagon")
        for holder in (propulsion, wagon):
            if holder is not None and holder.get("rotationMassFactor") is not None:
                src.rotating_mass_factor = attr_float(holder, "rotationMassFactor", p, minimum=1.0)
                break
            if holder is not None and holder.get("additionalRotationMass") is not None:
                extra = attr_float(holder, "additionalRotationMass", p, minimum=0)
                if extra is not None and src.mass_t > 0:
                    src.rotating_mass_factor = 1.0 + extra / src.mass_t
                break
        if wagon is not None:
            self.r.usage.use(wagon)
            src.auxiliary_w = attr_float(wagon, "auxiliaryPowerConsumption", p, minimum=0) or 0.0
        if propulsion is not None:
            self.r.usage.use(engine)
            self.r.usage.use(propulsion)
            for other in children(engine, "propulsion")[1:]:
                self.r.usage.skip(other, "only the first propulsion of a vehicle is read")
            src.powered = True
            src.propulsion = propulsion
            src.max_effort_n = attr_float(propulsion, "maxTractEffort", p, positive=True)
            src.power_w = attr_float(propulsion, "power", p, positive=True)
            src.max_brake_power_w = attr_float(propulsion, "maxBrakePower", p, positive=True)
            te = child(propulsion, "tractiveEffort")
            self.r.usage.use(te)
            vt = child(te, "valueTable")
            if vt is not None:
                src.traction = rc.read_value_table(vt, p, y_dimensions=("force",), usage=self.r.usage)
            be = child(propulsion, "brakeEffort")
            self.r.usage.use(be)
            vt = child(be, "valueTable")
            if vt is not None:
                src.regenerative = rc.read_value_table(vt, p, y_dimensions=("force",), usage=self.r.usage)
        for vt in descendants(v, "valueTable"):
            if local(vt.getparent()) == "decelerationTable":
                self.r.usage.use(vt.getparent())
                src.deceleration = rc.read_value_table(
                    vt, p, y_dimensions=("acceleration",), usage=self.r.usage
                )
                break

    def formation_data(self, formation: etree._Element, form: rc.FormationSource) -> None:
        """Braking and running resistance of a railML 2 formation."""
        p = self.r.problems
        for op in children(formation, "trainBrakeOperation") + children(formation, "trainBrakes"):
            self.r.usage.use(op)
            vt = child(child(op, "decelerationTable"), "valueTable")
            if vt is not None and form.deceleration_table is None:
                self.r.usage.use(vt.getparent())
                table = rc.read_value_table(vt, p, y_dimensions=("acceleration", "force"), usage=self.r.usage)
                kind = rc.ext(op, "tableIs") or "service"
                if kind not in ("service", "full"):
                    p.add(
                        op,
                        "unknown braking table kind",
                        attribute="ts:tableIs",
                        value=kind,
                        allowed="service, full",
                    )
                if rc.ext(op, "tableIs") is None:
                    form.notes.append(
                        f"{label(vt)} (line {vt.sourceline}): the deceleration table is read as the service "
                        "braking, braking force = deceleration x inertial mass"
                    )
                if table is not None:
                    form.deceleration_table = (table, kind, rc.num(rc.ext(op, "serviceFraction")))
            mean = attr_float(op, "meanDeceleration", p, positive=True)
            if mean is not None and form.mean_deceleration is None:
                form.mean_deceleration = (mean, op)
        tr = child(formation, "trainResistance")
        if tr is None:
            return
        self.r.usage.use(tr)
        if tr.get("tunnelFactor") is not None:
            form.notes.append(
                f"{label(tr)}: tunnelFactor not used (the tunnel resistance is the route's formula)"
            )
        if any(tr.get(a) is not None for a in ("daviesFactorA", "daviesFactorB", "daviesFactorC")):
            form.davis = (
                attr_float(tr, "daviesFactorA", p, minimum=0) or 0.0,
                attr_float(tr, "daviesFactorB", p) or 0.0,
                attr_float(tr, "daviesFactorC", p, minimum=0) or 0.0,
                attr_bool(tr, "daviesMassDependent") is True,
                tr,
            )
        elif tr.get("strahlFactor") is not None:
            k = attr_float(tr, "strahlFactor", p, minimum=0)
            if k is not None:
                form.strahl = (k, tr)
        else:
            vt = child(tr, "valueTable")
            if vt is not None:
                form.resistance_table = rc.read_value_table(
                    vt, p, y_dimensions=("force", "ratio"), usage=self.r.usage
                )

    def electrical(self, form: rc.FormationSource) -> None:
        p = self.r.problems
        prop = rc.powered_propulsion(form)
        if prop is None:
            return
        voltage = attr_float(prop, "voltage", p, positive=True)
        eta = attr_float(prop, "totalTractEfficiency", p, positive=True)
        if voltage is None or eta is None:
            return
        out: dict[str, Any] = {"line_voltage_v": voltage, "traction_efficiency": eta}
        regen = attr_float(prop, "totalBrakeEfficiency", p, minimum=0)
        if regen is not None:
            out["regenerative_efficiency"] = regen
        rc.extension_numbers(prop, out, (("power_factor", "powerFactor"), ("receptivity", "receptivity")))
        form.electrical = out


class _Tracks(Topology):
    """railML 2 tracks; operational points placed by ``crossSection@ocpRef``."""

    def __init__(
        self, net: rc.Network, origins: dict[str, float], locations: dict[str, list[tuple[str, float]]]
    ) -> None:
        super().__init__(net, origins)
        self.locations = locations

    def locate(self, point: etree._Element, ref: str) -> list[tuple[str, float]]:
        return self.locations.get(ref, [])


def read_railml2(
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
    """Read a railML 2 file: its train (formation) and route (the path of a train of its
    timetable, or of the operational points ``ocps``), as trainsim YAML mappings.

    Args:
        train_id: id, number or name of the timetable train (or train part) whose path is the route.
        formation_id: the formation to read (default: the one the train's timetable names, else
            the only or first one).
        ocps: ids or names of the operational points the route passes, instead of a timetable.
        line_resistance: ``curve_formula``, ``tunnel_formula`` (required unless the file has
            trainsim's attributes), ``gradient_formula``, ``apply_over``.
        rotating_mass_factor: the train's factor, when the vehicles do not give theirs.
        require_line_resistance: False to read without the formulas (for ``trainsim check``).

    Raises:
        InputError naming the element and its line for every problem found.
    """
    options = {k: v for k, v in locals().items() if k != "path"}
    return read_railml(path, Railml2, **options)


def load_train_railml2(path: str | Path, **options: Any) -> Train:
    """The train of a railML 2 file (see :func:`read_railml2` for the options)."""
    return rc.build_train(read_railml2(path, **options))


def load_route_railml2(path: str | Path, **options: Any) -> Route:
    """The route of a railML 2 file (see :func:`read_railml2` for the options)."""
    return rc.build_route(read_railml2(path, **options))


# ====================================================================== writing
class _Writer(rc.ElementWriter):
    family = "railML 2"
    value_tag = "values"

    def __init__(self, version: str) -> None:
        super().__init__(version, NAMESPACES)

    # ------------------------------------------------------------------ infrastructure
    def infrastructure(self, root: etree._Element, route: Route) -> None:
        lr = route.line_resistance
        infra = self.el(
            root,
            "infrastructure",
            id="inf",
            name=route.name,
            ts_curveFormula=lr.curve_formula,
            ts_tunnelFormula=lr.tunnel_formula,
            ts_gradientFormula=lr.gradient_formula,
            ts_applyOver=lr.apply_over,
        )
        tracks = self.el(infra, "tracks")
        track = self.el(tracks, "track", id="tr1", name=route.name)
        topo = self.el(track, "trackTopology")
        length = route.end_m - route.start_m
        begin = self.el(topo, "trackBegin", id="tr1_begin", pos=0.0, absPos=route.start_m)
        self.el(begin, "openEnd", id="tr1_begin_end")
        end = self.el(topo, "trackEnd", id="tr1_end", pos=length, absPos=route.end_m)
        self.el(end, "openEnd", id="tr1_end_end")
        css = self.el(topo, "crossSections")
        for i, st in enumerate(route.stations):
            self.el(
                css, "crossSection", id=f"cs{i + 1}", ocpRef=f"ocp{i + 1}", pos=st.position_m - route.start_m
            )
        elements = self.el(track, "trackElements")
        rel = route.start_m
        speed = self.el(elements, "speedChanges")
        for i, lim in enumerate(route.speed_limits):
            self.el(
                speed,
                "speedChange",
                id=f"sc{i + 1}",
                pos=lim.start_m - rel,
                dir="up",
                vMax=lim.limit_mps / KMH,
            )
        changes = _changes(
            route.start_m,
            route.end_m,
            [(g.start_m, g.end_m, g.gradient_permille) for g in route.gradients],
            0.0,
        )
        if changes:
            grad = self.el(elements, "gradientChanges")
            for i, (pos, value) in enumerate(changes):
                self.el(grad, "gradientChange", id=f"gc{i + 1}", pos=pos - rel, slope=value)
        changes = _changes(
            route.start_m, route.end_m, [(c.start_m, c.end_m, c.radius_m) for c in route.curves], 0.0
        )
        if changes:
            rad = self.el(elements, "radiusChanges")
            for i, (pos, value) in enumerate(changes):
                self.el(rad, "radiusChange", id=f"rc{i + 1}", pos=pos - rel, radius=value)
        if route.tunnels:
            tun = self.el(elements, "tunnels")
            for i, t in enumerate(route.tunnels):
                self.el(
                    tun,
                    "tunnel",
                    id=f"tn{i + 1}",
                    pos=t.start_m - rel,
                    length=t.end_m - t.start_m,
                    ts_limitingGradient=True if t.limiting_gradient else None,
                )
                if getattr(t, "extra_drag_n_s2_per_m2", 0.0):
                    self.notes.append(f"tunnel {i + 1}: its extra drag is not written (no railML attribute)")
        if route.electrification:
            elec = self.el(elements, "electrificationChanges")
            sections = [(e.start_m, e.end_m, (e.voltage_v, e.traction_share)) for e in route.electrification]
            changes = _changes(route.start_m, route.end_m, sections, None)
            if len(changes) > 1 and any(
                b < c - rc.POSITION_TOLERANCE_M for (_, b, _), (c, _, _) in itertools.pairwise(sections)
            ):
                self.notes.append(
                    "electrification: gaps between sections (the train's nominal voltage) are not written"
                )
            for i, (pos, (voltage, share)) in enumerate(changes):
                self.el(
                    elec,
                    "electrificationChange",
                    id=f"ec{i + 1}",
                    pos=pos - rel,
                    type="overhead" if voltage > 0 else "none",
                    voltage=voltage if voltage > 0 else None,
                    ts_tractionShare=share if share != 1.0 else None,
                )
        ocps = self.el(infra, "operationControlPoints")
        for i, st in enumerate(route.stations):
            ocp = self.el(ocps, "ocp", id=f"ocp{i + 1}", name=st.name)
            self.el(ocp, "propOperational", operationalType="station")

    # ------------------------------------------------------------------ rolling stock
    def rollingstock(self, root: etree._Element, train: Train) -> None:
        rs = self.el(root, "rollingstock")
        vehicles_el = self.el(rs, "vehicles")
        groups = rc.vehicle_groups(train)
        # the traction curve is the train's: shared equally by the powered vehicles (the first
        # vehicle when none is marked powered)
        powered_names = {v.name for v, _ in groups if v.powered} or {groups[0][0].name}
        n_powered = sum(n for v, n in groups if v.name in powered_names)
        tables = rc.written_tables(train, groups, self.notes)
        xi, speeds, forces = tables.xi, tables.speeds, tables.forces
        fcap, pcap = tables.force_cap_n, tables.power_cap_w
        r_speeds, r_forces = tables.regen_speeds, tables.regen_forces
        regen = train.braking.regenerative
        n_total = sum(n for _, n in groups)
        elec = train.electrical
        ids: dict[str, str] = {}
        for k, (v, _n) in enumerate(groups):
            vid = f"veh{k + 1}"
            ids[v.name + f"#{k}"] = vid
            veh = self.el(
                vehicles_el,
                "vehicle",
                id=vid,
                name=v.name,
                length=v.length_m,
                speed=None,
                bruttoWeight=(v.mass_kg + v.load_kg) / TONNE,
                nettoWeight=v.load_kg / TONNE,
                tareWeight=v.mass_kg / TONNE,
                numberNonDrivenAxles=(v.axles if v.axles and v.name not in powered_names else None),
                numberDrivenAxles=(v.axles if v.axles and v.name in powered_names else None),
            )
            if v.name in powered_names:
                engine = self.el(veh, "engine")
                prop = self.el(
                    engine,
                    "propulsion",
                    id=f"{vid}_prop",
                    # required by railML: the power cap, or for a table the table's highest F v
                    power=(pcap if len(speeds) == 0 else float(np.max(speeds * forces))) / n_powered,
                    powerType="electric" if elec is not None else "diesel",
                    maxTractEffort=(fcap / n_powered) if math.isfinite(fcap) else None,
                    rotationMassFactor=xi,
                    voltage=elec.line_voltage_v if elec else None,
                    totalTractEfficiency=elec.traction_efficiency if elec else None,
                    totalBrakeEfficiency=elec.regenerative_efficiency if elec else None,
                    ts_powerFactor=elec.power_factor if elec else None,
                    ts_receptivity=elec.receptivity if elec else None,
                )
                if len(speeds) and math.isfinite(pcap):
                    self.notes.append("traction power cap with a table: not written")
                if len(speeds):
                    te = self.el(prop, "tractiveEffort")
                    self.value_table(te, "tractiveEffort", "N", speeds, forces / n_powered)
                if regen is not None:
                    be = self.el(prop, "brakeEffort")
                    self.value_table(be, "brakeEffort", "N", r_speeds, r_forces / n_powered)
                    if math.isfinite(regen.power_cap_w):
                        prop.set("maxBrakePower", fmt(regen.power_cap_w / n_powered))
                if elec and elec.auxiliary_power_w:
                    self.el(veh, "wagon", auxiliaryPowerConsumption=elec.auxiliary_power_w / n_total)
            else:
                self.el(
                    veh,
                    "wagon",
                    rotationMassFactor=xi,
                    auxiliaryPowerConsumption=(elec.auxiliary_power_w / n_total)
                    if elec and elec.auxiliary_power_w
                    else None,
                )
        formations = self.el(rs, "formations")
        form = self.el(
            formations,
            "formation",
            id="f1",
            name=train.name,
            length=train.length_m,
            speed=train.max_speed_mps / KMH,
            weight=train.mass_kg / TONNE,
        )
        order = self.el(form, "trainOrder")
        for k, (_v, n) in enumerate(groups):
            self.el(order, "vehicleRef", orderNumber=k + 1, vehicleRef=f"veh{k + 1}", vehicleCount=n)
        law = train.resistance_law
        self.el(
            form,
            "trainResistance",
            daviesFactorA=law.c0,
            daviesFactorB=law.c1 * KMH,
            daviesFactorC=law.c2 * KMH**2,
            daviesMassDependent=False,
        )
        braking = train.braking
        if braking.deceleration_mps2 is not None:
            self.el(form, "trainBrakes", meanDeceleration=braking.deceleration_mps2)
        else:
            assert braking.service_force is not None
            b_speeds, b_forces, _, _, b_exact = rc.effort_table(braking.service_force, train.max_speed_mps)
            if not b_exact or len(b_speeds) == 0:
                b_speeds, b_forces = rc.sampled(braking.service_force, train.max_speed_mps)
                self.notes.append("braking: written as a sampled table")
            op = self.el(form, "trainBrakeOperation", ts_tableIs="service")
            dt = self.el(op, "decelerationTable")
            self.value_table(dt, "deceleration", "m/s^2", b_speeds, b_forces / train.inertial_mass_kg)

    # ------------------------------------------------------------------ timetable
    def timetable(
        self,
        root: etree._Element,
        route: Route,
        train: Train | None,
        times: Sequence[tuple[float, float]] | None,
    ) -> None:
        tt = self.el(root, "timetable")
        parts = self.el(tt, "trainParts")
        part = self.el(parts, "trainPart", id="tp1", name=route.name)
        if train is not None:
            self.el(part, "formationTT", formationRef="f1")
        ocps = self.el(part, "ocpsTT")
        n = len(route.stations)
        for i, st in enumerate(route.stations):
            kind = "begin" if i == 0 else "end" if i == n - 1 else "stop" if st.stop else "pass"
            o = self.el(ocps, "ocpTT", ocpRef=f"ocp{i + 1}", sequence=i + 1, ocpType=kind)
            if times is not None:
                arr, dep = times[i]
                attrs: dict[str, Any] = {"scope": "calculated"}
                if i > 0:
                    attrs["arrival"], day = rc.format_clock(arr)
                    if day:
                        attrs["arrivalDay"] = day
                if i < n - 1:
                    attrs["departure"], day = rc.format_clock(dep)
                    if day:
                        attrs["departureDay"] = day
                self.el(o, "times", **attrs)
                if i < n - 1:
                    sec = self.el(o, "sectionTT")
                    self.el(sec, "runTimes", minimalTime=rc.format_duration(times[i + 1][0] - dep))
            if st.stop and st.dwell_s > 0 and 0 < i < n - 1:
                desc = self.el(o, "stopDescription")
                self.el(desc, "stopTimes", minimalTime=rc.format_duration(st.dwell_s))
        trains = self.el(tt, "trains")
        t = self.el(trains, "train", id="t1", type="operational", name=train.name if train else route.name)
        seq = self.el(t, "trainPartSequence", sequence=1)
        self.el(seq, "trainPartRef", ref="tp1")


def _changes(
    start: float, end: float, sections: Sequence[tuple[float, float, float]], gap_value: float | None
) -> list[tuple[float, float]]:
    """Sections ``(a, b, value)`` as changes ``(position, value)``; gaps between them (and before
    the first one) get ``gap_value`` (level, straight); with None, gaps are not written."""
    out: list[tuple[float, float]] = []
    cursor = start
    for a, b, value in sorted(sections):
        if a > cursor + rc.POSITION_TOLERANCE_M and gap_value is not None:
            out.append((cursor, gap_value))
        out.append((a, value))
        cursor = b
    if sections and cursor < end - rc.POSITION_TOLERANCE_M and gap_value is not None:
        out.append((cursor, gap_value))
    return out


# Former names (the writers' helpers are in railml_common now).
_sampled = rc.sampled
_vehicle_groups = rc.vehicle_groups


def write_railml2(
    path: str | Path,
    *,
    train: Train | None = None,
    route: Route | None = None,
    times: Sequence[tuple[float, float]] | None = None,
    version: str = "2.4",
) -> list[str]:
    """Write a train and/or a route as a railML 2 file (infrastructure with one track, rolling
    stock with one formation, a timetable with one train whose path is the route).

    Args:
        times: arrival and departure time [s after midnight] at each station, written as
            ``times@scope="calculated"`` and the running times as ``sectionTT/runTimes@minimalTime``
            (see :mod:`trainsim.io.results_export`).
        version: 2.2 to 2.5 (namespace and version attribute).

    Returns:
        Notes on what could not be written exactly (sampled curves...).
    """
    w = _Writer(version)
    root = w.el(None, "railml", version=version)
    if route is not None:
        w.infrastructure(root, route)
    if train is not None:
        w.rollingstock(root, train)
    if route is not None:
        w.timetable(root, route, train, times)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    etree.ElementTree(root).write(str(out), xml_declaration=True, encoding="UTF-8", pretty_print=True)
    return w.notes
