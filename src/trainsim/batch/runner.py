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


#: Smallest and largest automatic chunk [runs].
MIN_CHUNK, MAX_CHUNK = 10, 200


def auto_chunk_size(remaining: int, workers: int) -> int:
    """Runs of the next chunk when ``remaining`` runs are left: a quarter of each worker's share,
    between 10 and 200 runs.

    Chunks of up to 200 metro runs (about half a second) keep the per-chunk cost (scheduling,
    pickling, one Parquet file) below 1 % while a killed study loses little work; chunks shrink
    towards the end of the study ("guided" scheduling) so that no worker waits long for the last
    one to finish.
    """
    return max(MIN_CHUNK, min(MAX_CHUNK, math.ceil(remaining / max(1, 4 * workers))))


def _chunks(expansion: Expansion, todo: list[int], size: int | None, workers: int) -> Iterator[list[RunTask]]:
    k = 0
    while k < len(todo):
        n = size or auto_chunk_size(len(todo) - k, workers)
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
    t0 = time.perf_counter()
    if todo:
        with executor_for(
            payload, executor, workers=workers, scheduler=scheduler, worker_timeout_s=worker_timeout_s
        ) as ex:
            n_workers = ex.workers
            # the bar (a thread) starts once the workers are running
            bar = _Progress(study.name, len(expansion), already, progress)
            try:
                for rows in ex.results(_chunks(expansion, todo, size, n_workers)):
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
        chunk_size=size or auto_chunk_size(len(todo), n_workers),
        executor=executor,
        workers=n_workers,
        _table=sink.table() if isinstance(sink, MemorySink) else None,
    )
