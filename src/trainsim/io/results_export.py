"""A run's results in the formats other tools read.

* The trace (one row per point, units in the column names, see ``Trace.to_dataframe``) and the
  summary (one row per section between stops and a ``total`` row) as CSV, Parquet or JSON.
  The JSON summary is ``RunResult.summary()``; the JSON trace is ``{"train", "route", "columns":
  {name: [values]}}`` with ``null`` for unknown values (NaN is not JSON).
* Running times back into a railML 2 timetable: the train's ``ocpTT`` get
  ``times@scope="calculated"`` (arrival and departure at every operational point, passing times
  at points where the train does not stop) and ``sectionTT/runTimes@minimalTime`` (the fastest
  running time to the next point); railML 3 base itineraries get ``times@scope="calculated"``
  and ``followupSections/followupSection/minimalTime@runTime``. The clock starts at the first
  point's scheduled departure, else at 00:00:00.

Parquet needs ``pyarrow``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from trainsim.errors import InputError
from trainsim.sim.result import RunResult

__all__ = [
    "FORMATS",
    "station_times",
    "summary_frame",
    "trace_frame",
    "write_results",
    "write_running_times_railml",
    "write_summary",
    "write_trace",
]

FORMATS = ("csv", "parquet", "json")


def _format(path: Path, fmt: str | None) -> str:
    fmt = (fmt or path.suffix.lstrip(".")).lower()
    if fmt not in FORMATS:
        raise InputError("unknown result format", file=str(path), value=fmt, allowed=", ".join(FORMATS))
    return fmt


def trace_frame(result: RunResult):  # -> pandas.DataFrame
    """The trace as a DataFrame (units in the column names; ``regime`` as text)."""
    df = result.to_dataframe()
    df["regime"] = df["regime"].astype(str)
    return df


def summary_frame(result: RunResult):  # -> pandas.DataFrame
    """One row per section between stops and a ``total`` row; units in the column names."""
    import pandas as pd

    rows = []
    for s in result.sections:
        rows.append(
            {
                "from": s.from_station,
                "to": s.to_station,
                "distance_m": s.distance_m,
                "running_time_s": s.running_time_s,
                "dwell_s": s.dwell_s,
                "max_speed_kmh": s.max_speed_kmh,
                "average_speed_kmh": s.average_speed_kmh,
                "peak_current_a": s.peak_current_a,
                **{f"energy_{k}_kwh": v for k, v in s.energy_kwh.__dict__.items()},
            }
        )
    e = result.energy_kwh
    rows.append(
        {
            "from": "total",
            "to": "",
            "distance_m": result.distance_m,
            "running_time_s": result.running_time_s,
            "dwell_s": result.dwell_s,
            "max_speed_kmh": result.max_speed_kmh,
            "average_speed_kmh": result.average_running_speed_kmh,
            "peak_current_a": result.peak_current_a,
            **{f"energy_{k}_kwh": v for k, v in e.__dict__.items()},
        }
    )
    return pd.DataFrame(rows)


def _json_value(x: Any) -> Any:
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def _write_frame(df, path: Path, fmt: str) -> None:  # df: pandas.DataFrame
    path.parent.mkdir(parents=True, exist_ok=True)
    if fmt == "csv":
        df.to_csv(path, index=False)
    elif fmt == "parquet":
        try:
            df.to_parquet(path, index=False)
        except ImportError as exc:
            raise InputError("writing Parquet needs the pyarrow package", file=str(path)) from exc


def write_trace(result: RunResult, path: str | Path, fmt: str | None = None) -> Path:
    """Write the trace as CSV, Parquet or JSON (from the suffix unless ``fmt`` is given)."""
    path = Path(path)
    fmt = _format(path, fmt)
    df = trace_frame(result)
    if fmt == "json":
        path.parent.mkdir(parents=True, exist_ok=True)
        data = {
            "train": result.train_name,
            "route": result.route_name,
            "columns": {c: [_json_value(x) for x in df[c].tolist()] for c in df.columns},
        }
        path.write_text(json.dumps(data, allow_nan=False) + "\n", encoding="utf-8")
    else:
        _write_frame(df, path, fmt)
    return path


def write_summary(result: RunResult, path: str | Path, fmt: str | None = None) -> Path:
    """Write the summary: JSON is ``result.summary()``; CSV and Parquet the section table."""
    path = Path(path)
    fmt = _format(path, fmt)
    if fmt == "json":
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result.summary(), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    else:
        _write_frame(summary_frame(result), path, fmt)
    return path


def write_results(result: RunResult, out_dir: str | Path, formats: Sequence[str] = FORMATS) -> list[Path]:
    """``trace.<fmt>`` and ``summary.<fmt>`` in ``out_dir`` for each format."""
    out = Path(out_dir)
    written = []
    for fmt in formats:
        written.append(write_trace(result, out / f"trace.{fmt}", fmt))
        written.append(write_summary(result, out / f"summary.{fmt}", fmt))
    return written


# ====================================================================== running times
def station_times(
    result: RunResult,
    positions_m: Sequence[float],
    stops: Sequence[bool],
    dwells_s: Sequence[float],
    start_s: float = 0.0,
) -> list[tuple[float, float]]:
    """Arrival and departure time [s after midnight] at each station of a run: arrival when the
    head reaches the station (passing time at points without a stop), departure after the dwell
    at intermediate stops. ``start_s``: the clock at the first departure."""
    pos = np.asarray(result.trace.position_m, dtype=float)
    t = np.asarray(result.trace.time_s, dtype=float)
    t0 = float(t[0]) if len(t) else 0.0
    out = []
    n = len(positions_m)
    for i, (s, stop, dwell) in enumerate(zip(positions_m, stops, dwells_s, strict=True)):
        if s > pos[-1] + 1e-6:
            raise InputError(
                "the run ends before this station: it does not belong to this route",
                value=(s, float(pos[-1])),
            )
        k = int(np.searchsorted(pos, s - 1e-9, side="left"))
        if k == 0:
            arrival = float(t[0])
        else:
            p0, p1 = pos[k - 1], pos[min(k, len(pos) - 1)]
            t_a, t_b = t[k - 1], t[min(k, len(pos) - 1)]
            # the time at the head position s, between two trace points (linear in position)
            arrival = float(t_a + (t_b - t_a) * (s - p0) / (p1 - p0)) if p1 > p0 else float(t_b)
        departure = arrival + (dwell if stop and 0 < i < n - 1 else 0.0)
        out.append((start_s + arrival - t0, start_s + departure - t0))
    return out


def write_running_times_railml(
    result: RunResult,
    railml_in: str | Path,
    out: str | Path,
    *,
    train_id: str | None = None,
    ocps: Sequence[str] | None = None,
) -> Path:
    """Write the running times of a run of a railML file's train into a copy of that file.

    The route is read again from the file (same ``train_id``), so the run must be of that route.
    Returns the written path.
    """
    from lxml import etree

    from trainsim.io import railml2, railml3
    from trainsim.io import railml_common as rc

    tree = rc.parse_xml(railml_in)
    root = tree.getroot()
    version2 = railml2.detect(root)
    reader = railml2.read_railml2 if version2 else railml3.read_railml3
    if not version2 and railml3.detect(root) is None:
        raise InputError("not a railML file", file=str(railml_in))
    content = reader(railml_in, train_id=train_id, ocps=ocps, require_line_resistance=False, tree=tree)
    if content.route is None or not content.station_elements:
        raise InputError("the file has no timetable train to write running times to", file=str(railml_in))
    stations = content.route["stations"]
    stops = [s.get("stop", True) for s in stations]
    if sum(stops) - 1 != len(result.sections):
        raise InputError(
            "the run does not match this timetable: it has a different number of sections between stops",
            file=str(railml_in),
            value=(len(result.sections), sum(stops) - 1),
        )
    elements = content.station_elements
    start = _first_departure(elements[0], bool(version2))
    times = station_times(
        result, [s["position_m"] for s in stations], stops, [s.get("dwell_s", 0.0) for s in stations], start
    )
    ns = etree.QName(root).namespace
    q = (lambda name: f"{{{ns}}}{name}") if ns else (lambda name: name)
    n = len(elements)
    for i, (el, (arr, dep)) in enumerate(zip(elements, times, strict=True)):
        for old in [c for c in el if rc.local(c) == "times" and c.get("scope") == "calculated"]:
            el.remove(old)
        attrs: dict[str, str] = {"scope": "calculated"}
        if version2:
            if i > 0:
                attrs["arrival"], day = rc.format_clock(arr)
                if day:
                    attrs["arrivalDay"] = str(day)
            if i < n - 1:
                attrs["departure"], day = rc.format_clock(dep)
                if day:
                    attrs["departureDay"] = str(day)
            new = etree.Element(q("times"), attrs)
        else:
            new = etree.Element(q("times"), attrs)
            for which, value, present in (("arrival", arr, i > 0), ("departure", dep, i < n - 1)):
                if present:
                    text, day = rc.format_clock(value)
                    sub = etree.SubElement(new, q(which), {"time": text})
                    if day:
                        sub.set("dayOffset", str(day))
        existing = [c for c in el if rc.local(c) == "times"]
        index = el.index(existing[-1]) + 1 if existing else 0
        el.insert(index, new)
        if i == n - 1:
            continue
        run = rc.format_duration(times[i + 1][0] - dep)
        if version2:
            section = rc.child(el, "sectionTT")
            if section is None:
                after = [c for c in el if rc.local(c) in ("times", "connections")]
                section = etree.Element(q("sectionTT"))
                el.insert(el.index(after[-1]) + 1 if after else 0, section)
            rt = rc.child(section, "runTimes")
            if rt is None:
                rt = etree.SubElement(section, q("runTimes"))
            rt.set("minimalTime", run)
        else:
            sections = rc.child(el, "followupSections")
            if sections is None:
                sections = etree.SubElement(el, q("followupSections"))
            section = rc.child(sections, "followupSection")
            if section is None:
                section = etree.SubElement(sections, q("followupSection"))
            minimal = rc.child(section, "minimalTime")
            if minimal is None:
                minimal = etree.SubElement(section, q("minimalTime"))
            minimal.set("runTime", run)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    etree.indent(tree, space="  ")  # the inserted elements have no layout of their own
    # the root element only: no document type declaration of the input is ever copied
    out.write_bytes(etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))
    return out


def _first_departure(el: Any, version2: bool) -> float:
    from trainsim.io import railml_common as rc

    for t in rc.children(el, "times"):
        if t.get("scope") == "calculated":
            continue
        if version2:
            value = rc.parse_clock(t.get("departure"), int(t.get("departureDay") or 0))
        else:
            dep = rc.child(t, "departure")
            value = (
                rc.parse_clock(dep.get("time"), int(dep.get("dayOffset") or 0)) if dep is not None else None
            )
        if value is not None:
            return value
    return 0.0
