"""A whole day of a timetable on the power network, with bounded memory.

A day of a metro at a 3-minute headway is 720 departures over 18 h: with every train's series kept
over the whole span (time x train arrays) that is 4.7e7 train-steps and about 5 GB. Each train is
on the network for a few minutes only, so :func:`run_day_study` keeps its series only there
(:class:`~trainsim.power.simulation.CompactPowerResult`, ``simulate(traces="on_network")``): the
memory grows with the trains' running time (about 65 bytes per train-step on the network, 90 with
on-board storage) and the substation series (needed for the moving RMS currents over 1 min, 15 min
and 1 h, the overload events and the plots) are kept whole.

The day is one pass over time, not independent windows solved apart: the rectifier states and node
potentials of a step are the next step's warm start and the storages' energy (wayside, on board)
carries from step to step, so windows would only give the same figures bit for bit if solved in
order with that state handed on, which is what the pass does. A compact day solves the same steps
in the same order as a full run: its step solutions are equal bit for bit, its sums equal to
rounding (other summation order, 1e-15 relative).

Feedback of voltage-limited traction (:mod:`trainsim.power.study`) needs each train's series over
the span and is not done on a compact day: the day is solved once with every train's nominal run
(the study's first iteration), and where the line limits a departure by more than the feedback
tolerance, the status is ``traction_limited`` (the limitation was not fed back into the runs; the
feedback block says ``enabled: false, requested: true``) and a warning names the departures and how
to proceed (those hours with ``traces: full``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from trainsim.errors import InputError
from trainsim.power.network import Network
from trainsim.power.simulation import CompactPowerResult, PowerResult, TrainLoad, simulate
from trainsim.power.study import (
    FeedbackSettings,
    TrainService,
    _load,
    _run,
    with_neutral_sections,
    with_status,
)

__all__ = ["departure_loads", "run_day_study", "write_compact_outputs"]


def departure_loads(services: list[TrainService]) -> tuple[list[TrainLoad], list[float]]:
    """Every departure's load (named like :func:`~trainsim.power.study.run_study`'s: ``id`` or
    ``id#k``) from one run per service (a departure time does not change a run), and each
    departure's running time [s]."""
    loads, running = [], []
    for k, s in enumerate(services):
        run = _run(s.scenario, np.inf)
        if run.status != "ok":
            raise InputError(f"the run of train {s.id} is not possible: " + "; ".join(run.warnings),
                             field=f"trains[{k}]", value=s.id)  # fmt: skip
        for j, dep in enumerate(s.departures_s):
            loads.append(_load(s, run, f"{s.id}#{j}" if len(s.departures_s) > 1 else s.id, dep))
            running.append(float(run.running_time_s))
    return loads, running


