"""Running a study: expand it, skip what is already written, compute the rest in chunks, write each chunk."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from trainsim.batch.executors import WORKER_TIMEOUT_S, ExecutorName, default_workers, executor_for
from trainsim.batch.expand import Expansion, RunTask
from trainsim.batch.sink import MemorySink, ParquetSink, read_results
from trainsim.batch.study import Study, load_study
from trainsim.batch.worker import Payload
from trainsim.errors import InputError

__all__ = ["StudyOutcome", "auto_chunk_size", "longest_first", "plan_chunks", "run_study"]


@dataclass
class StudyOutcome:
    """What a call of :func:`run_study` did.

    Attributes:
        study: the study's name.
        out: its output directory (None when run in memory).
        runs: number of runs of the study.
        already_done: runs found written when it started (resumed).
        computed: runs computed by this call.
        failed: failed runs among those computed by this call (failure rows, status ``failed``).
        stalled: runs computed by this call whose train stalled.
        elapsed_s: wall time of the computation (after the study was read and expanded) [s].
        chunks: chunks computed; chunk_size: runs per chunk (the largest, when automatic);
        chunk_sizes: runs of each chunk computed, in the order they completed;
        executor, workers: where;
        worker_cpu_s: CPU time of the runs each worker computed [s] (serial and processes executors;
            a process that died and the one that replaced it count as two; start-up, pipes and the
            writing are not in it): how evenly the chunks shared the work, whatever else the machine
            was doing.
    """

    study: str
    out: Path | None
    runs: int
    already_done: int
    computed: int
    failed: int
    stalled: int
    elapsed_s: float
    chunks: int
    chunk_size: int
    executor: str
    workers: int
    chunk_sizes: tuple[int, ...] = ()
    worker_cpu_s: tuple[float, ...] = ()
    _table: Any = field(default=None, repr=False)

    @property
    def runs_per_s(self) -> float:
        """Runs computed per second of wall time."""
        return self.computed / self.elapsed_s if self.elapsed_s > 0 else float("nan")

    @property
    def complete(self) -> bool:
        """Whether every run of the study is now written."""
        return self.already_done + self.computed == self.runs

    def results(self):
        """The study's rows as a pandas DataFrame sorted by run_index."""
        if self._table is not None:
            return self._table.to_pandas()
        assert self.out is not None
        return read_results(self.out)

    def table(self):
        """The study's rows as an Arrow table sorted by run_index."""
        if self._table is not None:
            return self._table
        assert self.out is not None
        return read_results(self.out, as_table=True)


#: Smallest and largest automatic chunk of cheap runs [runs].
MIN_CHUNK, MAX_CHUNK = 10, 200
#: Compute time aimed at for one chunk [s]: long against the cost of a chunk (scheduling, pickling, one
#: Parquet file: about 10 ms), short enough that a killed study loses little and the last chunks end
#: together. Runs costing more than this go one per chunk.
CHUNK_TARGET_S = 0.5
#: Cost of one run of the examples predicted before any is measured [s] (2-core development machine):
#: a metro fastest run, an energy-efficient run of the optimiser, a multi-point run of the heavy-haul
#: example (106 vehicles, 50 km, 0.05 s steps).
PREDICTED_RUN_S = {"fastest": 0.0025, "driving": 0.3, "multi_point": 3.0}
#: Work units of those example runs (:func:`run_work`): the metro (4.59 km, 4 stops) and heavy haul.
_EXAMPLE_WORK = {"fastest": 4.59 + 4, "driving": 4.59 + 4, "multi_point": 106 * 50.0}
#: Largest study whose runs are ordered by predicted cost (longest first) before they are chunked.
MAX_ORDERED_RUNS = 20_000
#: Default largest step of the multi-point integrator [s] (MultiPointSettings.time_step_s).
_MP_STEP_S = 0.05
_FORMATION_COUNT = re.compile(r"^train\.formation\[(\d+)\]\.count$")


def auto_chunk_size(remaining: int, workers: int, run_s: float = PREDICTED_RUN_S["fastest"]) -> int:
    """Runs of the next chunk when ``remaining`` runs are left, each costing about ``run_s`` seconds.

    Cheap runs: a quarter of each worker's share, between 10 and 200 runs ("guided" scheduling: the
    chunks shrink towards the end of the study so that no worker waits long for the last one). The
    chunk never holds more than :data:`CHUNK_TARGET_S` of work: multi-point and energy-efficient runs
    (seconds each) go one or a few per chunk, so that 12 runs on 2 workers are split 6 / 6, not 10 / 2,
    and a killed worker loses one run's work, not a chunk's.
    """
    by_cost = max(1, int(CHUNK_TARGET_S / max(run_s, 1e-9)))
    guided = max(MIN_CHUNK, min(MAX_CHUNK, math.ceil(remaining / max(1, 4 * workers))))
    return max(1, min(guided, by_cost))


