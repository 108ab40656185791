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

Lost workers (see docs/BATCH.md, "When workers or the cluster are lost"): a chunk whose worker
process died is submitted again, at most :data:`MAX_RESUBMITS` times (a process pool that broke is
started again with the chunks that were in flight; on Dask the scheduler itself reassigns the tasks of
a lost worker, and a chunk that killed ``allowed-failures`` workers is submitted again by us). When
nothing can compute any more (the Dask scheduler is lost, no worker has been connected for
``worker_timeout_s``, or a chunk was resubmitted too often) the executor raises
:class:`ClusterLostError`: the chunks completed so far are written, the study resumes when run again,
and ``trainsim batch`` exits with code 4 (:data:`INFRASTRUCTURE_EXIT_CODE`).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, CancelledError, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any, Literal

from trainsim.batch.expand import RunTask
from trainsim.batch.worker import Payload, init_process, run_chunk, run_chunk_in_process
from trainsim.errors import TrainsimError

__all__ = [
    "EXECUTORS",
    "INFRASTRUCTURE_EXIT_CODE",
    "MAX_RESUBMITS",
    "WORKER_TIMEOUT_S",
    "ClusterLostError",
    "ExecutorName",
    "configured_scheduler",
    "default_workers",
    "executor_for",
]

#: How often a chunk whose worker died is submitted again before the study gives up.
MAX_RESUBMITS = 3
#: How long a Dask study waits for a worker when the cluster has none [s] (workers restarting or
#: being added by an autoscaler take a few seconds; a minute without any means they are gone).
WORKER_TIMEOUT_S = 60.0
#: How often the Dask executor looks at the cluster while waiting for chunks [s].
_POLL_S = 0.5
#: Exit code of ``trainsim batch`` when the computing infrastructure failed (resumable).
INFRASTRUCTURE_EXIT_CODE = 4


class ClusterLostError(TrainsimError):
    """The workers or the scheduler that computed the study were lost and no work can go on.

    Not an input error: the study is intact and resumes from what was written when run again.
    ``trainsim batch`` exits with :data:`INFRASTRUCTURE_EXIT_CODE` (4).
    """

    exit_code = INFRASTRUCTURE_EXIT_CODE


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
        self.pending: dict[Future, tuple[list[RunTask], int]] = {}
        self.restarts = 0

    def start(self) -> None:
        self.pool = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=_pool_context(),
            initializer=init_process,
            initargs=(self.payload,),
        )
        # the first submission starts the worker processes, before the caller starts any thread
        self.pool.submit(os.getpid).result()

    def _submit(self, chunk: list[RunTask], attempts: int) -> None:
        assert self.pool is not None
        self.pending[self.pool.submit(run_chunk_in_process, chunk)] = (chunk, attempts)

    def _restart(self, exc: BaseException) -> None:
        """A worker process died (killed, out of memory...): the pool is broken. Start a new one and
        submit again every chunk that was in flight, each at most MAX_RESUBMITS times."""
        lost = list(self.pending.values())
        self.pending = {}
        over = [c for c, a in lost if a >= MAX_RESUBMITS]
        if over:
            first = over[0][0][0][0]
            raise ClusterLostError(
                f"a worker process died {MAX_RESUBMITS + 1} times while computing the chunk starting at "
                f"run {first} ({exc}); the runs written so far are kept and the study resumes when "
                "run again"
            ) from None
        assert self.pool is not None
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.restarts += 1
        self.start()
        for chunk, attempts in lost:
            self._submit(chunk, attempts + 1)

    def _collect(self) -> Iterator[Rows]:
        done, _ = wait(list(self.pending), return_when=FIRST_COMPLETED)
        broken: BaseException | None = None
        for fut in done:
            try:
                rows = fut.result()
            except BrokenProcessPool as exc:
                broken = exc
                continue
            del self.pending[fut]
            yield rows
        if broken is not None:
            self._restart(broken)

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        assert self.pool is not None
        for chunk in chunks:
            self._submit(chunk, 0)
            while len(self.pending) >= 2 * self.workers:
                yield from self._collect()
        while self.pending:
            yield from self._collect()

    def close(self) -> None:
        if self.pool is not None:
            # after an error or Ctrl-C in the parent: drop the queued chunks, do not wait for them
            self.pool.shutdown(wait=not self.pending, cancel_futures=True)
            self.pool = None


