"""Where the chunks of a study are computed: in this process, in a local process pool, or on Dask.

Each executor takes the study's :class:`~trainsim.batch.worker.Payload` and an iterator of chunks and
yields the rows of each chunk as it completes (in any order). Only a few chunks are in flight at a
time (twice the number of workers), so a study of a million runs never holds a million futures and
an interrupted study loses little work. The rows of a run depend only on its parameters, so every
executor gives the same results.

* ``serial``: in this process, chunk after chunk (debugging, tiny studies, the reference).
* ``processes``: a :class:`concurrent.futures.ProcessPoolExecutor` with ``workers`` processes
  (forked, see :func:`_pool_context`); each process receives the payload once (initializer) and loads
  the compiled kernel before its first chunk.
* ``dask``: a ``distributed`` cluster: the scheduler at ``scheduler`` (an address or a
  ``distributed.Client``), or Dask's configured ``scheduler-address``, or else a local cluster of
  ``workers`` processes. The payload is scattered to every worker once.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import threading
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from typing import Any, Literal

from trainsim.batch.expand import RunTask
from trainsim.batch.worker import Payload, init_process, run_chunk, run_chunk_in_process

__all__ = ["EXECUTORS", "ExecutorName", "configured_scheduler", "default_workers", "executor_for"]

ExecutorName = Literal["serial", "processes", "dask"]
EXECUTORS: tuple[str, ...] = ("serial", "processes", "dask")

Rows = list[tuple[int, dict[str, Any]]]


def default_workers() -> int:
    """The number of cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def configured_scheduler() -> str | None:
    """The scheduler address of Dask's configuration (``DASK_SCHEDULER_ADDRESS`` or a Dask config
    file), if Dask is installed and one is set."""
    try:
        import dask.config
    except ImportError:
        return None
    address = dask.config.get("scheduler-address", None) or dask.config.get("scheduler_address", None)
    return str(address) if address else None


class _Serial:
    workers = 1

    def __init__(self, payload: Payload) -> None:
        self.payload = payload

    def start(self) -> None:
        pass

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        for chunk in chunks:
            yield run_chunk(self.payload, chunk)

    def close(self) -> None:
        pass


def _pool_context():
    # fork when this process has one thread: workers start at once with trainsim imported and the
    # kernel compiled, and nothing of __main__ is run again. With other threads alive (a progress bar,
    # a Dask client...) forking could copy a lock held by one of them: then a fork server, which
    # forks each worker from a clean single-threaded process (it re-imports __main__, which must then
    # guard its code with `if __name__ == "__main__":`, as for any multiprocessing program).
    methods = multiprocessing.get_all_start_methods()
    # (on macOS system libraries are not fork-safe even in a single-threaded process)
    if sys.platform.startswith("linux") and "fork" in methods and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["trainsim.batch.worker", "trainsim.sim.fastest", "trainsim.io.loader"])
        return ctx
    return multiprocessing.get_context("spawn")


class _Processes:
    def __init__(self, payload: Payload, workers: int) -> None:
        self.payload = payload
        self.workers = workers
        self.pool: ProcessPoolExecutor | None = None
        self.pending: set[Future] = set()

    def start(self) -> None:
        self.pool = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=_pool_context(),
            initializer=init_process,
            initargs=(self.payload,),
        )
        # the first submission starts the worker processes, before the caller starts any thread
        self.pool.submit(os.getpid).result()

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        assert self.pool is not None
        for chunk in chunks:
            self.pending.add(self.pool.submit(run_chunk_in_process, chunk))
            if len(self.pending) >= 2 * self.workers:
                done, self.pending = wait(self.pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield fut.result()
        while self.pending:
            done, self.pending = wait(self.pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield fut.result()

    def close(self) -> None:
        if self.pool is not None:
            # after an error or Ctrl-C in the parent: drop the queued chunks, do not wait for them
            self.pool.shutdown(wait=not self.pending, cancel_futures=True)
            self.pool = None


class _Dask:
    def __init__(self, payload: Payload, scheduler: Any, workers: int | None) -> None:
        self.payload = payload
        self.scheduler = scheduler
        self.workers = workers
        self.client: Any = None
        self.own = False

    def start(self) -> None:
        from distributed import Client

        if isinstance(self.scheduler, Client):
            self.client = self.scheduler
        elif self.scheduler is not None:
            self.own = True
            self.client = Client(str(self.scheduler))
        elif configured_scheduler() is not None:
            self.own = True
            self.client = Client()  # Dask's configuration names the scheduler
        else:
            self.own = True
            n = self.workers or default_workers()
            self.client = Client(n_workers=n, threads_per_worker=1, processes=True)
        # from now on: the cluster's worker threads (for the chunk sizes and the summary)
        self.workers = sum(self.client.nthreads().values()) or self.workers or 1

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        from distributed import as_completed

        client = self.client
        threads = self.workers
        payload = client.scatter(self.payload, broadcast=True, hash=False)
        running = as_completed()
        inflight = 0
        for chunk in chunks:
            running.add(client.submit(run_chunk, payload, chunk, pure=False))
            inflight += 1
            if inflight >= 2 * threads:
                fut = next(running)
                inflight -= 1
                yield fut.result()
        for fut in running:
            yield fut.result()

    def close(self) -> None:
        if self.own and self.client is not None:
            self.client.close()
        self.client = None


@contextmanager
def executor_for(
    payload: Payload,
    executor: ExecutorName = "processes",
    *,
    workers: int | None = None,
    scheduler: Any = None,
) -> Iterator[Any]:
    """A started executor, shut down on leaving the block: ``.results(chunks)`` yields the rows of every
    chunk as chunks complete; ``.workers`` is the number of workers (for Dask: the cluster's threads)."""
    if executor == "serial":
        ex: Any = _Serial(payload)
    elif executor == "processes":
        ex = _Processes(payload, workers or default_workers())
    elif executor == "dask":
        ex = _Dask(payload, scheduler, workers)
    else:
        raise ValueError(f"unknown executor {executor!r}; allowed: {', '.join(EXECUTORS)}")
    try:
        ex.start()
        yield ex
    finally:
        ex.close()