def _number(x: Any, default: float) -> float:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) and x > 0 else default


def run_work(data: dict[str, Any], overrides: tuple = ()) -> tuple[str, float]:
    """Kind of a run and its predicted work from its scenario data, in units proportional to its cost.

    Single-point runs: route length [km] + stops (the cost model of docs/reference/performance.md:
    time per km and per stop, about one km's worth per stop). Multi-point runs: vehicles x route length
    [km] x (0.05 s / time step): the integrator's work per step is linear in the vehicles
    (docs/MULTIPOINT.md, "Cost"). Values the run's ``overrides`` set (model, time step, a formation
    count, the route length) are taken into account; a route or train given as a file name counts as
    the examples' (the figures then come from the measured costs).
    """
    model = data.get("model", "single_point")
    mp = data.get("multi_point") if isinstance(data.get("multi_point"), dict) else {}
    step = _number(mp.get("time_step_s"), _MP_STEP_S)
    train = data.get("train")
    formation = train.get("formation") if isinstance(train, dict) else None
    counts = (
        [_number(v.get("count", 1), 1.0) if isinstance(v, dict) else 1.0 for v in formation]
        if isinstance(formation, list)
        else None
    )
    route = data.get("route")
    length_km = _number(route.get("length_m"), 0.0) / 1e3 if isinstance(route, dict) else 0.0
    stops = data.get("stops")
    n_stops = len(stops) if isinstance(stops, list) else None
    if n_stops is None and isinstance(route, dict) and isinstance(route.get("stations"), list):
        n_stops = len(route["stations"])
    for path, value, relative in overrides:
        if path == "model":
            model = value
        elif path == "multi_point.time_step_s":
            step = _number(value * step if relative else value, step)
        elif path == "route.length_m":
            length_km = _number(value * length_km * 1e3 if relative else value, length_km * 1e3) / 1e3
        elif path == "stops" and isinstance(value, list):
            n_stops = len(value)
        elif counts is not None and (m := _FORMATION_COUNT.match(path)) and int(m.group(1)) < len(counts):
            k = int(m.group(1))
            counts[k] = _number(value * counts[k] if relative else value, counts[k])
    if model == "multi_point":
        vehicles = sum(counts) if counts else 106.0
        return "multi_point", vehicles * (length_km or 50.0) * _MP_STEP_S / step
    kind = "driving" if data.get("driving") is not None else "fastest"
    return kind, (length_km or 4.59) + (n_stops if n_stops is not None else 4)


class _Cost:
    """The cost of each run [s of one worker]: its predicted work (:func:`run_work`) times seconds per
    unit of work of its kind, predicted from the examples (:data:`PREDICTED_RUN_S`) until runs are
    measured, then the ratio of the measured CPU time of every run received to their predicted work.
    Executors that do not time single runs (Dask) are measured from the rate at which chunks complete
    after the first one (so that the workers' start-up does not count): wall time x workers / runs."""

    def __init__(self, expansion: Expansion, entries: tuple[dict[str, Any], ...] = ()) -> None:
        self.expansion = expansion
        self.entries = entries
        default = "multi_point" if expansion.multi_point else "driving" if expansion.driving else "fastest"
        self.kind = default
        self.unit_s = {k: PREDICTED_RUN_S[k] / _EXAMPLE_WORK[k] for k in PREDICTED_RUN_S}
        # the work of an entry's runs, and whether some swept value changes it (else it is the entry's)
        self._entry_work = [run_work(e) for e in entries]
        paths = {c.path for c in getattr(expansion, "_overrides", ())}
        self._per_run = any(
            p in ("model", "multi_point.time_step_s", "route.length_m", "stops") or _FORMATION_COUNT.match(p)
            for p in paths
        )
        self._sums: dict[str, list[float]] = {}  # kind -> [measured s, predicted work]
        self.first: tuple[float, int] | None = None
        self.done = 0
        self.rate_s: float | None = None

    def work(self, i: int) -> tuple[str, float]:
        """Kind and predicted work of run ``i``."""
        if not self.entries:
            return self.kind, _EXAMPLE_WORK[self.kind]
        if not self._per_run:
            return self._entry_work[self.expansion.entry[i]]
        task = self.expansion.task(i)
        return run_work(self.entries[task[1]], task[3])

    def seconds(self, i: int) -> float:
        """Predicted cost of run ``i`` [s]."""
        kind, work = self.work(i)
        if self.rate_s is not None and not self._sums:
            return self.rate_s * work / _EXAMPLE_WORK[self.kind]
        return self.unit_s[kind] * work

    @property
    def run_s(self) -> float:
        """Cost of a run of the study's kind with the examples' work [s]."""
        return self.unit_s[self.kind] * _EXAMPLE_WORK[self.kind]

    @run_s.setter
    def run_s(self, value: float) -> None:
        self.unit_s[self.kind] = value / _EXAMPLE_WORK[self.kind]

    def measured(self, runs: list[tuple[int, float]]) -> None:
        """Runs timed by the executor: (run index, CPU s) each."""
        for i, cpu_s in runs:
            kind, work = self.work(i)
            acc = self._sums.setdefault(kind, [0.0, 0.0])
            acc[0] += cpu_s
            acc[1] += work
            if acc[1] > 0 and acc[0] > 0:
                self.unit_s[kind] = acc[0] / acc[1]

    def update(self, runs: int, workers: int) -> None:
        """A chunk of ``runs`` completed (the fallback measure when runs are not timed one by one)."""
        self.done += runs
        now = time.perf_counter()
        if self.first is None:
            self.first = (now, self.done)
        elif self.done > self.first[1] and not self._sums:
            self.run_s = (now - self.first[0]) * max(workers, 1) / (self.done - self.first[1])

    def order(self, todo: list[int]) -> list[int]:
        """The runs longest predicted first (a study of at most :data:`MAX_ORDERED_RUNS` runs whose
        costs differ): the long runs start first and the short ones fill the gaps at the end, so that
        the workers finish together. Otherwise, and among equal costs, in run order."""
        if len(todo) > MAX_ORDERED_RUNS or not self.entries:
            return todo
        return [todo[k] for k in longest_first([self.seconds(i) for i in todo])]


