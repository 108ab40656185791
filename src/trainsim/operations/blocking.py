"""Blocking times, minimum headways and capacity consumption (UIC 406 compression).

The blocking time of a route for one train (Pachl, *Railway Operation and Control*, 4th ed. 2018,
section 4.2; UIC Code 406, 2nd ed. 2013, section 4) is the time the route is reserved for it:

    setup + sight and reaction + approach + occupation + clearing + release

* the route is set ``setup_s`` before the driver must see a proceed aspect, and the driver needs
  ``reaction_s`` besides the sighting distance; the **approach** starts where the train's head must see
  the first aspect that would make it brake for the route's signal: the distant signal (2 aspects),
  the previous (3 aspects) or second previous (4 aspects) main signal, each minus the sighting
  distance; with ETCS Level 2 the indication point of a movement authority ending at the route's
  entry; with moving block the service braking distance plus the safety margin before the route's
  entry. A train that stands (stops) between that point and the signal sees the signal when it
  departs, so its approach starts at its departure;
* the **occupation** lasts until the head reaches the end of the route (next signal plus overlap;
  with train detection points the overlap ends at one, ``line.overlap_end_m``, set on each route),
  the **clearing** until the rear has passed it (train length), and the resource is released
  ``release_s`` later (sectional release: each resource when the rear has passed its own end;
  whole-route release: all when the rear has passed the route's end).

The minimum headway between two trains is the smallest time between them at which no resource is
claimed by both at once (the blocking-time stairs touch at the *critical* resource). UIC 406's
compression pushes the trains of a timetable pattern together to their minimum headways; the
compressed span over the pattern period is its capacity consumption.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from trainsim.operations.line import DirectionPath, Route, Signalling


@dataclass(frozen=True)
class Trajectory:
    """Where a train's head is over time, in the running coordinate of its direction.

    Attributes:
        time_s: time, non-decreasing [s].
        position_m: head position, non-decreasing [m] (repeated positions are stops).
        speed_mps: speed [m/s].
        length_m: train length [m].
    """

    time_s: np.ndarray
    position_m: np.ndarray
    speed_mps: np.ndarray
    length_m: float

    def first_time_at(self, x_m: float | np.ndarray) -> np.ndarray:
        """The first time the head reaches ``x_m`` [s]; before the start: the start time; beyond the
        end: ``inf``.

        Between two trace points the acceleration is taken as constant (exact for the constant-speed
        and constant-acceleration pieces of a run): ``t = t0 + 2 dx / (v0 + v(x))`` with
        ``v(x)^2 = v0^2 + (v1^2 - v0^2) dx / ds``.
        """
        s, t, v = self.position_m, self.time_s, self.speed_mps
        if isinstance(x_m, float | int):
            return np.array([self.first_time_s(float(x_m))])
        x = np.atleast_1d(np.asarray(x_m, dtype=float))
        i = np.searchsorted(s, x, side="left")
        out = np.empty_like(x)
        before = i == 0
        beyond = i >= len(s)
        out[before] = t[0]
        out[beyond] = np.inf
        mid = ~(before | beyond)
        k = i[mid]
        s0, s1, t0, t1, v0, v1 = s[k - 1], s[k], t[k - 1], t[k], v[k - 1], v[k]
        ds = s1 - s0
        dx = x[mid] - s0
        frac = np.where(ds > 0, dx / np.where(ds > 0, ds, 1.0), 1.0)
        vx = np.sqrt(np.maximum(v0 * v0 + (v1 * v1 - v0 * v0) * frac, 0.0))
        vsum = v0 + vx
        kin = t0 + np.where(vsum > 1e-9, 2.0 * dx / np.where(vsum > 1e-9, vsum, 1.0), 0.0)
        lin = t0 + frac * (t1 - t0)
        # the kinematic form is only trusted where it stays inside the step
        ok = (vsum > 1e-9) & (kin >= t0 - 1e-9) & (kin <= t1 + 1e-9)
        out[mid] = np.where(ok, kin, lin)
        return out

    def first_time_s(self, x: float) -> float:
        """``first_time_at`` for one position ``x`` [m], as a float [s] (most calls of the
        dispatcher): the same arithmetic without the arrays."""
        x = float(x)
        s = self.position_m
        i = int(s.searchsorted(x, side="left"))
        if i == 0:
            return float(self.time_s[0])
        if i >= len(s):
            return float("inf")
        s0, s1 = float(s[i - 1]), float(s[i])
        t0, t1 = float(self.time_s[i - 1]), float(self.time_s[i])
        v0, v1 = float(self.speed_mps[i - 1]), float(self.speed_mps[i])
        ds, dx = s1 - s0, x - s0
        frac = dx / ds if ds > 0 else 1.0
        vx = max(v0 * v0 + (v1 * v1 - v0 * v0) * frac, 0.0) ** 0.5
        if v0 + vx > 1e-9:
            kin = t0 + 2.0 * dx / (v0 + vx)
            if t0 - 1e-9 <= kin <= t1 + 1e-9:
                return kin
        return t0 + frac * (t1 - t0)

    def last_time_at(self, x_m: float) -> float:
        """The last time the head is at ``x_m`` (the departure if the train stops there) [s]."""
        s, t = self.position_m, self.time_s
        j = int(s.searchsorted(x_m, side="right")) - 1
        if j >= 0 and abs(s[j] - x_m) < 1e-9:
            return float(t[j])
        return self.first_time_s(float(x_m))

    def speed_at(self, x_m: float) -> float:
        """Speed where the head first reaches ``x_m`` (linear in position) [m/s]."""
        return float(np.interp(x_m, self.position_m, self.speed_mps))

    def max_speed_between(self, a_m: float, b_m: float) -> float:
        """Highest speed of the head between ``a_m`` and ``b_m`` [m/s]."""
        m = (self.position_m >= a_m) & (self.position_m <= b_m)
        inner = self.speed_mps[m]
        ends = [self.speed_at(a_m), self.speed_at(b_m)]
        return float(max(ends + ([float(inner.max())] if inner.size else [])))

    def shifted(self, dt_s: float) -> Trajectory:
        """The same trajectory ``dt_s`` later [s]."""
        return Trajectory(self.time_s + dt_s, self.position_m, self.speed_mps, self.length_m)


@dataclass(frozen=True)
class BlockingTime:
    """The blocking time of one resource of one route for one train (times in s, positions on the line
    in m).

    ``start_s`` = ``approach_s - reaction - setup``; ``approach_s`` when the head passes the approach
    start (or departs from a stop within the approach); ``entry_s`` when it passes the route's signal;
    ``clear_s`` when the rear has passed the resource's release point; ``end_s`` = ``clear_s + release``.
    """

    train: str
    route: str
    resource: str
    step: int
    start_s: float
    approach_s: float
    entry_s: float
    clear_s: float
    end_s: float
    from_m: float
    to_m: float


_new = object.__new__


def blocking_time(
    train: str,
    route: str,
    resource: str,
    step: int,
    start_s: float,
    approach_s: float,
    entry_s: float,
    clear_s: float,
    end_s: float,
    from_m: float,
    to_m: float,
) -> BlockingTime:
    """``BlockingTime(...)`` without the frozen dataclass's ``__init__``, which sets each of its 11
    fields through ``object.__setattr__`` (twice as slow): a day of 1,000 trains makes some 150,000."""
    b = _new(BlockingTime)
    d = b.__dict__
    d["train"], d["route"], d["resource"], d["step"] = train, route, resource, step
    d["start_s"], d["approach_s"], d["entry_s"], d["clear_s"] = start_s, approach_s, entry_s, clear_s
    d["end_s"], d["from_m"], d["to_m"] = end_s, from_m, to_m
    return b


@dataclass(frozen=True)
class Headway:
    """Minimum headway between a leading and a following train.

    ``min_headway_s`` is the smallest time between their reference times (departures from their
    origins) at which the follower's blocking times nowhere overlap the leader's; ``critical_route`` and
    ``critical_resource`` are where the stairs touch; ``planned_headway_s`` is their actual difference and
    ``buffer_s`` = planned - minimum (negative: a conflict).
    """

    leader: str
    follower: str
    min_headway_s: float
    critical_route: str
    critical_resource: str
    planned_headway_s: float
    buffer_s: float

    def to_dict(self) -> dict[str, object]:
        return {
            "leader": self.leader,
            "follower": self.follower,
            "min_headway_s": round(self.min_headway_s, 3),
            "critical_block": self.critical_route,
            "critical_resource": self.critical_resource,
            "planned_headway_s": round(self.planned_headway_s, 3),
            "buffer_s": round(self.buffer_s, 3),
        }


def braking_distance_table(
    deceleration_mps2: Callable[[np.ndarray], np.ndarray], v_max_mps: float
) -> Callable[[float], float]:
    """Service braking distance from speed ``v`` to rest, ``D(v) = integral_0^v u / a(u) du`` [m], for a
    deceleration law ``a(u)`` [m/s^2] (kinematics; Pachl section 2.3), tabulated up to ``v_max_mps``."""
    v = np.linspace(0.0, max(v_max_mps, 1.0) * 1.05, 400)
    a = np.maximum(np.asarray(deceleration_mps2(v), dtype=float), 1e-6)
    integrand = v / a
    d = np.concatenate([[0.0], np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(v))])

    v2 = v * v

    def distance(speed_mps: float) -> float:
        # linear in v^2 between the table's points: exact for a constant deceleration
        return float(np.interp(speed_mps * speed_mps, v2, d))

    return distance


def approach_start_m(
    path: DirectionPath,
    step: int,
    signalling: Signalling,
    trajectory: Trajectory | None = None,
    approach_distance_m: Callable[[float], float] | None = None,
) -> float:
    """Where the approach to route step ``step`` of ``path`` starts (running coordinate) [m].

    Fixed block: the distant signal (``distant_distance_m`` before the main signal) for 2 aspects, the
    previous main signal for 3, the second previous for 4, minus the sighting distance. ETCS L2 and
    moving block: the signal (block marker, or the start of the virtual section) minus
    ``approach_distance_m(v)`` at the train's speed there, found by fixed-point iteration on the
    highest speed of the trajectory over the approach (moving block adds the safety margin). A function
    with an ``at_eoa(x)`` method (``separation.EtcsApproach`` on the line's gradients) is asked for the
    distance of an EoA at the signal ``x``.
    """
    sig = signalling
    x = path.steps[step].start_m
    if sig.system == "fixed_block":
        if sig.aspects == 2:
            return x - sig.distant_distance_m - sig.sighting_distance_m
        back = sig.aspects - 2
        if step - back >= 0:
            return path.steps[step - back].start_m - sig.sighting_distance_m
        # before the first signal of the direction: the warning is given by a distant signal
        return x - back * sig.distant_distance_m - sig.sighting_distance_m
    if trajectory is None or approach_distance_m is None:
        raise ValueError("ETCS and moving block need the train's trajectory and approach distance")
    margin = sig.safety_margin_m if sig.system == "moving_block" else 0.0
    at_eoa = getattr(approach_distance_m, "at_eoa", None)
    if at_eoa is not None:
        # ETCS on the line's gradients: the MA would end at this route's start
        approach_distance_m = at_eoa(x)
    p = x - margin - approach_distance_m(trajectory.speed_at(x))
    for _ in range(4):
        q = x - margin - approach_distance_m(trajectory.max_speed_between(p, x))
        if abs(q - p) < 1e-6:
            break
        p = min(p, q)
    return p


#: route_release_points by (id(route), release): (route, points); keyed by id because hashing a
#: route hashes all its resources, on every call of the dispatcher
_RELEASE_POINTS: dict[tuple[int, str], tuple[Route, tuple[float, ...]]] = {}


def route_release_points(route: Route, release: str) -> tuple[float, ...]:
    """Release point of each resource of ``route`` (running coordinate) [m]: its end, or the route's
    end plus overlap for the resource that reaches the route's end; with whole-route release, the
    farthest of them for all."""
    found = _RELEASE_POINTS.get((id(route), release))
    if found is not None and found[0] is route:
        return found[1]
    if len(_RELEASE_POINTS) > 65536:
        _RELEASE_POINTS.clear()
    points = _release_points(route, release)
    _RELEASE_POINTS[(id(route), release)] = (route, points)
    return points


def _release_points(route: Route, release: str) -> tuple[float, ...]:
    route_end = route.end_m + route.overlap_m
    points = [max(r.end_m, route_end) if r.end_m >= route.end_m - 1e-9 else r.end_m for r in route.resources]
    if release == "whole_route":
        far = max(points)
        points = [far] * len(points)
    return tuple(points)


def blocking_times(
    train_id: str,
    trajectory: Trajectory,
    path: DirectionPath,
    steps: Sequence[tuple[int, Route]],
    stops_m: Sequence[float],
    signalling: Signalling,
    line_position: Callable[[np.ndarray], np.ndarray] | None = None,
    approach_distance_m: Callable[[float], float] | None = None,
    given_at: Mapping[str, float] | None = None,
    released: Mapping[tuple[str, str], float] | None = None,
) -> list[BlockingTime]:
    """The blocking times of every resource of every route a train takes.

    Args:
        train_id: the train's id.
        trajectory: its head over time (running coordinate).
        path: its direction's path (for the signals that give the warning).
        steps: the routes it takes, each with its step index in ``path``.
        stops_m: where it stands (origin, stops, signal stops) [m]; a stop inside an approach moves the
            approach start to the departure from that stop.
        signalling: the times and distances of the model.
        line_position: maps running coordinates (an array) to line positions (for ``from_m``/``to_m``);
            None: the same.
        approach_distance_m: ETCS / moving block: approach distance over speed [m].
        given_at, released: a dispatcher's own times [s]: when each route (by name) was given, the
            start instead of the one from the trajectory; when each resource (route, resource) was
            released, the end instead (and the clearing ``release_s`` before it).
    """
    sig = signalling
    if not steps:
        return []
    stops = sorted(float(x) for x in stops_m)
    length = trajectory.length_m
    n = len(steps)
    approach = np.empty(n)
    stand = [None] * n
    for k, (j, route) in enumerate(steps):
        a = approach_start_m(path, j, sig, trajectory, approach_distance_m)
        approach[k] = a
        # the last stop before the signal, if it lies inside the approach
        i = bisect_left(stops, route.start_m)
        if i > 0 and stops[i - 1] >= a - 1e-9:
            stand[k] = stops[i - 1]
    starts = np.array([route.start_m for _j, route in steps])
    points = [route_release_points(route, sig.release) for _j, route in steps]
    flat = np.array([p for ps in points for p in ps]) + length
    # one call for the three sets of positions (element by element the same as three)
    times = trajectory.first_time_at(np.concatenate([approach, starts, flat]))
    t_pass, entries, clears = times[:n].tolist(), times[n : 2 * n].tolist(), times[2 * n :]
    t_see = [t_pass[k] if q is None else trajectory.last_time_at(q) for k, q in enumerate(stand)]
    # a train leaves the line at the end of its trajectory (its destination, after the dwell there)
    clears = np.where(np.isfinite(clears), clears, trajectory.time_s[-1]).tolist()
    ends = flat - length
    if line_position is not None:
        starts, ends = (
            np.asarray(line_position(starts), dtype=float),
            np.asarray(line_position(ends), dtype=float),
        )
    starts, ends = starts.tolist(), ends.tolist()
    out: list[BlockingTime] = []
    c = 0
    release_s = sig.release_s
    for k, (j, route) in enumerate(steps):
        see = float(t_see[k])
        start = see - sig.reaction_s - sig.setup_s
        if given_at is not None:
            start = given_at.get(route.name, start)
        lo, entry = starts[k], entries[k]
        for res in route.resources:
            clear = clears[c]
            end = clear + release_s
            if released is not None:
                end = released.get((route.name, res.name), end)
                clear = end - release_s
            out.append(
                blocking_time(train_id, route.name, res.name, j, start, see, entry, clear, end, lo, ends[c])
            )
            c += 1
    return out


def _by_resource(times: Sequence[BlockingTime]) -> dict[str, tuple[float, float, str]]:
    d: dict[str, tuple[float, float, str]] = {}
    for b in times:
        if b.resource in d:
            s0, e0, r0 = d[b.resource]
            d[b.resource] = (min(s0, b.start_s), max(e0, b.end_s), r0)
        else:
            d[b.resource] = (b.start_s, b.end_s, b.route)
    return d


def required_shift(
    leader: Sequence[BlockingTime], follower: Sequence[BlockingTime]
) -> tuple[float, str, str]:
    """The smallest shift of the follower's times after which none of its blocking times overlaps the
    leader's: ``max over shared resources of (end_leader - start_follower)`` [s], with the critical route
    (the follower's) and resource; ``-inf`` and empty names when they share no resource."""
    lead = _by_resource(leader)
    best, route, resource = -np.inf, "", ""
    for name, (start, _end, r) in _by_resource(follower).items():
        if name in lead:
            need = lead[name][1] - start
            if need > best:
                best, route, resource = need, r, name
    return float(best), route, resource


def minimum_headway(
    leader_id: str,
    leader: Sequence[BlockingTime],
    leader_ref_s: float,
    follower_id: str,
    follower: Sequence[BlockingTime],
    follower_ref_s: float,
) -> Headway | None:
    """Minimum headway between two trains from their blocking times (Pachl section 4.2.3).

    The reference times (e.g. departures from their origins) define the headway: the follower's
    blocking times may move by ``required_shift``, so the minimum headway is
    ``(follower_ref - leader_ref) + shift``. None when the trains share no resource.
    """
    shift, route, resource = required_shift(leader, follower)
    if not np.isfinite(shift):
        return None
    planned = follower_ref_s - leader_ref_s
    return Headway(leader_id, follower_id, planned + shift, route, resource, planned, -shift)


@dataclass(frozen=True)
class CapacityConsumption:
    """UIC 406 compression of a timetable pattern.

    Attributes:
        occupation_s: compressed occupation time: from the first train's compressed position to the
            first train of the next pattern at its minimum headway [s].
        period_s: the pattern's period [s].
        consumption: occupation / period [-].
        offsets_s: compressed blocking start of each train relative to the first train's [s].
    """

    occupation_s: float
    period_s: float
    consumption: float
    offsets_s: tuple[float, ...]

    def to_dict(self) -> dict[str, object]:
        return {
            "occupation_s": round(self.occupation_s, 3),
            "period_s": self.period_s,
            "consumption_percent": round(100 * self.consumption, 2),
            "offsets_s": [round(x, 3) for x in self.offsets_s],
        }


def compression(
    pattern: Sequence[Sequence[BlockingTime]], period_s: float, resources: set[str] | None = None
) -> CapacityConsumption:
    """UIC 406 (2013) compression of a timetable pattern that repeats every ``period_s`` [s].

    The trains keep their order; each is moved as close as its blocking times allow to *every* earlier
    train (not only the one before it), ``c_k = max_{j<k} (c_j + shift_jk)`` with ``c_0 = 0``; the
    occupation time closes the cycle with the first train of the next pattern,
    ``max_j (c_j + shift_j0)``. ``resources`` restricts the compression to a line section.
    """
    if not pattern:
        raise ValueError("an empty pattern")
    trains = [[b for b in t if resources is None or b.resource in resources] for t in pattern]
    n = len(trains)
    shifts = np.array([[required_shift(trains[j], trains[k])[0] for k in range(n)] for j in range(n)])
    c = [0.0]
    for k in range(1, n):
        c.append(max([c[j] + shifts[j, k] for j in range(k) if np.isfinite(shifts[j, k])], default=c[-1]))
    closing = [c[j] + shifts[j, 0] for j in range(n) if np.isfinite(shifts[j, 0])]
    if not closing:
        raise ValueError("the pattern's first train claims no resource of the section")
    occupation = max(closing)
    # compressed blocking start of each train relative to the first one's
    first = [min((b.start_s for b in t), default=0.0) for t in trains]
    offsets = tuple(float(c[k] + first[k] - first[0]) for k in range(n))
    return CapacityConsumption(float(occupation), float(period_s), float(occupation / period_s), offsets)
