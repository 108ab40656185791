"""Many trains on one power network over time: the network solved at every time step.

Trains enter as trajectories in time (:class:`TrainLoad`): chainage, and the electrical power they
ask for at the pantograph in traction (before any voltage limitation) and offer in regenerative
braking (before curtailment), plus auxiliaries. Any source of trajectories works: a fastest or an
energy-efficient run (:func:`train_load_from_run`), or an operated train later on.

Energies are sums of instantaneous powers times the step (the same rule for every quantity, so the
balance "substation sources = trains at the pantograph + losses" holds step by step to the solver
tolerance).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.power.network import Network
from trainsim.power.onboard import OnboardStorage, assist_power_w, charge_power_w
from trainsim.power.solver import StepGuess, StepLoads, solve_step
from trainsim.sim.result import RunResult

__all__ = ["PowerResult", "TrainLoad", "simulate", "train_load_from_run"]

#: Windows of the moving RMS substation current [s] (rating of rectifiers and transformers).
RMS_WINDOWS_S = (60.0, 900.0, 3600.0)


@dataclass(frozen=True)
class TrainLoad:
    """A train as the network sees it: a trajectory in time with its electrical demand.

    Attributes:
        id: name.
        track: id of the network track it runs on.
        time_s: absolute time of each point [s], non-decreasing; the train is on the network from
            the first to the last point.
        position_m: chainage of each point [m].
        traction_power_w: power asked at the pantograph for traction, before voltage limitation [W].
        regen_power_w: power offered to the line by regenerative braking, before curtailment [W].
        auxiliary_power_w: auxiliaries, drawn all the time the train is on the wire [W].
        power_factor: cos phi of the train (AC) [-].
        onboard_storage: the train's battery / supercapacitor (trainsim.power.onboard), or None.
    """

    id: str
    track: str
    time_s: np.ndarray
    position_m: np.ndarray
    traction_power_w: np.ndarray
    regen_power_w: np.ndarray
    auxiliary_power_w: float = 0.0
    power_factor: float = 1.0
    onboard_storage: OnboardStorage | None = None


def train_load_from_run(
    run: RunResult,
    *,
    id: str,
    track: str,
    departure_s: float = 0.0,
    origin_m: float = 0.0,
    direction: int = 1,
    traction_efficiency: float = 1.0,
    regenerative_efficiency: float = 1.0,
    auxiliary_power_w: float = 0.0,
    power_factor: float = 1.0,
) -> TrainLoad:
    """A train's demand from a single-train run (fastest or energy-efficient).

    Traction power at the pantograph = F_traction v / eta_t, regenerated power offered =
    F_regenerative v eta_r (trainsim.physics.electrical), at each trace point. The run's position
    s maps to chainage ``origin_m + direction (s - s0)``, its time t to ``departure_s + t - t0``.
    """
    if direction not in (1, -1):
        raise InputError("direction must be 1 or -1", field="direction", value=direction, allowed="1, -1")
    tr = run.trace
    t = departure_s + tr.time_s - tr.time_s[0]
    x = origin_m + direction * (tr.position_m - tr.position_m[0])
    trac = tr.traction_force_n * tr.speed_mps / traction_efficiency
    regen = tr.regenerative_braking_force_n * tr.speed_mps * regenerative_efficiency
    return TrainLoad(id, track, t, x, trac, regen, auxiliary_power_w, power_factor)


@dataclass(frozen=True)
class PowerResult:
    """Time series of a power simulation (rows: time steps; columns: trains or substations).

    Train arrays are NaN where the train is not on the network (and its voltage NaN where it is
    off the wire, e.g. in a neutral section). Powers [W], voltages [V], currents [A], times [s].
    ``storage_power_w`` [step, storage] is the power each wayside storage takes at its terminals
    (negative: gives), ``storage_energy_j`` its stored energy at the end of each step.
    ``stray_current_a`` [step] is the current leaving the rails into the earth (NaN where not
    defined: no rail-to-earth conductance, ideal return). With on-board storage,
    ``onboard_charge_w`` / ``onboard_discharge_w`` [step, train] are the powers at its terminals
    and ``onboard_energy_j`` its energy at the end of each step (NaN: no storage, or not on the
    network); ``traction_delivered_w`` then includes the storage's assist and
    ``regen_accepted_w`` is what the line took (the rest: stored or dissipated).
    """

    network: Network
    time_s: np.ndarray
    dt_s: float
    train_ids: tuple[str, ...]
    train_position_m: np.ndarray
    train_voltage_v: np.ndarray
    train_power_w: np.ndarray
    train_current_a: np.ndarray
    traction_demand_w: np.ndarray
    traction_delivered_w: np.ndarray
    regen_offered_w: np.ndarray
    regen_accepted_w: np.ndarray
    substation_power_w: np.ndarray
    substation_source_w: np.ndarray
    substation_current_a: np.ndarray
    line_loss_w: np.ndarray
    substation_loss_w: np.ndarray
    rail_potential_min_v: np.ndarray
    rail_potential_max_v: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    storage_power_w: np.ndarray | None = None
    storage_energy_j: np.ndarray | None = None
    stray_current_a: np.ndarray | None = None
    onboard_charge_w: np.ndarray | None = None
    onboard_discharge_w: np.ndarray | None = None
    onboard_energy_j: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    # ---- derived figures --------------------------------------------------------------------
    def _e(self, p: np.ndarray) -> np.ndarray:
        return np.nansum(p, axis=0) * self.dt_s

    def _storage_net_w(self) -> float:
        return 0.0 if self.storage_power_w is None else float(np.sum(self.storage_power_w))

    def _onboard_kwh(self, p: np.ndarray | None, k: int) -> float:
        return 0.0 if p is None else float(np.nansum(p[:, k]) * self.dt_s) / KWH

    def energy_balance_error(self) -> float:
        """|sources - (trains + losses)| / sources over the whole run [-]."""
        src = float(np.sum(self.substation_source_w) * self.dt_s)
        out = float(
            (
                np.nansum(self.train_power_w)
                + np.sum(self.line_loss_w)
                + np.sum(self.substation_loss_w)
                + self._storage_net_w()
            )
            * self.dt_s
        )
        scale = max(abs(src), float(np.sum(np.abs(self.substation_source_w)) * self.dt_s), 1e-30)
        return abs(src - out) / scale

    def regen_kwh(self) -> dict[str, float]:
        """Regenerated energy [kWh]: offered by the trains' electric brakes, accepted by the line,
        used_by_trains (accepted and neither returned through reversible substations nor stored),
        returned, dissipated (curtailed and not stored on board: burnt on board or taken by friction
        brakes), ``stored_onboard`` with on-board storage (charged at its terminals), and with
        wayside storage ``stored`` (all energy charged into storages, counted as regenerated: their
        thresholds lie above the substations' no-load voltage)."""
        offered = float(np.nansum(self.regen_offered_w) * self.dt_s)
        accepted = float(np.nansum(self.regen_accepted_w) * self.dt_s)
        returned = float(np.sum(np.maximum(-self.substation_power_w, 0.0)) * self.dt_s)
        onboard = 0.0 if self.onboard_charge_w is None else float(np.nansum(self.onboard_charge_w) * self.dt_s)
        out = {
            "offered": offered / KWH,
            "accepted": accepted / KWH,
            "used_by_trains": (accepted - returned) / KWH,
            "returned": returned / KWH,
            "dissipated": (offered - accepted - onboard) / KWH,
        }
        if self.onboard_charge_w is not None:
            out["stored_onboard"] = onboard / KWH
        if self.storage_power_w is not None:
            stored = float(np.sum(np.maximum(self.storage_power_w, 0.0)) * self.dt_s)
            out["stored"] = stored / KWH
            out["used_by_trains"] = (accepted - returned - stored) / KWH
        return out

    def rms_current_a(self, window_s: float) -> np.ndarray:
        """Largest moving RMS current of each substation over a window [A] (NaN if the run is
        shorter than the window)."""
        n = round(window_s / self.dt_s)
        i2 = self.substation_current_a**2
        if n < 1 or n > len(self.time_s):
            return np.full(i2.shape[1], np.nan)
        c = np.vstack([np.zeros((1, i2.shape[1])), np.cumsum(i2, axis=0)])
        return np.sqrt(np.max((c[n:] - c[:-n]) / n, axis=0))

    def overload_events(self, si: int) -> list[dict[str, Any]]:
        """Intervals where substation ``si`` delivers more than its rated power (and whether it
        exceeded its overload power): start_s, duration_s, peak_power_kw, beyond_overload."""
        s = self.network.substations[si]
        if s.rated_power_w is None:
            return []
        p = self.substation_power_w[:, si]
        over = p > s.rated_power_w
        events = []
        k = 0
        while k < len(p):
            if over[k]:
                j = k
                while j < len(p) and over[j]:
                    j += 1
                peak = float(np.max(p[k:j]))
                events.append(
                    {
                        "start_s": float(self.time_s[k]),
                        "duration_s": (j - k) * self.dt_s,
                        "peak_power_kw": peak / 1000,
                        "beyond_overload": bool(s.overload_power_w is not None and peak > s.overload_power_w),
                    }
                )
                k = j
            else:
                k += 1
        return events

    def problems(self) -> tuple[str, list[str]]:
        """(status, warnings): ``not_converged`` if any step failed, ``voltage_out_of_limits`` if a
        pantograph voltage left [Umin2, Umax2], ``feedback_not_converged`` if the runs fed back
        with limited traction did not become consistent, else ``ok``; overloads are warnings."""
        lim = self.network.limits
        warnings: list[str] = []
        status = "ok"
        bad = int(np.sum(~self.converged))
        if bad:
            status = "not_converged"
            warnings.append(f"the network solution did not converge at {bad} of {len(self.converged)} steps")
        v = self.train_voltage_v
        if np.any(np.isfinite(v)):
            vmin, vmax = float(np.nanmin(v)), float(np.nanmax(v))
            if vmin < lim.min2_v - 1e-6 or vmax > lim.max2_v + 1e-6:
                if status == "ok":
                    status = "voltage_out_of_limits"
                warnings.append(
                    f"pantograph voltage {vmin:.0f} .. {vmax:.0f} V leaves Umin2 .. Umax2 = "
                    f"{lim.min2_v:.0f} .. {lim.max2_v:.0f} V"
                )
        for si, s in enumerate(self.network.substations):
            ev = self.overload_events(si)
            if ev:
                beyond = sum(e["beyond_overload"] for e in ev)
                warnings.append(
                    f"substation {s.id} above its rated power {len(ev)} times"
                    + (f" ({beyond} beyond its overload power)" if beyond else "")
                )
        shortfall = np.nansum(self.traction_demand_w - self.traction_delivered_w) * self.dt_s
        if shortfall > 1e-6 * max(np.nansum(self.traction_demand_w) * self.dt_s, 1.0):
            warnings.append(
                f"traction limited by the line voltage: {shortfall / KWH:.3f} kWh not delivered (EN 50388)"
            )
        fb = self.extra.get("feedback")
        if fb and fb.get("enabled") and not fb.get("consistent"):
            if status == "ok":
                status = "feedback_not_converged"
            warnings.append(
                f"voltage-limited traction fed back into the runs {fb['iterations']} times without "
                "becoming consistent"
            )
        err = self.energy_balance_error()
        if err > 1e-6:
            warnings.append(f"energy balance closes only to {err:.2e}")
        return status, warnings

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (see docs/POWER.md for every field)."""
        status, warnings = self.problems()
        e_sub = self._e(self.substation_power_w)
        rms = {f"{int(w)}s": self.rms_current_a(w) for w in RMS_WINDOWS_S}
        substations = []
        for si, s in enumerate(self.network.substations):
            p = self.substation_power_w[:, si]
            i = self.substation_current_a[:, si]
            substations.append(
                {
                    "id": s.id,
                    "energy_kwh": float(e_sub[si]) / KWH,
                    "energy_delivered_kwh": float(np.sum(np.maximum(p, 0)) * self.dt_s) / KWH,
                    "energy_returned_kwh": float(np.sum(np.maximum(-p, 0)) * self.dt_s) / KWH,
                    "peak_power_kw": float(np.max(p)) / 1000,
                    "peak_current_a": float(np.max(np.abs(i))),
                    "rms_current_a": float(np.sqrt(np.mean(i**2))),
                    "rms_current_max_a": {k: _num(v[si]) for k, v in rms.items()},
                    "overload_events": self.overload_events(si),
                }
            )
        trains = []
        for k, tid in enumerate(self.train_ids):
            v = self.train_voltage_v[:, k]
            on = np.isfinite(v)
            trains.append(
                {
                    "id": tid,
                    "min_voltage_v": _num(np.min(v[on])) if on.any() else None,
                    "max_voltage_v": _num(np.max(v[on])) if on.any() else None,
                    "energy_kwh": float(np.nansum(self.train_power_w[:, k]) * self.dt_s) / KWH,
                    "traction_demand_kwh": float(np.nansum(self.traction_demand_w[:, k]) * self.dt_s) / KWH,
                    "traction_delivered_kwh": float(np.nansum(self.traction_delivered_w[:, k]) * self.dt_s)
                    / KWH,
                    "regen_offered_kwh": float(np.nansum(self.regen_offered_w[:, k]) * self.dt_s) / KWH,
                    "regen_accepted_kwh": float(np.nansum(self.regen_accepted_w[:, k]) * self.dt_s) / KWH,
                    "regen_dissipated_kwh": float(
                        np.nansum(self.regen_offered_w[:, k] - self.regen_accepted_w[:, k]) * self.dt_s
                    )
                    / KWH
                    - self._onboard_kwh(self.onboard_charge_w, k),
                    "peak_current_a": _num(np.nanmax(np.abs(self.train_current_a[:, k])))
                    if on.any()
                    else None,
                }
            )
        if self.onboard_energy_j is not None:
            for k, t in enumerate(trains):
                e = self.onboard_energy_j[:, k]
                if np.any(np.isfinite(e)):
                    t["onboard_charged_kwh"] = self._onboard_kwh(self.onboard_charge_w, k)
                    t["onboard_discharged_kwh"] = self._onboard_kwh(self.onboard_discharge_w, k)
                    t["onboard_final_energy_kwh"] = float(e[np.isfinite(e)][-1]) / KWH
        for extra in self.extra.get("trains", []):
            for t in trains:
                if t["id"] == extra["id"]:
                    t.update({k: v for k, v in extra.items() if k != "id"})
        rail_defined = bool(np.any(np.isfinite(self.rail_potential_min_v)))
        out = {
            "status": status,
            "warnings": warnings,
            "network": self.network.name,
            "system": self.network.system,
            "duration_s": float(self.time_s[-1] - self.time_s[0] + self.dt_s) if len(self.time_s) else 0.0,
            "step_s": self.dt_s,
            "substations": substations,
            "trains": trains,
            "substations_energy_kwh": float(np.sum(e_sub)) / KWH,
            "trains_energy_kwh": float(np.nansum(self.train_power_w) * self.dt_s) / KWH,
            "losses_kwh": float(np.sum(self.line_loss_w + self.substation_loss_w) * self.dt_s) / KWH,
            "line_losses_kwh": float(np.sum(self.line_loss_w) * self.dt_s) / KWH,
            "substation_losses_kwh": float(np.sum(self.substation_loss_w) * self.dt_s) / KWH,
            "regen_kwh": self.regen_kwh(),
            "rail_potential_v": {
                "min": _num(np.nanmin(self.rail_potential_min_v)) if rail_defined else None,
                "max": _num(np.nanmax(self.rail_potential_max_v)) if rail_defined else None,
            },
            "stray_current_a": _stray_summary(self.stray_current_a, self.dt_s),
            "energy_balance_error": self.energy_balance_error(),
            "solver": {
                "steps": len(self.time_s),
                "iterations_total": int(np.sum(self.iterations)),
                "iterations_max": int(np.max(self.iterations)) if len(self.iterations) else 0,
                "not_converged_steps": int(np.sum(~self.converged)),
            },
        }
        if self.storage_power_w is not None:
            storages = []
            for i, st in enumerate(self.network.storages):
                p = self.storage_power_w[:, i]
                storages.append(
                    {
                        "id": st.id,
                        "charged_kwh": float(np.sum(np.maximum(p, 0)) * self.dt_s) / KWH,
                        "discharged_kwh": float(np.sum(np.maximum(-p, 0)) * self.dt_s) / KWH,
                        "peak_power_kw": float(np.max(np.abs(p))) / 1000,
                        "final_soc": float(self.storage_energy_j[-1, i] / st.capacity_j),
                        "min_soc": float(np.min(self.storage_energy_j[:, i]) / st.capacity_j),
                        "max_soc": float(np.max(self.storage_energy_j[:, i]) / st.capacity_j),
                    }
                )
            out["storages"] = storages
            out["storages_energy_kwh"] = self._storage_net_w() * self.dt_s / KWH
        out.update({k: v for k, v in self.extra.items() if k != "trains"})
        return out


def _stray_summary(stray: np.ndarray | None, dt_s: float) -> dict[str, float | None]:
    """Mean and largest stray current [A] and the charge leaked [Ah] (None where not defined)."""
    if stray is None or not np.any(np.isfinite(stray)):
        return {"mean": None, "max": None, "charge_ah": None}
    return {
        "mean": float(np.nanmean(stray)),
        "max": float(np.nanmax(stray)),
        "charge_ah": float(np.nansum(stray) * dt_s / 3600.0),
    }


def _num(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def _sample(load: TrainLoad, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Position and demands of a train at times t (NaN outside its trajectory)."""
    present = (t >= load.time_s[0]) & (t <= load.time_s[-1])
    x = np.interp(t, load.time_s, load.position_m)
    pt = np.interp(t, load.time_s, load.traction_power_w)
    pr = np.interp(t, load.time_s, load.regen_power_w)
    return present, x, pt, pr


def _check_load(net: Network, load: TrainLoad, k: int) -> int:
    f = f"trains[{k}]"
    try:
        ti = net.track_index(load.track)
    except InputError as error:
        raise InputError(
            "unknown track", field=f"{f}.track", value=load.track, allowed=", ".join(t.id for t in net.tracks)
        ) from error
    t = net.tracks[ti]
    arrays = (load.time_s, load.position_m, load.traction_power_w, load.regen_power_w)
    if not all(np.all(np.isfinite(a)) for a in arrays) or len(load.time_s) < 2:
        raise InputError(
            "a train's trajectory must be finite with at least two points", field=f, value=load.id
        )
    if np.any(np.diff(load.time_s) < 0):
        raise InputError("a train's time must not decrease", field=f"{f}.time_s", value=load.id)
    if np.any(load.traction_power_w < 0) or np.any(load.regen_power_w < 0) or load.auxiliary_power_w < 0:
        raise InputError("train powers must be >= 0", field=f, value=load.id, allowed=">= 0 W")
    lo, hi = float(np.min(load.position_m)), float(np.max(load.position_m))
    if lo < t.start_m - 1e-6 or hi > t.end_m + 1e-6:
        raise InputError(
            f"train {load.id} runs off the wire of track {t.id}",
            field=f"{f}.origin_km",
            value=f"{lo / 1000:.3f} .. {hi / 1000:.3f} km",
            allowed=f"within the track's {t.start_m / 1000:g} .. {t.end_m / 1000:g} km",
        )
    if not 0 < load.power_factor <= 1:
        raise InputError(
            "invalid power factor", field=f"{f}.power_factor", value=load.power_factor, allowed="0 < x <= 1"
        )
    return ti


def simulate(
    network: Network,
    trains: list[TrainLoad],
    *,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
) -> PowerResult:
    """Solve the network at every time step from ``start_s`` to ``end_s`` (default: the span of
    the trains' trajectories) with step ``dt_s`` [s]."""
    if not trains:
        raise InputError("no trains to simulate", field="trains", allowed="one or more trains")
    if not (np.isfinite(dt_s) and 0 < dt_s <= 60):
        raise InputError("invalid time step", field="step_s", value=dt_s, allowed="0 < step <= 60 s")
    tracks = np.array([_check_load(network, load, k) for k, load in enumerate(trains)], dtype=np.int64)
    t0 = min(float(tr.time_s[0]) for tr in trains) if start_s is None else start_s
    t1 = max(float(tr.time_s[-1]) for tr in trains) if end_s is None else end_s
    n_steps = int(np.floor((t1 - t0) / dt_s + 1e-9)) + 1
    if n_steps > 10_000_000 // max(len(trains), 1):
        raise InputError(
            "too many time steps x trains", field="step_s", value=dt_s, allowed="at most 1e7 train-steps"
        )
    t = t0 + dt_s * np.arange(n_steps)
    nt, ns = len(trains), len(network.substations)
    present = np.zeros((n_steps, nt), dtype=bool)
    xs = np.zeros((n_steps, nt))
    pt = np.zeros((n_steps, nt))
    pr = np.zeros((n_steps, nt))
    supplied = np.zeros((n_steps, nt), dtype=bool)
    for k, load in enumerate(trains):
        present[:, k], xs[:, k], pt[:, k], pr[:, k] = _sample(load, t)
        supplied[:, k] = present[:, k] & network.supplied(int(tracks[k]), xs[:, k])
    aux = np.array([tr.auxiliary_power_w for tr in trains])
    tan_phi = np.array([np.sqrt(1 - tr.power_factor**2) / tr.power_factor for tr in trains])
    if network.system == "dc":
        tan_phi[:] = 0.0
    nan = np.full((n_steps, nt), np.nan)
    volt, power, current = nan.copy(), nan.copy(), nan.copy()
    demand, delivered = nan.copy(), nan.copy()
    offered, accepted = nan.copy(), nan.copy()
    p_sub = np.zeros((n_steps, ns))
    p_src = np.zeros((n_steps, ns))
    i_sub = np.zeros((n_steps, ns))
    line_loss = np.zeros(n_steps)
    sub_loss = np.zeros(n_steps)
    rmin = np.full(n_steps, np.nan)
    rmax = np.full(n_steps, np.nan)
    stray = np.full(n_steps, np.nan)
    converged = np.ones(n_steps, dtype=bool)
    iterations = np.zeros(n_steps, dtype=np.int64)
    on = np.ones(ns, dtype=bool)
    n_st = len(network.storages)
    st_energy = np.array([st.initial_soc * st.capacity_j for st in network.storages])
    st_cap = np.array([st.capacity_j for st in network.storages])
    st_pmax = np.array([st.max_power_w for st in network.storages])
    st_eta = np.sqrt(np.array([st.efficiency for st in network.storages]))
    st_power = np.zeros((n_steps, n_st)) if n_st else None
    st_record = np.zeros((n_steps, n_st)) if n_st else None
    ob = [tr.onboard_storage for tr in trains]
    has_ob = any(o is not None for o in ob)
    if has_ob:
        for k, o in enumerate(ob):
            if o is not None:
                o.check(f"trains[{k}].onboard_storage")

        def _ob(attr: str, default: float) -> np.ndarray:
            return np.array([default if o is None else float(getattr(o, attr)) for o in ob])

        ob_cap = _ob("capacity_j", 0.0)
        ob_pmax = _ob("max_power_w", 0.0)
        ob_eta_c, ob_eta_d = _ob("charge_efficiency", 1.0), _ob("discharge_efficiency", 1.0)
        ob_emin, ob_emax = ob_cap * _ob("min_soc", 0.0), ob_cap * _ob("max_soc", 0.0)
        ob_thr = _ob("assist_above_w", np.inf)
        ob_energy = ob_cap * _ob("initial_soc", 0.0)
        ob_charge, ob_discharge, ob_record = nan.copy(), nan.copy(), nan.copy()
        with_ob = np.array([o is not None for o in ob])
    fixed_v = None
    prev_c = np.full(nt, np.nan)
    prev_r = np.full(nt, np.nan)
    for j in range(n_steps):
        sel = np.flatnonzero(supplied[j])
        # present but off the wire (neutral section): no supply, demands unmet
        off = present[j] & ~supplied[j]
        demand[j, present[j]] = pt[j, present[j]]
        offered[j, present[j]] = pr[j, present[j]]
        delivered[j, off] = 0.0
        accepted[j, off] = 0.0
        power[j, off] = 0.0
        current[j, off] = 0.0
        pt_line = pt[j]
        if has_ob:
            assist = np.where(present[j] & with_ob,
                              assist_power_w(pt[j], ob_energy, ob_thr, ob_pmax, ob_emin, ob_eta_d, dt_s), 0.0)
            pt_line = pt[j] - assist
            delivered[j, off] = assist[off]  # fmt: skip
        loads = StepLoads(tracks[sel], xs[j, sel], pt_line[sel], pr[j, sel], aux[sel], tan_phi[sel])
        if n_st:
            # what each storage can take / give during this step: its power, and its charge
            loads.storage_charge_max_w = np.minimum(st_pmax, (st_cap - st_energy) / (st_eta * dt_s))
            loads.storage_discharge_max_w = np.minimum(st_pmax, st_energy * st_eta / dt_s)
        guess = None if fixed_v is None else StepGuess(fixed_v, prev_c[sel], prev_r[sel])
        sol = solve_step(network, loads, on, guess)
        if sol.guess is not None and sol.converged:
            fixed_v = sol.guess.fixed_v
            prev_c[sel] = sol.guess.train_contact_v
            prev_r[sel] = sol.guess.train_rail_v
        on = sol.substation_on
        if n_st:
            ps = sol.storage_power_w
            st_power[j] = ps
            st_energy = np.clip(
                st_energy + (np.maximum(ps, 0.0) * st_eta - np.maximum(-ps, 0.0) / st_eta) * dt_s, 0.0, st_cap
            )
            st_record[j] = st_energy
        converged[j] = sol.converged
        iterations[j] = sol.iterations
        volt[j, sel] = sol.train_voltage_v
        power[j, sel] = sol.train_power_w
        current[j, sel] = sol.train_current_a
        delivered[j, sel] = pt_line[sel] * sol.traction_share
        accepted[j, sel] = pr[j, sel] * sol.regen_share
        if has_ob:
            delivered[j, sel] += assist[sel]
            on_net = present[j] & with_ob
            curtailed = np.where(on_net, pr[j] - np.nan_to_num(accepted[j]), 0.0)
            charge = np.where(on_net, charge_power_w(curtailed, ob_energy, ob_pmax, ob_emax, ob_eta_c, dt_s), 0.0)
            ob_energy = ob_energy + (ob_eta_c * charge - assist / ob_eta_d) * dt_s
            ob_charge[j, on_net] = charge[on_net]
            ob_discharge[j, on_net] = assist[on_net]
            ob_record[j, on_net] = ob_energy[on_net]
        p_sub[j] = sol.substation_power_w
        p_src[j] = sol.substation_source_w
        i_sub[j] = sol.substation_current_a
        line_loss[j] = sol.line_loss_w
        sub_loss[j] = sol.substation_loss_w
        stray[j] = sol.stray_current_a
        if len(sol.rail_potential_v):
            rmin[j] = np.min(sol.rail_potential_v)
            rmax[j] = np.max(sol.rail_potential_v)
    return PowerResult(
        network=network,
        time_s=t,
        dt_s=dt_s,
        train_ids=tuple(tr.id for tr in trains),
        train_position_m=np.where(present, xs, np.nan),
        train_voltage_v=volt,
        train_power_w=power,
        train_current_a=current,
        traction_demand_w=demand,
        traction_delivered_w=delivered,
        regen_offered_w=offered,
        regen_accepted_w=accepted,
        substation_power_w=p_sub,
        substation_source_w=p_src,
        substation_current_a=i_sub,
        line_loss_w=line_loss,
        substation_loss_w=sub_loss,
        rail_potential_min_v=rmin,
        rail_potential_max_v=rmax,
        converged=converged,
        iterations=iterations,
        storage_power_w=st_power,
        storage_energy_j=st_record,
        stray_current_a=stray,
        onboard_charge_w=ob_charge if has_ob else None,
        onboard_discharge_w=ob_discharge if has_ob else None,
        onboard_energy_j=ob_record if has_ob else None,
    )
