"""The traction power network: tracks, substations, connections between tracks, gaps.

A line is described along one chainage axis [m]. Each track has a contact line (overhead wire or
third rail) and, for DC, its running rails as the return conductor; both are resistances per metre.
Substations feed one or more tracks at their position; paralleling posts join the contact lines of
several tracks, cross-bonds their rails; section insulators (gaps of length 0) and neutral sections
(gaps of some length) cut a track's contact line.

For DC the network is modelled with two layers: contact nodes and rail nodes at every substation,
connection and train position of each track; rails leak to earth through the rail-to-earth
conductance per metre (lumped half to each end of a segment). For AC (simplified impedance model)
the contact line and its return form one loop impedance per metre and the return is the reference
(earth).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from trainsim.errors import InputError, Problem
from trainsim.power.limits import VoltageLimits

__all__ = ["Connection", "Gap", "Network", "Storage", "Substation", "Track", "regulation_points"]

System = Literal["dc", "ac"]


@dataclass(frozen=True)
class Track:
    """One track of the line.

    Attributes:
        id: track name (unique).
        start_m, end_m: where its contact line starts and ends on the line's chainage [m].
        contact_resistance_ohm_per_m: contact line (wire, feeders or third rail) resistance [ohm/m];
            for AC the loop resistance (contact line and return).
        rail_resistance_ohm_per_m: resistance of the running rails as return conductor [ohm/m]
            (DC only; 0 for AC).
        rail_to_earth_conductance_s_per_m: rail-to-earth conductance [S/m] (DC only).
        contact_reactance_ohm_per_m: loop reactance [ohm/m] (AC only).
    """

    id: str
    start_m: float
    end_m: float
    contact_resistance_ohm_per_m: float
    rail_resistance_ohm_per_m: float = 0.0
    rail_to_earth_conductance_s_per_m: float = 0.0
    contact_reactance_ohm_per_m: float = 0.0


@dataclass(frozen=True)
class Substation:
    """A traction substation: a source of no-load voltage E behind an internal impedance.

    Attributes:
        id: name (unique).
        position_m: where it feeds [m].
        tracks: ids of the tracks it feeds (contact lines joined to its positive busbar; for DC its
            negative busbar joined to their rails).
        no_load_voltage_v: E [V] (AC: RMS).
        internal_resistance_ohm: R_i [ohm] (> 0; rectifier regulation plus transformer).
        internal_reactance_ohm: X_i [ohm] (AC only).
        rated_power_w: rated output power [W], or None.
        overload_power_w: admissible overload power [W], or None.
        reversible: True if it can return power to the grid (an inverter, or an AC substation
            whose grid takes power back); False: a diode rectifier (DC), or an AC substation whose
            supply contract or protection forbids return: it never takes power back.
        regulation: DC regulation curve ((current_a, voltage_v), ...), current increasing and
            voltage strictly decreasing, through current 0 at ``no_load_voltage_v`` with its
            first segment's slope equal to ``internal_resistance_ohm``
            (:func:`regulation_points` builds such a substation's E and R_i); None: the
            Thevenin source E, R_i alone (trainsim.power.regulation).
    """

    id: str
    position_m: float
    tracks: tuple[str, ...]
    no_load_voltage_v: float
    internal_resistance_ohm: float
    internal_reactance_ohm: float = 0.0
    rated_power_w: float | None = None
    overload_power_w: float | None = None
    reversible: bool = False
    regulation: tuple[tuple[float, float], ...] | None = None


def regulation_points(points: list[tuple[float, float]]) -> tuple[float, float]:
    """(no_load_voltage_v, internal_resistance_ohm) of a regulation curve ((current_a, voltage_v),
    ...): the voltage at current 0 and the slope of the segment starting there. The points must
    hold a current 0 and be sorted by current (else an InputError)."""
    currents = [float(i) for i, _ in points]
    if 0.0 not in currents or currents != sorted(currents) or len(points) < 2:
        raise InputError(
            "a regulation curve needs at least two points sorted by current, one at current 0",
            field="regulation",
            value=[list(q) for q in points],
            allowed="[[0, E], [I1, U1], ...] with 0 < I1 < ...",
        )
    k = currents.index(0.0)
    if k == len(points) - 1:
        k -= 1
    (i0, u0), (i1, u1) = points[k], points[k + 1]
    e = float(points[currents.index(0.0)][1])
    return e, float(-(u1 - u0) / (i1 - i0))


@dataclass(frozen=True)
class Connection:
    """A paralleling post (joins contact lines) or a cross-bond (joins rails) between tracks.

    Attributes:
        id: name.
        position_m: where [m].
        tracks: ids of the tracks it joins (at least two).
        kind: ``paralleling_post`` or ``cross_bond``.
    """

    id: str
    position_m: float
    tracks: tuple[str, ...]
    kind: Literal["paralleling_post", "cross_bond"] = "paralleling_post"


@dataclass(frozen=True)
class Gap:
    """A cut in a track's contact line: a section insulator (``start_m == end_m``) or a neutral
    section / dead section (``start_m < end_m``, no supply inside: trains coast through it).

    Attributes:
        id: name.
        track: id of the track.
        start_m, end_m: extent [m].
    """

    id: str
    track: str
    start_m: float
    end_m: float


@dataclass(frozen=True)
class Storage:
    """Wayside energy storage (DC): a battery or supercapacitor bank with a converter, at one point.

    It charges when its terminal voltage rises above ``charge_above_v`` (full power ``ramp_v``
    higher) and discharges when the voltage falls below ``discharge_below_v`` (full power ``ramp_v``
    lower), within its power and its state of charge. Its converter and cells lose
    ``1 - efficiency`` of the energy on the way in and out (sqrt(efficiency) each way).

    Attributes:
        id: name.
        position_m: where it is connected [m].
        tracks: tracks whose contact line and rails it is connected to.
        capacity_j: usable energy [J].
        max_power_w: converter power, charging or discharging [W].
        efficiency: round-trip efficiency [-].
        charge_above_v, discharge_below_v: voltage thresholds [V] (discharge_below_v < charge_above_v).
        ramp_v: width of the power ramps [V].
        initial_soc: state of charge at the start [-].
    """

    id: str
    position_m: float
    tracks: tuple[str, ...]
    capacity_j: float
    max_power_w: float
    efficiency: float
    charge_above_v: float
    discharge_below_v: float
    ramp_v: float = 20.0
    initial_soc: float = 0.5


@dataclass(frozen=True)
class Network:
    """A traction power network.

    Attributes:
        name: name.
        system: ``dc`` or ``ac``.
        limits: the supply system's voltage limits and the trains' limitation thresholds.
        tracks, substations, connections, gaps: see the classes.
        negative_earthed: DC: substation negative busbars solidly earthed (else floating).
        contact_leakage_s: conductance from every contact node to its return [S]; keeps a
            section whose substations all block (diode rectifiers, regenerating trains) solvable.
            Its losses are counted. Default 1e-9 S (0.75 uW at 750 V).
        frequency_hz: AC frequency (informative) [Hz].
        storages: wayside energy storages (DC only).
    """

    name: str
    system: System
    limits: VoltageLimits
    tracks: tuple[Track, ...]
    substations: tuple[Substation, ...]
    connections: tuple[Connection, ...] = ()
    gaps: tuple[Gap, ...] = ()
    negative_earthed: bool = False
    contact_leakage_s: float = 1e-9
    frequency_hz: float = 0.0
    storages: tuple[Storage, ...] = ()
    _topology: Topology | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        problems = validate_network(self)
        if problems:
            raise InputError.from_problems(problems)
        object.__setattr__(self, "_topology", Topology(self))

    @property
    def ideal_return(self) -> bool:
        """Whether the return is the reference (AC, or DC with rail resistance 0 on every track):
        then there are no rail nodes and no rail potentials."""
        return self.system == "ac" or all(t.rail_resistance_ohm_per_m == 0 for t in self.tracks)

    @property
    def topology(self) -> Topology:
        """Fixed nodes and supplied stretches (built once)."""
        assert self._topology is not None
        return self._topology

    def track_index(self, track_id: str) -> int:
        """Index of a track by id (InputError if unknown)."""
        for i, t in enumerate(self.tracks):
            if t.id == track_id:
                return i
        raise InputError(
            "unknown track", field="track", value=track_id, allowed=", ".join(t.id for t in self.tracks)
        )

    def supplied(self, track: int, position_m: np.ndarray) -> np.ndarray:
        """Whether a train on ``track`` at each position is under a live contact line (on the
        track's extent and not inside a neutral section)."""
        return self.topology.supplied(track, position_m)


def _nonneg(
    problems: list[Problem], field_name: str, value: float, strict: bool = False, why: str = ""
) -> None:
    """A problem unless ``value`` is finite and > 0 (``strict``) or >= 0; the message states that
    range, with ``why`` where the range depends on the system (a value refused is never inside the
    range the message gives)."""
    ok = np.isfinite(value) and (value > 0 if strict else value >= 0)
    if not ok:
        bound = "> 0" if strict else ">= 0"
        problems.append(
            Problem(
                f"must be a finite number {bound}",
                field=field_name,
                value=value,
                allowed=f"{bound} ({why})" if why else bound,
            )
        )


def validate_network(net: Network) -> list[Problem]:
    """Everything wrong with a network (empty list if it is fine)."""
    p: list[Problem] = []
    if net.system not in ("dc", "ac"):
        p.append(Problem("unknown system", field="system", value=net.system, allowed="dc, ac"))
    if not net.tracks:
        p.append(Problem("a network needs at least one track", field="tracks", allowed="one or more tracks"))
    if not net.substations:
        p.append(
            Problem("a network needs at least one substation", field="substations", allowed="one or more")
        )
    ids = [t.id for t in net.tracks]
    for i, t in enumerate(net.tracks):
        f = f"tracks[{i}]"
        if ids.count(t.id) > 1:
            p.append(Problem("duplicate track id", field=f"{f}.id", value=t.id, allowed="unique ids"))
        if not (np.isfinite(t.start_m) and np.isfinite(t.end_m) and t.end_m > t.start_m):
            p.append(
                Problem(
                    "track must end after it starts",
                    field=f"{f}.end_km",
                    value=t.end_m / 1000,
                    allowed=f"> start_km = {t.start_m / 1000:g}",
                )
            )
        dc = net.system == "dc"
        _nonneg(
            p,
            f"{f}.contact_resistance_ohm_per_km",
            t.contact_resistance_ohm_per_m * 1000,
            strict=dc,
            why="DC: a contact line has a resistance" if dc else "AC: with resistance or reactance > 0",
        )
        _nonneg(
            p,
            f"{f}.rail_resistance_ohm_per_km",
            t.rail_resistance_ohm_per_m * 1000,
            why="0 on every track: an ideal return" if dc else "AC: not used",
        )
        _nonneg(p, f"{f}.rail_to_earth_conductance_s_per_km", t.rail_to_earth_conductance_s_per_m * 1000)
        _nonneg(p, f"{f}.contact_reactance_ohm_per_km", t.contact_reactance_ohm_per_m * 1000)
        if net.system == "ac" and t.contact_resistance_ohm_per_m == 0 and t.contact_reactance_ohm_per_m == 0:
            p.append(
                Problem(
                    "an AC track needs a loop impedance",
                    field=f"{f}.contact_resistance_ohm_per_km",
                    value=0.0,
                    allowed="resistance or reactance > 0",
                )
            )
    zero_rails = [t.rail_resistance_ohm_per_m == 0 for t in net.tracks]
    if net.system == "dc" and any(zero_rails) and not all(zero_rails):
        k = zero_rails.index(True)
        p.append(
            Problem(
                "rail resistance 0 (ideal return, rails = earth) must hold for every track or none",
                field=f"tracks[{k}].rail_resistance_ohm_per_km",
                value=0.0,
                allowed="> 0 on every track, or 0 on every track",
            )
        )
    by_id = {t.id: t for t in net.tracks}

    def check_on_tracks(f: str, tracks: tuple[str, ...], position: float) -> None:
        for k, tid in enumerate(tracks):
            if tid not in by_id:
                p.append(
                    Problem("unknown track", field=f"{f}.tracks[{k}]", value=tid, allowed=", ".join(ids))
                )
            elif not by_id[tid].end_m > by_id[tid].start_m:
                continue  # the track's own extent is reported already
            elif not by_id[tid].start_m <= position <= by_id[tid].end_m:
                t = by_id[tid]
                p.append(
                    Problem(
                        f"position off track {tid}",
                        field=f"{f}.position_km",
                        value=position / 1000,
                        allowed=f"{t.start_m / 1000} .. {t.end_m / 1000} km",
                    )
                )

    sids = [s.id for s in net.substations]
    for i, s in enumerate(net.substations):
        f = f"substations[{i}]"
        if sids.count(s.id) > 1:
            p.append(Problem("duplicate substation id", field=f"{f}.id", value=s.id, allowed="unique ids"))
        if not s.tracks:
            p.append(Problem("a substation must feed at least one track", field=f"{f}.tracks", value=[]))
        check_on_tracks(f, s.tracks, s.position_m)
        _nonneg(p, f"{f}.no_load_voltage_v", s.no_load_voltage_v, strict=True)
        _nonneg(
            p,
            f"{f}.internal_resistance_ohm",
            s.internal_resistance_ohm,
            strict=net.system == "dc",
            why="DC: a source has an internal resistance"
            if net.system == "dc"
            else "AC: with resistance or reactance > 0",
        )
        _nonneg(p, f"{f}.internal_reactance_ohm", s.internal_reactance_ohm)
        if net.system == "ac" and s.internal_resistance_ohm == 0 and s.internal_reactance_ohm == 0:
            p.append(
                Problem(
                    "an AC substation needs an internal impedance",
                    field=f"{f}.internal_resistance_ohm",
                    value=0.0,
                    allowed="resistance or reactance > 0",
                )
            )
        if s.regulation is not None:
            p.extend(_regulation_problems(f, s, net.system))
        for name in ("rated_power_w", "overload_power_w"):
            v = getattr(s, name)
            if v is not None:
                _nonneg(p, f"{f}.{name.replace('_w', '_kw')}", v / 1000, strict=True)
    for i, c in enumerate(net.connections):
        f = f"connections[{i}]"
        if len(set(c.tracks)) < 2:
            p.append(
                Problem(
                    "a connection joins at least two tracks",
                    field=f"{f}.tracks",
                    value=list(c.tracks),
                    allowed="two or more track ids",
                )
            )
        if c.kind not in ("paralleling_post", "cross_bond"):
            p.append(
                Problem(
                    "unknown connection kind",
                    field=f"{f}.kind",
                    value=c.kind,
                    allowed="paralleling_post, cross_bond",
                )
            )
        if c.kind == "cross_bond" and net.system == "ac":
            p.append(
                Problem(
                    "cross-bonds are DC only (AC rails are the reference)",
                    field=f"{f}.kind",
                    value=c.kind,
                    allowed="paralleling_post",
                )
            )
        check_on_tracks(f, c.tracks, c.position_m)
    for i, g in enumerate(net.gaps):
        f = f"gaps[{i}]"
        if g.track not in by_id:
            p.append(Problem("unknown track", field=f"{f}.track", value=g.track, allowed=", ".join(ids)))
        if not (np.isfinite(g.start_m) and np.isfinite(g.end_m) and g.end_m >= g.start_m):
            p.append(
                Problem(
                    "gap must end at or after its start",
                    field=f"{f}.end_km",
                    value=g.end_m / 1000,
                    allowed=f">= start_km = {g.start_m / 1000}",
                )
            )
        elif g.track in by_id:
            t = by_id[g.track]
            if t.end_m > t.start_m and not t.start_m <= g.start_m <= g.end_m <= t.end_m:
                p.append(
                    Problem(
                        f"gap {g.id} lies off its track {t.id}",
                        field=f"{f}.start_km",
                        value=g.start_m / 1000,
                        allowed=f"start_km .. end_km within {t.start_m / 1000:g} .. {t.end_m / 1000:g} km",
                    )
                )
        for s in net.substations:
            if g.track in s.tracks and g.start_m <= s.position_m <= g.end_m:
                p.append(
                    Problem(
                        f"substation {s.id} feeds inside gap {g.id}",
                        field=f"{f}.start_km",
                        value=g.start_m / 1000,
                        allowed="gaps away from substations",
                    )
                )
        for c in net.connections:
            if g.track in c.tracks and g.start_m <= c.position_m <= g.end_m:
                p.append(
                    Problem(
                        f"connection {c.id} lies inside gap {g.id}",
                        field=f"{f}.start_km",
                        value=g.start_m / 1000,
                        allowed="gaps away from connections",
                    )
                )
    for i, st in enumerate(net.storages):
        f = f"storages[{i}]"
        if net.system != "dc":
            p.append(
                Problem("wayside storage is modelled on DC networks only", field=f, value=st.id, allowed="dc")
            )
        check_on_tracks(f, st.tracks, st.position_m)
        _nonneg(p, f"{f}.capacity_kwh", st.capacity_j / 3.6e6, strict=True)
        _nonneg(p, f"{f}.max_power_kw", st.max_power_w / 1000, strict=True)
        _nonneg(p, f"{f}.ramp_v", st.ramp_v, strict=True)
        if not 0 < st.efficiency <= 1:
            p.append(
                Problem(
                    "invalid efficiency", field=f"{f}.efficiency", value=st.efficiency, allowed="0 < x <= 1"
                )
            )
        if not 0 <= st.initial_soc <= 1:
            p.append(
                Problem(
                    "invalid state of charge",
                    field=f"{f}.initial_soc",
                    value=st.initial_soc,
                    allowed="0 .. 1",
                )
            )
        if not st.discharge_below_v < st.charge_above_v:
            p.append(
                Problem(
                    "the storage must discharge below a lower voltage than it charges above",
                    field=f"{f}.discharge_below_v",
                    value=st.discharge_below_v,
                    allowed=f"< charge_above_v = {st.charge_above_v} V",
                )
            )
        for g in net.gaps:
            if g.track in st.tracks and g.start_m <= st.position_m <= g.end_m:
                p.append(
                    Problem(
                        f"storage {st.id} lies inside gap {g.id}",
                        field=f"{f}.position_km",
                        value=st.position_m / 1000,
                        allowed="away from gaps",
                    )
                )
    _nonneg(p, "contact_leakage_s", net.contact_leakage_s, strict=True)
    if not p:
        p.extend(_connectivity_problems(net))
    return p


def _regulation_problems(f: str, s: Substation, system: str) -> list[Problem]:
    """A regulation curve: DC, finite, current increasing, voltage strictly decreasing (the
    current at a voltage must be unique), through (0, E) with slope R_i."""
    pts = np.asarray(s.regulation, dtype=float)
    field_name = f"{f}.regulation"
    if system != "dc":
        return [Problem("regulation curves are modelled on DC networks", field=field_name, allowed="dc")]
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        return [
            Problem(
                "a regulation curve is a list of at least two finite [current_a, voltage_v] pairs",
                field=field_name,
                allowed="[[0, E], [I1, U1], ...]",
            )
        ]
    i, u = pts[:, 0], pts[:, 1]
    if np.any(np.diff(i) <= 0) or np.any(np.diff(u) >= 0) or np.any(u <= 0):
        return [
            Problem(
                "regulation curve: currents must increase and voltages (> 0) strictly decrease",
                field=field_name,
                value=[list(q) for q in s.regulation],
                allowed="I increasing, U decreasing (a flat segment has no unique current)",
            )
        ]
    try:
        e, r = regulation_points(list(map(tuple, pts)))
    except InputError as exc:
        return [dataclasses.replace(q, field=field_name) for q in exc.problems]
    if not (
        np.isclose(e, s.no_load_voltage_v, rtol=1e-12) and np.isclose(r, s.internal_resistance_ohm, rtol=1e-9)
    ):
        return [
            Problem(
                "regulation curve disagrees with the substation's no-load voltage / internal resistance",
                field=field_name,
                value=f"E = {e} V, R_i = {r} ohm",
                allowed=f"E = {s.no_load_voltage_v} V and R_i = {s.internal_resistance_ohm} ohm "
                "(give them from trainsim.power.network.regulation_points)",
            )
        ]
    return []


def _stretches(net: Network, ti: int) -> list[tuple[float, float]]:
    """The live stretches of a track's contact line, split at its gaps: [(a, b)] in order."""
    t = net.tracks[ti]
    gaps = sorted((g.start_m, g.end_m) for g in net.gaps if g.track == t.id)
    out = []
    a = t.start_m
    for g0, g1 in gaps:
        if g1 < t.start_m or g0 > t.end_m:
            continue
        if g0 > a or (g0 == a == g1):
            out.append((a, max(g0, a)))
        a = max(a, g1)
    out.append((a, t.end_m))
    return [(x, y) for x, y in out if y > x or (x == y == t.start_m == t.end_m)]


def _stretch_of(stretches: list[tuple[float, float]], x: float) -> int:
    """Index of the stretch holding x (a section insulator at x belongs to the stretch on its right,
    matching the per-step assembly), or -1."""
    for k, (a, b) in enumerate(stretches):
        if a <= x < b or (x == b and k == len(stretches) - 1):
            return k
    return -1


def _connectivity_problems(net: Network) -> list[Problem]:
    """Every live stretch of contact line must reach a substation; every track's rails too (DC)."""
    parent: dict = {}

    def find(a):
        parent.setdefault(a, a)
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    def union(a, b):
        parent[find(a)] = find(b)

    stretches = [_stretches(net, i) for i in range(len(net.tracks))]
    index = {t.id: i for i, t in enumerate(net.tracks)}
    for ti, st in enumerate(stretches):
        for k in range(len(st)):
            find(("c", ti, k))
        find(("r", ti))
    for s in net.substations:
        for tid in s.tracks:
            ti = index[tid]
            union(("c", ti, _stretch_of(stretches[ti], s.position_m)), ("sub", s.id))
            union(("r", ti), ("neg", s.id))
    for c in net.connections:
        for tid in c.tracks[1:]:
            a, b = index[c.tracks[0]], index[tid]
            if c.kind == "paralleling_post":
                union(
                    ("c", a, _stretch_of(stretches[a], c.position_m)),
                    ("c", b, _stretch_of(stretches[b], c.position_m)),
                )
            else:
                union(("r", a), ("r", b))
    fed = {find(("sub", s.id)) for s in net.substations}
    neg = {find(("neg", s.id)) for s in net.substations}
    problems = []
    for ti, st in enumerate(stretches):
        for k, (a, b) in enumerate(st):
            if find(("c", ti, k)) not in fed:
                problems.append(
                    Problem(
                        f"disconnected network: the contact line of track {net.tracks[ti].id} from "
                        f"{a / 1000:g} km to {b / 1000:g} km reaches no substation",
                        field="substations",
                        allowed="every feeding section fed by a substation or a paralleling post",
                    )
                )
        if not net.ideal_return and find(("r", ti)) not in neg:
            problems.append(
                Problem(
                    f"disconnected network: the rails of track {net.tracks[ti].id} reach no substation negative",
                    field="substations",
                    allowed="every track fed by a substation or cross-bonded to one",
                )
            )
    return problems


class Topology:
    """The fixed part of the network: node ids of substations and connections, and the live
    stretches of each track (used to place trains and cut contact segments).

    Node numbering: each fixed point (substation, connection) of each track gets a contact node
    and a rail node; points joined by a substation (contact and rails of the tracks it feeds), a
    paralleling post (contacts) or a cross-bond (rails) share the node. ``-1`` is earth (AC returns,
    earthed DC negatives).
    """

    def __init__(self, net: Network) -> None:
        self.net = net
        self.stretches = [_stretches(net, i) for i in range(len(net.tracks))]
        index = {t.id: i for i, t in enumerate(net.tracks)}
        n_tracks = len(net.tracks)
        points: list[list[float]] = [[t.start_m, t.end_m] for t in net.tracks]
        for s in net.substations:
            for tid in s.tracks:
                points[index[tid]].append(s.position_m)
        for c in net.connections:
            for tid in c.tracks:
                points[index[tid]].append(c.position_m)
        for st in net.storages:
            for tid in st.tracks:
                points[index[tid]].append(st.position_m)
        self.fixed_positions = [np.unique(np.asarray(pts, dtype=float)) for pts in points]
        # union-find over (layer, track, point index)
        parent: dict = {}

        def find(a):
            parent.setdefault(a, a)
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        def union(a, b):
            parent[find(a)] = find(b)

        def pidx(ti: int, x: float) -> int:
            return int(np.searchsorted(self.fixed_positions[ti], x))

        for ti in range(n_tracks):
            for k in range(len(self.fixed_positions[ti])):
                find(("c", ti, k))
                find(("r", ti, k))
        for s in net.substations:
            tis = [index[tid] for tid in s.tracks]
            for ti in tis:
                union(("c", tis[0], pidx(tis[0], s.position_m)), ("c", ti, pidx(ti, s.position_m)))
                union(("r", tis[0], pidx(tis[0], s.position_m)), ("r", ti, pidx(ti, s.position_m)))
        for st in net.storages:
            tis = [index[tid] for tid in st.tracks]
            for ti in tis:
                union(("c", tis[0], pidx(tis[0], st.position_m)), ("c", ti, pidx(ti, st.position_m)))
                union(("r", tis[0], pidx(tis[0], st.position_m)), ("r", ti, pidx(ti, st.position_m)))
        for c in net.connections:
            layer = "c" if c.kind == "paralleling_post" else "r"
            tis = [index[tid] for tid in c.tracks]
            for ti in tis:
                union((layer, tis[0], pidx(tis[0], c.position_m)), (layer, ti, pidx(ti, c.position_m)))
        roots: dict = {}
        ac = net.ideal_return
        self.contact_ids: list[np.ndarray] = []
        self.rail_ids: list[np.ndarray] = []
        for ti in range(n_tracks):
            cids, rids = [], []
            for k in range(len(self.fixed_positions[ti])):
                cids.append(roots.setdefault(find(("c", ti, k)), len(roots)))
                if ac:
                    rids.append(-1)
                else:
                    rids.append(roots.setdefault(find(("r", ti, k)), len(roots)))
            self.contact_ids.append(np.asarray(cids, dtype=np.int64))
            self.rail_ids.append(np.asarray(rids, dtype=np.int64))
        self.n_fixed = len(roots)
        self.substation_nodes = []
        for s in net.substations:
            ti = index[s.tracks[0]]
            k = pidx(ti, s.position_m)
            self.substation_nodes.append((int(self.contact_ids[ti][k]), int(self.rail_ids[ti][k])))
        self.storage_nodes = []
        for st in net.storages:
            ti = index[st.tracks[0]]
            k = pidx(ti, st.position_m)
            self.storage_nodes.append((int(self.contact_ids[ti][k]), int(self.rail_ids[ti][k])))
        # earth: earthed negatives are the reference; floating rails without leakage get one reference
        # node per rail group (rail potentials are then not defined)
        self.earthed: set[int] = set()
        self.rail_potential_defined = not ac
        if not ac:
            if net.negative_earthed:
                self.earthed = {rn for _, rn in self.substation_nodes}
            elif all(t.rail_to_earth_conductance_s_per_m == 0 for t in net.tracks):
                self.rail_potential_defined = False
                self.earthed = {
                    self.substation_nodes[si][1] for si in _first_substation_per_rail_group(net, index)
                }
        #: (start_m, end_m) of every track, as arrays (each step's loads are checked against them)
        self.extents_m = (
            np.array([t.start_m for t in net.tracks], dtype=float),
            np.array([t.end_m for t in net.tracks], dtype=float),
        )
        # gaps per track as arrays
        self.gap_starts = []
        self.gap_ends = []
        for t in net.tracks:
            gs = sorted((g.start_m, g.end_m) for g in net.gaps if g.track == t.id)
            self.gap_starts.append(np.asarray([g[0] for g in gs], dtype=float))
            self.gap_ends.append(np.asarray([g[1] for g in gs], dtype=float))

    def supplied(self, ti: int, x: np.ndarray) -> np.ndarray:
        """Whether positions x on track ti are under a live contact line."""
        x = np.asarray(x, dtype=float)
        t = self.net.tracks[ti]
        ok = (x >= t.start_m) & (x <= t.end_m)
        for a, b in zip(self.gap_starts[ti], self.gap_ends[ti], strict=True):
            if b > a:
                ok &= ~((x > a) & (x < b))
        return ok

    def segment_cut(self, ti: int, x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
        """Whether the contact segments (x0, x1) of track ti cross a gap (x0 < x1)."""
        cut = np.zeros(len(x0), dtype=bool)
        for a, b in zip(self.gap_starts[ti], self.gap_ends[ti], strict=True):
            if b > a:
                cut |= (x0 < b) & (x1 > a)
            else:
                cut |= (x0 < a) & (x1 >= a)
        return cut


def _first_substation_per_rail_group(net: Network, index: dict[str, int]) -> list[int]:
    """Index of the first substation of each group of tracks whose rails are joined (by a
    substation feeding several tracks or by cross-bonds)."""
    group = list(range(len(net.tracks)))

    def find(a: int) -> int:
        while group[a] != a:
            group[a] = group[group[a]]
            a = group[a]
        return a

    joins = [s.tracks for s in net.substations] + [
        c.tracks for c in net.connections if c.kind == "cross_bond"
    ]
    for tracks in joins:
        for tid in tracks[1:]:
            group[find(index[tid])] = find(index[tracks[0]])
    first: dict[int, int] = {}
    for si, s in enumerate(net.substations):
        first.setdefault(find(index[s.tracks[0]]), si)
    return sorted(first.values())