class _Dask:
    def __init__(
        self,
        payload: Payload,
        scheduler: Any,
        workers: int | None,
        worker_timeout_s: float = WORKER_TIMEOUT_S,
    ) -> None:
        self.payload = payload
        self.scheduler = scheduler
        self.workers = workers
        self.worker_timeout_s = worker_timeout_s
        self.client: Any = None
        self.own = False
        self.resubmitted = 0

    def start(self) -> None:
        from distributed import Client

        try:
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
        except OSError as exc:  # distributed raises OSError (TimeoutError) when it cannot connect
            where = self.scheduler or configured_scheduler() or "a local cluster"
            raise ClusterLostError(f"cannot connect to the Dask scheduler at {where}: {exc}") from None
        # from now on: the cluster's worker threads (for the chunk sizes and the summary)
        self.workers = sum(self.client.nthreads().values()) or self.workers or 1

    def _lost(self, why: str) -> ClusterLostError:
        return ClusterLostError(
            f"the Dask cluster was lost ({why}); the runs written so far are kept and the study resumes "
            "when the same command is run again"
        )

    def _check_cluster(self, no_workers_since: float | None) -> float | None:
        """Raise ClusterLostError if the scheduler is gone or no worker has been connected for
        worker_timeout_s; return since when the cluster has had no worker (None: it has some)."""
        if self.client.status != "running":  # "connecting" after the scheduler was lost, then "closed"
            raise self._lost("the connection to the scheduler was lost")
        try:
            n = len(self.client.scheduler_info(n_workers=-1).get("workers", {}))
        except (OSError, KeyError):
            raise self._lost("the scheduler does not answer") from None
        if n:
            return None
        now = time.monotonic()
        if no_workers_since is None:
            return now
        if now - no_workers_since > self.worker_timeout_s:
            raise self._lost(f"no worker connected for {self.worker_timeout_s:g} s")
        return no_workers_since

    def _scatter(self) -> Any:
        """Send the payload to every worker (again, after the workers that held it were lost)."""
        from distributed import Future

        try:
            if not self.client.scheduler_info(n_workers=-1).get("workers"):
                self.client.wait_for_workers(1, timeout=self.worker_timeout_s)
            payload = self.client.scatter(self.payload, broadcast=True, hash=False)
        except TimeoutError:
            raise self._lost(f"no worker connected for {self.worker_timeout_s:g} s") from None
        except (OSError, CancelledError) as exc:
            raise self._lost(f"the payload could not be sent to the workers: {exc}") from None
        assert isinstance(payload, Future)
        return payload

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        from distributed import wait as dask_wait

        client = self.client
        threads = self.workers
        payload = self._scatter()
        pending: dict[Any, tuple[list[RunTask], int]] = {}

        def submit(chunk: list[RunTask], attempts: int) -> None:
            pending[client.submit(run_chunk, payload, chunk, pure=False)] = (chunk, attempts)

        def resubmit(chunk: list[RunTask], attempts: int, why: str) -> None:
            if attempts >= MAX_RESUBMITS:
                raise self._lost(
                    f"the chunk starting at run {chunk[0][0]} was lost {attempts + 1} times ({why})"
                )
            self.resubmitted += 1
            submit(chunk, attempts + 1)

        def collect() -> Iterator[Rows]:
            nonlocal payload
            no_workers_since: float | None = None
            while True:
                try:
                    dask_wait(list(pending), timeout=_POLL_S, return_when="FIRST_COMPLETED")
                except TimeoutError:
                    no_workers_since = self._check_cluster(no_workers_since)
                    continue
                except CancelledError:
                    pass  # some were cancelled: seen below
                except OSError as exc:  # the connection to the scheduler closed
                    raise self._lost(f"the connection to the scheduler was lost: {exc}") from None
                done = [f for f in pending if f.status != "pending"]
                if done:
                    break
            lost_payload: list[tuple[list[RunTask], int]] = []
            for fut in done:
                if fut.status == "finished":
                    try:
                        # (a worker that died after finishing: distributed computes the chunk again)
                        rows = fut.result(timeout=self.worker_timeout_s)
                    except TimeoutError:
                        continue  # still pending: the next round waits for it
                    except CancelledError:
                        pass  # cancelled meanwhile: below
                    except OSError as exc:
                        if client.status != "running":
                            raise self._lost(f"the connection to the scheduler was lost: {exc}") from None
                        continue  # its worker died: distributed computes it again
                    else:
                        del pending[fut]
                        yield rows
                        continue
                chunk, attempts = pending.pop(fut)
                if fut.status == "cancelled":
                    if client.status != "running":
                        raise self._lost("the connection to the scheduler was lost")
                    # the payload it needs was on workers that are gone ("lost dependencies")
                    lost_payload.append((chunk, attempts))
                    continue
                exc = fut.exception()
                if type(exc).__name__ != "KilledWorker":
                    raise exc  # a bug in trainsim: a run's own errors are rows, never exceptions
                resubmit(chunk, attempts, "its worker died")
            if lost_payload:
                # every chunk still waiting needs the payload again: cancel them, scatter it again
                for fut, (chunk, attempts) in list(pending.items()):
                    if fut.status == "pending":
                        fut.cancel()
                        del pending[fut]
                        lost_payload.append((chunk, attempts))
                payload = self._scatter()
                for chunk, attempts in sorted(lost_payload, key=lambda c: c[0][0][0]):
                    resubmit(chunk, attempts, "the workers holding the study were lost")

        for chunk in chunks:
            submit(chunk, 0)
            while len(pending) >= 2 * threads:
                yield from collect()
        while pending:
            yield from collect()

    def close(self) -> None:
        if self.own and self.client is not None:
            with contextlib.suppress(OSError, CancelledError):  # the scheduler may already be gone
                self.client.close(timeout=5)
        self.client = None


@contextmanager
def executor_for(
    payload: Payload,
    executor: ExecutorName = "processes",
    *,
    workers: int | None = None,
    scheduler: Any = None,
    worker_timeout_s: float = WORKER_TIMEOUT_S,
) -> Iterator[Any]:
    """A started executor, shut down on leaving the block: ``.results(chunks)`` yields the rows of every
    chunk as chunks complete; ``.workers`` is the number of workers (for Dask: the cluster's threads).
    ``worker_timeout_s``: how long a Dask study waits when the cluster has no worker [s]."""
    if executor == "serial":
        ex: Any = _Serial(payload)
    elif executor == "processes":
        ex = _Processes(payload, workers or default_workers())
    elif executor == "dask":
        ex = _Dask(payload, scheduler, workers, worker_timeout_s)
    else:
        raise ValueError(f"unknown executor {executor!r}; allowed: {', '.join(EXECUTORS)}")
    try:
        ex.start()
        yield ex
    finally:
        ex.close()
