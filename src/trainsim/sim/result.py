"""Typed results of a run: the trace, the energy accounting and the per-section summary."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np

from trainsim.constants import KMH, KWH
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.physics import electrical as el
from trainsim.sim._trace_c import (
    PROBLEM_NEGATIVE_SPEED,
    PROBLEM_NOT_FINITE,
    PROBLEM_POSITION_DECREASING,
    PROBLEM_TIME_DECREASING,
    TRACE_ROWS,
    cumulative_rows,
    point_problems,
    run_arrays,
    run_peaks,
)
from trainsim.sim.codes import BRAKE, CRUISE, DWELL, FOLLOW, REGEN, REGIME_NAMES, TRACTION
from trainsim.sim.energy import run_works
from trainsim.sim.parameters import _NO_CURVE
from trainsim.sim.profile import LineResistanceProfile, PiecewiseLinear, _law_arrays

#: What a run's ``status`` can say (``RunResult.status`` and ``summary()["status"]``); anything but
#: ``ok`` comes with warnings saying where and why, and the result is the best feasible run.
STATUSES: dict[str, str] = {
    "ok": "the run went as asked: standstill at every stop, within every limit",
    "stalled": "the tractive effort could not overcome the resistance; the run ends where it stopped",
    "brake_limited": "the brakes cannot hold the train at a limit or stop it on a descent; the run ends "
    "before that place",
    "did_not_reach_stop": "the run does not end at standstill at its last stop",
    "in progress": "a driving session that has not reached its destination yet",
    "not_finite": "an energy or current figure is not finite (an input of absurd magnitude, such as "
    "an efficiency of 1e-308, overflowed); the warning names the figure, which is not usable",
    "error": "an internal consistency check failed (a bug: please report it with the input)",
}


@dataclass(frozen=True)
class Trace:
    """Point-by-point record of a run. Every array has one entry per point; ``regime[k]`` is the
    regime of the stretch from point k to point k + 1. Forces are those of that regime at the
    point. Cumulative energies are integrated stretch by stretch up to the point."""

    time_s: np.ndarray
    position_m: np.ndarray
    speed_mps: np.ndarray
    acceleration_mps2: np.ndarray
    regime: np.ndarray  # int codes, see REGIME_NAMES
    traction_force_n: np.ndarray
    braking_force_n: np.ndarray
    regenerative_braking_force_n: np.ndarray
    friction_braking_force_n: np.ndarray
    running_resistance_n: np.ndarray
    gradient_resistance_n: np.ndarray
    curve_resistance_n: np.ndarray
    tunnel_resistance_n: np.ndarray
    speed_limit_mps: np.ndarray
    mechanical_power_w: np.ndarray
    electrical_power_w: np.ndarray
    line_current_a: np.ndarray
    paper_power_w: np.ndarray
    paper_line_current_a: np.ndarray
    traction_work_j: np.ndarray
    braking_work_j: np.ndarray
    regenerated_energy_j: np.ndarray
    electrical_energy_j: np.ndarray

    @property
    def regime_names(self) -> list[str]:
        """Regime of each point as a name."""
        return [REGIME_NAMES[int(r)] for r in self.regime]

    def __len__(self) -> int:
        return len(self.time_s)

    def to_dataframe(self):  # -> pandas.DataFrame (imported lazily: pandas is slow to import)
        """The trace as a pandas DataFrame, one column per quantity, units in column names."""
        import pandas as pd

        data = {name: getattr(self, name) for name in self.__dataclass_fields__ if name != "regime"}
        df = pd.DataFrame(data)
        df.insert(4, "regime", pd.Categorical(self.regime_names, categories=list(REGIME_NAMES)))
        df.insert(3, "speed_kmh", self.speed_mps / KMH)
        return df


@dataclass(frozen=True)
class EnergyFigures:
    """Energy of a run or a section [kWh].

    traction: traction work at the wheel. braking: braking work at the wheel (regenerative and
    friction). regenerated: energy returned to the line (regenerative work x efficiency x
    receptivity). auxiliary: auxiliaries. net: drawn from the line = traction / efficiency +
    auxiliary - regenerated. paper: source 002's convention, integral of F v eta in traction.
    """

    traction: float
    braking: float
    regenerated: float
    auxiliary: float
    net: float
    paper: float


_ENERGY_NAMES = tuple(f.name for f in fields(EnergyFigures))


@dataclass(frozen=True)
class SectionSummary:
    """One section between two consecutive stops."""

    from_station: str
    to_station: str
    distance_m: float
    running_time_s: float
    dwell_s: float
    max_speed_kmh: float
    average_speed_kmh: float
    peak_current_a: float
    energy_kwh: EnergyFigures

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["from"] = d.pop("from_station")
        d["to"] = d.pop("to_station")
        return d


@dataclass(frozen=True)
class RunResult:
    """Result of a run: status, warnings, trace, sections and totals.

    Attributes:
        status: ``ok``, or one of ``STATUSES`` (``stalled``, ``brake_limited``,
            ``did_not_reach_stop``...) with the reason in ``warnings``.
        warnings: sentences, each saying what is wrong or implausible and where.
        kind: what produced it (``fastest``, ``driven``...).
    """

    train_name: str
    route_name: str
    kind: str
    status: str
    warnings: tuple[str, ...]
    trace: Trace | None  # None for a summary-only run (``run_fastest(..., trace=False)``)
    sections: tuple[SectionSummary, ...]
    distance_m: float
    running_time_s: float
    total_time_s: float
    dwell_s: float
    max_speed_kmh: float
    average_speed_kmh: float
    average_running_speed_kmh: float
    peak_current_a: float
    peak_paper_current_a: float
    energy_kwh: EnergyFigures
    energy_balance: dict[str, float] = field(default_factory=dict)

    def to_dataframe(self):
        """The trace as a pandas DataFrame."""
        if self.trace is None:
            raise ValueError("this run was computed without its trace (trace=False)")
        return self.trace.to_dataframe()

    def summary(self) -> dict[str, Any]:
        """The run summary as plain JSON-ready data."""
        out: dict[str, Any] = {
            "status": self.status,
            "warnings": list(self.warnings),
            "kind": self.kind,
            "train": self.train_name,
            "route": self.route_name,
            "distance_m": self.distance_m,
            "running_time_s": self.running_time_s,
            "dwell_s": self.dwell_s,
            "total_time_s": self.total_time_s,
            "max_speed_kmh": self.max_speed_kmh,
            "average_speed_kmh": self.average_speed_kmh,
            "average_running_speed_kmh": self.average_running_speed_kmh,
            "peak_current_a": self.peak_current_a,
            "peak_current_paper_convention_a": self.peak_paper_current_a,
            "energy_kwh": asdict(self.energy_kwh),
            "energy_balance": dict(self.energy_balance),
            "sections": [s.to_dict() for s in self.sections],
        }
        return _finite(out)


def _finite(obj: Any) -> Any:
    """JSON has no NaN: unknown values become null."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, float | np.floating):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _regime_forces(
    train: Train,
    settings: RunSettings,
    regime: np.ndarray,
    v: np.ndarray,
    running: np.ndarray,
    line: np.ndarray,
    level: np.ndarray | None = None,
    available: np.ndarray | None = None,
    inertia: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Traction and braking force [N] in each point's regime at speed v; ``level`` is the
    driver's command magnitude (0..1) in traction and braking, 1 for the envelope regimes;
    ``available`` the share of tractive effort the line allows (0 where an electric train has no
    supply)."""
    traction = np.zeros_like(v)
    braking = np.zeros_like(v)
    level = np.ones_like(v) if level is None else level
    available = np.ones_like(v) if available is None else available
    is_t = regime == TRACTION
    traction[is_t] = level[is_t] * available[is_t] * train.traction(v[is_t])
    is_c = regime == CRUISE
    need = running[is_c] + line[is_c]
    traction[is_c] = np.maximum(need, 0.0)
    braking[is_c] = np.maximum(-need, 0.0)
    is_b = regime == BRAKE
    if train.braking.deceleration_mps2 is not None:
        decel = train.braking.deceleration_mps2 * settings.braking_fraction
        braking[is_b] = level[is_b] * np.maximum(
            train.inertial_mass_kg * decel - running[is_b] - line[is_b], 0.0
        )
    else:
        braking[is_b] = level[is_b] * settings.braking_fraction * train.braking.service_force(v[is_b])
    is_r = regime == REGEN
    if is_r.any() and train.braking.regenerative is not None:
        braking[is_r] = train.braking.regenerative(v[is_r])
    is_f = regime == FOLLOW
    if is_f.any() and inertia is not None:
        # a prescribed speed profile: whatever force its acceleration needs
        need = inertia[is_f] + running[is_f] + line[is_f]
        traction[is_f] = np.maximum(need, 0.0)
        braking[is_f] = np.maximum(-need, 0.0)
    return traction, braking


def _invariant_violations(s: np.ndarray, v: np.ndarray, t: np.ndarray) -> list[str]:
    """What is wrong with a trace: NaN, negative speed, position or time going backwards (by more
    than 1e-9 m or s); checked in one compiled pass (``_trace_c.point_problems``)."""
    found = point_problems(s, v, t, 1e-9)
    return [text for bit, text in _PROBLEMS if found & bit]


_PROBLEMS = (
    (PROBLEM_NOT_FINITE, "non-finite position, speed or time"),
    (PROBLEM_NEGATIVE_SPEED, "negative speed"),
    (PROBLEM_POSITION_DECREASING, "position decreasing"),
    (PROBLEM_TIME_DECREASING, "time decreasing"),
)


#: A run ends at a stop when its head is this close [m] and its speed this low [m/s].
STOP_POSITION_TOLERANCE_M = 1e-3
STOP_SPEED_TOLERANCE_MPS = 1e-6


def _check_stops(
    route: Route,
    s: np.ndarray,
    v: np.ndarray,
    regime: np.ndarray,
    stop_names: list[str] | None,
    warnings: list[str],
) -> str:
    """``ok`` when the run stands still at every dwell point and ends at standstill at its last stop;
    otherwise ``did_not_reach_stop`` with a warning saying where it ended and how fast."""
    moving_dwell = np.flatnonzero((regime == DWELL) & (v > STOP_SPEED_TOLERANCE_MPS))
    stops = route.stops  # a property that builds its tuple on each call
    last = stops[-1] if stops and stop_names is None else None
    short = last is not None and abs(float(s[-1]) - last.position_m) > STOP_POSITION_TOLERANCE_M
    if not (short or v[-1] > STOP_SPEED_TOLERANCE_MPS or len(moving_dwell)):
        return "ok"
    where = f"{last.position_m - float(s[-1]):.3f} m short of {last.name}, " if short and last else ""
    warnings.append(
        f"the run does not end at standstill at its last stop: it ends at {float(s[-1]):.3f} m "
        f"({where}{float(v[-1]) / KMH:.3f} km/h)"
        + (f"; {len(moving_dwell)} dwell point(s) are not at standstill" if len(moving_dwell) else "")
    )
    return "did_not_reach_stop"


#: Below these the inputs are probably wrong (units, a missing block): a warning, not an error.
PLAUSIBLE_MIN_LIMIT_KMH = 5.0  # a speed limit [km/h] (shunting speeds are 5-25 km/h)
PLAUSIBLE_MIN_AVERAGE_KMH = 5.0  # a section's average running speed [km/h]
PLAUSIBLE_MIN_BRAKING_MPS2 = 0.1  # service deceleration on the level [m/s^2] (freight: 0.2-0.4, metro: ~1)
PLAUSIBLE_MIN_EFFICIENCY = 0.5  # line <-> wheel efficiency, power factor [-] (usual ranges below)
#: Usual ranges of the electrical ratios, named in their plausibility warnings.
_USUAL_EFFICIENCY = {
    "traction_efficiency": ("0.6 to 0.95", "the line energy and current scale with its inverse"),
    "regenerative_efficiency": ("0.6 to 0.95", "the regenerated energy scales with it"),
    "power_factor": ("0.6 to 1", "the line current scales with its inverse"),
}


def plausibility_warnings(
    train: Train, route: Route, settings: RunSettings, sections: list[SectionSummary]
) -> list[str]:
    """Sentences about inputs that are possible but implausible: a speed limit below 5 km/h, a
    section averaging below 5 km/h, service brakes that decelerate the train by less than
    0.1 m/s^2 on the level (none at all, or a unit mistake), an efficiency or power factor below 0.5."""
    out = []
    low = [lim for lim in route.speed_limits if lim.limit_mps / KMH < PLAUSIBLE_MIN_LIMIT_KMH]
    if low:
        lim = min(low, key=lambda x: x.limit_mps)
        out.append(
            f"implausible speed limit: {lim.limit_mps / KMH:.3g} km/h on {lim.start_m:.0f}-{lim.end_m:.0f} m "
            f"({len(low)} limit(s) below {PLAUSIBLE_MIN_LIMIT_KMH:g} km/h); check the limits' units"
        )
    slow = [sec for sec in sections if 0 < sec.average_speed_kmh < PLAUSIBLE_MIN_AVERAGE_KMH]
    if slow:
        sec = min(slow, key=lambda x: x.average_speed_kmh)
        out.append(
            f"implausibly slow run: {sec.from_station} - {sec.to_station} averages {sec.average_speed_kmh:.3g} "
            f"km/h over {sec.running_time_s:.4g} s; check the traction, the limits and their units"
        )
    b = train.braking
    if b.deceleration_mps2 is not None:
        decel = b.deceleration_mps2 * settings.braking_fraction
    else:
        speeds = np.linspace(0.0, train.max_speed_mps, 201)
        decel = settings.braking_fraction * float(np.min(b.service_force(speeds))) / train.inertial_mass_kg
    if decel < PLAUSIBLE_MIN_BRAKING_MPS2:
        out.append(
            f"implausible brakes: the service brakes decelerate the train by only {decel:.3g} m/s^2 on the "
            f"level at their weakest (usual: 0.3 to 1.2 m/s^2); check the braking data and its units"
        )
    el = train.electrical
    if el is not None:
        # readers refuse efficiencies below 0.1 (model.bounds.MIN_EFFICIENCY); between that and 0.5 a
        # value is possible (an old diesel-electric chain) but far more often a unit mistake, and the
        # line energy and current scale with its inverse. A regenerative efficiency of 0 means no
        # regeneration, which is plausible.
        for name, (usual, effect) in _USUAL_EFFICIENCY.items():
            eta = getattr(el, name)
            if 0 < eta < PLAUSIBLE_MIN_EFFICIENCY:
                out.append(
                    f"implausible {name.replace('_', ' ')}: {eta:.3g} (usual: {usual}); {effect}; "
                    "check the electrical data and its units"
                )
    return out


def _section_ends(regime: np.ndarray) -> list[int]:
    """Index of the arrival point of each section: the first point of each run of DWELL points,
    and the last point if the run ends without a stop."""
    n = len(regime)
    is_dwell = regime == DWELL
    first = is_dwell & np.concatenate([[False], ~is_dwell[:-1]])
    first[0] = False
    ends = np.flatnonzero(first).tolist()
    if n and (not ends or ends[-1] != n - 1) and regime[-1] != DWELL:
        ends.append(n - 1)
    return ends


def _line_forces(
    profile: LineResistanceProfile, mass_kg: float, s: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, ...]:
    weight = profile.weight_n(mass_kg)
    return (
        weight * profile.gradient(s),
        weight * profile.curve(s),
        weight * (profile.tunnel(s) + profile.tunnel_v2(s) * v * v),
    )


class TraceInputs(NamedTuple):
    """What a run's point arrays are computed from: the train and route with their laws, the run's
    points, the works of its stretches and the electrical ratios. One container for the compiled pass
    (``_trace_and_peaks``) and its numpy reference (``_trace_and_peaks_numpy``), so that the two take
    the same inputs by construction."""

    train: Train
    settings: RunSettings
    route: Route
    profile: LineResistanceProfile
    ceiling: PiecewiseLinear  # speed ceiling over head position [m/s]
    availability: PiecewiseLinear  # share of the tractive effort available [-]
    voltage: PiecewiseLinear  # line voltage [V]
    s: np.ndarray  # positions [m], one per point
    v: np.ndarray  # speeds [m/s]
    t: np.ndarray  # times [s]
    regime: np.ndarray  # regime code of the stretch each point starts (``codes``)
    level: np.ndarray  # driver's level [-]
    s_right: np.ndarray | None  # positions just right of the points [m], where the laws are read (trace)
    w_traction: np.ndarray  # traction work of each stretch [J], one fewer than points
    w_braking: np.ndarray  # braking work [J]
    e_regen_line: np.ndarray  # energy returned to the line [J]
    e_net: np.ndarray  # energy drawn from the line [J]
    eta_t: float  # traction efficiency [-]
    eta_r: float  # regenerative efficiency x receptivity [-]
    aux_w: float  # auxiliary power [W]


def _trace_and_peaks_numpy(inp: TraceInputs, with_trace: bool) -> tuple[Trace | None, np.ndarray, np.ndarray]:
    """Forces, powers and currents at every point of a run: its trace (None without ``with_trace``)
    and the line current at each point and the stretch it starts, for the peaks [A].

    The numpy form of ``_trace_and_peaks`` (which evaluates the same expressions compiled, in one
    pass): kept as the reference its results are tested against, bit for bit."""
    train, settings, profile, ceiling = inp.train, inp.settings, inp.profile, inp.ceiling
    availability, voltage, s, v, t = inp.availability, inp.voltage, inp.s, inp.v, inp.t
    regime, level, s_right = inp.regime, inp.level, inp.s_right
    eta_t, eta_r, aux_w = inp.eta_t, inp.eta_r, inp.aux_w
    m = train.mass_kg
    n = len(s)
    elec = train.electrical
    # point values in each point's own regime, line resistance from the right of the point
    running = np.asarray(train.running_resistance_n(v), dtype=float) * (v > 0)
    grad, curve, tunnel = _line_forces(profile, m, s_right, v)
    line = grad + curve + tunnel
    # stretch accelerations for prescribed profiles (FOLLOW): constant over each stretch
    ds_all = np.diff(s)
    with np.errstate(divide="ignore", invalid="ignore"):
        acc_stretch = np.where(ds_all > 0, (v[1:] ** 2 - v[:-1] ** 2) / (2 * ds_all), 0.0)
    inertia_pts = train.inertial_mass_kg * np.concatenate([acc_stretch, [0.0]])
    traction, braking = _regime_forces(
        train, settings, regime, v, running, line, level, availability(s_right), inertia_pts
    )
    regen_cap = train.braking.regenerative(v) if train.braking.regenerative is not None else np.zeros(n)
    regen = np.minimum(braking, regen_cap)
    friction = braking - regen
    accel = (traction - braking - running - line) / train.inertial_mass_kg
    accel[regime == DWELL] = 0.0

    # stretch integrals: both ends in the stretch's regime, line resistance at its middle
    r = regime[:-1]
    v0, v1 = v[:-1], v[1:]
    mid = 0.5 * (s[:-1] + s[1:])
    run0 = np.asarray(train.running_resistance_n(v0), dtype=float)
    run1 = np.asarray(train.running_resistance_n(v1), dtype=float)
    g_mid, c_mid, t_mid = _line_forces(profile, m, mid, np.sqrt(0.5 * (v0**2 + v1**2)))
    line_mid = g_mid + c_mid + t_mid
    avail_mid = availability(mid)
    f0t, f0b = _regime_forces(train, settings, r, v0, run0, line_mid, level[:-1], avail_mid, inertia_pts[:-1])
    f1t, f1b = _regime_forces(train, settings, r, v1, run1, line_mid, level[:-1], avail_mid, inertia_pts[:-1])
    if train.braking.regenerative is not None:
        rg0 = np.minimum(f0b, train.braking.regenerative(v0))
        rg1 = np.minimum(f1b, train.braking.regenerative(v1))
    else:
        rg0 = rg1 = np.zeros_like(v0)

    mech_power = traction * v
    el_power = (
        el.traction_line_power_w(traction, v, eta_t) + aux_w - el.regenerated_line_power_w(regen, v, eta_r)
    )
    paper_power = el.paper_power_w(traction, v, eta_t)
    if elec:
        # on a non-electrified part (0 V) the train draws nothing: current 0, not a division by 0
        u_line = voltage(s_right)
        safe = np.where(u_line > 0, u_line, 1.0)
        current = np.where(u_line > 0, el.line_current_a(el_power, safe, elec.power_factor), 0.0)
        paper_current = np.where(u_line > 0, el.line_current_a(paper_power, safe, elec.power_factor), 0.0)
        # a point carries the forces of the stretch it starts, so the end of a traction stretch (full
        # effort at its highest speed, often the peak) is only seen from the stretch: take it too
        u_mid = voltage(mid)
        safe_mid = np.where(u_mid > 0, u_mid, 1.0)
        end_power = np.maximum(
            el.traction_line_power_w(f0t * v0, 1.0, eta_t)
            - el.regenerated_line_power_w(rg0 * v0, 1.0, eta_r),
            el.traction_line_power_w(f1t * v1, 1.0, eta_t)
            - el.regenerated_line_power_w(rg1 * v1, 1.0, eta_r),
        )
        end_current = np.where(u_mid > 0, (end_power + aux_w) / (safe_mid * elec.power_factor), 0.0)
        end_paper = np.where(
            u_mid > 0, eta_t * np.maximum(f0t * v0, f1t * v1) / (safe_mid * elec.power_factor), 0.0
        )
        # stretch k's end belongs to point k for the peaks (both lie in the same section)
        peak_current = np.maximum(current, np.concatenate([end_current, [-np.inf]]))
        peak_paper = np.maximum(paper_current, np.concatenate([end_paper, [-np.inf]]))
    else:
        current = np.full(n, np.nan)
        paper_current = np.full(n, np.nan)
        peak_current = peak_paper = current

    def cumulative(x: np.ndarray) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(x)])

    if not with_trace:
        return None, peak_current, peak_paper
    trace = Trace(
        time_s=t,
        position_m=s,
        speed_mps=v,
        acceleration_mps2=accel,
        regime=regime,
        traction_force_n=traction,
        braking_force_n=braking,
        regenerative_braking_force_n=regen,
        friction_braking_force_n=friction,
        running_resistance_n=running,
        gradient_resistance_n=grad,
        curve_resistance_n=curve,
        tunnel_resistance_n=tunnel,
        speed_limit_mps=ceiling(s_right),
        mechanical_power_w=mech_power,
        electrical_power_w=el_power,
        line_current_a=current,
        paper_power_w=paper_power,
        paper_line_current_a=paper_current,
        traction_work_j=cumulative(inp.w_traction),
        braking_work_j=cumulative(inp.w_braking),
        regenerated_energy_j=cumulative(inp.e_regen_line),
        electrical_energy_j=cumulative(inp.e_net),
    )
    return trace, peak_current, peak_paper


def _run_arrays_args(inp: TraceInputs) -> tuple:
    """The arguments of ``run_arrays`` but ``with_trace``: the run's arrays, the line laws, the
    train's scalars and its effort curves (see there)."""
    train, settings, profile = inp.train, inp.settings, inp.profile
    eta_t, eta_r, aux_w = inp.eta_t, inp.eta_r, inp.aux_w
    elec = train.electrical
    # the ratios are checked where the numpy form checks them, with the same messages
    el.traction_line_power_w(0.0, 0.0, eta_t)
    el.regenerated_line_power_w(0.0, 0.0, eta_r)
    if elec:
        el.line_current_a(0.0, 1.0, elec.power_factor)
    b = train.braking
    law = train.resistance_law
    decel = b.deceleration_mps2 * settings.braking_fraction if b.deceleration_mps2 is not None else 0.0
    mech = (
        float(train.inertial_mass_kg),
        float(decel),
        float(settings.braking_fraction),
        b.deceleration_mps2 is not None,
        b.service_force is not None,
        b.regenerative is not None,
    )
    traction = train.traction.as_arrays()
    service = b.service_force.as_arrays() if b.service_force is not None else _NO_CURVE
    regen = b.regenerative.as_arrays() if b.regenerative is not None else _NO_CURVE
    laws = tuple(
        _law_arrays(f)
        for f in (
            profile.gradient,
            profile.curve,
            profile.tunnel,
            profile.tunnel_v2,
            inp.availability,
            inp.voltage,
            inp.ceiling,
        )
    )
    electric = (
        elec is not None,
        float(eta_t),
        float(eta_r),
        float(aux_w),
        float(elec.power_factor if elec else 1.0),
    )
    return (
        np.ascontiguousarray(inp.s, dtype=float),
        np.ascontiguousarray(inp.v, dtype=float),
        np.ascontiguousarray(inp.regime, dtype=np.int64),
        np.ascontiguousarray(inp.level, dtype=float),
        None if inp.s_right is None else np.ascontiguousarray(inp.s_right, dtype=float),
        laws,
        (float(law.c0), float(law.c1), float(law.c2)),
        float(profile.weight_n(train.mass_kg)),
        mech,
        electric,
        traction,
        service,
        regen,
    )


