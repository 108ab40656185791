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

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.power.network import Network
from trainsim.power.onboard import OnboardStorage, assist_power_w, charge_power_w
from trainsim.power.solver import StepGuess, StepLoads, solve_step
from trainsim.sim.result import RunResult

__all__ = ["CompactPowerResult", "PowerResult", "TrainLoad", "simulate", "train_load_from_run"]

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
    contact_loss_w: np.ndarray | None = None
    return_loss_w: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    # ---- derived figures --------------------------------------------------------------------
    def _e(self, p: np.ndarray) -> np.ndarray:
        return np.nansum(p, axis=0) * self.dt_s

    def _storage_net_w(self) -> float:
        return 0.0 if self.storage_power_w is None else float(np.sum(self.storage_power_w))

    def _onboard_kwh(self, p: np.ndarray | None, k: int) -> float:
        return 0.0 if p is None else float(np.nansum(self.train_series(p, k)) * self.dt_s) / KWH

    def _train_kwh(self, a: np.ndarray, k: int) -> float:
        return float(np.nansum(self.train_series(a, k)) * self.dt_s) / KWH

    def train_series(self, a: np.ndarray, k: int) -> np.ndarray:
        """Train k's values of a train field (``train_voltage_v``, ...): one per time step, NaN
        where it is not on the network."""
        return a[:, k]

    def train_time_s(self, k: int) -> np.ndarray:
        """The times of :meth:`train_series` [s]."""
        return self.time_s

    def losses_kwh(self) -> dict[str, float | None]:
        """The losses over the run split by where they arise [kWh]: ``contact_line_kwh`` (contact
        lines and the contact-to-return leakage; AC: the loop impedance, return included),
        ``return_kwh`` (DC rails in series and leaking to earth; 0 with an ideal return and for AC),
        ``substation_internal_kwh`` (internal resistances: source energy less busbar energy) and
        ``total_kwh``, their sum (``losses_kwh``). The substations' energy at their sources equals
        the trains' at the pantographs plus ``total_kwh`` (plus the wayside storages' intake); at
        their busbars, the trains' plus the contact line's and the return's (None: not recorded)."""
        line = float(np.sum(self.line_loss_w) * self.dt_s)
        sub = float(np.sum(self.substation_loss_w) * self.dt_s)
        if self.contact_loss_w is None or self.return_loss_w is None:
            contact = ret = None
        else:
            contact = float(np.sum(self.contact_loss_w) * self.dt_s) / KWH
            ret = float(np.sum(self.return_loss_w) * self.dt_s) / KWH
        return {
            "contact_line_kwh": contact,
            "return_kwh": ret,
            "substation_internal_kwh": sub / KWH,
            "total_kwh": (line + sub) / KWH,
        }

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
        onboard = (
            0.0 if self.onboard_charge_w is None else float(np.nansum(self.onboard_charge_w) * self.dt_s)
        )
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
        e_src = self._e(self.substation_source_w)
        rms = {f"{int(w)}s": self.rms_current_a(w) for w in RMS_WINDOWS_S}
        substations = []
        for si, s in enumerate(self.network.substations):
            p = self.substation_power_w[:, si]
            i = self.substation_current_a[:, si]
            substations.append(
                {
                    "id": s.id,
                    "energy_kwh": float(e_sub[si]) / KWH,
                    "energy_at_source_kwh": float(e_src[si]) / KWH,
                    "internal_losses_kwh": float(e_src[si] - e_sub[si]) / KWH,
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
            v = self.train_series(self.train_voltage_v, k)
            on = np.isfinite(v)
            offered = self.train_series(self.regen_offered_w, k)
            accepted = self.train_series(self.regen_accepted_w, k)
            trains.append(
                {
                    "id": tid,
                    "min_voltage_v": _num(np.min(v[on])) if on.any() else None,
                    "max_voltage_v": _num(np.max(v[on])) if on.any() else None,
                    "energy_kwh": self._train_kwh(self.train_power_w, k),
                    "traction_demand_kwh": self._train_kwh(self.traction_demand_w, k),
                    "traction_delivered_kwh": self._train_kwh(self.traction_delivered_w, k),
                    "regen_offered_kwh": float(np.nansum(offered) * self.dt_s) / KWH,
                    "regen_accepted_kwh": float(np.nansum(accepted) * self.dt_s) / KWH,
                    "regen_dissipated_kwh": float(np.nansum(offered - accepted) * self.dt_s) / KWH
                    - self._onboard_kwh(self.onboard_charge_w, k),
                    "peak_current_a": _num(np.nanmax(np.abs(self.train_series(self.train_current_a, k))))
                    if on.any()
                    else None,
                }
            )
        if self.onboard_energy_j is not None:
            for k, t in enumerate(trains):
                e = self.train_series(self.onboard_energy_j, k)
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
            "substations_source_energy_kwh": float(np.sum(e_src)) / KWH,
            "trains_energy_kwh": float(np.nansum(self.train_power_w) * self.dt_s) / KWH,
            "losses_kwh": float(np.sum(self.line_loss_w + self.substation_loss_w) * self.dt_s) / KWH,
            "line_losses_kwh": float(np.sum(self.line_loss_w) * self.dt_s) / KWH,
            "substation_losses_kwh": float(np.sum(self.substation_loss_w) * self.dt_s) / KWH,
            "losses": self.losses_kwh(),
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


@dataclass(frozen=True)
class CompactPowerResult(PowerResult):
    """A :class:`PowerResult` whose train fields keep only the steps where each train is on the
    network (``simulate(traces="on_network")``, for a whole day): every train field is one flat
    array, train k's values at rows ``train_offset[k] : train_offset[k + 1]``, its steps
    ``train_step_range[k, 0] ..`` of ``time_s``. Sums, extremes, the summary and the status are the
    same as the full result's (the same values, without the NaN padding); read one train's series
    with :meth:`train_series` and :meth:`train_time_s`, and :meth:`full` gives the dense result
    back for short spans (tables and plots that take the time x train arrays)."""

    train_step_range: np.ndarray | None = None
    train_offset: np.ndarray | None = None

    def train_series(self, a: np.ndarray, k: int) -> np.ndarray:
        return a[self.train_offset[k] : self.train_offset[k + 1]]

    def train_time_s(self, k: int) -> np.ndarray:
        return self.time_s[self.train_step_range[k, 0] : self.train_step_range[k, 1]]

    def memory_bytes(self) -> int:
        """Bytes held by the result's arrays."""
        return sum(
            v.nbytes
            for v in (getattr(self, f.name) for f in dataclasses.fields(self))
            if isinstance(v, np.ndarray)
        )

    def fits_full(self) -> bool:
        """Whether :meth:`full` is within :data:`MAX_FULL_TRAIN_STEPS`."""
        return len(self.time_s) * len(self.train_ids) <= MAX_FULL_TRAIN_STEPS

    def full(self) -> PowerResult:
        """The same result with time x train arrays (NaN where a train is not on the network); the
        same cap as ``simulate(traces="full")``."""
        n, nt = len(self.time_s), len(self.train_ids)
        if not self.fits_full():
            raise InputError(
                f"too many time steps x trains ({n} x {nt}) for time x train arrays",
                field="simulation.traces",
                value="full",
                allowed=f"at most {MAX_FULL_TRAIN_STEPS:.0e} train-steps: a shorter span (start_s, end_s)",
            )
        flat = {f.name: getattr(self, f.name) for f in dataclasses.fields(PowerResult)}
        train = _Flat.from_fields(flat)
        flat.update(train.dense(n, self.train_step_range, self.train_offset))
        return PowerResult(**flat)


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


#: Train-steps kept with every train's series over the whole span (``traces="full"``): the dense
#: arrays take about 100 bytes per train-step, so 1e7 is about 1 GB.
MAX_FULL_TRAIN_STEPS = 10_000_000
#: Train-steps on the network kept with ``traces="on_network"`` (about 90 bytes each with on-board
#: storage, 65 without; an 18 h metro day of 720 departures is about 3e5).
MAX_ON_NETWORK_TRAIN_STEPS = 10_000_000
#: Time steps at most (the substation and network series: about 8 (3 n_substations + 7) bytes
#: per step; 1e6 is 11.6 days at 1 s).
MAX_STEPS = 1_000_000


def _step_range(t: np.ndarray, load: TrainLoad) -> tuple[int, int]:
    """(first, last + 1) step of the time grid ``t`` at which the train is on the network: the
    steps with load.time_s[0] <= t <= load.time_s[-1] (the same comparisons as a mask over t)."""
    return (
        int(np.searchsorted(t, load.time_s[0], side="left")),
        int(np.searchsorted(t, load.time_s[-1], side="right")),
    )


def simulate(
    network: Network,
    trains: list[TrainLoad],
    *,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
    traces: str = "full",
) -> PowerResult:
    """Solve the network at every time step from ``start_s`` to ``end_s`` (default: the span of
    the trains' trajectories) with step ``dt_s`` [s].

    ``traces``: ``full`` keeps each train's series over the whole span (NaN where it is not on the
    network; a :class:`PowerResult`, at most :data:`MAX_FULL_TRAIN_STEPS` steps x trains);
    ``on_network`` keeps them only at the steps where the train is on the network (a
    :class:`CompactPowerResult`, for a whole day: memory grows with the trains' running time, not
    with the span times the number of trains). Both solve the same steps in the same order with the
    same warm starts and storage states, so their figures are equal bit for bit.
    """
    if not trains:
        raise InputError("no trains to simulate", field="trains", allowed="one or more trains")
    if not (np.isfinite(dt_s) and 0 < dt_s <= 60):
        raise InputError("invalid time step", field="step_s", value=dt_s, allowed="0 < step <= 60 s")
    if traces not in ("full", "on_network"):
        raise InputError(
            "unknown traces", field="simulation.traces", value=traces, allowed="full, on_network"
        )
    tracks = np.array([_check_load(network, load, k) for k, load in enumerate(trains)], dtype=np.int64)
    t0 = min(float(tr.time_s[0]) for tr in trains) if start_s is None else start_s
    t1 = max(float(tr.time_s[-1]) for tr in trains) if end_s is None else end_s
    n_steps = int(np.floor((t1 - t0) / dt_s + 1e-9)) + 1
    if n_steps > MAX_STEPS:
        raise InputError(
            f"too many time steps ({n_steps}) for the substation series",
            field="step_s",
            value=dt_s,
            allowed=f"at most {MAX_STEPS} steps: a longer step or a shorter span (start_s, end_s)",
        )
    nt = len(trains)
    if traces == "full" and n_steps * nt > MAX_FULL_TRAIN_STEPS:
        raise InputError(
            f"too many time steps x trains ({n_steps} x {nt}) to keep every train's series over the whole span",
            field="simulation.traces",
            value=traces,
            allowed=f"at most {MAX_FULL_TRAIN_STEPS:.0e} train-steps; for a whole day keep the series only while "
            "each train runs (traces: on_network, or simulate(..., traces='on_network')), or shorten the span "
            "(start_s, end_s)",
        )
    t = t0 + dt_s * np.arange(n_steps)
    ranges = np.array([_step_range(t, load) for load in trains], dtype=np.int64).reshape(nt, 2)
    ranges[:, 1] = np.maximum(ranges[:, 1], ranges[:, 0])
    counts = ranges[:, 1] - ranges[:, 0]
    offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    if traces == "on_network" and offset[-1] > MAX_ON_NETWORK_TRAIN_STEPS:
        raise InputError(
            f"the trains are on the network for {offset[-1]} train-steps in all",
            field="step_s",
            value=dt_s,
            allowed=f"at most {MAX_ON_NETWORK_TRAIN_STEPS:.0e}: a longer step, or the day in parts (start_s, end_s)",
        )
    flat = _Flat.sample(network, trains, tracks, t, ranges, offset)
    series = _Series.empty(n_steps, len(network.substations), len(network.storages))
    _solve_steps(network, trains, tracks, dt_s, ranges, offset, flat, series)
    common = {
        "network": network,
        "time_s": t,
        "dt_s": dt_s,
        "train_ids": tuple(tr.id for tr in trains),
        **series.fields(),
    }
    if traces == "on_network":
        return CompactPowerResult(**common, **flat.fields(), train_step_range=ranges, train_offset=offset)
    return PowerResult(**common, **flat.dense(n_steps, ranges, offset))


@dataclass
class _Flat:
    """Per train and step on the network, train after train (train k: rows offset[k]:offset[k+1],
    its steps ranges[k, 0] ..)."""

    position_m: np.ndarray
    traction_w: np.ndarray
    regen_w: np.ndarray
    supplied: np.ndarray
    voltage_v: np.ndarray
    power_w: np.ndarray
    current_a: np.ndarray
    delivered_w: np.ndarray
    accepted_w: np.ndarray
    ob_charge_w: np.ndarray | None
    ob_discharge_w: np.ndarray | None
    ob_energy_j: np.ndarray | None

    @classmethod
    def sample(
        cls,
        network: Network,
        trains: list[TrainLoad],
        tracks: np.ndarray,
        t: np.ndarray,
        ranges: np.ndarray,
        offset: np.ndarray,
    ) -> _Flat:
        n = int(offset[-1])
        x, pt, pr = np.zeros(n), np.zeros(n), np.zeros(n)
        sup = np.zeros(n, dtype=bool)
        for k, load in enumerate(trains):
            a, b = offset[k], offset[k + 1]
            tk = t[ranges[k, 0] : ranges[k, 1]]
            x[a:b] = np.interp(tk, load.time_s, load.position_m)
            pt[a:b] = np.interp(tk, load.time_s, load.traction_power_w)
            pr[a:b] = np.interp(tk, load.time_s, load.regen_power_w)
            sup[a:b] = network.supplied(int(tracks[k]), x[a:b])
        has_ob = any(tr.onboard_storage is not None for tr in trains)
        nan = np.full(n, np.nan)
        return cls(x, pt, pr, sup, nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy(),
                   nan.copy() if has_ob else None, nan.copy() if has_ob else None,
                   nan.copy() if has_ob else None)  # fmt: skip

    @classmethod
    def from_fields(cls, fields: dict[str, Any]) -> _Flat:
        """The train fields of a compact result (inverse of :meth:`fields`; not for solving)."""
        return cls(fields["train_position_m"], fields["traction_demand_w"], fields["regen_offered_w"],
                   np.zeros(0, dtype=bool), fields["train_voltage_v"], fields["train_power_w"],
                   fields["train_current_a"], fields["traction_delivered_w"], fields["regen_accepted_w"],
                   fields["onboard_charge_w"], fields["onboard_discharge_w"], fields["onboard_energy_j"])  # fmt: skip

    def fields(self) -> dict[str, np.ndarray | None]:
        """The train fields of a result, as kept (on-network steps only)."""
        return {
            "train_position_m": self.position_m,
            "train_voltage_v": self.voltage_v,
            "train_power_w": self.power_w,
            "train_current_a": self.current_a,
            "traction_demand_w": self.traction_w,
            "traction_delivered_w": self.delivered_w,
            "regen_offered_w": self.regen_w,
            "regen_accepted_w": self.accepted_w,
            "onboard_charge_w": self.ob_charge_w,
            "onboard_discharge_w": self.ob_discharge_w,
            "onboard_energy_j": self.ob_energy_j,
        }

    def dense(self, n_steps: int, ranges: np.ndarray, offset: np.ndarray) -> dict[str, np.ndarray | None]:
        """The train fields over the whole span [step, train], NaN where a train is not on the network."""
        nt = len(ranges)
        rows = np.concatenate([np.arange(ranges[k, 0], ranges[k, 1]) for k in range(nt)]).astype(np.int64)
        cols = np.repeat(np.arange(nt), offset[1:] - offset[:-1])
        out: dict[str, np.ndarray | None] = {}
        for name, a in self.fields().items():
            if a is None:
                out[name] = None
                continue
            d = np.full((n_steps, nt), np.nan)
            d[rows, cols] = a
            out[name] = d
        return out


@dataclass
class _Series:
    """Per time step: substations, network and wayside storages."""

    p_sub: np.ndarray
    p_src: np.ndarray
    i_sub: np.ndarray
    line_loss: np.ndarray
    sub_loss: np.ndarray
    contact_loss: np.ndarray
    return_loss: np.ndarray
    rmin: np.ndarray
    rmax: np.ndarray
    stray: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    st_power: np.ndarray | None
    st_energy: np.ndarray | None

    @classmethod
    def empty(cls, n: int, ns: int, n_st: int) -> _Series:
        return cls(np.zeros((n, ns)), np.zeros((n, ns)), np.zeros((n, ns)), np.zeros(n), np.zeros(n),
                   np.zeros(n), np.zeros(n),
                   np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan), np.ones(n, dtype=bool),
                   np.zeros(n, dtype=np.int64), np.zeros((n, n_st)) if n_st else None,
                   np.zeros((n, n_st)) if n_st else None)  # fmt: skip

    def fields(self) -> dict[str, np.ndarray | None]:
        return {
            "substation_power_w": self.p_sub,
            "substation_source_w": self.p_src,
            "substation_current_a": self.i_sub,
            "line_loss_w": self.line_loss,
            "substation_loss_w": self.sub_loss,
            "contact_loss_w": self.contact_loss,
            "return_loss_w": self.return_loss,
            "rail_potential_min_v": self.rmin,
            "rail_potential_max_v": self.rmax,
            "converged": self.converged,
            "iterations": self.iterations,
            "storage_power_w": self.st_power,
            "storage_energy_j": self.st_energy,
            "stray_current_a": self.stray,
        }


def _solve_steps(
    network: Network,
    trains: list[TrainLoad],
    tracks: np.ndarray,
    dt_s: float,
    ranges: np.ndarray,
    offset: np.ndarray,
    f: _Flat,
    out: _Series,
) -> None:
    """The network solved step after step, only the trains on the network at each step taken
    (the state carried from step to step: rectifier states and potentials as the next warm start,
    the storages' energy)."""
    nt, ns = len(trains), len(network.substations)
    n_steps = len(out.converged)
    aux = np.array([tr.auxiliary_power_w for tr in trains])
    tan_phi = np.array([np.sqrt(1 - tr.power_factor**2) / tr.power_factor for tr in trains])
    if network.system == "dc":
        tan_phi[:] = 0.0
    on = np.ones(ns, dtype=bool)
    n_st = len(network.storages)
    st_energy = np.array([st.initial_soc * st.capacity_j for st in network.storages])
    st_cap = np.array([st.capacity_j for st in network.storages])
    st_pmax = np.array([st.max_power_w for st in network.storages])
    st_eta = np.sqrt(np.array([st.efficiency for st in network.storages]))
    ob = [tr.onboard_storage for tr in trains]
    has_ob = f.ob_energy_j is not None
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
        with_ob = np.array([o is not None for o in ob])
    fixed_v = None
    prev_c = np.full(nt, np.nan)
    prev_r = np.full(nt, np.nan)
    # the trains on the network change only where one enters or leaves: the active set is rebuilt there
    order_in = np.argsort(ranges[:, 0], kind="stable")
    order_out = np.argsort(ranges[:, 1], kind="stable")
    active = np.zeros(nt, dtype=bool)
    n_in = n_out = 0
    act = np.zeros(0, dtype=np.int64)
    base = offset[:-1] - ranges[:, 0]
    for j in range(n_steps):
        changed = False
        while n_in < nt and ranges[order_in[n_in], 0] <= j:
            active[order_in[n_in]] = ranges[order_in[n_in], 1] > j
            n_in += 1
            changed = True
        while n_out < nt and ranges[order_out[n_out], 1] <= j:
            active[order_out[n_out]] = False
            n_out += 1
            changed = True
        if changed:
            act = np.flatnonzero(active)
        rows = base[act] + j
        sup = f.supplied[rows]
        sel, rs = act[sup], rows[sup]
        # present but off the wire (neutral section): no supply, demands unmet
        ro = rows[~sup]
        pt_a = f.traction_w[rows]
        pr_a = f.regen_w[rows]
        f.accepted_w[ro] = 0.0
        f.power_w[ro] = 0.0
        f.current_a[ro] = 0.0
        pt_line = pt_a
        if has_ob:
            w = with_ob[act]
            assist = np.where(w, assist_power_w(pt_a, ob_energy[act], ob_thr[act], ob_pmax[act], ob_emin[act],
                                                ob_eta_d[act], dt_s), 0.0)  # fmt: skip
            pt_line = pt_a - assist
            f.delivered_w[ro] = assist[~sup]
        else:
            f.delivered_w[ro] = 0.0
        loads = StepLoads(tracks[sel], f.position_m[rs], pt_line[sup], pr_a[sup], aux[sel], tan_phi[sel])
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
            out.st_power[j] = ps
            st_energy = np.clip(
                st_energy + (np.maximum(ps, 0.0) * st_eta - np.maximum(-ps, 0.0) / st_eta) * dt_s, 0.0, st_cap
            )
            out.st_energy[j] = st_energy
        out.converged[j] = sol.converged
        out.iterations[j] = sol.iterations
        f.voltage_v[rs] = sol.train_voltage_v
        f.power_w[rs] = sol.train_power_w
        f.current_a[rs] = sol.train_current_a
        f.delivered_w[rs] = pt_line[sup] * sol.traction_share
        f.accepted_w[rs] = pr_a[sup] * sol.regen_share
        if has_ob:
            f.delivered_w[rs] += assist[sup]
            curtailed = np.where(w, pr_a - f.accepted_w[rows], 0.0)
            charge = np.where(w, charge_power_w(curtailed, ob_energy[act], ob_pmax[act], ob_emax[act],
                                                ob_eta_c[act], dt_s), 0.0)  # fmt: skip
            ob_energy[act] = ob_energy[act] + (ob_eta_c[act] * charge - assist / ob_eta_d[act]) * dt_s
            rw = rows[w]
            f.ob_charge_w[rw] = charge[w]
            f.ob_discharge_w[rw] = assist[w]
            f.ob_energy_j[rw] = ob_energy[act][w]
        out.p_sub[j] = sol.substation_power_w
        out.p_src[j] = sol.substation_source_w
        out.i_sub[j] = sol.substation_current_a
        out.line_loss[j] = sol.line_loss_w
        out.sub_loss[j] = sol.substation_loss_w
        out.contact_loss[j] = sol.contact_loss_w
        out.return_loss[j] = sol.return_loss_w
        out.stray[j] = sol.stray_current_a
        if len(sol.rail_potential_v):
            out.rmin[j] = np.min(sol.rail_potential_v)
            out.rmax[j] = np.max(sol.rail_potential_v)
