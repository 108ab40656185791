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

Feedback of voltage-limited traction (:mod:`trainsim.power.study`): with feedback enabled, the day
is :func:`~trainsim.power.study.run_study`'s loop with compact traces (it reads every train's series
through ``result.train_series``): the runs the line limits are made again with their caps and the
day solved again until consistent, the ``feedback`` block giving the iterations, consistency and
mismatch, each train its caps and time lost, as a full study does (the same figures, sums to
rounding). Each iteration solves the whole day again. With feedback disabled, the day is solved once
with every train's nominal run, and where the line limits a departure by more than the feedback
tolerance, the status is ``traction_limited`` (not fed back: the feedback block says ``enabled:
false, requested: false``) and a warning names the departures.
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
    run_study,
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
    """The timetable's departures over the span with compact traces (module doc), with the study's
    summary blocks (``trains``, ``feedback``) and status: with ``feedback.enabled``, fed back into the
    runs as :func:`~trainsim.power.study.run_study` does; else solved once with the nominal runs.
    ``loads``: :func:`departure_loads` already computed, of services with the network's neutral
    sections laid over their routes (:func:`~trainsim.power.study.with_neutral_sections`); used
    without feedback only (the fed-back study makes its runs, capped ones included, itself)."""
    feedback = feedback or FeedbackSettings()
    if not services:
        raise InputError("no trains", field="trains", allowed="one or more trains")
    if feedback.enabled:
        # the services as given: run_study lays the network's neutral sections over their routes itself
        fed = run_study(
            network, services, dt_s=dt_s, start_s=start_s, end_s=end_s, feedback=feedback, traces="on_network"
        )
        if not isinstance(fed, CompactPowerResult):  # run_study keeps the traces it is asked for
            raise TypeError("run_study(traces='on_network') did not return a CompactPowerResult")
        fed.extra["traces"] = _traces_block(fed)
        return fed
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
        "requested": False,
        "iterations": 1,
        "consistent": not bool(limited.any()),
        "mismatch": float(np.max(1.0 - ratio, initial=0.0)),
        "knock_on": feedback.knock_on,
        "buffer_s": feedback.buffer_s,
        "method": "none: feedback disabled, the day is solved once with the nominal runs",
        "note": "voltage-limited traction is checked, not fed back (feedback disabled)"
        + (
            f"; it limits {int(limited.sum())} departures ("
            + ", ".join(day_loads[i].id for i in np.flatnonzero(limited)[:5])
            + (", ..." if limited.sum() > 5 else "")
            + "): enable simulation.feedback to feed it back into their runs"
            if limited.any()
            else ""
        ),
    }
    base = with_status(
        _replace_extra(result, {"trains": trains, "feedback": block, "neutral_sections": neutral})
    )
    if limited.any():
        base.extra["warnings"].append(block["note"])
    base.extra["traces"] = _traces_block(base)
    return base


def _traces_block(result: CompactPowerResult) -> dict[str, Any]:
    """The summary's ``traces`` block: how the trains' series were kept and what they hold."""
    return {
        "kept": "on_network",
        "train_steps": int(result.train_offset[-1]),
        "memory_mb": result.memory_bytes() / 1e6,
    }


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
