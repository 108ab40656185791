"""One reader for railML 2 and railML 3: a single walk over the document, the version differences
held by a :class:`Dialect` (element and attribute names as data, the parts whose structure
differs as small methods).

The walk, the same for every version:

1. the root: version, ids (a duplicate id is an error), the top-level sections;
2. infrastructure: the network (tracks or netElements joined at ports), the operational points,
   the path of the chosen timetable train (or of the points given) through the network, the
   stations on it, the line data (speed, gradient, curves, tunnels, electrification) on it;
3. rolling stock: the formation (the one the timetable names, or the one asked for), its vehicles
   in order, each vehicle's equipment, the formation's braking and running resistance, the
   electrical data;
4. what was not used, for ``trainsim check``.

What differs between railML 2 and 3 is in :mod:`trainsim.io.railml2` and :mod:`trainsim.io.railml3`
as a :class:`Dialect` each; everything else is here, so that a fix reaches both versions.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

from lxml import etree

from trainsim.errors import InputError
from trainsim.io import railml_common as rc
from trainsim.io.railml_common import Content, Problems, Usage, attr_float, child, children, label

__all__ = ["Dialect", "Entry", "Reader", "Topology", "read_railml"]

#: A point of the route: operational point id, dwell [s], whether the train stops, source element.
Entry = tuple[str | None, float, bool, etree._Element]


class Topology:
    """The network of a file and where its operational points lie on it (version-specific)."""

    def __init__(self, net: rc.Network, origins: dict[str, float]) -> None:
        self.net = net
        self.origins = origins  #: edge -> mileage of its begin [m]

    def locate(self, point: etree._Element, ref: str) -> list[tuple[str, float]]:
        """The (edge, position [m]) places of an operational point."""
        raise NotImplementedError


class Dialect:
    """What one railML version names and places differently. Subclasses set the data below and
    implement the methods; an instance is made per read, bound to its :class:`Reader`."""

    family: ClassVar[str]  #: "railML 2"
    root_tag: ClassVar[str]  #: local name of the root element
    fallback_version: ClassVar[str]  #: "2.x" when the version cannot be told
    read_as: ClassVar[str]  #: the version an unsupported one is read as
    supported: ClassVar[tuple[str, ...]]
    sections: ClassVar[tuple[str, ...]]  #: top-level elements the reader walks into
    edge_figure: ClassVar[str]  #: what an edge of the network is called ("tracks")
    points_word: ClassVar[str]  #: "ocps"
    unplaced_point: ClassVar[str]  #: message for an operational point off the network ({ref})
    stop_at_ends: ClassVar[bool]  #: the first and last stations are stops whatever the timetable says
    vehicle_family: ClassVar[str | None]  #: attribute naming a vehicle to inherit missing data from
    axles: ClassVar[tuple[str, str]]  #: driven and non-driven axle count attributes
    stock_in_containers: ClassVar[bool]  #: vehicles/formations only in ``vehicles``/``formations``
    no_formation_note: ClassVar[str]
    unknown_vehicle: ClassVar[str]
    empty_formation: ClassVar[str]
    merge_repeats: ClassVar[bool]  #: consecutive references to one vehicle add up
    order_entries: ClassVar[bool]  #: ``trainOrder`` elements may reference the vehicles themselves

    def __init__(self, reader: Reader) -> None:
        self.r = reader

    @classmethod
    def detect(cls, root: etree._Element) -> str | None:
        """The version of a document root of this family, or None."""
        raise NotImplementedError

    def name(self, el: etree._Element | None, use: bool = False) -> str:
        """The name of an element ("" without one); ``use`` marks a name element used."""
        return (el.get("name") or "") if el is not None else ""

    def topology(self) -> Topology:
        raise NotImplementedError

    def points(self) -> dict[str | None, etree._Element]:
        """Operational points by id."""
        raise NotImplementedError

    def timetable_path(
        self, train_id: str | None, points: dict[str | None, etree._Element]
    ) -> tuple[list[Entry], etree._Element | None, str | None, str] | None:
        """The points of the chosen train, its formation (element or id), its name; None when the
        file has no timetable."""
        raise NotImplementedError

    def line_data(self, topology: Topology) -> dict[str, list[Any]]:
        """Spans on edges by kind (``speed``, ``gradient``, ``radius``, ``tunnel``,
        ``electrification``) and direction-bound speed changes (``speed_changes``)."""
        raise NotImplementedError

    def vehicle_equipment(self, vehicle: etree._Element, src: rc.VehicleSource) -> None:
        """Rotating masses, auxiliaries, traction, braking of one vehicle into ``src``."""
        raise NotImplementedError

    def formation_data(self, formation: etree._Element, form: rc.FormationSource) -> None:
        """Braking and running resistance of a formation."""
        raise NotImplementedError

    def electrical(self, form: rc.FormationSource) -> None:
        raise NotImplementedError


class Reader:
    """One read of one railML file: the walk of the module docstring."""

    def __init__(self, path: str | Path, tree: etree._ElementTree, dialect: type[Dialect]) -> None:
        self.file = str(path)
        self.root = tree.getroot()
        self.problems = Problems(self.file)
        self.usage = Usage()
        self.usage.use(self.root)
        self.d = dialect(self)
        self.version = dialect.detect(self.root) or dialect.fallback_version
        self.content = Content(format=f"railML {self.version}", file=self.file)
        if self.version not in dialect.supported:
            self.content.notes.append(f"railML version {self.version}: read as railML {dialect.read_as}")
        self.ids = rc.index_ids(self.root, self.problems)
        self.problems.raise_if_any()
        self.infra = child(self.root, "infrastructure")
        self.rollingstock = child(self.root, "rollingstock")
        self.timetable = child(self.root, "timetable")
        self.common = child(self.root, "common") if "common" in dialect.sections else None
        self.topology: Topology | None = None
        self.path: rc.RoutePath | None = None
        self.stations: list[rc.StationAt] = []
        self.station_places: dict[etree._Element, tuple[tuple[str, float], ...]] = {}
        for name in dialect.sections:
            self.usage.use(child(self.root, name))
        meta = child(self.root, "metadata")
        if meta is not None:
            self.usage.use(meta, deep=True)

    # ------------------------------------------------------------------ helpers for the dialects
    def within(self, el: etree._Element, pos: float, begin: float, end: float) -> bool:
        """Whether ``pos`` lies on ``[begin, end]`` (a problem if not)."""
        if not begin - rc.POSITION_TOLERANCE_M <= pos <= end + rc.POSITION_TOLERANCE_M:
            self.problems.add(
                el,
                "position outside its track",
                attribute="pos",
                value=pos,
                allowed=f"{begin:g} .. {end:g} m",
            )
            return False
        return True

    def vehicle_float(self, vehicle: etree._Element, name: str, **kwargs: Any) -> float | None:
        """A number attribute of a vehicle or, if missing, of the vehicle it inherits from."""
        owner = vehicle
        seen: set[int] = set()
        v: etree._Element | None = vehicle
        while self.d.vehicle_family and v is not None and id(v) not in seen:
            seen.add(id(v))
            if v.get(name) is not None:
                owner = v
                break
            ref = v.get(self.d.vehicle_family)
            v = self.ids.get(ref) if ref else None
        return attr_float(owner, name, self.problems, **kwargs)

    # ------------------------------------------------------------------ infrastructure
    def route(
        self,
        *,
        train_id: str | None,
        ocps: Sequence[str] | None,
        line_resistance: dict[str, str] | None,
        require_line_resistance: bool,
    ) -> tuple[dict[str, Any] | None, etree._Element | None, str | None]:
        """The route mapping, and the formation the timetable names (element or id)."""
        if self.infra is None:
            return None, None, None
        p = self.problems
        topology = self.d.topology()
        p.raise_if_any()
        points = self.d.points()
        by_name: dict[str, list[str | None]] = {}
        for oid, op in points.items():
            by_name.setdefault(self.d.name(op), []).append(oid)
        formation: etree._Element | None = None
        formation_ref: str | None = None
        entries: list[Entry] = []
        name = self.d.name(self.infra, use=True) or Path(self.file).stem
        if ocps:
            entries = self._given_points(ocps, points, by_name)
        else:
            found = self.d.timetable_path(train_id, points)
            if found is None:
                self.content.notes.append(
                    "no route: the file has no timetable; give the operational points of the path (--ocps)"
                )
                return None, None, None
            entries, formation, formation_ref, tname = found
            name = f"{tname} path" if tname else name
        p.raise_if_any()
        stops: list[rc.Stop] = []
        for ref, _, _, el in entries:
            op = points[ref]
            self.usage.use(op, deep=True)
            places = topology.locate(op, ref)
            if not places:
                p.add(el, self.d.unplaced_point.format(ref=ref))
                continue
            stops.append(rc.Stop(self.d.name(op, use=True) or ref, tuple(places), el))
        p.raise_if_any()
        path = rc.route_path(topology.net, stops, p, topology.origins.get)
        p.raise_if_any()
        assert path is not None
        stations = rc.stations_on_path(path, entries, stops, p)
        # kept for the readers of what lies along the path (signals, detection points, switches)
        self.topology, self.path, self.stations = topology, path, stations
        self.station_places = {stop.element: stop.locations for stop in stops}
        if self.d.stop_at_ends and stations:
            for k in (0, -1):
                st = stations[k]
                stations[k] = rc.StationAt(st.name, st.position_m, st.dwell_s, True, st.element)
        self.content.station_elements = [st.element for st in stations]
        data = self.d.line_data(topology)
        p.raise_if_any()
        # railML 3 sections may overlap (an error); railML 2 changes cannot, the check passes
        spans = {}
        for kind, what, down in (
            ("speed", "speed section", None),
            ("gradient", "gradient curve", lambda g: -g),
            ("electrification", "electrification section", None),
        ):
            spans[kind] = path.spans(data[kind], down=down)
            rc.check_overlaps(spans[kind], what, p)
        p.raise_if_any()
        lr = rc.line_resistance_choice(
            self.infra, line_resistance, self.content, required=require_line_resistance
        )
        route = rc.route_mapping(
            self.content,
            p,
            name=name,
            path=path,
            stations=stations,
            speed=sorted(
                path.changes(data["speed_changes"]) + rc.events_from_spans(spans["speed"]),
                key=lambda e: e.position_m,
            ),
            gradients=rc.events_from_spans(spans["gradient"]),
            electrification=rc.events_from_spans(spans["electrification"]),
            curves=path.spans(data["radius"]),
            tunnels=path.spans(data["tunnel"]),
            line_resistance=lr,
            anchor=self.infra,
        )
        p.raise_if_any()
        self.content.figures.update(
            {
                self.d.edge_figure: str(len(topology.net.extent)),
                "operational points": str(len(points)),
                "route path": " -> ".join(f"{leg.edge} ({leg.start:g}..{leg.end:g} m)" for leg in path.legs),
            }
        )
        return route, formation, formation_ref

    def _given_points(
        self,
        ocps: Sequence[str],
        points: dict[str | None, etree._Element],
        by_name: dict[str, list[str | None]],
    ) -> list[Entry]:
        entries: list[Entry] = []
        for given in ocps:
            ids = [given] if given in points else by_name.get(given, [])
            if len(ids) != 1:
                names = ((o, self.d.name(points[o])) for o in points)
                raise InputError(
                    "no operational point of that id or name"
                    if not ids
                    else f"several {self.d.points_word} have that name",
                    file=self.file,
                    field="ocps",
                    value=given,
                    allowed=", ".join(f"{o} ({n})" if n else str(o) for o, n in names),
                )
            entries.append((ids[0], 0.0, True, points[ids[0]]))
        self.content.notes.append("route from the operational points given: a stop at each, dwell 0 s")
        return entries

    # ------------------------------------------------------------------ rolling stock
    def train(
        self, formation: etree._Element | None, formation_id: str | None, rho: float | None
    ) -> dict[str, Any] | None:
        rs = self.rollingstock
        if rs is None:
            return None
        p = self.problems
        c = self.content
        scope = (child(rs, "vehicles"), child(rs, "formations")) if self.d.stock_in_containers else (rs, rs)
        vehicles = {v.get("id"): v for v in rc.descendants(scope[0], "vehicle")}
        formations = {f.get("id"): f for f in rc.descendants(scope[1], "formation")}
        for el in (child(rs, "vehicles"), child(rs, "formations")):
            self.usage.use(el)
        if formation_id is not None:
            formation = rc.formation_by_id(formations, formation_id, self.file)
        elif formation is None and formations:
            formation = next(iter(formations.values()))
            if len(formations) > 1:
                c.notes.append(
                    f"{len(formations)} formations: the first, {label(formation)}, is read "
                    "(choose with --formation-id)"
                )
        if formation is None:
            if len(vehicles) != 1:
                c.notes.append(self.d.no_formation_note)
                return None
            v = next(iter(vehicles.values()))
            order = [(v, 1, v)]
            name = self.d.name(v, use=True) or v.get("id") or "train"
        else:
            self.usage.use(formation)
            name = self.d.name(formation, use=True) or formation.get("id") or "train"
            train_order = child(formation, "trainOrder")
            refs = children(train_order, "vehicleRef") or (
                children(formation, "trainOrder") if self.d.order_entries else []
            )
            self.usage.use(train_order)
            order = rc.vehicle_order(
                refs,
                vehicles,
                self.usage,
                p,
                unknown=self.d.unknown_vehicle,
                merge_repeats=self.d.merge_repeats,
            )
            if not order:
                p.add(formation, self.d.empty_formation)
        p.raise_if_any()
        sources = self._vehicles(order)
        p.raise_if_any()
        anchor = formation if formation is not None else order[0][0]
        form = rc.FormationSource(name, anchor, sources, rotating_mass_factor=rho)
        if formation is not None:
            form.max_speed_kmh = attr_float(formation, "speed", p, positive=True)
            self.d.formation_data(formation, form)
        self.d.electrical(form)
        p.raise_if_any()
        train = rc.train_mapping(form, c, p)
        p.raise_if_any()
        return train

    def _vehicles(
        self, order: Sequence[tuple[etree._Element, int, etree._Element]]
    ) -> list[rc.VehicleSource]:
        sources: list[rc.VehicleSource] = []
        names: set[str] = set()
        vf = self.vehicle_float
        for i, (v, count, ref) in enumerate(order):
            self.usage.use(v)
            vname = self.d.name(v, use=True) or v.get("id") or f"vehicle {i + 1}"
            if vname in names or vname == "train":
                vname = f"{vname} #{i + 1}"
            names.add(vname)
            masses = rc.vehicle_mass(
                vf(v, "tareWeight", minimum=0),
                vf(v, "bruttoWeight", minimum=0),
                vf(v, "nettoWeight", minimum=0),
                v,
                self.content,
                self.problems,
            )
            length = vf(v, "length", required=True, what="vehicle length [m]", positive=True)
            if masses is None or length is None:
                continue
            src = rc.VehicleSource(vname, count, masses[0], masses[1], length, ref)
            src.max_speed_kmh = vf(v, "speed", positive=True)
            axles = [vf(v, a, minimum=0) for a in self.d.axles]
            if any(a is not None for a in axles):
                src.axles = int(sum(a or 0 for a in axles)) or None
            self.d.vehicle_equipment(v, src)
            sources.append(src)
        return sources


def read_railml(
    path: str | Path,
    dialect: type[Dialect],
    *,
    train_id: str | None = None,
    formation_id: str | None = None,
    ocps: Sequence[str] | None = None,
    line_resistance: dict[str, str] | None = None,
    rotating_mass_factor: float | None = None,
    require_line_resistance: bool = True,
    tree: etree._ElementTree | None = None,
) -> Content:
    """Read a railML file of ``dialect``'s version: its train (formation) and route, as trainsim
    YAML mappings (the options: :func:`trainsim.io.railml2.read_railml2`)."""
    tree = tree if tree is not None else rc.parse_xml(path)
    if dialect.detect(tree.getroot()) is None:
        raise InputError(
            f"not a {dialect.family} file (root element '{dialect.root_tag}' with version "
            f"{dialect.fallback_version})",
            file=str(path),
        )
    reader = Reader(path, tree, dialect)
    content = reader.content
    route, formation, formation_ref = reader.route(
        train_id=train_id,
        ocps=ocps,
        line_resistance=line_resistance,
        require_line_resistance=require_line_resistance,
    )
    content.route = route
    content.train = reader.train(formation, formation_id or formation_ref, rotating_mass_factor)
    reader.problems.raise_if_any()
    content.ignored = reader.usage.ignored(reader.root)
    content.figures["railML version"] = reader.version
    return content
