"""A bounded pool of worker processes for the web application's heavy work, with limits per request.

Validation of edited trains and routes, uploads and runs go to worker processes
(:mod:`trainsim.web.jobs`), never into the server process:

* **time**: a request's work that takes longer than ``job_time_limit_s`` is stopped (the worker is
  killed and replaced) and the request gets :class:`JobLimitError`;
* **memory**: each worker's address space is limited to what it holds at start plus
  ``job_memory_limit_bytes`` (``RLIMIT_AS``); a job that runs out gets :class:`JobLimitError` and the
  worker is replaced;
* **cancellation**: :meth:`WorkerPool.call` takes a ``gone`` callback; when the client has gone away
  the job is stopped the same way;
* **queue**: at most ``max_queued_jobs`` requests wait for a worker; one more gets
  :class:`PoolBusyError` (the API answers 503).

Workers are started by a fork server that has imported trainsim and compiled its kernels once
(:mod:`trainsim.web.jobs` warms them up), so a replaced worker is ready in milliseconds.
Errors from a job come back as values: :class:`trainsim.errors.InputError` with its problems, other
trainsim errors with their message.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import multiprocessing.connection
import os
import resource
import signal
import time
import traceback
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

from trainsim.errors import InputError, TrainsimError

__all__ = ["JobFailedError", "JobLimitError", "PoolBusyError", "WorkerPool", "run_job"]

log = logging.getLogger("trainsim.web")

#: how often a waiting request checks whether its client is still there [s]
GONE_POLL_S = 0.25


#: why a request could not start: the workers are still being started
STARTING = (
    "the server is still starting its worker processes (the first start after an install or an "
    "update compiles trainsim's kernels once: up to a few minutes)"
)


class PoolBusyError(Exception):
    """Every worker is busy and the waiting queue is full (or the workers are still starting)."""


class JobLimitError(Exception):
    """A job went over the time or memory limit (``what`` is ``time`` or ``memory``)."""

    def __init__(self, what: str, message: str) -> None:
        super().__init__(message)
        self.what = what
        self.message = message


class JobFailedError(Exception):
    """A job failed with an unexpected error (a bug in trainsim on this input); logged in full."""


class ClientGoneError(Exception):
    """The client went away; the job was stopped."""


def _vm_size_bytes() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def in_daemon_thread(fn: Callable[[], Any]) -> asyncio.Future:
    """``fn()`` in a daemon thread, as a future of the running loop. Starting processes waits for the
    fork server, which compiles trainsim's kernels on its first start; a daemon thread never keeps
    the server from exiting while it waits (the default executor's threads would)."""
    import threading

    loop = asyncio.get_running_loop()
    future: asyncio.Future = loop.create_future()

    def settle(value: Any, error: BaseException | None) -> None:
        if future.done():
            return
        if error is not None:
            future.set_exception(error)
        else:
            future.set_result(value)

    def hand_over(value: Any, error: BaseException | None) -> None:
        # the server may have stopped (its loop closed) while the work ran: nobody awaits it then
        with contextlib.suppress(RuntimeError):
            loop.call_soon_threadsafe(settle, value, error)

    def work() -> None:
        try:
            value = fn()
        except BaseException as exc:  # handed to the awaiting coroutine
            hand_over(None, exc)
        else:
            hand_over(value, None)

    threading.Thread(target=work, daemon=True, name="trainsim-web-spawn").start()
    return future


def run_job(name: str, args: tuple[Any, ...]) -> tuple[str, Any]:
    """Run a job of :mod:`trainsim.web.jobs` and wrap its outcome as ``(kind, value)``.

    kinds: ``ok`` (value: the job's result), ``input`` (value: the problems of an InputError),
    ``error`` (a trainsim error's message), ``memory``, ``recursion``, ``bug`` (a traceback).
    """
    from trainsim.web import jobs

    try:
        return "ok", getattr(jobs, name)(*args)
    except InputError as exc:
        from trainsim.web.errors import problems_of

        return "input", problems_of(exc)
    except TrainsimError as exc:
        return "error", str(exc)
    except MemoryError:
        return "memory", None
    except RecursionError:
        return "recursion", None
    except Exception:
        return "bug", traceback.format_exc(limit=20)


def _worker_main(conn: multiprocessing.connection.Connection, memory_limit_bytes: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the server stops us; Ctrl-C is its to handle
    if memory_limit_bytes > 0:
        limit = _vm_size_bytes() + memory_limit_bytes
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    while True:
        try:
            name, args = conn.recv()
        except (EOFError, OSError):
            return
        except MemoryError:
            out: tuple[str, Any] = ("memory", None)
        else:
            out = run_job(name, args)
        try:
            conn.send(out)
        except MemoryError:
            conn.send(("memory", None))
        except (BrokenPipeError, OSError):
            return
        except Exception:  # an unpicklable result: a bug
            conn.send(("bug", traceback.format_exc(limit=20)))


def unwrap(outcome: tuple[str, Any], limits_text: str = "") -> Any:
    """The job's result, or the matching exception raised."""
    kind, value = outcome
    if kind == "ok":
        return value
    if kind == "input":
        raise InputError.from_problems(value)
    if kind == "error":
        raise TrainsimError(value)
    if kind == "memory":
        raise JobLimitError("memory", f"the request needs more memory than one request may use{limits_text}")
    if kind == "recursion":
        raise InputError("document nested too deeply", allowed="a plainer document")
    log.error("trainsim web job failed:\n%s", value)
    raise JobFailedError(str(value).strip().splitlines()[-1] if value else "unknown error")


@dataclass
class _Worker:
    process: Any
    conn: multiprocessing.connection.Connection
    jobs: int = 0


class WorkerPool:
    """``processes`` worker processes, each doing one job at a time (see the module docstring)."""

    def __init__(
        self,
        processes: int,
        time_limit_s: float,
        memory_limit_bytes: int,
        max_queued: int,
        start_timeout_s: float = 600.0,
    ) -> None:
        self.processes = processes
        self.start_timeout_s = start_timeout_s
        self.time_limit_s = time_limit_s
        self.memory_limit_bytes = memory_limit_bytes
        self.max_queued = max_queued
        self._idle: asyncio.Queue[_Worker] | None = None
        self._starting: asyncio.Task | None = None
        self._all: list[_Worker] = []
        self._waiting = 0
        self._closed = False
        self._ctx = multiprocessing.get_context("forkserver")
        self._ctx.set_forkserver_preload(["trainsim.web._preload"])
        self.stats = {"jobs": 0, "timeouts": 0, "memory": 0, "cancelled": 0, "replaced": 0, "busy": 0}

    # ------------------------------------------------------------------ workers
    def _spawn(self) -> _Worker:
        parent, child = self._ctx.Pipe()
        process = self._ctx.Process(
            target=_worker_main,
            args=(child, self.memory_limit_bytes),
            daemon=True,
            name="trainsim-web-worker",
        )
        process.start()
        child.close()
        worker = _Worker(process, parent)
        self._all.append(worker)
        return worker

    def _kill(self, worker: _Worker) -> None:
        with contextlib.suppress(Exception):
            worker.process.kill()
        with contextlib.suppress(Exception):
            worker.conn.close()
        with contextlib.suppress(Exception):
            worker.process.join(timeout=5)
        if worker in self._all:
            self._all.remove(worker)

    async def start(self) -> None:
        """Start the workers (in a thread: the first start also starts the fork server, which
        imports trainsim and compiles its kernels: seconds). Concurrent callers wait for one start."""
        if self._starting is None:
            self._starting = asyncio.ensure_future(self._start())
        await asyncio.shield(self._starting)

    async def _start(self) -> None:
        idle: asyncio.Queue[_Worker] = asyncio.Queue()
        workers = await in_daemon_thread(lambda: [self._spawn() for _ in range(self.processes)])
        for w in workers:
            idle.put_nowait(w)
        self._idle = idle

    def close(self) -> None:
        """Stop every worker."""
        self._closed = True
        for worker in list(self._all):
            self._kill(worker)

    @property
    def busy(self) -> int:
        """Workers doing a job now."""
        idle = self._idle.qsize() if self._idle is not None else 0
        return len(self._all) - idle

    @property
    def waiting(self) -> int:
        """Requests waiting for a worker."""
        return self._waiting

    # ------------------------------------------------------------------ jobs
    async def call(
        self,
        name: str,
        *args: Any,
        gone: Callable[[], Awaitable[bool]] | None = None,
        time_limit_s: float | None = None,
    ) -> Any:
        """Run ``trainsim.web.jobs.<name>(*args)`` in a worker and return its result.

        Raises the job's InputError / TrainsimError, :class:`JobLimitError` (time or memory),
        :class:`PoolBusyError`, :class:`ClientGoneError` or :class:`JobFailedError`.
        """
        if self._idle is None:
            # the first start imports trainsim in the fork server (about a second; the kernels are
            # compiled at install); a request waits at most start_timeout_s
            try:
                await asyncio.wait_for(self.start(), timeout=self.start_timeout_s)
            except TimeoutError:
                self.stats["busy"] += 1
                raise PoolBusyError(STARTING) from None
            except Exception as exc:  # e.g. the fork server died: 503 now, a new start next time
                self._starting = None
                self.stats["busy"] += 1
                raise PoolBusyError(f"the worker processes could not start ({type(exc).__name__})") from exc
        assert self._idle is not None
        if self._closed:
            raise PoolBusyError("the server is shutting down")
        if self._idle.empty() and self._waiting >= self.max_queued:
            self.stats["busy"] += 1
            raise PoolBusyError("every worker is busy")
        self._waiting += 1
        try:
            worker = await self._idle.get()
        finally:
            self._waiting -= 1
        limit = self.time_limit_s if time_limit_s is None else time_limit_s
        outcome: tuple[str, Any] | None = None
        try:
            outcome = await self._roundtrip(worker, name, args, limit, gone)
        finally:
            # a worker stopped mid-job, or one that ran out of memory, is replaced
            if outcome is not None and outcome[0] != "memory" and worker.process.is_alive():
                self._idle.put_nowait(worker)
            else:
                self._kill(worker)
                self.stats["replaced"] += 1
                if not self._closed:
                    self._idle.put_nowait(await in_daemon_thread(self._spawn))
        self.stats["jobs"] += 1
        if outcome[0] == "memory":
            self.stats["memory"] += 1
        mib = self.memory_limit_bytes / 2**20
        return unwrap(outcome, f" ({mib:.0f} MiB); allowed: a smaller train, route or a coarser step")

    async def _roundtrip(
        self,
        worker: _Worker,
        name: str,
        args: tuple[Any, ...],
        limit_s: float,
        gone: Callable[[], Awaitable[bool]] | None,
    ) -> tuple[str, Any]:
        loop = asyncio.get_running_loop()
        ready = loop.create_future()
        fd = worker.conn.fileno()

        def on_readable() -> None:
            if not ready.done():
                ready.set_result(None)

        worker.conn.send((name, args))
        loop.add_reader(fd, on_readable)
        deadline = time.monotonic() + limit_s
        try:
            while True:
                left = deadline - time.monotonic()
                if left <= 0:
                    self.stats["timeouts"] += 1
                    raise JobLimitError(
                        "time",
                        f"the request took longer than the limit of {limit_s:g} s for one request; "
                        "allowed: a shorter route, a coarser integration step or a simpler schedule",
                    )
                try:
                    await asyncio.wait_for(asyncio.shield(ready), timeout=min(left, GONE_POLL_S))
                    break
                except TimeoutError:
                    if gone is not None and await gone():
                        self.stats["cancelled"] += 1
                        raise ClientGoneError from None
        finally:
            loop.remove_reader(fd)
        try:
            return worker.conn.recv()
        except (EOFError, OSError):
            # the worker died: killed (by the kernel's OOM killer: memory) or crashed
            worker.process.join(timeout=1.0)
            code = worker.process.exitcode
            kind = "memory" if code == -signal.SIGKILL else "bug"
            return kind, f"the worker process exited with code {code}"


def pid_of_workers(pool: WorkerPool) -> list[int]:
    """Process ids of the pool's workers (tests)."""
    return [w.process.pid for w in pool._all if w.process.pid is not None and w.process.pid != os.getpid()]
