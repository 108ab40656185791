"""A network-day: several lines in operation (one operation file each), each a day of trains, and
optionally sampled days (Monte Carlo of entry delays and disturbances), simulated locally or on a
Dask cluster with the same results.

The unit of work is one line on one day (``line_day``). The operation files are read once, by the
process that starts the network-day, and the lines read (their trains, routes and timetables) are
sent to the workers, as ``trainsim batch`` sends its payload: the workers need no access to the
files, so relative paths and a remote cluster work alike.

Sampled days: day ``k`` of a line draws from its own stream, ``SeedSequence(seed, spawn_key=(k,
line key...))`` where the line key is taken from the SHA-256 of the line's name and the number of
earlier files with the same name (:func:`line_stream`). So the lines of a network draw
independently of each other (one ``--seed`` does not give every line the same draws), a line's
draws do not depend on which other lines are simulated with it or in what order, and a seed gives
the same network-day every time.

Lines of a network are simulated independently, except where a file's ``connections`` make a train
wait at its origin for a train of another file's line (a passenger connection, or the same unit
turning round): the lines so joined are simulated together, feeders first, and a late feeder makes
the waiting train late (knock-on). Each line keeps its own sampled stream, so a line's disturbances
do not depend on the lines it is joined to.

Lost infrastructure: when the Dask scheduler or the workers are lost while the line-days are
computed (a worker killed too often, the scheduler gone, no worker connected for
:data:`~trainsim.batch.executors.WORKER_TIMEOUT_S`), ``run_network_day`` and ``network_day`` raise
:class:`~trainsim.batch.executors.ClusterLostError` (``trainsim operate`` exits with 4). Nothing is
written then: a network-day has no resume.
"""

from __future__ import annotations

import contextlib
import hashlib
import time
from collections.abc import Sequence
from concurrent.futures import CancelledError
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from trainsim.errors import InputError, Problem
from trainsim.io.operation_file import Operation, read_operation
from trainsim.io.operation_run import delay_stats, run_operation

#: The most local Dask worker processes started for a network-day.
MAX_LOCAL_WORKERS = 256
#: How long to try to reach a Dask scheduler [s].
CONNECT_TIMEOUT_S = 10
#: Status order, worst last: the network-day's status is its worst line-day's.
STATUS_ORDER = ("ok", "conflicts", "stalled", "deadlock")
#: How long the line-days may wait for a worker when the cluster has none [s] (as ``trainsim batch``).
WORKER_TIMEOUT_S = 60.0
#: How often the cluster is looked at while the line-days are computed [s].
POLL_S = 0.5


#: Arrivals of the trains of the lines simulated so far: (line name, train, station) -> time [s], None
#: when the train did not arrive there.
Arrivals = dict[tuple[str, str, str], float | None]


#: One line of a network-day as sent to a worker: the file as given (the label of its results),
#: the operation read from it, and the key of its sampled streams (``line_key``).
LineInput = tuple[str, Operation, tuple[int, ...]]


def line_key(name: str, occurrence: int = 0) -> tuple[int, ...]:
    """The key of a line's sampled streams: four 32-bit words of the SHA-256 of its ``name`` and the
    number of earlier files of the network-day with the same name (``occurrence``), so two copies of
    one line still draw independently."""
    digest = hashlib.sha256(name.encode("utf-8")).digest()
    return (*(int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)), occurrence)


def line_stream(seed: int, day: int, key: tuple[int, ...]) -> np.random.SeedSequence:
    """The stream of sampled day ``day`` of the line of ``key`` (``line_key``) under ``seed``."""
    return np.random.SeedSequence(seed, spawn_key=(day, *key))


def line_day(
    path: str | Path, sample: int | None = None, samples: int = 0, seed: int | None = None
) -> dict[str, Any]:
    """Simulate one line's day: the file's own timetable (``sample`` None) or sampled day ``sample``
    (of ``samples``; seed: ``seed``, default the file's; stream: ``line_stream``). Returns a picklable
    summary: per train its delay [s] and operated energy [kWh], the status, the planned conflicts
    (None on sampled days: they are not checked) and the totals. The file's connections are not
    applied (``lines_day`` applies them)."""
    op = read_operation(path)
    return _line_day((str(path), op, line_key(op.name)), sample, samples, seed, None)[0]


def lines_day(
    lines: Sequence[LineInput], sample: int | None = None, samples: int = 0, seed: int | None = None
) -> list[dict[str, Any]]:
    """``line_day`` of each of ``lines`` in turn (feeders first), each line's trains waiting for the
    feeders of its connections as the lines before it ran them."""
    arrivals: Arrivals = {}
    out = []
    for line in lines:
        day, found = _line_day(line, sample, samples, seed, arrivals)
        arrivals.update(found)
        out.append(day)
    return out