def longest_first(costs_s: Sequence[float]) -> list[int]:
    """Positions of ``costs_s`` ordered longest first, equal costs in their order; the given order
    when every cost is the same (within 1e-7 relative)."""
    if not costs_s or max(costs_s) <= min(costs_s) * 1.0000001:
        return list(range(len(costs_s)))
    return sorted(range(len(costs_s)), key=lambda k: -costs_s[k])


def _take(run_s: Callable[[int], float], todo: Sequence[int], k: int, limit: int) -> int:
    """Runs of the chunk starting at ``todo[k]``: at least one, at most ``limit``, adding runs while
    their predicted cost ``run_s(run)`` stays within :data:`CHUNK_TARGET_S`."""
    n, total = 0, 0.0
    while k + n < len(todo) and n < limit:
        total += run_s(todo[k + n])
        if n and total > CHUNK_TARGET_S:
            break
        n += 1
    return n


def plan_chunks(costs_s: Sequence[float], workers: int) -> list[list[int]]:
    """The chunks :func:`run_study` forms for runs of the given predicted costs [s] on ``workers``
    workers, as lists of positions in ``costs_s``: longest first (:func:`longest_first`), each chunk
    at most :data:`CHUNK_TARGET_S` of work or a single run, at most the guided size of
    :func:`auto_chunk_size`. Handed to the next idle worker in this order, this is longest-processing-
    time-first list scheduling: the expensive runs start first, alone, and the cheap ones fill the
    gaps at the end, so that the workers finish together and a killed worker loses little.

    (The study itself reads the costs again before each chunk, as measured runs come in; this is the
    plan when the predictions hold.)
    """
    order = longest_first(costs_s)
    chunks, k = [], 0
    while k < len(order):
        n = _take(costs_s.__getitem__, order, k, auto_chunk_size(len(order) - k, workers, 0.0))
        chunks.append(order[k : k + n])
        k += n
    return chunks


def _chunks(
    expansion: Expansion, todo: list[int], size: int | None, workers: int, cost: _Cost | None = None
) -> Iterator[list[RunTask]]:
    """The runs ``todo`` in chunks: of ``size`` runs, or else sized by their predicted cost as
    :func:`plan_chunks` does, the costs read again before each chunk as measured runs come in."""
    k = 0
    while k < len(todo):
        if size:
            n = size
        elif cost is None:
            n = auto_chunk_size(len(todo) - k, workers)
        else:
            n = _take(cost.seconds, todo, k, auto_chunk_size(len(todo) - k, workers, 0.0))
        yield [expansion.task(i) for i in todo[k : k + n]]
        k += n


class _Progress:
    """A rich progress bar on stderr: runs done of all, failures, rate and time left."""

    def __init__(self, name: str, total: int, done: int, enabled: bool) -> None:
        from rich.console import Console

        console = Console(stderr=True)
        # a bar redrawn into a log file or a pipe is noise: only on a terminal
        self.enabled = enabled and console.is_terminal
        if not self.enabled:
            return
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("runs"),
            TextColumn("{task.fields[failed]}"),
            TextColumn("{task.fields[rate]:>9s}"),
            TimeElapsedColumn(),
            TextColumn("left"),
            TimeRemainingColumn(),
            console=console,
            transient=False,
        )
        self.t0 = time.perf_counter()
        self.new = 0
        self.failed = 0
        self.progress.start()
        self.task = self.progress.add_task(name, total=total, completed=done, failed="", rate="")

    def advance(self, n: int, failed: int) -> None:
        if not self.enabled:
            return
        self.new += n
        self.failed += failed
        rate = self.new / max(time.perf_counter() - self.t0, 1e-9)
        self.progress.update(
            self.task,
            advance=n,
            failed=f"[red]{self.failed} failed" if self.failed else "",
            rate=f"{rate:,.0f} runs/s",
        )

    def close(self) -> None:
        if self.enabled:
            self.progress.stop()


