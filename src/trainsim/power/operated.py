"""Voltage-limited traction of operated trains fed back into their operation (issue 18).

The trains of an operation (``trainsim operate``: timetable, signalling, dispatching) are placed on
the network as operated. Where the line voltage limits a train's traction (EN 50388 reduction below
``traction_full_v``), its runs assumed more power than it got. As in the timetable study
(:mod:`trainsim.power.study`), the train is given a cap on its traction power at the wheel: the least
electrical power the line delivered to it at a limited step, times its traction efficiency, lowered
again at each iteration where it is still limited (never raised, so the iteration cannot cycle).

- ``per_stretch``: one cap per stretch between two scheduled stops (where the train is at rest, so
  the stretches are independent runs), set only on the stretches where the line limited it;
- ``constant``: one cap for the whole run (conservative: the train is held back where the voltage
  would have allowed more).

The operation itself is run again with the caps (by the caller, who knows the operation), so that a
slowed train holds the trains behind it at signals: the knock-on between trains is the operation's
signalling and dispatching, not an assumption of the power study. The network is solved again, until
every train gets at least ``1 - tolerance`` of the traction energy it asks, or ``max_iterations`` is
reached (then ``feedback_not_converged``).

A cap below :data:`NO_TRACTION_SHARE` of the train's greatest traction power at the wheel means the
line gives it (next to) nothing on that stretch: the stretch is run with no traction at all, so the
train stands (the operation reports it stalled, and the trains behind it held) instead of crawling
for hours at a speed no timetable would keep. Such a train does not reach its destination: its
``time_lost_s`` is null and the study's status says so, naming it.

This module knows nothing of operation files nor of ``trainsim.operations`` (an independent layer):
the caller's ``operate`` runs the operation under given caps and hands back loads and times.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trainsim.errors import InputError
from trainsim.model.train import Train
from trainsim.power.network import Network
from trainsim.power.simulation import PowerResult, TrainLoad, simulate
from trainsim.power.study import FeedbackSettings, with_status

__all__ = [
    "METHODS",
    "NO_TRACTION_SHARE",
    "Operated",
    "OperatedTrain",
    "feed_back_operated",
    "greatest_wheel_power_w",
    "lowered_caps",
    "stretch_index",
]

#: Feedback methods for operated trains and what each does (the file's ``feedback.method``).
#: ``per_step`` (a share of tractive effort per position, :mod:`trainsim.power.traction_share`) is
#: not offered: the operation's runs take one traction curve per stretch.
METHODS: dict[str, str] = {
    "per_stretch": "a cap on the traction power at the wheel per stretch between two scheduled stops of "
    "each operated train: the least power delivered at a limited step of that stretch times the traction "
    "efficiency; the operation re-simulated with the caps",
    "constant": "one cap on the traction power at the wheel per operated train for its whole run: the least "
    "power delivered at a limited step times the traction efficiency; the operation re-simulated with the caps",
}

#: A cap below this share of a train's greatest traction power at the wheel is no traction [-]: the
#: same floor as the least share of tractive effort of per-step feedback
#: (``trainsim.power.traction_share.SHARE_FLOOR``).
NO_TRACTION_SHARE = 1e-3

#: Speeds at which a train's traction curve is sampled for its greatest power at the wheel [-].
_POWER_SAMPLES = 400


@dataclass(frozen=True)
class OperatedTrain:
    """An operated train as the feedback sees it.

    Attributes:
        id: the operation's train id.
        stops_m: running positions of its scheduled stops, origin and destination included,
            increasing [m]: the stretches of ``per_stretch`` lie between them.
        zero_m: network chainage of running position 0 [m].
        sign: +1 if the chainage grows with the running position, -1 otherwise.
        traction_efficiency: electrical power at the pantograph to power at the wheel [-].
        greatest_power_w: its greatest traction power at the wheel [W]
            (:func:`greatest_wheel_power_w`).
        stop_names: the names of its scheduled stops (for the explanations), or empty.
    """

    id: str
    stops_m: np.ndarray
    zero_m: float
    sign: int
    traction_efficiency: float
    greatest_power_w: float
    stop_names: tuple[str, ...] = ()

    def stretch_name(self, k: int, count: int) -> str:
        """'A - B' of stretch ``k`` of ``count`` (the whole run when ``count`` is 1)."""
        names = self.stop_names or tuple(f"{x:.0f} m" for x in self.stops_m)
        return f"{names[0]} - {names[-1]}" if count == 1 else f"{names[k]} - {names[k + 1]}"

    def running_m(self, chainage_m: np.ndarray) -> np.ndarray:
        """Running positions [m] of network chainages [m]."""
        return self.sign * (np.asarray(chainage_m, dtype=float) - self.zero_m)


@dataclass
class Operated:
    """The operation run under some caps, as the feedback needs it (given by ``operate``).

    Attributes:
        loads: the trains on the network.
        info: the summary's ``operation`` block.
        arrival_s: per train id, its arrival at its destination [s] (NaN: it did not arrive).
        status: per train id, its operated status (``ok``, ``stalled``, ``deadlocked``).
        wait_s: per train id, the time it waited at signals and was held at stops [s].
    """

    loads: list[TrainLoad]
    info: dict[str, Any]
    arrival_s: dict[str, float]
    status: dict[str, str]
    wait_s: dict[str, float] = field(default_factory=dict)


def greatest_wheel_power_w(train: Train) -> float:
    """The greatest F(v) v of the train's traction curve from standstill to its top speed [W]."""
    v = np.linspace(0.0, train.max_speed_mps, _POWER_SAMPLES)
    return float(np.max(np.asarray(train.traction(v), dtype=float) * v))


