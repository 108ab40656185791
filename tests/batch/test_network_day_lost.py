"""A network-day whose Dask scheduler or workers are lost while it runs: ClusterLostError (exit 4 with a
message), never exit 2 ("bad input") nor a traceback; an error of a line-day itself stays what it is."""

from __future__ import annotations

import os
from concurrent.futures import CancelledError
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trainsim.batch import network_day as nd
from trainsim.batch.executors import INFRASTRUCTURE_EXIT_CODE, ClusterLostError
from trainsim.cli import app
from trainsim.errors import InputError

CBTC = Path(__file__).resolve().parents[2] / "examples" / "operations" / "metro_cbtc.yaml"
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


class _Future:
    def __init__(self, status: str, exc: BaseException | None = None) -> None:
        self.status, self._exc = status, exc

    def exception(self) -> BaseException | None:
        return self._exc


class _Client:
    def __init__(self, status: str = "running", workers: int = 1, gather: BaseException | None = None):
        self.status, self.workers, self.gather_error = status, workers, gather

    def scheduler_info(self, n_workers: int = 0) -> dict:
        return {"workers": {f"w{i}": {} for i in range(self.workers)}}

    def gather(self, futures: list) -> list:
        if self.gather_error is not None:
            raise self.gather_error
        return [f"result {i}" for i in range(len(futures))]


KilledWorker = type("KilledWorker", (Exception,), {})  # distributed's, by name as the code matches it


@pytest.mark.parametrize(
    ("futures", "client", "words"),
    [
        ([_Future("finished"), _Future("cancelled")], _Client(), "cancelled"),
        ([_Future("error", KilledWorker("line-day x"))], _Client(), "killed the workers"),
        ([_Future("error", CancelledError())], _Client(), "cancelled"),
        ([_Future("finished")], _Client(gather=OSError("comm closed")), "comm closed"),
        ([_Future("finished")], _Client(gather=CancelledError()), "could not be fetched"),
    ],
)
def test_lost_line_days_are_cluster_lost(monkeypatch, futures, client, words) -> None:
    monkeypatch.setattr(nd, "_wait", lambda futures, timeout: None)
    with pytest.raises(ClusterLostError, match=words) as info:
        nd._gather(client, futures)
    assert info.value.exit_code == INFRASTRUCTURE_EXIT_CODE


def test_finished_line_days_are_gathered_and_their_own_errors_kept(monkeypatch) -> None:
    monkeypatch.setattr(nd, "_wait", lambda futures, timeout: None)
    assert nd._gather(_Client(), [_Future("finished")] * 2) == ["result 0", "result 1"]
    bad = InputError("sampled days need a 'delays' or 'disturbances' block", field="delays")
    with pytest.raises(InputError, match="delays"):
        nd._gather(_Client(), [_Future("finished"), _Future("error", bad)])


def _never_done(futures: list, timeout: float) -> None:
    raise TimeoutError


def test_a_scheduler_lost_or_no_worker_for_the_timeout_is_cluster_lost(monkeypatch) -> None:
    monkeypatch.setattr(nd, "_wait", _never_done)
    with pytest.raises(ClusterLostError, match="connection to the scheduler was lost"):
        nd._gather(_Client(status="connecting"), [_Future("pending")])
    monkeypatch.setattr(nd, "WORKER_TIMEOUT_S", 0.05)
    with pytest.raises(ClusterLostError, match=r"no worker connected for 0\.05 s"):
        nd._gather(_Client(workers=0), [_Future("pending")])


def test_a_real_killed_worker_is_cluster_lost() -> None:
    distributed = pytest.importorskip("distributed")
    import dask

    with (
        dask.config.set({"distributed.scheduler.allowed-failures": 0}),
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
        ) as c,
        distributed.Client(c) as client,
    ):
        futures = [client.submit(os._exit, 1, pure=False)]
        with pytest.raises(ClusterLostError, match="killed the workers"):
            nd._gather(client, futures)


def test_operate_exits_4_with_a_message_when_its_workers_die(monkeypatch) -> None:
    pytest.importorskip("distributed")
    import dask

    # every line-day kills its worker (sent by value to the workers: a lambda is not importable there)
    monkeypatch.setattr(nd, "lines_day", lambda *args: os._exit(1))
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        result = CliRunner().invoke(app, ["operate", str(CBTC), "--local-workers", "1"])
    assert result.exit_code == INFRASTRUCTURE_EXIT_CODE, result.output
    assert "Traceback" not in result.output
    assert "the Dask cluster was lost during the network-day" in result.stderr
    assert "killed the workers" in result.stderr


def test_a_real_scheduler_lost_mid_run_is_cluster_lost() -> None:
    distributed = pytest.importorskip("distributed")
    import threading
    import time

    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
        ) as c,
        distributed.Client(c) as client,
    ):
        futures = [client.submit(time.sleep, 60, pure=False)]
        closer = threading.Timer(1.0, c.close)  # the scheduler goes away while the task runs
        closer.start()
        t0 = time.monotonic()
        with pytest.raises(ClusterLostError, match="the Dask cluster was lost during the network-day"):
            nd._gather(client, futures)
        closer.join()
    assert time.monotonic() - t0 < 30  # noticed, not waited out