def run_study(
    study: Study | str | Path,
    out: str | Path | None = None,
    *,
    executor: ExecutorName = "processes",
    workers: int | None = None,
    scheduler: Any = None,
    chunk_size: int | None = None,
    restart: bool = False,
    progress: bool = False,
    worker_timeout_s: float = WORKER_TIMEOUT_S,
) -> StudyOutcome:
    """Run every run of a study that is not yet in ``out``; a failed run is a row, never an exception.

    Args:
        study: a :class:`Study` or a study file.
        out: output directory (Parquet dataset ``out/results``); None keeps the rows in memory
            (``outcome.results()``) and cannot resume.
        executor: ``serial``, ``processes`` (default) or ``dask``.
        workers: processes of the pool (default: the cores available), or of the local Dask cluster.
        scheduler: Dask scheduler address or ``distributed.Client`` (implies ``executor="dask"``).
        chunk_size: runs per task (default: the study's ``chunk_size``, else :func:`auto_chunk_size`).
        restart: discard the results already in ``out`` and start again.
        progress: show a progress bar on stderr.
        worker_timeout_s: how long a Dask study waits when its cluster has no worker [s].

    Raises:
        InputError: the study cannot be run as written.
        ClusterLostError: the workers or the Dask scheduler were lost (see
            :mod:`trainsim.batch.executors`); what was computed is written and the study resumes.
    """
    if not isinstance(study, Study):
        study = load_study(study)
    if scheduler is not None:
        executor = "dask"
    if executor not in ("serial", "processes", "dask"):
        raise InputError(
            "unknown executor", field="executor", value=executor, allowed="serial, processes, dask"
        )
    if workers is not None and workers < 1:
        raise InputError("at least one worker is needed", field="workers", value=workers, allowed=">= 1")
    expansion = study.expand()
    sink: MemorySink | ParquetSink
    sink = MemorySink(expansion) if out is None else ParquetSink(out, expansion, study_file=study.file)
    done = sink.open(restart=restart)
    todo = [i for i, rid in enumerate(expansion.run_ids) if rid not in done]
    n_workers = 1 if executor == "serial" else (workers or default_workers())  # Dask: known once started
    size = chunk_size or study.spec.chunk_size  # None: automatic, shrinking towards the end
    payload = Payload.of(study)
    already = len(expansion) - len(todo)
    computed = failed = stalled = chunks = 0
    sizes: list[int] = []
    worker_cpu: tuple[float, ...] = ()
    t0 = time.perf_counter()
    if todo:
        with executor_for(
            payload, executor, workers=workers, scheduler=scheduler, worker_timeout_s=worker_timeout_s
        ) as ex:
            n_workers = ex.workers
            # the bar (a thread) starts once the workers are running
            bar = _Progress(study.name, len(expansion), already, progress)
            cost = _Cost(expansion, payload.entries)
            order = todo if size else cost.order(todo)
            try:
                for rows in ex.results(_chunks(expansion, order, size, n_workers, cost)):
                    cost.measured(getattr(ex, "measured", []))
                    if hasattr(ex, "measured"):
                        ex.measured.clear()
                    cost.update(len(rows), n_workers)
                    sizes.append(len(rows))
                    sink.write(rows)
                    n_failed = sum(1 for _, r in rows if r["status"] == "failed")
                    computed += len(rows)
                    failed += n_failed
                    stalled += sum(1 for _, r in rows if r["status"] == "stalled")
                    chunks += 1
                    bar.advance(len(rows), n_failed)
            finally:
                bar.close()
        worker_cpu = tuple(getattr(ex, "worker_cpu_s", ()))  # complete once the executor is closed
    elapsed = time.perf_counter() - t0
    return StudyOutcome(
        study=study.name,
        out=Path(out) if out is not None else None,
        runs=len(expansion),
        already_done=already,
        computed=computed,
        failed=failed,
        stalled=stalled,
        elapsed_s=elapsed,
        chunks=chunks,
        chunk_size=size or max(sizes, default=auto_chunk_size(len(todo), n_workers)),
        executor=executor,
        workers=n_workers,
        chunk_sizes=tuple(sizes),
        worker_cpu_s=worker_cpu,
        _table=sink.table() if isinstance(sink, MemorySink) else None,
    )
