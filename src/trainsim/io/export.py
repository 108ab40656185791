"""Write a run's results: the trace as CSV, the summary as JSON, the per-section table for a terminal."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
from rich.console import JustifyMethod
from rich.table import Table
from rich.text import Text

from trainsim.constants import KMH
from trainsim.sim.result import RunResult

__all__ = ["summary_table", "write_summary_json", "write_trace_csv"]


def _trace_columns(result: RunResult) -> tuple[list[str], list]:
    """Column names and values (as text) of the trace, in ``Trace.to_dataframe``'s order."""
    trace = result.trace
    if trace is None:
        raise ValueError("this run was computed without its trace (trace=False)")
    names = [name for name in trace.__dataclass_fields__ if name != "regime"]
    values = [np.asarray(getattr(trace, name)) for name in names]
    # the same places as to_dataframe's inserts: regime after the fourth column, then speed_kmh third
    names.insert(4, "regime")
    values.insert(4, np.asarray(trace.regime_names, dtype=object))
    names.insert(3, "speed_kmh")
    values.insert(3, trace.speed_mps / KMH)
    text = []
    for col in values:
        if col.dtype == object:
            text.append(col.tolist())
            continue
        # the shortest round-trip repr is pandas' to_csv format; NaN is an empty field there
        text.append([repr(v) if v == v else "" for v in np.asarray(col, dtype=float).tolist()])
    return names, text


def write_trace_csv(result: RunResult, path: str | Path) -> Path:
    """Write the trace, one row per point and units in the column names (see ``Trace.to_dataframe``).

    Written with the csv module, byte for byte what ``result.to_dataframe().to_csv(path,
    index=False)`` writes, without importing pandas (a quarter of a second per process)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names, columns = _trace_columns(result)
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(names)
        writer.writerows(zip(*columns, strict=True))
    return path


def write_summary_json(result: RunResult, path: str | Path) -> Path:
    """Write ``result.summary()`` as indented JSON (unknown values are ``null``, never NaN)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # allow_nan=False: summary() already maps NaN to None; a NaN here would be a bug, not output
    path.write_text(json.dumps(result.summary(), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path


def _num(value: float | None, digits: int) -> str:
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value:,.{digits}f}"


def summary_table(result: RunResult, status: str | None = None) -> Table:
    """Per-section figures and a total row, for printing with ``rich``.

    ``status`` replaces the run's own status in the caption where the command's result has one of its
    own (an optimisation whose schedule cannot be met drives a run that is itself ``ok``).
    """
    table = Table(
        title=Text(f"{result.train_name} on {result.route_name}"),
        caption=Text(f"{result.kind} run, status {status or result.status}"),
    )
    headers: tuple[tuple[str, JustifyMethod], ...] = (
        ("from", "left"),
        ("to", "left"),
        ("distance\n[km]", "right"),
        ("running\ntime [s]", "right"),
        ("dwell\n[s]", "right"),
        ("max\n[km/h]", "right"),
        ("avg\n[km/h]", "right"),
        ("traction\n[kWh]", "right"),
        ("regenerated\n[kWh]", "right"),
        ("net\n[kWh]", "right"),
        ("peak current\n[A]", "right"),
    )
    for name, justify in headers:
        # Text, not str: rich would read '[km]' as a markup tag and drop it
        table.add_column(Text(name), justify=justify)
    for s in result.sections:
        table.add_row(
            Text(s.from_station),
            Text(s.to_station),
            _num(s.distance_m / 1000.0, 3),
            _num(s.running_time_s, 1),
            _num(s.dwell_s, 0),
            _num(s.max_speed_kmh, 1),
            _num(s.average_speed_kmh, 1),
            _num(s.energy_kwh.traction, 2),
            _num(s.energy_kwh.regenerated, 2),
            _num(s.energy_kwh.net, 2),
            _num(s.peak_current_a, 0),
        )
    first = result.sections[0].from_station if result.sections else ""
    last = result.sections[-1].to_station if result.sections else ""
    table.add_section()
    # the total's average is the running average, like the sections' (distance / running time)
    table.add_row(
        "total",
        Text(f"{first} → {last}" if result.sections else ""),
        _num(result.distance_m / 1000.0, 3),
        _num(result.running_time_s, 1),
        _num(result.dwell_s, 0),
        _num(result.max_speed_kmh, 1),
        _num(result.average_running_speed_kmh, 1),
        _num(result.energy_kwh.traction, 2),
        _num(result.energy_kwh.regenerated, 2),
        _num(result.energy_kwh.net, 2),
        _num(result.peak_current_a, 0),
        style="bold",
    )
    return table
