"""Running the multi-point model: following a speed profile (the fastest run of the single-point model,
or any profile, e.g. an optimizer's), and driving by command step by step.

The strategies are those of the single-point model:

* :func:`run_multipoint_fastest`: the single-point fastest run gives, over head position, the regime
  (traction, cruising, coasting, braking) and the speed; a controller drives the multi-point train with
  the same regimes and force limits: full traction up to the speed ceiling, the holding force plus a
  speed correction when cruising, full service braking from the same braking points (earlier by the
  mean brake delay if the brake command propagates along the train), easing off when below the braking
  curve. Stops are served when the train is at rest with its head within ``stop_window_m`` of the stop.
* :func:`follow_profile`: the same controller on a given speed profile, following its speed in
  traction as well.
* :class:`MultiPointSession`: ``step(command, dt_s)`` as ``trainsim.DrivingSession``, optionally with
  one command per locomotive (independent distributed power).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.multipoint import kernel as mpk
from trainsim.multipoint.model import MultiPointSettings, MultiPointTrain, build_multipoint_train
from trainsim.multipoint.result import MultiPointResult, build_multipoint_result
from trainsim.sim.codes import BRAKE, COAST, CRUISE, DWELL, TRACTION
from trainsim.sim.fastest import run_fastest
from trainsim.sim.profile import (
    PiecewiseLinear,
    averaged_over_length,
    line_resistance_profile,
    speed_ceiling,
    traction_availability,
)
from trainsim.sim.result import RunResult

if TYPE_CHECKING:
    from trainsim.optimize.api import OptimizationResult

#: Newton tolerance on the midpoint speeds [m/s]: far below any physical meaning, far above round-off.
NEWTON_TOLERANCE_MPS = 1e-9
#: The train is at rest when its mean speed is below this and no vehicle is faster than 10 x this [m/s].
REST_SPEED_MPS = 5e-3
#: At rest with full traction for this long: the train has stalled [s].
STALL_TIME_S = 60.0
#: A segment may take this many times the reference's time (plus a margin) before it is given up.
SEGMENT_TIME_FACTOR = 3.0
SEGMENT_TIME_MARGIN_S = 600.0


@dataclass(frozen=True)
class SpeedProfile:
    """A speed profile over head position between stops, for :func:`follow_profile`.

    Attributes:
        position_m: head positions, non-decreasing [m].
        speed_mps: speed at each position [m/s].
        regime: regime of the stretch from each point to the next (``trainsim.sim.codes``
            TRACTION, CRUISE, COAST, BRAKE, DWELL; a DWELL point is the arrival at a stop); None: read
            from the speed (rising: traction, falling: braking, flat: cruising; arrivals where the speed
            is 0 after the start).
        time_s: time at each point [s] (used for the dwell times: the time from an arrival to the
            next point); None: the dwell times of the route's stations.
    """

    position_m: np.ndarray
    speed_mps: np.ndarray
    regime: np.ndarray | None = None
    time_s: np.ndarray | None = None

    @classmethod
    def from_result(cls, result: RunResult) -> SpeedProfile:
        """The profile of a single-point run (fastest, driven or optimised)."""
        tr = result.trace
        return cls(tr.position_m, tr.speed_mps, tr.regime, tr.time_s)


@dataclass(frozen=True)
class _Segment:
    s: np.ndarray
    v2: np.ndarray
    regime: np.ndarray
    stop_m: float
    dwell_s: float
    duration_s: float
    is_stop: bool


def _segments(profile: SpeedProfile, route: Route) -> list[_Segment]:
    """Split a profile into runs between stops."""
    s = np.asarray(profile.position_m, dtype=float)
    v = np.asarray(profile.speed_mps, dtype=float)
    if len(s) < 2 or s.shape != v.shape or np.any(np.diff(s) < -1e-9) or np.any(v < 0):
        raise InputError(
            "a speed profile needs at least two points, non-decreasing positions and speeds >= 0",
            field="profile",
        )
    if profile.regime is not None:
        regime = np.asarray(profile.regime, dtype=np.int8)
    else:
        dv = np.diff(v)
        regime = np.where(dv > 1e-6, TRACTION, np.where(dv < -1e-6, BRAKE, CRUISE)).astype(np.int8)
        regime = np.concatenate([regime, [DWELL]]).astype(np.int8)
        arrivals = (v == 0.0) & (np.arange(len(v)) > 0)
        regime[arrivals] = DWELL
    t = np.asarray(profile.time_s, dtype=float) if profile.time_s is not None else None
    stations = {round(st.position_m, 3): st for st in route.stations}
    out: list[_Segment] = []
    a = 0
    n = len(s)
    while a < n - 1:
        # skip dwell points at the start of a segment
        while a < n - 1 and regime[a] == DWELL and s[a + 1] - s[a] < 1e-9:
            a += 1
        b = a + 1
        while b < n - 1 and regime[b] != DWELL:
            b += 1
        if b <= a:
            break
        seg_s = s[a : b + 1].copy()
        seg_m = regime[a : b + 1].copy()
        seg_v2 = v[a : b + 1] ** 2
        is_stop = regime[b] == DWELL
        # dwell: time to the next departure point
        d = b
        while d < n - 1 and regime[d] == DWELL:
            d += 1
        if t is not None:
            dwell = float(t[d] - t[b]) if d > b else 0.0
            duration = float(t[b] - t[a])
        else:
            st = stations.get(round(float(s[b]), 3))
            dwell = st.dwell_s if st is not None and d < n - 1 else 0.0
            vm = np.maximum(np.sqrt(0.5 * (seg_v2[1:] + seg_v2[:-1])), 0.5)
            duration = float(np.sum(np.diff(seg_s) / vm))
        out.append(_Segment(seg_s, seg_v2, seg_m, float(s[b]), dwell, duration, bool(is_stop)))
        a = d
        if d == b:
            break
    return out


# ============================================================================ compiled arrays
def _curve_bank(curves: Sequence) -> tuple[np.ndarray, ...]:
    starts, coefs, offs, fcap, pcap = [], [], [0], [], []
    for c in curves:
        s, co, fc, pc = c.as_arrays()
        starts.append(s)
        coefs.append(co)
        offs.append(offs[-1] + len(s))
        fcap.append(fc)
        pcap.append(pc)
    return (
        np.ascontiguousarray(np.concatenate(starts)),
        np.ascontiguousarray(np.concatenate(coefs).reshape(-1, 4)),
        np.array(offs, dtype=np.int64),
        np.array(fcap, dtype=float),
        np.array(pcap, dtype=float),
    )


def _merged(functions: Sequence[PiecewiseLinear]) -> tuple[np.ndarray, np.ndarray]:
    """Continuous piecewise linear functions on a common grid of nodes: (nodes, values n x k)."""
    nodes = np.unique(np.concatenate([f.x for f in functions]))
    if len(nodes) < 2:
        nodes = np.array([nodes[0], nodes[0] + 1.0])
    return nodes, np.column_stack([f(nodes) for f in functions])


class _Compiled:
    """The arrays the kernel reads, for one multi-point train on one route."""

    def __init__(self, mp: MultiPointTrain, route: Route, run_settings: RunSettings) -> None:
        train = mp.train
        settings = mp.settings
        n = mp.n_vehicles
        self.mp = mp
        self.route = route
        self.run_settings = run_settings
        # line resistance at points, averaged over each vehicle's own length
        point_route = dataclasses.replace(
            route, line_resistance=dataclasses.replace(route.line_resistance, apply_over="head")
        )
        point = line_resistance_profile(point_route, train)
        self.profile = line_resistance_profile(route, train)  # the single-point view, for the summary
        self.ceiling = speed_ceiling(route, train)
        lengths = sorted(set(np.round(mp.length_m, 9)))
        poff, pxs, pvals = [0], [], []
        prof_of_length = {}
        for k, L in enumerate(lengths):
            fs = [
                averaged_over_length(f, L)
                for f in (point.gradient, point.curve, point.tunnel, point.tunnel_v2)
            ]
            nodes, vals = _merged(fs)
            pxs.append(nodes)
            pvals.append(vals)
            poff.append(poff[-1] + len(nodes))
            prof_of_length[L] = k
        self.prof = (
            np.array(poff, dtype=np.int64),
            np.ascontiguousarray(np.concatenate(pxs)),
            np.ascontiguousarray(np.concatenate(pvals)),
        )
        avail = traction_availability(route, train)
        self.avail = (np.ascontiguousarray(avail.x), np.ascontiguousarray(avail.left))
        # curves: locomotives, service braking, regenerative braking
        curves = list(mp.traction_curves)
        braking = train.braking
        service_idx = len(curves)
        if braking.service_force is not None:
            curves.append(braking.service_force)
        else:
            from trainsim.model.effort import EffortCurve

            curves.append(EffortCurve.constant(0.0))
        regen_idx = -1
        if braking.regenerative is not None:
            regen_idx = len(curves)
            curves.append(braking.regenerative)
        self.bank = _curve_bank(curves)
        VP = np.zeros((n, mpk.N_V))
        VP[:, mpk.V_MASS] = mp.mass_kg
        VP[:, mpk.V_INERTIAL] = mp.inertial_mass_kg
        VP[:, mpk.V_LENGTH] = mp.length_m
        VP[:, mpk.V_R0] = [q.c0 for q in mp.resistance]
        VP[:, mpk.V_R1] = [q.c1 for q in mp.resistance]
        VP[:, mpk.V_R2] = [q.c2 for q in mp.resistance]
        VP[:, mpk.V_BRAKE] = mp.brake_share
        VP[:, mpk.V_REGEN] = mp.regen_share
        VP[:, mpk.V_CURVE] = -1
        for j, loco in enumerate(mp.locomotives):
            VP[loco.vehicle, mpk.V_CURVE] = j
        VP[:, mpk.V_PROFILE] = [prof_of_length[L] for L in np.round(mp.length_m, 9)]
        VP[:, mpk.V_DELAY] = mp.brake_delay_s
        self.VP = VP
        self.CP = np.ascontiguousarray(np.array([c.as_row() for c in mp.couplers]).reshape(-1, mpk.N_C))
        elec = train.electrical
        SP = np.zeros(mpk.N_S)
        SP[mpk.S_STEP] = settings.time_step_s
        SP[mpk.S_STEP_MIN] = min(settings.min_time_step_s, settings.time_step_s)
        SP[mpk.S_FORCE_TOL] = settings.force_tolerance_n or 0.0
        SP[mpk.S_VEPS] = settings.standstill_speed_mps
        SP[mpk.S_BRAKE_FRACTION] = run_settings.braking_fraction
        SP[mpk.S_DECEL] = braking.deceleration_mps2 or 0.0
        SP[mpk.S_BUILD_UP] = settings.brake_propagation.build_up_s
        SP[mpk.S_TAU] = settings.speed_time_constant_s
        SP[mpk.S_RAMP] = settings.traction_ramp_s
        mean_delay = float(np.sum(mp.brake_delay_s * mp.mass_kg) / mp.mass_kg.sum())
        SP[mpk.S_LOOKAHEAD] = (
            (mean_delay + settings.brake_propagation.build_up_s) if settings.lookahead else 0.0
        )
        SP[mpk.S_REST_SPEED] = REST_SPEED_MPS
        SP[mpk.S_STOP_WINDOW] = settings.stop_window_m
        SP[mpk.S_RECORD_DT] = settings.record_interval_s
        SP[mpk.S_ETA_T] = elec.traction_efficiency if elec else 1.0
        SP[mpk.S_ETA_R] = elec.regenerative_efficiency * elec.receptivity if elec else 0.0
        SP[mpk.S_SERVICE_CURVE] = service_idx
        SP[mpk.S_REGEN_CURVE] = regen_idx
        SP[mpk.S_G] = route.gravity_mps2
        SP[mpk.S_STALL_S] = STALL_TIME_S
        SP[mpk.S_NEWTON_TOL] = NEWTON_TOLERANCE_MPS
        self.SP = SP
        self.ceiling_arrays = (
            np.ascontiguousarray(self.ceiling.x),
            np.ascontiguousarray(self.ceiling.left),
            np.ascontiguousarray(self.ceiling.right),
        )


class _Runner:
    """State, records and buffers of one run; calls the kernel and grows buffers when full."""

    def __init__(self, c: _Compiled, head_m: float) -> None:
        self.c = c
        mp = c.mp
        n = mp.n_vehicles
        s = mp.settings
        half = 0.5 * np.array([cp.slack_m for cp in mp.couplers])
        delta = {"neutral": 0.0 * half, "stretched": half, "bunched": -half}[s.initial_couplers]
        offsets = np.concatenate([[0.0], np.cumsum(mp.length_m[:-1] + delta)])
        self.x = head_m - offsets
        self.v = np.zeros(n)
        self.b = np.zeros(n)
        self.t = np.zeros(1)
        self.a = np.zeros(n)
        self.next_rec = np.zeros(1)
        self.pcache = np.zeros(n, dtype=np.int64)
        self.tmem = np.zeros((3, max(n - 1, 1)))
        self.tmem_t = np.zeros(3)
        self.CMD = np.zeros(mpk.N_K)
        self.trac = np.zeros(n)
        self.elec = np.zeros(n)
        self.hist = np.zeros((1024, 2))
        self.hist[0] = (-1e30, 0.0)
        self.nh = 1
        self.acc = np.zeros(mpk.N_A)
        self.acc[mpk.A_PEAK_POWER] = -np.inf
        self.acc[mpk.A_REST_SINCE] = -1.0
        cap = 1024
        self.rec_t = np.zeros(cap)
        self.rec_x = np.zeros((cap, n))
        self.rec_v = np.zeros((cap, n))
        self.rec_a = np.zeros((cap, n))
        self.rec_T = np.zeros((cap, max(n - 1, 1)))
        self.rec_agg = np.zeros((cap, mpk.N_R))
        self.dwell = np.zeros(cap, dtype=bool)
        self.nrec = 0
        self.ext = np.zeros(mpk.N_E + mpk.N_EK * max(n - 1, 1))
        self.ext[mpk.E_DRAFT] = -np.inf
        self.ext[mpk.E_BUFF] = np.inf
        self.ext[mpk.N_E + mpk.EK_DRAFT :: mpk.N_EK] = -np.inf
        self.ext[mpk.N_E + mpk.EK_BUFF :: mpk.N_EK] = np.inf
        self.wall_s = 0.0
        self.record_now(COAST, 0.0)

    # ---------------------------------------------------------------- buffers
    def _grow_records(self) -> None:
        cap = 2 * len(self.rec_t)
        for name in ("rec_t", "rec_x", "rec_v", "rec_a", "rec_T", "rec_agg", "dwell"):
            old = getattr(self, name)
            new = np.zeros((cap, *old.shape[1:]), dtype=old.dtype)
            new[: len(old)] = old
            setattr(self, name, new)

    def _grow_history(self) -> None:
        new = np.zeros((2 * len(self.hist), 2))
        new[: len(self.hist)] = self.hist
        self.hist = new

    def record_now(self, regime: int, command: float) -> None:
        """Record the present state (after a dwell, at the start)."""
        if self.nrec >= len(self.rec_t):
            self._grow_records()
        self.CMD[mpk.K_REGIME] = regime
        self.CMD[mpk.K_COMMAND] = command
        # the forces of a state between runs of the kernel are not known; they are recorded as zero
        parts = np.zeros((len(self.x), 7))
        self.nrec = mpk.record(
            self.nrec, self.t[0], self.x, self.v, self.a, self.c.VP, self.c.CP, self.CMD, parts, self.acc,
            self.rec_t, self.rec_x, self.rec_v, self.rec_a, self.rec_T, self.rec_agg,
        )  # fmt: skip
        self.next_rec[0] = self.t[0] + self.c.SP[mpk.S_RECORD_DT]
        # the step-size control extrapolates the coupler forces of the last steps: not across a jump in time
        self.acc[mpk.A_NMEM] = 0

    def advance(self, mode: int, t_end: float, ref=None) -> int:
        """Run the kernel until ``t_end`` or an event; returns the status."""
        c = self.c
        if ref is None:
            ref = (np.zeros(2), np.zeros(2), np.zeros(2, dtype=np.int8), 0.0)
        t0 = time.perf_counter()
        try:
            while True:
                state = (
                    self.x, self.v, self.b, self.t, self.a, self.next_rec, self.pcache, self.tmem, self.tmem_t
                )  # fmt: skip
                status, self.nh, self.nrec = mpk.run(
                    mode, t_end, state, c.VP, c.CP, c.SP, self.CMD, self.trac, self.elec, c.bank, c.prof,
                    c.avail, ref, c.ceiling_arrays, self.hist, self.nh, self.acc, self.rec_t, self.rec_x,
                    self.rec_v, self.rec_a, self.rec_T, self.rec_agg, self.nrec, self.ext,
                    c.route.end_m + c.mp.settings.stop_window_m,
                )  # fmt: skip
                if status == mpk.ST_RECORD_FULL:
                    self._grow_records()
                elif status == mpk.ST_HISTORY_FULL:
                    self._grow_history()
                else:
                    return int(status)
        finally:
            self.wall_s += time.perf_counter() - t0

    def hold(self) -> None:
        """The train is at rest: speeds set to 0 (the kinetic energy left counts as braking)."""
        mi = self.c.VP[:, mpk.V_INERTIAL]
        self.acc[mpk.A_HELD] += float(np.sum(0.5 * mi * self.v**2))
        self.v[:] = 0.0
        self.a[:] = 0.0
        self.acc[mpk.A_NMEM] = 0

    def set_brake_command(self, level: float) -> None:
        if self.nh >= len(self.hist):
            self._grow_history()
        if abs(self.hist[self.nh - 1, 1] - level) > 1e-12:
            self.hist[self.nh] = (self.t[0], level)
            self.nh += 1
        self.CMD[mpk.K_FRICTION] = level

    def mark_dwell(self) -> None:
        """The last record is an arrival at a stop."""
        self.dwell[self.nrec - 1] = True
        self.rec_agg[self.nrec - 1, mpk.R_REGIME] = DWELL

    def statistics(self) -> dict[str, float]:
        return {
            "steps": float(self.acc[mpk.A_STEPS]),
            "newton_iterations": float(self.acc[mpk.A_NEWTON]),
            "halved_steps": float(self.acc[mpk.A_SUBSTEPS]),
            "rejected_steps": float(self.acc[mpk.A_REJECTED]),
            "wall_time_s": self.wall_s,
            "largest_time_step_s": float(self.c.SP[mpk.S_STEP]),
            "mean_time_step_s": float(self.acc[mpk.A_INTEGRATED] / max(self.acc[mpk.A_STEPS], 1.0)),
        }

    def result(self, status: str, kind: str, warnings: list[str], stop_names=None) -> MultiPointResult:
        k = self.nrec
        c = self.c
        return build_multipoint_result(
            mptrain=c.mp,
            route=c.route,
            settings=c.run_settings,
            profile=c.profile,
            ceiling=c.ceiling,
            rec_t=self.rec_t[:k].copy(),
            rec_x=self.rec_x[:k].copy(),
            rec_v=self.rec_v[:k].copy(),
            rec_a=self.rec_a[:k].copy(),
            rec_T=self.rec_T[:k, : c.mp.n_vehicles - 1].copy(),
            rec_agg=self.rec_agg[:k].copy(),
            dwell_mask=self.dwell[:k].copy(),
            ext=self.ext.copy(),
            status=status,
            kind=kind,
            warnings=warnings,
            statistics=self.statistics(),
            stop_names=stop_names,
            rest_speed_mps=REST_SPEED_MPS,
        )


# ============================================================================ strategies
def _as_multipoint(train: Train | MultiPointTrain, settings: MultiPointSettings | None) -> MultiPointTrain:
    if isinstance(train, MultiPointTrain):
        if settings is not None and settings is not train.settings:
            raise InputError(
                "give the settings when building the MultiPointTrain, not twice", field="settings"
            )
        return train
    return build_multipoint_train(train, settings)


def follow_profile(
    train: Train | MultiPointTrain,
    route: Route,
    profile: SpeedProfile | RunResult | OptimizationResult,
    settings: MultiPointSettings | None = None,
    run_settings: RunSettings | None = None,
    *,
    track_profile: bool = True,
    kind: str = "multi_point follow",
) -> MultiPointResult:
    """Drive the multi-point train along a speed profile over head position (see the module doc).

    Args:
        train: a single-point train with its formation, or a built :class:`MultiPointTrain`.
        route: the route (stations, line data).
        profile: the speed profile: a single-point ``RunResult`` (fastest or driven run), the timetable
            optimizer's result (``trainsim.optimize.api.OptimizationResult``, whose ``run`` is followed)
            or a :class:`SpeedProfile`.
        settings: multi-point settings (when ``train`` is a single-point train).
        run_settings: braking fraction and the like (as for the single-point model).
        track_profile: follow the profile's speed in traction too (True), or apply full traction up to
            the speed ceiling in traction (False, the fastest-run strategy).
    """
    mp = _as_multipoint(train, settings)
    run_settings = run_settings or RunSettings()
    if not isinstance(profile, SpeedProfile | RunResult) and isinstance(
        getattr(profile, "run", None), RunResult
    ):
        profile = profile.run  # the timetable optimizer's OptimizationResult: follow its run
    if isinstance(profile, RunResult):
        profile = SpeedProfile.from_result(profile)
    segments = _segments(profile, route)
    c = _Compiled(mp, route, run_settings)
    c.SP[mpk.S_TRACK_PROFILE] = 1.0 if track_profile else 0.0
    runner = _Runner(c, float(profile.position_m[0]))
    warnings: list[str] = []
    status = "ok"
    served = [_station_name(route, float(profile.position_m[0]))]
    for j, seg in enumerate(segments):
        ref = (seg.s, seg.v2, seg.regime, seg.stop_m)
        t_limit = runner.t[0] + SEGMENT_TIME_FACTOR * seg.duration_s + SEGMENT_TIME_MARGIN_S
        st = runner.advance(1, t_limit, ref)
        if st == mpk.ST_STOPPED and not seg.is_stop:
            # the profile ends without an arrival (a stalled reference run): so does the train
            runner.hold()
            status = "stalled"
            warnings.append(f"the profile ends at {seg.stop_m:.0f} m without a stop; the train stopped there")
            break
        if st == mpk.ST_STOPPED:
            runner.hold()
            last = j == len(segments) - 1
            if seg.is_stop:
                served.append(_station_name(route, seg.stop_m))
                off = runner.x[0] - seg.stop_m
                if abs(off) > mp.settings.stop_window_m:
                    status = "did_not_reach_stop"
                    warnings.append(
                        f"stopped {off:+.1f} m from the stop at {seg.stop_m:.0f} m (more than the "
                        f"stop window of {mp.settings.stop_window_m:g} m)"
                    )
                runner.mark_dwell()
                if not last:
                    # brakes held during the dwell; released (with the propagation delay) on departure
                    runner.set_brake_command(1.0)
                    runner.b[:] = 1.0
                    if seg.dwell_s > 0:
                        runner.t[0] += seg.dwell_s
                        runner.record_now(COAST, 0.0)
            continue
        if st == mpk.ST_STALLED:
            status = "stalled"
            warnings.append(
                f"the train stalls at {runner.x[0]:.1f} m (at rest with full traction for {STALL_TIME_S:.0f} s)"
            )
        elif st == mpk.ST_FAILED:
            status = "error"
            warnings.append(f"the implicit integrator did not converge at t = {runner.t[0]:.1f} s")
        elif st == mpk.ST_END_OF_ROUTE:
            warnings.append("the head reached the end of the route before stopping")
        else:
            status = "incomplete"
            warnings.append(
                f"did not reach the stop at {seg.stop_m:.0f} m within {t_limit:.0f} s (head at {runner.x[0]:.1f} m)"
            )
        break
    return runner.result(status, kind, warnings, stop_names=served)


def _station_name(route: Route, position_m: float) -> str:
    for st in route.stations:
        if abs(st.position_m - position_m) < 1.0:
            return st.name
    return f"{position_m:.0f} m"


def run_multipoint_fastest(
    train: Train | MultiPointTrain,
    route: Route,
    settings: MultiPointSettings | None = None,
    run_settings: RunSettings | None = None,
    *,
    reference: RunResult | None = None,
) -> MultiPointResult:
    """The fastest run with the multi-point model: the single-point fastest run's regimes and braking
    points, driven by the controller with full traction up to the speed ceiling (see the module doc).

    Args:
        train: a train with its formation, or a built :class:`MultiPointTrain`.
        route: the route.
        settings: multi-point settings.
        run_settings: as for ``trainsim.run_fastest``.
        reference: the single-point fastest run, if already computed.
    """
    mp = _as_multipoint(train, settings)
    run_settings = run_settings or RunSettings()
    if reference is None:
        reference = run_fastest(mp.train, route, run_settings)
    result = follow_profile(
        mp, route, reference, None, run_settings, track_profile=False, kind="multi_point fastest"
    )
    if reference.status != "ok":
        result = dataclasses.replace(
            result, warnings=(*result.warnings, f"the single-point reference run is {reference.status}")
        )
    return result


# ============================================================================ driving by command
@dataclass(frozen=True)
class MultiPointState:
    """What the driver sees after a step (SI units)."""

    time_s: float
    head_position_m: float
    speed_mps: float
    command: float
    max_draft_n: float
    max_buff_n: float
    next_stop_name: str | None
    next_stop_distance_m: float | None
    dwell_remaining_s: float
    finished: bool
    message: str


class MultiPointSession:
    """The multi-point train driven by command, from standstill at the route's first stop.

    ``step(command, dt_s)`` applies a command in [-1, 1] for ``dt_s`` seconds: positive, that share of
    the maximum traction at every locomotive; negative, that share of the service braking (electric
    brake at the locomotives first, friction brakes on every vehicle for the rest, the friction brake
    command propagating along the train as the settings say); 0, coasting. With ``loco_commands``
    (one value per locomotive in [-1, 1]) each locomotive has its own traction (positive) or electric
    braking (negative) level, as with independent distributed power; ``command`` then must be <= 0 and
    sets the friction (train) brake alone. Stops are served as in ``trainsim.DrivingSession``.
    """

    def __init__(
        self,
        train: Train | MultiPointTrain,
        route: Route,
        settings: MultiPointSettings | None = None,
        run_settings: RunSettings | None = None,
    ) -> None:
        self.mp = _as_multipoint(train, settings)
        self.route = route
        self.run_settings = run_settings or RunSettings()
        stops = route.stops
        if not stops:
            raise InputError("the route has no stop to start from", field="stations")
        self._stops = list(stops)
        self._next = 1
        self._c = _Compiled(self.mp, route, self.run_settings)
        self._runner = _Runner(self._c, stops[0].position_m)
        self.dwell_remaining_s = 0.0
        self.finished = len(stops) < 2
        self._message = f"at {stops[0].name}"
        self._warnings: list[str] = []
        self._served = [stops[0].name]

    @property
    def time_s(self) -> float:
        return float(self._runner.t[0])

    @property
    def positions_m(self) -> np.ndarray:
        return self._runner.x.copy()

    @property
    def speeds_mps(self) -> np.ndarray:
        return self._runner.v.copy()

    def set_state(self, positions_m: Sequence[float], speeds_mps: Sequence[float]) -> None:
        """Set every vehicle's front position [m] and speed [m/s] (head first) before the first step,
        e.g. to start from a stretched or compressed train or to test the coupler dynamics."""
        r = self._runner
        if r.acc[mpk.A_STEPS] > 0 or r.t[0] > 0:
            raise InputError("the state can only be set before the first step", field="state")
        x = np.asarray(positions_m, dtype=float)
        v = np.asarray(speeds_mps, dtype=float)
        n = self.mp.n_vehicles
        if x.shape != (n,) or v.shape != (n,) or not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
            raise InputError(
                "give one finite position and speed per vehicle", field="state", allowed=f"{n} values"
            )
        if np.any(np.diff(x) >= 0):
            raise InputError("positions must decrease from the head to the rear", field="state.positions_m")
        r.x[:] = x
        r.v[:] = v
        r.a[:] = 0.0
        r.acc[mpk.A_NMEM] = 0
        r.nrec = 0
        r.record_now(int(r.CMD[mpk.K_REGIME]), float(r.CMD[mpk.K_COMMAND]))

    def coupler_forces_n(self) -> np.ndarray:
        """Tension of every coupling now [N]."""
        r, c = self._runner, self._c
        out = np.empty(self.mp.n_vehicles - 1)
        for k in range(len(out)):
            delta = r.x[k] - c.VP[k, mpk.V_LENGTH] - r.x[k + 1]
            s, d, _, _ = mpk.coupler_force(delta, r.v[k] - r.v[k + 1], c.CP[k])
            out[k] = s + d
        return out

    def step(
        self, command: float, dt_s: float, loco_commands: Sequence[float] | None = None
    ) -> MultiPointState:
        """Apply the command for ``dt_s`` seconds (0 < dt_s <= 60) and return the state."""
        if not np.isfinite(command) or not -1.0 <= command <= 1.0:
            raise InputError("the driving command must be in [-1, 1]", field="command", value=command)
        if not 0.0 < dt_s <= 60.0:
            raise InputError("the time step must be in (0, 60] s", field="dt_s", value=dt_s)
        n_loco = len(self.mp.locomotives)
        if loco_commands is not None:
            lc = np.asarray(loco_commands, dtype=float)
            if lc.shape != (n_loco,) or not np.all(np.isfinite(lc)) or np.any(np.abs(lc) > 1):
                raise InputError(
                    "give one command in [-1, 1] per locomotive",
                    field="loco_commands",
                    value=list(np.atleast_1d(lc)),
                    allowed=f"{n_loco} values",
                )
            if command > 0:
                raise InputError(
                    "with per-locomotive commands, 'command' is the train brake only (<= 0)",
                    field="command",
                    value=command,
                )
        if self.finished:
            return self.state()
        r = self._runner
        t_end = r.t[0] + dt_s
        if self.dwell_remaining_s > 0:
            stay = min(self.dwell_remaining_s, dt_s)
            r.t[0] += stay
            self.dwell_remaining_s -= stay
            if self.dwell_remaining_s <= 1e-9:
                self.dwell_remaining_s = 0.0
                r.record_now(COAST, 0.0)
                self._message = f"departing {self._stops[self._next - 1].name}"
            if t_end - r.t[0] <= 1e-9:
                return self.state(command)
        self._set_commands(command, loco_commands)
        status = r.advance(0, t_end)
        if status == mpk.ST_FAILED:
            self.finished = True
            self._warnings.append(f"the implicit integrator did not converge at t = {r.t[0]:.1f} s")
        elif status == mpk.ST_END_OF_ROUTE:
            self.finished = True
            self._message = "reached the end of the route"
        self._after_move()
        return self.state(command)

    def _set_commands(self, command: float, loco_commands: Sequence[float] | None) -> None:
        r = self._runner
        r.trac[:] = 0.0
        r.elec[:] = 0.0
        if loco_commands is None:
            for loco in self.mp.locomotives:
                r.trac[loco.vehicle] = max(command, 0.0)
            r.elec[:] = max(-command, 0.0)
            r.CMD[mpk.K_BLEND] = 1.0
        else:
            for loco, lc in zip(self.mp.locomotives, loco_commands, strict=True):
                r.trac[loco.vehicle] = max(lc, 0.0)
                r.elec[loco.vehicle] = max(-lc, 0.0)
            r.CMD[mpk.K_BLEND] = 0.0
        r.CMD[mpk.K_FRICTION] = max(-command, 0.0)
        r.CMD[mpk.K_COMMAND] = command
        r.CMD[mpk.K_REGIME] = TRACTION if command > 0 else BRAKE if command < 0 else COAST

    def _after_move(self) -> None:
        r = self._runner
        if self._next >= len(self._stops):
            return
        stop = self._stops[self._next]
        ahead = stop.position_m - r.x[0]
        m = self._c.VP[:, mpk.V_INERTIAL]
        at_rest = abs(r.v @ m / m.sum()) < REST_SPEED_MPS and bool(np.all(np.abs(r.v) < 10 * REST_SPEED_MPS))
        window = self.mp.settings.stop_window_m
        if at_rest and abs(ahead) <= max(window, 5.0):
            r.hold()
            self._next += 1
            self._served.append(stop.name)
            if r.nrec == 0 or r.rec_t[r.nrec - 1] < r.t[0]:
                r.record_now(COAST, 0.0)
            if self._next >= len(self._stops):
                self.finished = True
                self._message = f"arrived at {stop.name}: end of the route"
            else:
                r.mark_dwell()
                self.dwell_remaining_s = stop.dwell_s
                self._message = f"stopped at {stop.name}: dwell {stop.dwell_s:.0f} s"
        elif ahead < -max(window, 5.0):
            self._warnings.append(f"passed {stop.name} without stopping")
            self._next += 1
            if self._next >= len(self._stops):
                self.finished = True

    def state(self, command: float = 0.0) -> MultiPointState:
        r = self._runner
        m = self._c.VP[:, mpk.V_INERTIAL]
        forces = self.coupler_forces_n()
        nxt = self._stops[self._next] if self._next < len(self._stops) else None
        return MultiPointState(
            time_s=float(r.t[0]),
            head_position_m=float(r.x[0]),
            speed_mps=float(r.v @ m / m.sum()),
            command=command,
            max_draft_n=float(forces.max(initial=0.0)),
            max_buff_n=float(forces.min(initial=0.0)),
            next_stop_name=nxt.name if nxt else None,
            next_stop_distance_m=float(nxt.position_m - r.x[0]) if nxt else None,
            dwell_remaining_s=self.dwell_remaining_s,
            finished=self.finished,
            message=self._message,
        )

    def result(self) -> MultiPointResult:
        """The drive so far."""
        r = self._runner
        if r.rec_t[r.nrec - 1] < r.t[0] - 1e-9:
            r.record_now(int(r.CMD[mpk.K_REGIME]), float(r.CMD[mpk.K_COMMAND]))
        warnings = list(self._warnings)
        if not self.finished:
            warnings.append("the drive has not reached its destination yet")
        return r.result(
            "ok" if self.finished else "in progress", "multi_point driven", warnings, stop_names=self._served
        )
