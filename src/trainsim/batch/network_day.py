"""A network-day: several lines in operation (one operation file each), each a day of trains, and
optionally sampled days (Monte Carlo of entry delays and disturbances), simulated locally or on a
Dask cluster with the same results.

The unit of work is one line on one day (``line_day``): it reads its operation file, samples the day
(sample ``k`` of ``n`` uses the ``k``-th stream spawned from the seed, exactly as
``trainsim.io.operation_run.monte_carlo``) and simulates it. Lines of a network are simulated
independently, except where a file's ``connections`` make a train wait at its origin for a train of
another file's line (a passenger connection, or the same unit turning round): the lines so joined
are simulated together, feeders first, and a late feeder makes the waiting train late (knock-on). Each
line keeps its own sampled stream, so a line's disturbances do not depend on the lines it is joined to.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from trainsim.errors import InputError, Problem
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import delay_stats, run_operation

#: The most local Dask worker processes started for a network-day.
MAX_LOCAL_WORKERS = 256
#: How long to try to reach a Dask scheduler [s].
CONNECT_TIMEOUT_S = 10
#: Status order, worst last: the network-day's status is its worst line-day's.
STATUS_ORDER = ("ok", "conflicts", "stalled", "deadlock")


#: Arrivals of the trains of the lines simulated so far: (line name, train, station) -> time [s], None
#: when the train did not arrive there.
Arrivals = dict[tuple[str, str, str], float | None]


def line_day(
    path: str, sample: int | None = None, samples: int = 0, seed: int | None = None
) -> dict[str, Any]:
    """Simulate one line's day: the file's own timetable (``sample`` None) or sample ``sample`` of
    ``samples`` sampled days (seed: ``seed``, default the file's). Returns a picklable summary: per
    train its delay [s] and operated energy [kWh], the status, totals and the run-cache counts. The
    file's connections are not applied (``lines_day`` applies them)."""
    return _line_day(path, sample, samples, seed, None)[0]


def lines_day(
    paths: Sequence[str], sample: int | None = None, samples: int = 0, seed: int | None = None
) -> list[dict[str, Any]]:
    """``line_day`` of each of ``paths`` in turn (feeders first), each line's trains waiting for the
    feeders of its connections as the lines before it ran them."""
    arrivals: Arrivals = {}
    out = []
    for path in paths:
        day, found = _line_day(path, sample, samples, seed, arrivals)
        arrivals.update(found)
        out.append(day)
    return out


def _line_day(
    path: str, sample: int | None, samples: int, seed: int | None, arrivals: Arrivals | None
) -> tuple[dict[str, Any], Arrivals]:
    op = read_operation(path)
    services = op.services
    if sample is not None:
        sampler = op.disturbances if op.disturbances is not None else op.delays
        if sampler is None:
            raise InputError(
                "sampled days need a 'delays' or 'disturbances' block", file=str(path), field="delays"
            )
        base = sampler.seed if seed is None else seed
        stream = np.random.SeedSequence(base).spawn(samples)[sample]
        services = sampler.sample(op.given_services, np.random.default_rng(stream))
    knock_on = []
    if arrivals is not None:
        services = list(services)
        for c in op.connections:
            k = next(i for i, svc in enumerate(services) if svc.id == c.train)
            svc = services[k]
            station = c.station or _destination(c, arrivals)
            arrived = arrivals[(c.line, c.feeder, station)]
            entry = {"train": c.train, "line": c.line, "feeder": c.feeder, "station": station}
            if arrived is None:
                # the feeder never arrives: the train leaves as planned (the feeder's line is not ok)
                knock_on.append({**entry, "feeder_arrival_s": None, "delay_s": None})
                continue
            late = arrived + c.min_s - (svc.departure_s + svc.entry_delay_s)
            if late > 0:
                services[k] = replace(svc, entry_delay_s=svc.entry_delay_s + late)
            knock_on.append({**entry, "feeder_arrival_s": float(arrived), "delay_s": float(max(late, 0.0))})
    res = run_operation(op, services, conflicts=sample is None, headways=False)
    found: Arrivals = {
        (op.name, t.id, s.station): (float(s.arrival_s) if s.arrival_s is not None else None)
        for t in res.trains
        for s in t.stops
        if s.kind != "origin"
    }
    trains = [
        {
            "id": t.id,
            "status": t.status,
            "delay_s": float(t.delay_s) if np.isfinite(t.delay_s) else None,
            "energy_kwh": float(t.energy_kwh) if np.isfinite(t.energy_kwh) else None,
        }
        for t in res.trains
    ]
    summary = {
        "file": str(path),
        "line": op.name,
        "sample": sample,
        "status": res.status,
        "trains": trains,
        "conflicts": len(res.conflicts),
        "total_delay_s": float(sum(t.delay_s for t in res.trains if np.isfinite(t.delay_s))),
        "energy_kwh": float(sum(t.energy_kwh for t in res.trains if np.isfinite(t.energy_kwh))),
    }
    if op.connections:
        summary["knock_on"] = knock_on
    return summary, found


def _destination(c: Any, arrivals: Arrivals) -> str:
    """The destination of the feeder of connection ``c``: the last station it has an arrival at
    (a train's stops end at its destination)."""
    stations = [st for (ln, tr, st) in arrivals if ln == c.line and tr == c.feeder]
    return stations[-1]


def _groups(files: Sequence[str]) -> list[tuple[str, ...]]:
    """The files as groups simulated together: the files joined by connections (feeders first), every
    other file alone; in the order of their first file. Bad connections are refused."""
    ops = {f: read_operation(f) for f in files}
    if not any(op.connections for op in ops.values()):
        return [(f,) for f in files]
    by_name: dict[str, list[str]] = {}
    for f, op in ops.items():
        by_name.setdefault(op.name, []).append(f)
    feeders: dict[str, set[str]] = {f: set() for f in files}
    problems: list[Problem] = []
    for f, op in ops.items():
        for i, c in enumerate(op.connections):
            where = f"connections[{i}]"
            found = by_name.get(c.line, [])
            if len(found) != 1:
                problems.append(
                    Problem("no line of that name" if not found else "several lines have that name",
                            file=f, field=f"{where}.line", value=c.line,
                            allowed="the name of exactly one other file's line: " + ", ".join(sorted(by_name)))
                )  # fmt: skip
                continue
            other = ops[found[0]]
            svc = next((x for x in other.services if x.id == c.feeder), None)
            if svc is None:
                problems.append(
                    Problem("unknown feeder train", file=f, field=f"{where}.feeder", value=c.feeder,
                            allowed=f"a train of '{c.line}'")
                )  # fmt: skip
                continue
            stations = [x.station for x in svc.stops if x.station != svc.destination] + [svc.destination]
            if c.station is not None and c.station not in stations:
                problems.append(
                    Problem("the feeder does not stop there", file=f, field=f"{where}.station",
                            value=c.station, allowed=", ".join(stations))
                )  # fmt: skip
                continue
            feeders[f].add(found[0])
    if problems:
        raise InputError.from_problems(problems)
    # joined files: union of the connections in either direction
    parent = {f: f for f in files}

    def root(f: str) -> str:
        while parent[f] != f:
            f = parent[f]
        return f

    for f, ups in feeders.items():
        for u in ups:
            parent[root(u)] = root(f)
    groups: dict[str, list[str]] = {}
    for f in files:
        groups.setdefault(root(f), []).append(f)
    out = []
    for members in groups.values():
        order: list[str] = []
        todo = list(members)
        while todo:
            ready = [f for f in todo if feeders[f] <= set(order)]
            if not ready:
                raise InputError(
                    "connections form a cycle: each of these lines waits for another of them",
                    field="connections", value=[ops[f].name for f in todo],
                    allowed="feeders that do not wait, directly or not, for the lines they feed",
                )  # fmt: skip
            order.extend(ready)
            todo = [f for f in todo if f not in ready]
        out.append(tuple(order))
    return out


def _tasks(files: Sequence[str | Path], samples: int, seed: int | None) -> list[tuple]:
    if not files:
        raise InputError("a network-day needs at least one operation file", field="files", value=[])
    if not 0 <= samples <= 10_000:
        raise InputError("invalid number of samples", field="samples", value=samples, allowed="0 .. 10000")
    missing = [str(f) for f in files if not Path(f).is_file()]
    if missing:
        raise InputError("operation file not found", field="files", value=missing)
    if samples:
        for f in files:
            op = read_operation(f)
            if op.disturbances is None and op.delays is None:
                raise InputError(
                    "sampled days need a 'delays' or 'disturbances' block", file=str(f), field="delays"
                )
    groups = _groups([str(f) for f in files])
    if samples == 0:
        return [(g, None, 0, seed) for g in groups]
    return [(g, k, samples, seed) for g in groups for k in range(samples)]


def network_day(
    files: Sequence[str | Path], samples: int = 0, seed: int | None = None, client: Any = None
) -> dict[str, Any]:
    """Simulate every line of ``files`` (its own timetable, or ``samples`` sampled days each) locally
    (``client`` None) or on the Dask cluster of ``client`` (a ``distributed.Client``): the same line-day
    summaries either way, in the order of the files and samples.

    Returns ``status`` (the worst line-day status), ``line_days`` (``line_day`` summaries) and the
    totals ``total_delay_s`` and ``energy_kwh`` over all line-days."""
    tasks = _tasks(files, samples, seed)
    if client is None:
        done = [lines_day(*t) for t in tasks]
    else:
        futures = client.map(lines_day, *zip(*tasks, strict=True), pure=False)
        done = client.gather(futures)
    # back in the order of the files and samples
    by_key: dict[tuple[str, int | None], list[dict[str, Any]]] = {}
    for group in done:
        for d in group:
            by_key.setdefault((d["file"], d["sample"]), []).append(d)
    days = [by_key[(str(f), k)].pop(0) for f in files for k in (range(samples) if samples else [None])]
    worst = max((d["status"] for d in days), key=lambda s: STATUS_ORDER.index(s) if s in STATUS_ORDER else 99)
    return {
        "status": worst,
        "samples": samples,
        "seed": seed,
        "lines": line_statistics(days),
        "line_days": days,
        "total_delay_s": float(sum(d["total_delay_s"] for d in days)),
        "energy_kwh": float(sum(d["energy_kwh"] for d in days)),
    }


def line_statistics(days: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per line (file) over its line-days: the number of days, how often each status came out, the
    conflicts of the planned timetable (counted on unsampled days only: sampled days skip that
    check) and per train the delay statistics (``delay_stats``: mean, p50, p95, max [s]; None and
    ``unfinished`` when the train did not finish on some day) and the mean operated energy [kWh]."""
    by_file: dict[str, list[dict[str, Any]]] = {}
    for d in days:
        by_file.setdefault(d["file"], []).append(d)
    out = []
    for file, group in by_file.items():
        statuses: dict[str, int] = {}
        for d in group:
            statuses[d["status"]] = statuses.get(d["status"], 0) + 1
        delays: dict[str, list[float | None]] = {}
        energy: dict[str, list[float | None]] = {}
        for d in group:
            for t in d["trains"]:
                delays.setdefault(t["id"], []).append(t["delay_s"])
                energy.setdefault(t["id"], []).append(t["energy_kwh"])
        unsampled = [d for d in group if d["sample"] is None]
        out.append(
            {
                "file": file,
                "line": group[0]["line"],
                "days": len(group),
                "statuses": statuses,
                "conflicts": sum(d["conflicts"] for d in unsampled) if unsampled else None,
                "total_delay_s": delay_stats([d["total_delay_s"] for d in group]),
                "trains": [
                    {
                        "id": k,
                        "delay_s": delay_stats(v),
                        "energy_kwh_mean": None
                        if any(e is None for e in energy[k])
                        else round(float(np.mean(energy[k])), 3),
                    }
                    for k, v in delays.items()
                ],
            }
        )
    return out


def run_network_day(
    files: Sequence[str | Path],
    samples: int = 0,
    seed: int | None = None,
    scheduler: str | None = None,
    local_workers: int | None = None,
) -> dict[str, Any]:
    """``network_day`` in this process (neither ``scheduler`` nor ``local_workers``), on the Dask
    scheduler at ``scheduler`` (an address such as ``tcp://10.0.0.5:8786``) or on a local Dask cluster
    of ``local_workers`` processes started and closed here. A scheduler that cannot be reached is a
    ``ClusterLostError`` (``trainsim`` exits with 4)."""
    if scheduler is not None and local_workers is not None:
        raise InputError(
            "give a scheduler address or a number of local workers, not both",
            field="--scheduler/--local-workers",
            value=(scheduler, local_workers),
        )
    if local_workers is not None and not (
        isinstance(local_workers, int) and 1 <= local_workers <= MAX_LOCAL_WORKERS
    ):
        raise InputError(
            "invalid number of local workers",
            field="--local-workers",
            value=local_workers,
            allowed=f"1 .. {MAX_LOCAL_WORKERS}",
        )
    _tasks(files, samples, seed)  # bad input is refused before a cluster is started
    if scheduler is None and local_workers is None:
        return network_day(files, samples, seed)
    from distributed import Client

    from trainsim.batch.executors import ClusterLostError

    try:
        if scheduler is not None:
            client = Client(str(scheduler), timeout=f"{CONNECT_TIMEOUT_S}s")
        else:
            client = Client(
                n_workers=local_workers, threads_per_worker=1, processes=True, dashboard_address=None
            )
    except OSError as exc:  # distributed raises OSError (TimeoutError) when it cannot connect
        raise ClusterLostError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from None
    with client:
        return network_day(files, samples, seed, client=client)


__all__ = ["line_day", "line_statistics", "lines_day", "network_day", "run_network_day"]
