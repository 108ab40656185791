"""Results of a multi-point run: per-vehicle motion, coupler forces, extremes, energy, run summary."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trainsim.constants import KMH, KWH
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.multipoint import kernel as mpk
from trainsim.multipoint.model import MultiPointTrain
from trainsim.sim.codes import BRAKE, COAST, DWELL, TRACTION
from trainsim.sim.profile import LineResistanceProfile, PiecewiseLinear, line_voltage
from trainsim.sim.result import EnergyFigures, RunResult, SectionSummary, build_result


@dataclass(frozen=True)
class CouplerExtreme:
    """The largest draft (tension) or buff (compression) force of a run and where and when it occurred.

    Attributes:
        force_n: the force [N], positive in draft, negative in buff.
        coupler: index of the coupling (0 = between vehicles 0 and 1).
        behind_vehicle: name of the vehicle in front of the coupling.
        time_s: when [s].
        head_position_m: where the head was [m].
        coupler_position_m: where the coupling was on the route [m].
    """

    force_n: float
    coupler: int
    behind_vehicle: str
    time_s: float
    head_position_m: float
    coupler_position_m: float

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["force_kn"] = self.force_n / 1e3
        return d


@dataclass(frozen=True)
class CapacityExceedance:
    """A coupling whose force passed its rated capacity during a run (its peak in that direction).

    Attributes:
        coupler: index of the coupling (0 = between vehicles 0 and 1).
        behind_vehicle: name of the vehicle in front of the coupling.
        mode: ``draft`` (tension) or ``buff`` (compression).
        force_n: the coupling's peak force in that direction [N] (positive in draft, negative in buff).
        capacity_n: its rated capacity [N] (positive).
        time_s: when the peak occurred [s].
        head_position_m: where the head was [m].
        coupler_position_m: where the coupling was on the route [m].
    """

    coupler: int
    behind_vehicle: str
    mode: str
    force_n: float
    capacity_n: float
    time_s: float
    head_position_m: float
    coupler_position_m: float

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["force_kn"] = self.force_n / 1e3
        d["capacity_kn"] = self.capacity_n / 1e3
        return d


def capacity_exceedances(mptrain: MultiPointTrain, ext: np.ndarray) -> tuple[CapacityExceedance, ...]:
    """Every coupling whose peak draft or buff force (taken at every integration step by the kernel)
    passed its capacity (``CouplerModel.draft_capacity_n`` / ``buff_capacity_n``), worst first."""
    nc = mptrain.n_vehicles - 1
    if len(ext) < mpk.N_E + mpk.N_EK * nc:
        return ()
    per = ext[mpk.N_E : mpk.N_E + mpk.N_EK * nc].reshape(nc, mpk.N_EK)
    offsets = np.cumsum(mptrain.length_m[:-1])
    out = []
    for k, coupler in enumerate(mptrain.couplers):
        for mode, cap, f, t, head in (
            ("draft", coupler.draft_capacity_n, per[k, mpk.EK_DRAFT], per[k, mpk.EK_DRAFT_T],
             per[k, mpk.EK_DRAFT_HEAD]),
            ("buff", coupler.buff_capacity_n, -per[k, mpk.EK_BUFF], per[k, mpk.EK_BUFF_T],
             per[k, mpk.EK_BUFF_HEAD]),
        ):  # fmt: skip
            if cap is not None and np.isfinite(f) and f > cap:
                out.append(
                    CapacityExceedance(
                        coupler=k,
                        behind_vehicle=mptrain.vehicles[k].name,
                        mode=mode,
                        force_n=float(f if mode == "draft" else -f),
                        capacity_n=float(cap),
                        time_s=float(t),
                        head_position_m=float(head),
                        coupler_position_m=float(head - offsets[k]),
                    )
                )
    out.sort(key=lambda e: -abs(e.force_n) / e.capacity_n)
    return tuple(out)


def capacity_warnings(exceedances: tuple[CapacityExceedance, ...]) -> list[str]:
    """One warning per direction: how many couplings passed their capacity, and the worst of them with
    its vehicle, force, time and place."""
    out = []
    for mode in ("buff", "draft"):
        these = [e for e in exceedances if e.mode == mode]
        if not these:
            continue
        e = these[0]
        others = f" (and {len(these) - 1} other couplings)" if len(these) > 1 else ""
        out.append(
            f"{mode} force above the coupler capacity: {abs(e.force_n) / 1e6:.2f} MN at coupling {e.coupler} "
            f"(behind vehicle {e.coupler} '{e.behind_vehicle}') at t = {e.time_s:.1f} s, coupling at "
            f"{e.coupler_position_m:.0f} m (head at {e.head_position_m:.0f} m); capacity "
            f"{e.capacity_n / 1e6:.2f} MN{others}"
        )
    return out


@dataclass(frozen=True)
class EnergyAccount:
    """Energy of a multi-point run at the wheels [J].

    ``traction`` is balanced by the rest: kinetic energy change (all vehicles, with their rotating
    masses), spring energy change, damper losses, running resistance, gradient (potential energy),
    curve and tunnel resistance, braking (friction + electric + the kinetic energy left when the train
    is declared at rest). ``balance_error`` is (traction - sum of the rest) / traction.
    """

    traction_j: float
    kinetic_change_j: float
    spring_change_j: float
    damper_j: float
    running_j: float
    gradient_j: float
    curve_j: float
    tunnel_j: float
    friction_braking_j: float
    electric_braking_j: float
    held_j: float
    spring_work_j: float

    @property
    def braking_j(self) -> float:
        return self.friction_braking_j + self.electric_braking_j + self.held_j

    @property
    def spent_j(self) -> float:
        return (
            self.kinetic_change_j
            + self.spring_change_j
            + self.damper_j
            + self.running_j
            + self.gradient_j
            + self.curve_j
            + self.tunnel_j
            + self.braking_j
        )

    @property
    def balance_error(self) -> float:
        return (self.traction_j - self.spent_j) / max(abs(self.traction_j), 1.0)

    def to_dict(self) -> dict[str, float]:
        d = dataclasses.asdict(self)
        d["braking_j"] = self.braking_j
        d["balance_error"] = self.balance_error
        return d


@dataclass(frozen=True, eq=False)
class MultiPointResult:
    """A multi-point run.

    Per-vehicle arrays have one row per recorded instant and one column per vehicle (head first);
    coupler arrays one column per coupling (k between vehicles k and k+1).

    Attributes:
        run: the run summary as for the single-point model (trace of the head position and the train's
            mean speed, sections, energy, current), built from the multi-point forces.
        time_s: recorded instants [s].
        position_m: position of each vehicle's front [m].
        speed_mps: speed of each vehicle [m/s].
        acceleration_mps2: acceleration of each vehicle over the step before the instant [m/s^2].
        coupler_force_n: tension of each coupling (spring + damper), positive in draft [N].
        max_draft: largest tension of the run (taken at every integration step).
        max_buff: largest compression (most negative force).
        energy: the energy account at the wheels.
        statistics: integrator figures (steps, Newton iterations, sub-steps, wall time).
        capacity_exceedances: the couplings whose force passed their rated capacity (each with a
            warning in ``warnings``), worst first.
    """

    mptrain: MultiPointTrain
    run: RunResult
    time_s: np.ndarray
    position_m: np.ndarray
    speed_mps: np.ndarray
    acceleration_mps2: np.ndarray
    coupler_force_n: np.ndarray
    max_draft: CouplerExtreme
    max_buff: CouplerExtreme
    energy: EnergyAccount
    status: str
    warnings: tuple[str, ...] = ()
    statistics: dict[str, float] = field(default_factory=dict)
    regime: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))
    command: np.ndarray = field(default_factory=lambda: np.zeros(0))
    capacity_exceedances: tuple[CapacityExceedance, ...] = ()

    # ---------------------------------------------------------------- convenience
    @property
    def vehicle_names(self) -> list[str]:
        return [v.name for v in self.mptrain.vehicles]

    @property
    def running_time_s(self) -> float:
        return self.run.running_time_s

    @property
    def energy_kwh(self) -> EnergyFigures:
        return self.run.energy_kwh

    @property
    def head_position_m(self) -> np.ndarray:
        return self.position_m[:, 0]

    @property
    def mean_speed_mps(self) -> np.ndarray:
        """Inertial-mass-weighted mean speed of the train [m/s]."""
        m = self.mptrain.inertial_mass_kg
        return self.speed_mps @ m / m.sum()

    def coupler_force_at(self, coupler: int) -> np.ndarray:
        """Force of one coupling over the recorded instants [N]."""
        return self.coupler_force_n[:, coupler]

    def summary(self) -> dict[str, Any]:
        """The single-point summary (``RunResult.summary()``) plus a ``multi_point`` block."""
        out = self.run.summary()
        out["multi_point"] = {
            "vehicles": self.mptrain.n_vehicles,
            "locomotives": [int(i) for i in self.mptrain.locomotive_indices],
            "max_draft": self.max_draft.to_dict(),
            "max_buff": self.max_buff.to_dict(),
            "capacity_exceedances": [e.to_dict() for e in self.capacity_exceedances],
            "energy_j": self.energy.to_dict(),
            "statistics": dict(self.statistics),
        }
        return out

    def vehicle_dataframe(self):
        """Per-vehicle motion in long form: time, vehicle, name, position, speed, acceleration."""
        import pandas as pd

        nt, nv = self.position_m.shape
        return pd.DataFrame(
            {
                "time_s": np.repeat(self.time_s, nv),
                "vehicle": np.tile(np.arange(nv), nt),
                "name": np.tile(np.array(self.vehicle_names, dtype=object), nt),
                "position_m": self.position_m.ravel(),
                "speed_mps": self.speed_mps.ravel(),
                "acceleration_mps2": self.acceleration_mps2.ravel(),
            }
        )

    def coupler_dataframe(self):
        """Coupler forces in wide form: one column per coupling (``c0`` ... ), index time [s]."""
        import pandas as pd

        cols = {f"c{k}": self.coupler_force_n[:, k] for k in range(self.coupler_force_n.shape[1])}
        return pd.DataFrame(cols, index=pd.Index(self.time_s, name="time_s"))


# ---------------------------------------------------------------------------------------------- building
def _section_ends(regime: np.ndarray) -> list[int]:
    """Index of the arrival point of each section (as ``trainsim.sim.result`` counts them)."""
    n = len(regime)
    is_dwell = regime == DWELL
    first = is_dwell & np.concatenate([[False], ~is_dwell[:-1]])
    if n:
        first[0] = False
    ends = np.flatnonzero(first).tolist()
    if n and (not ends or ends[-1] != n - 1) and regime[-1] != DWELL:
        ends.append(n - 1)
    return ends


def extreme(mptrain: MultiPointTrain, ext: np.ndarray, draft: bool) -> CouplerExtreme:
    """The extreme recorded by the kernel as a CouplerExtreme."""
    if draft:
        f, k, t, head = ext[mpk.E_DRAFT], ext[mpk.E_DRAFT_K], ext[mpk.E_DRAFT_T], ext[mpk.E_DRAFT_HEAD]
    else:
        f, k, t, head = ext[mpk.E_BUFF], ext[mpk.E_BUFF_K], ext[mpk.E_BUFF_T], ext[mpk.E_BUFF_HEAD]
    if not np.isfinite(f):
        return CouplerExtreme(0.0, 0, mptrain.vehicles[0].name, 0.0, float("nan"), float("nan"))
    k = int(k)
    return CouplerExtreme(
        force_n=float(f),
        coupler=k,
        behind_vehicle=mptrain.vehicles[k].name,
        time_s=float(t),
        head_position_m=float(head),
        coupler_position_m=float(head - np.sum(mptrain.length_m[: k + 1])),
    )


def build_multipoint_result(
    *,
    mptrain: MultiPointTrain,
    route: Route,
    settings: RunSettings,
    profile: LineResistanceProfile,
    ceiling: PiecewiseLinear,
    rec_t: np.ndarray,
    rec_x: np.ndarray,
    rec_v: np.ndarray,
    rec_a: np.ndarray,
    rec_T: np.ndarray,
    rec_agg: np.ndarray,
    dwell_mask: np.ndarray,
    ext: np.ndarray,
    status: str,
    kind: str,
    warnings: list[str],
    statistics: dict[str, float],
    stop_names: list[str] | None = None,
    rest_speed_mps: float = 5e-3,
) -> MultiPointResult:
    """Assemble the result; the single-point summary is built by ``build_result`` from the head position
    and the mean speed, then its forces, powers and energies are replaced by the multi-point ones."""
    train = mptrain.train
    warnings = list(warnings)
    agg = rec_agg
    head = agg[:, mpk.R_HEAD]
    speed = agg[:, mpk.R_SPEED]
    # the summary trace needs non-decreasing positions and speeds >= 0; the train may settle back by a
    # few millimetres at a stop, which the per-vehicle arrays keep
    back = float(np.max(np.maximum.accumulate(head) - head)) if len(head) else 0.0
    if back > 0.5:
        warnings.append(f"the train rolled back by up to {back:.1f} m")
    s = np.maximum.accumulate(head)
    v = np.maximum(speed, 0.0)
    # at a stop the model declares the train at rest when its mean speed is below rest_speed_mps (the
    # regularised dry friction, tanh(v / standstill_speed_mps), lets the vehicles creep by a fraction
    # of that while the couplers relax); the summary trace shows those points at 0, the per-vehicle
    # arrays keep the speeds
    at_rest = dwell_mask & (np.abs(speed) < rest_speed_mps)
    v[at_rest] = 0.0
    if np.min(speed, initial=0.0) < -0.05:
        warnings.append(f"the train moved backwards (mean speed down to {np.min(speed):.2f} m/s)")
    exceedances = capacity_exceedances(mptrain, ext)
    warnings += capacity_warnings(exceedances)
    u = agg[:, mpk.R_COMMAND]
    regime = np.where(u > 1e-9, TRACTION, np.where(u < -1e-9, BRAKE, COAST)).astype(np.int8)
    regime[dwell_mask] = DWELL
    level = np.abs(u)
    base = build_result(
        train=train,
        route=route,
        settings=settings,
        profile=profile,
        ceiling=ceiling,
        s=s,
        v=v,
        t=rec_t,
        regime=regime,
        status=status,
        stall_position_m=float(s[-1]) if status == "stalled" and len(s) else float("nan"),
        kind=kind,
        warnings=warnings,
        level=level,
        stop_names=stop_names,
    )

    elec = train.electrical
    eta_t = elec.traction_efficiency if elec else 1.0
    eta_r = elec.regenerative_efficiency * elec.receptivity if elec else 0.0
    aux = elec.auxiliary_power_w if elec else 0.0
    w = {name: agg[:, mpk.R_W0 + getattr(mpk, "A_" + name)] for name in (
        "TRACTION", "FRICTION", "ELECTRIC", "RUNNING", "GRADIENT", "CURVE", "TUNNEL", "DAMPER",
        "SPRING_WORK", "HELD",
    )}  # fmt: skip
    t0 = rec_t[0] if len(rec_t) else 0.0
    braking_cum = w["FRICTION"] + w["ELECTRIC"] + w["HELD"]
    regen_cum = w["ELECTRIC"] * eta_r
    net_cum = w["TRACTION"] / eta_t + aux * (rec_t - t0) - regen_cum
    p_tr = agg[:, mpk.R_TRACTION_POWER]
    p_el = agg[:, mpk.R_ELECTRIC_POWER]
    el_power = p_tr / eta_t + aux - p_el * eta_r
    s_right = np.minimum(s + 1e-7, route.end_m)
    if elec:
        u_line = line_voltage(route, train)(s_right)
        safe = np.where(u_line > 0, u_line, 1.0)
        current = np.where(u_line > 0, el_power / (safe * elec.power_factor), 0.0)
        paper_current = np.where(u_line > 0, p_tr * eta_t / (safe * elec.power_factor), 0.0)
        peak_power = np.where(np.isfinite(agg[:, mpk.R_PEAK_POWER]), agg[:, mpk.R_PEAK_POWER] + aux, el_power)
        peak_current = np.where(
            u_line > 0, np.maximum(peak_power, el_power) / (safe * elec.power_factor), 0.0
        )
    else:
        current = paper_current = peak_current = np.full(len(s), np.nan)
    m_in = mptrain.inertial_mass_kg
    trace = dataclasses.replace(
        base.trace,
        acceleration_mps2=rec_a @ m_in / m_in.sum(),
        traction_force_n=agg[:, mpk.R_TRACTION],
        braking_force_n=agg[:, mpk.R_ELECTRIC] + agg[:, mpk.R_FRICTION],
        regenerative_braking_force_n=agg[:, mpk.R_ELECTRIC],
        friction_braking_force_n=agg[:, mpk.R_FRICTION],
        running_resistance_n=agg[:, mpk.R_RUNNING],
        gradient_resistance_n=agg[:, mpk.R_GRADIENT],
        curve_resistance_n=agg[:, mpk.R_CURVE],
        tunnel_resistance_n=agg[:, mpk.R_TUNNEL],
        mechanical_power_w=p_tr,
        electrical_power_w=el_power,
        line_current_a=current,
        paper_power_w=p_tr * eta_t,
        paper_line_current_a=paper_current,
        traction_work_j=w["TRACTION"] - w["TRACTION"][0],
        braking_work_j=braking_cum - braking_cum[0],
        regenerated_energy_j=regen_cum - regen_cum[0],
        electrical_energy_j=net_cum - net_cum[0],
    )

    def figures(a: int, b: int, d: int) -> EnergyFigures:
        return EnergyFigures(
            traction=float((w["TRACTION"][b] - w["TRACTION"][a]) / KWH),
            braking=float((braking_cum[b] - braking_cum[a]) / KWH),
            regenerated=float((regen_cum[b] - regen_cum[a]) / KWH),
            auxiliary=float(aux * (rec_t[d] - rec_t[a]) / KWH),
            net=float((net_cum[d] - net_cum[a]) / KWH),
            paper=float((w["TRACTION"][b] - w["TRACTION"][a]) * eta_t / KWH),
        )

    sections: list[SectionSummary] = []
    a = 0
    n = len(s)
    for k, b in enumerate(_section_ends(regime)):
        d = b
        while d < n - 1 and regime[d] == DWELL:
            d += 1
        if k < len(base.sections):
            sec = base.sections[k]
            sections.append(
                dataclasses.replace(
                    sec,
                    energy_kwh=figures(a, b, d),
                    peak_current_a=float(np.nanmax(peak_current[a : b + 1])) if elec else float("nan"),
                )
            )
        a = d
    last = n - 1
    energy = EnergyAccount(
        traction_j=float(w["TRACTION"][last] - w["TRACTION"][0]),
        kinetic_change_j=float(agg[last, mpk.R_KINETIC] - agg[0, mpk.R_KINETIC]),
        spring_change_j=float(agg[last, mpk.R_SPRING] - agg[0, mpk.R_SPRING]),
        damper_j=float(w["DAMPER"][last] - w["DAMPER"][0]),
        running_j=float(w["RUNNING"][last] - w["RUNNING"][0]),
        gradient_j=float(w["GRADIENT"][last] - w["GRADIENT"][0]),
        curve_j=float(w["CURVE"][last] - w["CURVE"][0]),
        tunnel_j=float(w["TUNNEL"][last] - w["TUNNEL"][0]),
        friction_braking_j=float(w["FRICTION"][last] - w["FRICTION"][0]),
        electric_braking_j=float(w["ELECTRIC"][last] - w["ELECTRIC"][0]),
        held_j=float(w["HELD"][last] - w["HELD"][0]),
        spring_work_j=float(w["SPRING_WORK"][last] - w["SPRING_WORK"][0]),
    )
    balance = {
        "traction_work_j": energy.traction_j,
        "kinetic_potential_resistance_braking_j": energy.spent_j,
        "relative_error": energy.balance_error,
        "spring_energy_change_j": energy.spring_change_j,
        "damper_losses_j": energy.damper_j,
    }
    run = dataclasses.replace(
        base,
        trace=trace,
        sections=tuple(sections),
        peak_current_a=float(np.nanmax(peak_current)) if elec and n else float("nan"),
        peak_paper_current_a=float(np.nanmax(paper_current)) if elec and n else float("nan"),
        energy_kwh=figures(0, last, last),
        energy_balance=balance,
    )
    return MultiPointResult(
        mptrain=mptrain,
        run=run,
        time_s=rec_t,
        position_m=rec_x,
        speed_mps=rec_v,
        acceleration_mps2=rec_a,
        coupler_force_n=rec_T,
        max_draft=extreme(mptrain, ext, True),
        max_buff=extreme(mptrain, ext, False),
        energy=energy,
        status=base.status,
        warnings=base.warnings,
        statistics=statistics,
        regime=regime,
        command=u,
        capacity_exceedances=exceedances,
    )


def max_speed_kmh(result: MultiPointResult) -> float:
    """Highest speed of any vehicle [km/h]."""
    return float(np.max(result.speed_mps) / KMH)
