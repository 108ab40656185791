"""Where the chunks of a study are computed: in this process, in a local process pool, or on Dask.

Each executor takes the study's :class:`~trainsim.batch.worker.Payload` and an iterator of chunks and
yields the rows of each chunk as it completes (in any order). Only a few chunks are in flight at a
time (twice the number of workers), so a study of a million runs never holds a million futures and
an interrupted study loses little work. The rows of a run depend only on its parameters, so every
executor gives the same results.

* ``serial``: in this process, chunk after chunk (debugging, tiny studies, the reference).
* ``processes``: a :class:`concurrent.futures.ProcessPoolExecutor` with ``workers`` processes started
  by a fork server that has trainsim imported; each process receives the payload once (initializer)
  and loads the compiled kernel before its first chunk.
* ``dask``: a ``distributed`` cluster: the scheduler at ``scheduler`` (an address or a
  ``distributed.Client``), or Dask's configured ``scheduler-address``, or else a local cluster of
  ``workers`` processes. The payload is scattered to every worker once.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Literal

from trainsim.batch.expand import RunTask
from trainsim.batch.worker import Payload, init_process, run_chunk, run_chunk_in_process

__all__ = ["EXECUTORS", "ExecutorName", "configured_scheduler", "default_workers", "execute"]

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


def _serial(payload: Payload, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
    for chunk in chunks:
        yield run_chunk(payload, chunk)


def _pool_context():
    # A fork server forks each worker from a clean single-threaded process with trainsim already
    # imported: fast to start like fork, without forking the threads of the parent (progress bar,
    # Dask client...) like spawn.
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["trainsim.batch.worker", "trainsim.sim.fastest", "trainsim.io.loader"])
        return ctx
    return multiprocessing.get_context("spawn")


def _processes(payload: Payload, chunks: Iterator[list[RunTask]], workers: int) -> Iterator[Rows]:
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=_pool_context(), initializer=init_process, initargs=(payload,)
    )
    pending: set[Future] = set()
    try:
        for chunk in chunks:
            pending.add(pool.submit(run_chunk_in_process, chunk))
            if len(pending) >= 2 * workers:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield fut.result()
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield fut.result()
    finally:
        # on an error or Ctrl-C in the parent: drop the queued chunks, do not wait for them
        pool.shutdown(wait=not pending, cancel_futures=True)


def _dask(
    payload: Payload, chunks: Iterator[list[RunTask]], scheduler: Any, workers: int | None
) -> Iterator[Rows]:
    from distributed import Client, as_completed

    own = not isinstance(scheduler, Client)
    if not own:
        client = scheduler
    elif scheduler is not None:
        client = Client(str(scheduler))
    elif configured_scheduler() is not None:
        client = Client()  # Dask's configuration names the scheduler
    else:
        client = Client(n_workers=workers or default_workers(), threads_per_worker=1, processes=True)
    try:
        threads = sum(client.nthreads().values()) or (workers or 1)
        future_payload = client.scatter(payload, broadcast=True, hash=False)
        running = as_completed()
        inflight = 0
        for chunk in chunks:
            running.add(client.submit(run_chunk, future_payload, chunk, pure=False))
            inflight += 1
            if inflight >= 2 * threads:
                fut = next(running)
                inflight -= 1
                yield fut.result()
        for fut in running:
            yield fut.result()
    finally:
        if own:
            client.close()


def execute(
    payload: Payload,
    chunks: Iterator[list[RunTask]],
    executor: ExecutorName = "processes",
    *,
    workers: int | None = None,
    scheduler: Any = None,
) -> Iterator[Rows]:
    """Rows of every chunk, as chunks complete."""
    if executor == "serial":
        return _serial(payload, chunks)
    if executor == "processes":
        return _processes(payload, chunks, workers or default_workers())
    if executor == "dask":
        return _dask(payload, chunks, scheduler, workers)
    raise ValueError(f"unknown executor {executor!r}; allowed: {', '.join(EXECUTORS)}")