def stretch_index(stops_m: np.ndarray, running_m: np.ndarray, count: int) -> np.ndarray:
    """Index of the stretch (between consecutive ``stops_m``) of each running position [m]; with
    ``count`` 1 every position is on stretch 0 (one cap for the whole run)."""
    if count == 1:
        return np.zeros(np.shape(running_m), dtype=int)
    k = np.searchsorted(stops_m, running_m, side="right") - 1
    return np.clip(k, 0, count - 1)


def lowered_caps(
    caps_w: np.ndarray, running_m: np.ndarray, delivered_w: np.ndarray, train: OperatedTrain
) -> np.ndarray:
    """The train's caps on the traction power at the wheel [W] after one network solution: on each
    stretch with a limited step (at running positions ``running_m`` [m], electrical power
    ``delivered_w`` [W]), the lower of its cap and the least delivered power times the traction
    efficiency; 0 (no traction) where that is below :data:`NO_TRACTION_SHARE` of the train's
    greatest power at the wheel."""
    out = np.array(caps_w, dtype=float)
    stretch = stretch_index(train.stops_m, running_m, len(out))
    floor = NO_TRACTION_SHARE * train.greatest_power_w
    for j in np.unique(stretch):
        cap = float(np.min(delivered_w[stretch == j])) * train.traction_efficiency
        out[j] = min(out[j], cap if cap >= floor else 0.0)
    return out


def _check_settings(settings: FeedbackSettings, explicit: set[str]) -> None:
    """Refuse feedback settings that cannot apply to operated trains (see docs/POWER.md)."""
    if settings.method not in METHODS:
        raise InputError(
            "this feedback method is not available for operated trains (the operation's runs take one "
            "traction curve per stretch)",
            field="simulation.feedback.method",
            value=settings.method,
            allowed=", ".join(METHODS),
        )
    if "knock_on" in explicit and not settings.knock_on:
        raise InputError(
            "operated trains always pass their delays on: a slowed train holds the trains behind it "
            "through the operation's signalling and dispatching",
            field="simulation.feedback.knock_on",
            value=False,
            allowed="true, or leave it out, with operation:",
        )
    if settings.buffer_s != 0.0:
        raise InputError(
            "operated trains recover time as their operation's timetable lets them (scheduled departures, "
            "dwell times), not by a buffer of the power study",
            field="simulation.feedback.buffer_s",
            value=settings.buffer_s,
            allowed="0, or leave it out, with operation: (recovery time goes into the operation file)",
        )