def _trace_and_peaks(inp: TraceInputs, with_trace: bool) -> tuple[Trace | None, np.ndarray, np.ndarray]:
    """Forces, powers and currents at every point of a run: its trace (None without ``with_trace``)
    and the line current at each point and the stretch it starts, for the peaks [A]. Evaluated in one
    compiled pass (``_trace_c.run_arrays``, Cython), the same bits as ``_trace_and_peaks_numpy``; without
    ``with_trace`` only the peaks are stored. The cumulative works are summed in compiled code too
    (``_trace_c.cumulative_rows``: one block, the order of ``np.cumsum``)."""
    rows, peak_current, peak_paper = run_arrays(*_run_arrays_args(inp), with_trace)
    if not with_trace:
        return None, peak_current, peak_paper
    works = cumulative_rows((inp.w_traction, inp.w_braking, inp.e_regen_line, inp.e_net))
    trace = Trace(
        time_s=inp.t,
        position_m=inp.s,
        speed_mps=inp.v,
        regime=inp.regime,
        traction_work_j=works[0],
        braking_work_j=works[1],
        regenerated_energy_j=works[2],
        electrical_energy_j=works[3],
        **{name: rows[k] for k, name in enumerate(TRACE_ROWS)},
    )
    return trace, peak_current, peak_paper


