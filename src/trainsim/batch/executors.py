"""Where the chunks of a study are computed: in this process, in a local process pool, or on Dask.

Each executor takes the study's :class:`~trainsim.batch.worker.Payload` and an iterator of chunks and
yields the rows of each chunk as it completes (in any order). Only a few chunks are in flight at a
time (twice the number of workers), so a study of a million runs never holds a million futures and
an interrupted study loses little work. The rows of a run depend only on its parameters, so every
executor gives the same results.

* ``serial``: in this process, chunk after chunk (debugging, tiny studies, the reference).
* ``processes``: ``workers`` independent processes (forked, see :func:`_pool_context`), each with its
  own pipe; each process receives the payload once and loads the compiled kernel before its first
  chunk, computes one chunk at a time and sends the rows of its runs back as they are computed (at
  least every :data:`~trainsim.batch.worker.SEND_INTERVAL_S`).
* ``dask``: a ``distributed`` cluster: the scheduler at ``scheduler`` (an address or a
  ``distributed.Client``), or Dask's configured ``scheduler-address``, or else a local cluster of
  ``workers`` processes. The payload is scattered to every worker once.

Lost workers (see docs/BATCH.md, "When workers or the cluster are lost"): when a worker process
dies, the rows it sent are kept and the rest of its chunk is computed by the others (a new process
takes its place): a kill loses the run it was computing and at most
:data:`~trainsim.batch.worker.SEND_INTERVAL_S` of runs not yet sent; a run is computed again at most
:data:`MAX_RESUBMITS` times. On Dask the scheduler itself reassigns the tasks of a lost worker (the
chunk is computed again: chunks hold about :data:`~trainsim.batch.runner.CHUNK_TARGET_S` of work),
and a chunk that killed ``allowed-failures`` workers is submitted again by us. When nothing can
compute any more (the Dask scheduler is lost, no worker has been connected for ``worker_timeout_s``,
or a run or chunk was lost too often) the executor raises
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
from concurrent.futures import CancelledError
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Literal

from trainsim.batch.expand import RunTask
from trainsim.batch.worker import Payload, run_chunk, serve_process, single_threaded_env
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
        self.measured: list[tuple[int, float]] = []  # (run index, CPU s) of each run
        self.worker_cpu_s = [0.0]  # CPU time of the runs [s]

    def start(self) -> None:
        pass

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        for chunk in chunks:
            rows = []
            for task in chunk:
                c0 = time.process_time()
                rows.extend(run_chunk(self.payload, [task]))
                self.measured.append((task[0], time.process_time() - c0))
                self.worker_cpu_s[0] += self.measured[-1][1]
            yield rows

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


@dataclass
class _Worker:
    """One process of the pool, its pipe, and the chunk it is computing (rows received so far)."""

    process: Any
    conn: Any
    chunk: list[RunTask] | None = None
    rows: Rows = field(default_factory=list)
    cpu_s: float = 0.0  # CPU time of the runs it sent [s]


class _Processes:
    """A pool of independent worker processes, each fed one chunk at a time through its own pipe.

    Rows come back as runs are computed, at least every :data:`~trainsim.batch.worker.SEND_INTERVAL_S`
    (:func:`~trainsim.batch.worker.serve_process`), so a worker killed in the middle of a chunk loses
    only the run it was computing and the few runs not yet sent: the rows it sent are kept, that run and the rest of its chunk go to the other workers, and a new process takes its
    place. The other workers are not disturbed (a ``ProcessPoolExecutor`` whose process dies breaks:
    every chunk in flight on every worker is lost). A run that killed its worker more than
    :data:`MAX_RESUBMITS` times stops the study (ClusterLostError, resumable).
    """

    def __init__(self, payload: Payload, workers: int) -> None:
        self.payload = payload
        self.workers = workers
        self.ctx: Any = None
        self.pool: list[_Worker] = []
        self.restarts = 0
        self.attempts: dict[int, int] = {}  # run index -> times its worker died while computing it
        self.retry: list[list[RunTask]] = []
        self.measured: list[tuple[int, float]] = []  # (run index, CPU s) of the runs received
        self.worker_cpu_s: list[float] = []  # CPU time of the runs of each process that ended [s]

    @property
    def processes(self) -> list[int]:
        """Process ids of the workers (for tests and diagnostics)."""
        return [w.process.pid for w in self.pool]

    def _spawn(self) -> _Worker:
        parent, child = self.ctx.Pipe(duplex=True)
        process = self.ctx.Process(target=serve_process, args=(self.payload, child), daemon=True)
        # one thread per numerical library in the worker: a spawned worker (or the fork server) reads
        # these when it loads numpy; a forked one has no BLAS or OpenMP threads until it calls them,
        # which the runs do not. Set only while starting, so that this process keeps its settings.
        env = single_threaded_env()
        saved = {k: os.environ.get(k) for k in env}
        os.environ.update(env)
        try:
            process.start()
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
        child.close()  # only the worker holds its end: a dead worker's pipe reads as closed
        return _Worker(process, parent)

    def start(self) -> None:
        self.ctx = _pool_context()
        self.pool = [self._spawn() for _ in range(self.workers)]

    def _send(self, w: _Worker, chunk: list[RunTask]) -> None:
        w.chunk, w.rows = chunk, []
        with contextlib.suppress(OSError):  # a worker that just died: its sentinel tells, below
            w.conn.send(chunk)

    def _receive(self, w: _Worker) -> bool:
        """Read what ``w`` sent; True when its chunk is complete."""
        assert w.chunk is not None
        while w.conn.poll():
            try:
                batch = w.conn.recv()
            except (EOFError, OSError):
                break
            for index, row, cpu_s in batch:
                w.rows.append((index, row))
                self.measured.append((index, cpu_s))
                w.cpu_s += cpu_s
        return len(w.rows) == len(w.chunk)

    def _replace(self, w: _Worker) -> Rows:
        """``w`` died: keep the rows it sent, queue the rest of its chunk, start a new process."""
        rows = w.rows if w.chunk is not None else []
        if w.chunk is not None:
            done = {i for i, _ in w.rows}
            rest = [t for t in w.chunk if t[0] not in done]
            if rest:
                lost = rest[0][0]  # the run it was computing
                self.attempts[lost] = self.attempts.get(lost, 0) + 1
                if self.attempts[lost] > MAX_RESUBMITS:
                    raise ClusterLostError(
                        f"a worker process died {MAX_RESUBMITS + 1} times while computing run {lost}; the "
                        "runs written so far are kept and the study resumes when run again"
                    )
                self.retry.append(rest)
        with contextlib.suppress(OSError):
            w.conn.close()
        w.process.join(timeout=1.0)
        self.worker_cpu_s.append(w.cpu_s)
        self.restarts += 1
        self.pool[self.pool.index(w)] = self._spawn()
        return rows

    def results(self, chunks: Iterator[list[RunTask]]) -> Iterator[Rows]:
        from multiprocessing.connection import wait as mp_wait

        feed = iter(chunks)

        def feed_idle() -> None:
            # the runs of a dead worker first, then the next chunks
            for w in self.pool:
                if w.chunk is None:
                    chunk = self.retry.pop(0) if self.retry else next(feed, None)
                    if chunk is None:
                        return
                    self._send(w, chunk)

        feed_idle()
        while True:
            busy = [w for w in self.pool if w.chunk is not None]
            if not busy:
                return
            ready = set(mp_wait([w.conn for w in busy] + [w.process.sentinel for w in busy]))
            for w in busy:
                if w.conn not in ready and w.process.sentinel not in ready:
                    continue
                if self._receive(w):
                    rows = w.rows
                    w.chunk, w.rows = None, []
                    feed_idle()  # before the caller writes the rows: the worker goes on meanwhile
                    yield rows
                elif not w.process.is_alive():
                    rows = self._replace(w)
                    feed_idle()
                    if rows:
                        yield rows

    def close(self) -> None:
        self.worker_cpu_s.extend(w.cpu_s for w in self.pool)
        for w in self.pool:
            if w.chunk is None and w.process.is_alive():
                with contextlib.suppress(OSError):
                    w.conn.send(None)
            else:
                # after an error or Ctrl-C in the parent: do not wait for the chunk in flight
                w.process.terminate()
        for w in self.pool:
            w.process.join(timeout=5.0)
            if w.process.is_alive():
                w.process.kill()
                w.process.join()
            with contextlib.suppress(OSError):
                w.conn.close()
        self.pool = []


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