def _line_day(
    line: LineInput, sample: int | None, samples: int, seed: int | None, arrivals: Arrivals | None
) -> tuple[dict[str, Any], Arrivals]:
    path, op, key = line
    services = op.services
    if sample is not None:
        sampler = op.disturbances if op.disturbances is not None else op.delays
        if sampler is None:
            raise InputError(
                "sampled days need a 'delays' or 'disturbances' block", file=str(path), field="delays"
            )
        base = sampler.seed if seed is None else seed
        services = sampler.sample(op.given_services, np.random.default_rng(line_stream(base, sample, key)))
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
        # sampled days skip the conflict check: 0 there would claim a check that was not made
        "conflicts": len(res.conflicts) if sample is None else None,
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


def _groups(files: Sequence[str], ops: Sequence[Operation]) -> list[tuple[int, ...]]:
    """The files (by position) as groups simulated together: the files joined by connections (feeders
    first), every other file alone; in the order of their first file. Bad connections are refused."""
    if not any(op.connections for op in ops):
        return [(i,) for i in range(len(files))]
    by_name: dict[str, list[int]] = {}
    for i, op in enumerate(ops):
        by_name.setdefault(op.name, []).append(i)
    feeders: dict[int, set[int]] = {i: set() for i in range(len(files))}
    problems: list[Problem] = []
    for at, op in enumerate(ops):
        f = files[at]
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
            feeders[at].add(found[0])
    if problems:
        raise InputError.from_problems(problems)
    # joined files: union of the connections in either direction
    parent = {f: f for f in feeders}

    def root(f: int) -> int:
        while parent[f] != f:
            f = parent[f]
        return f

    for f, ups in feeders.items():
        for u in ups:
            parent[root(u)] = root(f)
    groups: dict[int, list[int]] = {}
    for f in feeders:
        groups.setdefault(root(f), []).append(f)
    out = []
    for members in groups.values():
        order: list[int] = []
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


def _tasks(
    files: Sequence[str | Path], samples: int, seed: int | None
) -> tuple[list[tuple[LineInput, ...]], list[int | None]]:
    """The groups of lines simulated together (``_groups``, the lines as ``LineInput``) and the days
    (None: the timetable; else the sampled days): one task per group and day."""
    if not files:
        raise InputError("a network-day needs at least one operation file", field="files", value=[])
    if not 0 <= samples <= 10_000:
        raise InputError("invalid number of samples", field="samples", value=samples, allowed="0 .. 10000")
    if seed is not None and not (isinstance(seed, int) and 0 <= seed < 2**63):
        raise InputError("invalid seed", field="--seed", value=seed, allowed="an integer 0 .. 2**63 - 1")
    missing = [str(f) for f in files if not Path(f).is_file()]
    if missing:
        raise InputError("operation file not found", field="files", value=missing)
    names = [str(f) for f in files]
    # read here, once: the workers get the lines read, never a path they may not see
    ops = [read_operation(f) for f in files]
    if samples:
        for f, op in zip(names, ops, strict=True):
            if op.disturbances is None and op.delays is None:
                raise InputError(
                    "sampled days need a 'delays' or 'disturbances' block", file=f, field="delays"
                )
    seen: dict[str, int] = {}
    lines: list[LineInput] = []
    for f, op in zip(names, ops, strict=True):
        lines.append((f, op, line_key(op.name, seen.get(op.name, 0))))
        seen[op.name] = seen.get(op.name, 0) + 1
    groups = [tuple(lines[i] for i in g) for g in _groups(names, ops)]
    return groups, (list(range(samples)) if samples else [None])


def network_day(
    files: Sequence[str | Path], samples: int = 0, seed: int | None = None, client: Any = None
) -> dict[str, Any]:
    """Simulate every line of ``files`` (its own timetable, or ``samples`` sampled days each) locally
    (``client`` None) or on the Dask cluster of ``client`` (a ``distributed.Client``): the same line-day
    summaries either way, in the order of the files and samples. The files are read here; the
    workers get the lines read. A cluster lost meanwhile is a ``ClusterLostError``.

    Returns ``status`` (the worst line-day status), ``line_days`` (``line_day`` summaries: on sampled
    days ``conflicts`` is None, as they are not checked) and the totals ``total_delay_s`` and
    ``energy_kwh`` over all line-days."""
    return _network_day(files, samples, seed, client, _tasks(files, samples, seed))