def run_day_study(
    network: Network,
    services: list[TrainService],
    *,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
    feedback: FeedbackSettings | None = None,
    loads: tuple[list[TrainLoad], list[float]] | None = None,
) -> CompactPowerResult:
    """The timetable's departures solved once over the span with compact traces (module doc), with
    the study's summary blocks (``trains``: running times, no caps; ``feedback``) and status.
    ``loads``: :func:`departure_loads` already computed, of services with the network's neutral
    sections laid over their routes (:func:`~trainsim.power.study.with_neutral_sections`)."""
    feedback = feedback or FeedbackSettings()
    if not services:
        raise InputError("no trains", field="trains", allowed="one or more trains")
    # the runs coast through the network's neutral sections, as run_study's do
    services, neutral = with_neutral_sections(network, services)
    day_loads, running = loads if loads is not None else departure_loads(services)
    result = simulate(network, day_loads, dt_s=dt_s, start_s=start_s, end_s=end_s, traces="on_network")
    asked = np.array(
        [np.nansum(result.train_series(result.traction_demand_w, i)) for i in range(len(day_loads))]
    )
    got = np.array(
        [np.nansum(result.train_series(result.traction_delivered_w, i)) for i in range(len(day_loads))]
    )
    ratio = np.where(asked > 0, got / np.where(asked > 0, asked, 1.0), 1.0)
    limited = ratio < 1.0 - feedback.tolerance
    trains = [
        {"id": load.id, "running_time_s": rt, "nominal_running_time_s": rt, "time_lost_s": 0.0,
         "traction_power_cap_kw": None, "departure_delay_s": 0.0, "traction_power_caps_kw": None}
        for load, rt in zip(day_loads, running, strict=True)
    ]  # fmt: skip
    block: dict[str, Any] = {
        # not fed back: the study's status is then traction_limited where the line limits a departure
        "enabled": False,
        "requested": feedback.enabled,
        "iterations": 1,
        "consistent": not bool(limited.any()),
        "mismatch": float(np.max(1.0 - ratio, initial=0.0)),
        "knock_on": feedback.knock_on,
        "buffer_s": feedback.buffer_s,
        "method": "none: a compact (whole-day) run is solved once with the nominal runs",
        "note": "voltage-limited traction is checked, not fed back, on a compact run"
        + (
            f"; it limits {int(limited.sum())} departures ("
            + ", ".join(day_loads[i].id for i in np.flatnonzero(limited)[:5])
            + (", ..." if limited.sum() > 5 else "")
            + "): run their hours with simulation.traces: full (start_s, end_s) to feed it back"
            if limited.any()
            else ""
        ),
    }
    base = with_status(
        _replace_extra(result, {"trains": trains, "feedback": block, "neutral_sections": neutral})
    )
    if limited.any():
        base.extra["warnings"].append(block["note"])
    base.extra["traces"] = {
        "kept": "on_network",
        "train_steps": int(result.train_offset[-1]),
        "memory_mb": result.memory_bytes() / 1e6,
    }
    return base


def _replace_extra(result: CompactPowerResult, extra: dict[str, Any]) -> CompactPowerResult:
    import dataclasses

    return dataclasses.replace(result, extra=extra)


def write_compact_outputs(result: PowerResult, out: Path) -> list[Path]:
    """CSV tables of a compact result: ``trains.csv`` (one row per train and step on the network,
    in train order), ``substations.csv`` (power [kW], current [A] per step) and ``network.csv``
    (losses [kW], convergence per step). Plots take time x train arrays (trainsim.power.output) and
    are not drawn for a compact result that does not fit them."""
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    names = {
        "position_m": (result.train_position_m, 1.0),
        "voltage_v": (result.train_voltage_v, 1.0),
        "current_a": (result.train_current_a, 1.0),
        "power_kw": (result.train_power_w, 1e-3),
        "traction_demand_kw": (result.traction_demand_w, 1e-3),
        "traction_delivered_kw": (result.traction_delivered_w, 1e-3),
        "regen_offered_kw": (result.regen_offered_w, 1e-3),
        "regen_accepted_kw": (result.regen_accepted_w, 1e-3),
    }
    columns: dict[str, Any] = {
        "time_s": np.concatenate([result.train_time_s(k) for k in range(len(result.train_ids))]),
        "train": np.repeat(np.array(result.train_ids, dtype=object), np.diff(result.train_offset)),
    }
    columns.update({name: a * scale for name, (a, scale) in names.items()})
    written = [out / "trains.csv", out / "substations.csv", out / "network.csv"]
    pd.DataFrame(columns).to_csv(written[0], index=False, float_format="%.4f")
    subs: dict[str, Any] = {"time_s": result.time_s}
    for i, s in enumerate(result.network.substations):
        subs[f"{s.id}_power_kw"] = result.substation_power_w[:, i] * 1e-3
        subs[f"{s.id}_current_a"] = result.substation_current_a[:, i]
    pd.DataFrame(subs).to_csv(written[1], index=False, float_format="%.4f")
    losses = {
        "line_loss_kw": result.line_loss_w * 1e-3,
        "substation_loss_kw": result.substation_loss_w * 1e-3,
    }
    pd.DataFrame({"time_s": result.time_s, **losses, "converged": result.converged}).to_csv(
        written[2], index=False, float_format="%.4f"
    )
    return written
