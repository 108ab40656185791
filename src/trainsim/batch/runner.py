"""Running a study: expand it, skip what is already written, compute the rest in chunks, write each chunk."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from trainsim.batch.executors import WORKER_TIMEOUT_S, ExecutorName, default_workers, executor_for
from trainsim.batch.expand import Expansion, RunTask
from trainsim.batch.sink import MemorySink, ParquetSink, read_results
from trainsim.batch.study import Study, load_study
from trainsim.batch.worker import Payload
from trainsim.errors import InputError

__all__ = ["StudyOutcome", "auto_chunk_size", "run_study"]


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
        executor, workers: where.
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
#: Cost of one run predicted before any is measured [s] (2-core development machine): a metro fastest
#: run, an energy-efficient run of the optimiser, a multi-point run of the heavy-haul example.
PREDICTED_RUN_S = {"fastest": 0.0025, "driving": 0.3, "multi_point": 3.0}


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


class _Cost:
    """The cost of a run [s of one worker]: predicted from the kind of study, then measured from the
    rate at which chunks complete after the first one (so that the workers' start-up does not count):
    wall time x workers / runs."""

    def __init__(self, expansion: Expansion) -> None:
        kind = "multi_point" if expansion.multi_point else "driving" if expansion.driving else "fastest"
        self.run_s = PREDICTED_RUN_S[kind]
        self.first: tuple[float, int] | None = None
        self.done = 0

    def update(self, runs: int, workers: int) -> None:
        self.done += runs
        now = time.perf_counter()
        if self.first is None:
            self.first = (now, self.done)
        elif self.done > self.first[1]:
            self.run_s = (now - self.first[0]) * max(workers, 1) / (self.done - self.first[1])


def _chunks(
    expansion: Expansion, todo: list[int], size: int | None, workers: int, cost: _Cost | None = None
) -> Iterator[list[RunTask]]:
    k = 0
    while k < len(todo):
        run_s = cost.run_s if cost is not None else PREDICTED_RUN_S["fastest"]
        n = size or auto_chunk_size(len(todo) - k, workers, run_s)
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
    payload = Payload(
        study.fingerprint,
        study.name,
        tuple(e.data for e in study.entries),
        timetables=tuple(study.timetables.items()),
        driving=study.driving,
        profiles=tuple(study.profiles.items()),
        multi_point=study.multi_point,
    )
    already = len(expansion) - len(todo)
    computed = failed = stalled = chunks = 0
    sizes: list[int] = []
    t0 = time.perf_counter()
    if todo:
        with executor_for(
            payload, executor, workers=workers, scheduler=scheduler, worker_timeout_s=worker_timeout_s
        ) as ex:
            n_workers = ex.workers
            # the bar (a thread) starts once the workers are running
            bar = _Progress(study.name, len(expansion), already, progress)
            cost = _Cost(expansion)
            try:
                for rows in ex.results(_chunks(expansion, todo, size, n_workers, cost)):
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
        _table=sink.table() if isinstance(sink, MemorySink) else None,
    )