def _network_day(
    files: Sequence[str | Path],
    samples: int,
    seed: int | None,
    client: Any,
    tasks: tuple[list[tuple[LineInput, ...]], list[int | None]],
) -> dict[str, Any]:
    groups, days = tasks
    if client is None:
        done = [lines_day(g, k, samples, seed) for g in groups for k in days]
    else:
        done = _on_cluster(client, groups, days, samples, seed)
    # back in the order of the files and samples
    by_key: dict[tuple[str, int | None], list[dict[str, Any]]] = {}
    for group in done:
        for d in group:
            by_key.setdefault((d["file"], d["sample"]), []).append(d)
    line_days = [by_key[(str(f), k)].pop(0) for f in files for k in days]
    worst = max(
        (d["status"] for d in line_days), key=lambda s: STATUS_ORDER.index(s) if s in STATUS_ORDER else 99
    )
    return {
        "status": worst,
        "samples": samples,
        "seed": seed,
        "lines": line_statistics(line_days),
        "line_days": line_days,
        "total_delay_s": float(sum(d["total_delay_s"] for d in line_days)),
        "energy_kwh": float(sum(d["energy_kwh"] for d in line_days)),
    }


def _on_cluster(
    client: Any, groups: list[tuple[LineInput, ...]], days: list[int | None], samples: int, seed: int | None
) -> list[list[dict[str, Any]]]:
    """``lines_day`` of every group and day on the cluster of ``client``; each group's lines are sent
    to the cluster once (not once per day)."""
    try:
        sent = client.scatter(groups, hash=False)
        tasks = [(g, k) for g in sent for k in days]
        futures = client.map(
            lines_day, [g for g, _ in tasks], [k for _, k in tasks], [samples] * len(tasks),
            [seed] * len(tasks), pure=False,
        )  # fmt: skip
    except TimeoutError:
        raise _lost("no worker took the lines") from None
    except (OSError, CancelledError) as exc:
        raise _lost(f"the lines could not be sent to the cluster: {exc}") from None
    return _gather(client, futures)


def _lost(why: str) -> Exception:
    from trainsim.batch.executors import ClusterLostError

    return ClusterLostError(
        f"the Dask cluster was lost during the network-day ({why}); nothing was written: run the "
        "command again"
    )


def _wait(futures: list[Any], timeout: float) -> None:
    from distributed import wait

    wait(futures, timeout=timeout)


def _gather(client: Any, futures: list[Any]) -> list[Any]:
    """The results of ``futures``, in order. Lost infrastructure (the scheduler gone, a line-day that
    killed its workers: Dask's ``KilledWorker``, futures cancelled, no worker connected for
    ``WORKER_TIMEOUT_S``) is a ``ClusterLostError``; an error of a line-day itself (an ``InputError``)
    is raised as it is."""
    no_workers_since: float | None = None
    while True:
        try:
            _wait(futures, POLL_S)
            break
        except TimeoutError:  # (before OSError, of which it is a subclass)
            no_workers_since = _check_cluster(client, no_workers_since)
        except CancelledError:
            break  # the cancelled ones are seen below
        except OSError as exc:
            raise _lost(f"the connection to the scheduler was lost: {exc}") from None
    for i, fut in enumerate(futures):
        if fut.status == "cancelled":
            raise _lost("its line-days were cancelled: the scheduler or their workers are gone")
        if fut.status == "error":
            exc = fut.exception()
            if type(exc).__name__ == "KilledWorker":
                raise _lost(f"line-day task {i} killed the workers that computed it: {exc}")
            if isinstance(exc, CancelledError):
                raise _lost(f"line-day task {i} was cancelled")
            raise exc
    try:
        return client.gather(futures)
    except TimeoutError as exc:
        raise _lost(f"the results could not be fetched: {exc!r}") from None
    except (OSError, CancelledError) as exc:
        raise _lost(f"the results could not be fetched: {exc!r}") from None


def _check_cluster(client: Any, no_workers_since: float | None) -> float | None:
    """Raise ClusterLostError if the scheduler is gone or no worker has been connected for
    ``WORKER_TIMEOUT_S``; return since when the cluster has had no worker (None: it has some)."""
    if client.status != "running":  # "connecting" after the scheduler was lost, then "closed"
        raise _lost("the connection to the scheduler was lost")
    try:
        n = len(client.scheduler_info(n_workers=-1).get("workers", {}))
    except (OSError, KeyError):
        raise _lost("the scheduler does not answer") from None
    if n:
        return None
    now = time.monotonic()
    if no_workers_since is None:
        return now
    if now - no_workers_since > WORKER_TIMEOUT_S:
        raise _lost(f"no worker connected for {WORKER_TIMEOUT_S:g} s")
    return no_workers_since


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
    of ``local_workers`` processes started and closed here. A scheduler that cannot be reached, or
    the scheduler or workers lost during the run, is a ``ClusterLostError`` (``trainsim`` exits with
    4)."""
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
    tasks = _tasks(files, samples, seed)  # bad input is refused before a cluster is started
    if scheduler is None and local_workers is None:
        return _network_day(files, samples, seed, None, tasks)
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
    try:
        return _network_day(files, samples, seed, client, tasks)
    finally:
        # the scheduler may be gone already: its loss is the error to report, not the close
        with contextlib.suppress(OSError, CancelledError):
            client.close(timeout=5)


__all__ = ["line_day", "line_statistics", "lines_day", "network_day", "run_network_day"]