def feed_back_operated(
    network: Network,
    trains: list[OperatedTrain],
    operate: Callable[[dict[str, np.ndarray] | None], Operated],
    settings: FeedbackSettings,
    *,
    explicit: set[str] | None = None,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
    blocks: dict[str, Any] | None = None,
) -> PowerResult:
    """The power study of operated trains with voltage-limited traction fed back (module doc).

    ``operate(caps)`` runs the operation with, per train id, its caps on the traction power at the
    wheel [W] (one per stretch between its scheduled stops for ``per_stretch``, one for
    ``constant``; inf: none, 0: no traction), or with None the operation as it is (no cap at all).
    ``explicit`` are the feedback fields the file gave (a value that cannot apply is refused);
    ``blocks`` go into the summary as they are (e.g. ``neutral_sections``, which the status reads).

    The summary gets a ``feedback`` block (``method`` actually used, ``iterations``, ``consistent``,
    ``mismatch``, ``knock_on``, ``buffer_s``, ``note``) and per train ``arrival_s``,
    ``nominal_arrival_s`` (no cap), ``time_lost_s`` (null: it did not arrive), its caps,
    ``operated_status`` and ``wait_s`` / ``nominal_wait_s`` (waits at signals and holds at stops:
    the part of a loss the trains ahead passed on).
    """
    if settings.enabled:
        _check_settings(settings, explicit or set())
    by_id = {t.id: t for t in trains}
    count = {t.id: (len(t.stops_m) - 1 if settings.method == "per_stretch" else 1) for t in trains}
    caps = {t.id: np.full(count[t.id], np.inf) for t in trains}
    nominal = operated = operate(None)
    iterations = 0
    while True:
        iterations += 1
        if iterations > 1:
            operated = operate({tid: c.copy() for tid, c in caps.items() if not np.all(np.isinf(c))})
        try:
            result = simulate(network, operated.loads, dt_s=dt_s, start_s=start_s, end_s=end_s)
        except InputError as exc:
            if not any(p.field == "simulation.traces" for p in exc.problems):
                raise
            # the full traces' cap suggests compact traces, which operated trains cannot use (their
            # feedback re-simulates the operation from each train's series over the whole span)
            raise InputError(
                "too many time steps x operated trains to keep every train's series over the whole span",
                field="simulation",
                value=f"step_s {dt_s:g}, start_s {start_s}, end_s {end_s}",
                allowed="a shorter span (simulation.start_s, simulation.end_s) or a longer step_s; compact "
                "traces (traces: on_network) are for trains of a timetable, not of an operation",
            ) from None
        if not settings.enabled:
            feedback = {"enabled": False, "iterations": 1, "consistent": True, "method": "none",
                        "note": "operated trains are solved once: their delays come from the operation"}  # fmt: skip
            return with_status(
                dataclasses.replace(
                    result, extra={**(blocks or {}), "operation": operated.info, "feedback": feedback}
                )
            )
        # off the wire (a neutral section) the run coasts and the line gives nothing: no voltage limitation
        # there, only the run's traction sampled at a step that straddles the section's end
        wired = np.isfinite(result.train_voltage_v)
        demand = np.where(wired, result.traction_demand_w, 0.0)
        delivered = np.where(wired, result.traction_delivered_w, 0.0)
        asked = np.nansum(demand, axis=0)
        got = np.nansum(delivered, axis=0)
        ratio = np.where(asked > 0, got / np.where(asked > 0, asked, 1.0), 1.0)
        mismatch = 1.0 - ratio
        limited = ratio < 1.0 - settings.tolerance
        consistent = not limited.any()
        if consistent or iterations >= settings.max_iterations:
            break
        short = wired & (delivered < demand * (1.0 - settings.tolerance))
        for i in np.flatnonzero(limited):
            tid = result.train_ids[i]
            steps = short[:, i]
            if steps.any():
                train = by_id[tid]
                running = train.running_m(result.train_position_m[steps, i])
                caps[tid] = lowered_caps(caps[tid], running, delivered[steps, i], train)
    rows = []
    # the operation's trains that never reached the network too: a status names them
    for tid in [*result.train_ids, *(t for t in operated.status if t not in result.train_ids)]:
        arrival = operated.arrival_s.get(tid, np.nan)
        lost = arrival - nominal.arrival_s.get(tid, np.nan)
        c = caps.get(tid, np.full(1, np.inf))
        finite = np.isfinite(c)
        rows.append({
            "id": tid,
            "arrival_s": _finite(arrival),
            "nominal_arrival_s": _finite(nominal.arrival_s.get(tid, np.nan)),
            # a train that no longer arrives under its caps lost all: no finite figure, said by its status
            "time_lost_s": float(lost) if np.isfinite(lost) else None,
            "traction_power_cap_kw": float(np.min(c)) / 1e3 if finite.any() else None,
            "traction_power_caps_kw": [float(x) / 1e3 if np.isfinite(x) else None for x in c] if len(c) > 1
            else None,
            "operated_status": operated.status.get(tid, "ok"),
            "wait_s": _finite(operated.wait_s.get(tid, np.nan)),
            "nominal_wait_s": _finite(nominal.wait_s.get(tid, np.nan)),
        })  # fmt: skip
        if not np.isfinite(arrival):
            rows[-1]["explanation"] = _unfinished(by_id.get(tid), c, operated, caps)
    feedback = {
        "enabled": True,
        "iterations": iterations,
        "consistent": bool(consistent),
        "mismatch": float(np.max(mismatch, initial=0.0)),
        # between trains the operation's signalling and dispatching pass the delays on
        "knock_on": True,
        "buffer_s": 0.0,
        "method": settings.method,
        "note": METHODS[settings.method],
        # every train that did not arrive, those the network never saw too (no row in trains)
        "unfinished": [
            {"id": r["id"], "operated_status": r["operated_status"], "explanation": r["explanation"]}
            for r in rows
            if "explanation" in r
        ],
    }
    extra = {**(blocks or {}), "operation": operated.info, "feedback": feedback, "trains": rows}
    return with_status(dataclasses.replace(result, extra=extra))


def _unfinished(
    train: OperatedTrain | None, caps_w: np.ndarray, operated: Operated, caps: dict[str, np.ndarray]
) -> str:
    """Why an operated train did not reach its destination under the caps."""
    status = operated.status.get(train.id if train else "", "not run")
    if train is not None and np.any(caps_w == 0.0):
        where = ", ".join(train.stretch_name(int(k), len(caps_w)) for k in np.flatnonzero(caps_w == 0.0))
        return (
            f"{train.id} is {status}: no traction on {where}, where the line voltage gave it less than "
            f"{NO_TRACTION_SHARE:.1%} of its greatest traction power at a limited step"
        )
    stopped = sorted(t for t, c in caps.items() if np.any(c == 0.0) and operated.status.get(t) != "ok")
    behind = f" behind {', '.join(stopped)}, which the line gave no traction" if stopped else ""
    return f"{train.id if train else 'the train'} is {status}: held{behind} (the operation's signalling)"


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None