def _section_peaks(inp: TraceInputs, sections: list[tuple[int, int]]) -> tuple[list[float], float, float]:
    """The largest line current [A] of each section (its first to its last point) and of the whole
    run, and the run's largest in the paper convention, without the run's point arrays: what
    ``np.nanmax`` gives on ``_trace_and_peaks``'s peaks, evaluated in one compiled pass that keeps
    only the running maxima (``_trace_c.run_peaks``); the line laws are read just right of each
    point, as there."""
    args = _run_arrays_args(inp)
    bounds = np.array(sections, dtype=np.int64).reshape(len(sections), 2)
    section, _, peak, paper = run_peaks(*args[:4], float(inp.route.end_m), *args[5:], bounds)
    return section.tolist(), peak, paper


def build_result(
    *,
    train: Train,
    route: Route,
    settings: RunSettings,
    profile: LineResistanceProfile,
    ceiling: PiecewiseLinear,
    s: np.ndarray,
    v: np.ndarray,
    t: np.ndarray,
    regime: np.ndarray,
    status: str,
    stall_position_m: float = float("nan"),
    kind: str = "fastest",
    warnings: list[str] | None = None,
    level: np.ndarray | None = None,
    stop_names: list[str] | None = None,
    with_trace: bool = True,
    availability: PiecewiseLinear | None = None,
    voltage: PiecewiseLinear | None = None,
) -> RunResult:
    """Evaluate forces, powers, currents and energies along a run given as points; without
    ``with_trace`` only the summary figures (sections, totals, energy balance), the same numbers.
    ``availability`` and ``voltage`` are the route's ``traction_availability`` and ``line_voltage``
    for this train, computed here when the caller does not have them."""
    from trainsim.sim.profile import line_voltage, traction_availability

    warnings = list(warnings or [])
    train = train.at_gravity(route.gravity_mps2)
    problems = _invariant_violations(s, v, t)
    if problems:
        # never hand out a broken trace as if it were fine
        status = "error"
        warnings.append("internal consistency check failed: " + "; ".join(problems))
    if status == "ok" and kind != "driven" and len(s):
        status = _check_stops(route, s, v, regime, stop_names, warnings)
    m = train.mass_kg
    n = len(s)
    elec = train.electrical
    level = np.ones(n) if level is None else np.asarray(level, dtype=float)
    # the caller's, when it has them (``profile.compile_route``): the same laws of the same route
    voltage = line_voltage(route, train) if voltage is None else voltage
    availability = traction_availability(route, train, voltage) if availability is None else availability
    dt = np.diff(t)

    # work integrals: exact between the events of each stretch's motion (trainsim.sim.energy)
    works, v_end, off_regime = run_works(
        train=train,
        route=route,
        settings=settings,
        profile=profile,
        available=availability,
        s=s,
        v=v,
        regime=regime,
        level=level,
    )
    w_traction, w_braking, w_regen, w_running, w_gradient, w_curve_tunnel = (works[:, q] for q in range(6))

    eta_t = elec.traction_efficiency if elec else 1.0
    eta_r = elec.regenerative_efficiency * elec.receptivity if elec else 0.0
    aux_w = elec.auxiliary_power_w if elec else 0.0
    # an absurd input (an efficiency of 1e-308 given through the API; readers refuse it) overflows
    # here: numpy's warning would be the only sign, so it is silenced and _not_finite says it instead
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        e_traction_line = w_traction / eta_t
        e_regen_line = w_regen * eta_r
        e_aux = aux_w * dt
        e_net = e_traction_line + e_aux - e_regen_line
        e_paper = w_traction * (elec.traction_efficiency if elec else 1.0)

    # sections: between consecutive stop points (a DWELL point ends a section); stretches a .. b-1
    # are the run, b .. d-1 the dwell at its arrival station
    bounds = []
    a = 0
    for b in _section_ends(regime):
        d = b
        while d < n - 1 and regime[d] == DWELL:
            d += 1
        bounds.append((a, b, d))
        a = d
    section_peak = [float("nan")] * len(bounds)
    peak = peak_paper_a = float("nan")
    trace = None
    if with_trace or elec:
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # see _not_finite
            inputs = TraceInputs(
                train, settings, route, profile, ceiling, availability, voltage, s, v, t, regime, level,
                None, w_traction, w_braking, e_regen_line, e_net, eta_t, eta_r, aux_w,
            )  # fmt: skip
            if with_trace:
                # point values in each point's own regime, line resistance from the right of the point
                inputs = inputs._replace(s_right=np.minimum(s + 1e-7, route.end_m))
                trace, peak_current, peak_paper = _trace_and_peaks(inputs, True)
                if elec and n:
                    section_peak = [float(np.nanmax(peak_current[a : b + 1])) for a, b, _ in bounds]
                    peak, peak_paper_a = float(np.nanmax(peak_current)), float(np.nanmax(peak_paper))
            elif n:
                # a summary of an electric train: only the peaks, no point arrays (``run_peaks``)
                section_peak, peak, peak_paper_a = _section_peaks(inputs, [(a, b) for a, b, _ in bounds])

    names = stop_names if stop_names is not None else [st.name for st in route.stops]
    sections = []
    for k, (a, b, d) in enumerate(bounds):
        dwell = float(t[d] - t[b])
        run_time = float(t[b] - t[a])
        dist = float(s[b] - s[a])
        run, stay = slice(a, b), slice(b, d)
        sections.append(
            SectionSummary(
                from_station=names[k] if k < len(names) else "?",
                to_station=names[k + 1] if k + 1 < len(names) else "(end of run)",
                distance_m=dist,
                running_time_s=run_time,
                dwell_s=dwell,
                max_speed_kmh=float(v[a : b + 1].max() / KMH),
                average_speed_kmh=dist / run_time / KMH if run_time > 0 else 0.0,
                peak_current_a=section_peak[k],
                energy_kwh=EnergyFigures(
                    traction=float(w_traction[run].sum() / KWH),
                    braking=float(w_braking[run].sum() / KWH),
                    regenerated=float(e_regen_line[run].sum() / KWH),
                    auxiliary=float((e_aux[run].sum() + e_aux[stay].sum()) / KWH),
                    net=float((e_net[run].sum() + e_net[stay].sum()) / KWH),
                    paper=float(e_paper[run].sum() / KWH),
                ),
            )
        )
    if status == "stalled":
        at = np.array([min(stall_position_m + 1e-7, route.end_m)])
        share = float(availability(at)[0])
        effort_kn = float(train.traction(0.0)) / 1e3
        probe = np.linspace(0.0, max(train.max_speed_mps, 1.0), 201)
        g_n, c_n, t_n = (float(x[0]) for x in _line_forces(profile, m, at, np.zeros(1)))
        resist_kn = (float(train.running_resistance_n(0.0)) + g_n + c_n + t_n) / 1e3
        if share == 0.0:
            why = "the line there is not electrified and the train is electric"
        elif not np.any(np.asarray(train.traction(probe)) > 0.0):
            why = "the train has no tractive effort at any speed (its traction curve is zero)"
        else:
            why = (
                f"its maximum tractive effort at standstill, {share * effort_kn:.1f} kN, is below the "
                f"{resist_kn:.1f} kN of running and line resistance"
            )
        warnings.append(
            f"the train stalls at {stall_position_m:.1f} m: {why}; the result ends there (the best "
            "feasible run); a stronger train, a lighter load or a lower grade is needed"
        )
        if sections:
            last = sections[-1]
            sections[-1] = SectionSummary(
                **{**last.__dict__, "to_station": f"(stalled at {stall_position_m:.0f} m)"}
            )
    if status == "brake_limited" and sections:
        last = sections[-1]
        sections[-1] = SectionSummary(
            **{**last.__dict__, "to_station": f"(brake-limited at {stall_position_m:.0f} m)"}
        )
    warnings.extend(plausibility_warnings(train, route, settings, sections))
    total_time = float(t[-1] - t[0]) if n else 0.0
    dwell_total = float(sum(sec.dwell_s for sec in sections))
    running_time = total_time - dwell_total
    distance = float(s[-1] - s[0]) if n else 0.0
    # energy balance: traction work = kinetic + potential change + resistance + braking work
    kinetic = 0.5 * train.inertial_mass_kg * (v[-1] ** 2 - v[0] ** 2)
    # each sum once: the totals below divide the same values
    traction_sum, braking_sum = w_traction.sum(), w_braking.sum()
    supplied = float(traction_sum)
    spent = float(kinetic + w_gradient.sum() + w_running.sum() + w_curve_tunnel.sum() + braking_sum)
    balance = {
        "traction_work_j": supplied,
        "kinetic_potential_resistance_braking_j": spent,
        "relative_error": (supplied - spent) / max(abs(supplied), 1.0),
        "off_regime_stretches": float(off_regime.sum()),
    }
    totals = EnergyFigures(
        traction=float(traction_sum / KWH),
        braking=float(braking_sum / KWH),
        regenerated=float(e_regen_line.sum() / KWH),
        auxiliary=float(e_aux.sum() / KWH),
        net=float(e_net.sum() / KWH),
        paper=float(e_paper.sum() / KWH),
    )
    bad = _not_finite(totals, peak, peak_paper_a, electric=elec is not None and n > 0)
    if bad:
        # JSON writes a non-finite figure as null: with status ok it would pass as "no figure"
        warnings.append(
            f"{', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not finite (overflow): an input of absurd "
            "magnitude (an efficiency, power factor, force or voltage); check the train's electrical and "
            "effort data"
        )
        if status == "ok":
            status = "not_finite"
    if off_regime.any():
        # stretches whose recorded motion is not their regime's maximum effort (a holding arc labelled
        # braking, a head trace of a multi-point run): their energy is that of the recorded motion
        k_off = np.flatnonzero(off_regime)
        balance["off_regime_max_speed_difference_mps"] = float(np.max(np.abs(v_end[k_off] - v[k_off + 1])))
    return RunResult(
        train_name=train.name,
        route_name=route.name,
        kind=kind,
        status=status,
        warnings=tuple(warnings),
        trace=trace,
        sections=tuple(sections),
        distance_m=distance,
        running_time_s=running_time,
        total_time_s=total_time,
        dwell_s=dwell_total,
        max_speed_kmh=float(v.max() / KMH) if n else 0.0,
        average_speed_kmh=distance / total_time / KMH if total_time > 0 else 0.0,
        average_running_speed_kmh=distance / running_time / KMH if running_time > 0 else 0.0,
        peak_current_a=peak,
        peak_paper_current_a=peak_paper_a,
        energy_kwh=totals,
        energy_balance=balance,
    )


def _not_finite(totals: EnergyFigures, peak_a: float, peak_paper_a: float, *, electric: bool) -> list[str]:
    """Names of the run's figures that are not finite: every energy, and the peak currents of an
    electric train (a train without electrics has no current: NaN there is "none", not an overflow)."""
    # the fields' values directly: asdict deep-copies (a tenth of a summary's Python time)
    bad = [f"the {name} energy" for name in _ENERGY_NAMES if not math.isfinite(getattr(totals, name))]
    if electric:
        for name, value in (("peak current", peak_a), ("paper peak current", peak_paper_a)):
            if not math.isfinite(value):
                bad.append(f"the {name}")
    return bad
