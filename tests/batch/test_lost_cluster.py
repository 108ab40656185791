"""A study on Dask whose workers or scheduler die: lost work is computed again, or the study stops with
ClusterLostError (exit code 4 in the CLI) in bounded time and resumes with every run exactly once.

The cluster runs in subprocesses (``dask scheduler``, ``dask worker --no-nanny``) so that it can be
killed with SIGKILL like a crashed machine.
"""

from __future__ import annotations

import contextlib
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from batchcases import metro_study

from trainsim.batch import ClusterLostError, read_results, run_study, study_from_dict

pytestmark = [pytest.mark.slow]
pytest.importorskip("distributed")

#: 400 metro runs of about 1.5 ms each in chunks of 10: a few seconds on 2 workers, long enough to
#: kill the cluster in the middle
RUNS = 400


def study():
    axes = [{"field": "train.formation[*].load_t", "range": {"from": 0, "to": 18, "count": RUNS}}]
    return study_from_dict(metro_study(axes=axes), "lost.yaml")


def _dask(*args: str) -> subprocess.Popen:
    exe = shutil.which("dask")
    cmd = [exe, *args] if exe else [sys.executable, "-m", "dask", *args]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


class Cluster:
    """A scheduler and workers in their own processes."""

    def __init__(self, tmp: Path) -> None:
        tmp.mkdir(parents=True, exist_ok=True)
        self.file = tmp / "scheduler.json"
        self.scheduler = _dask(
            "scheduler", "--scheduler-file", str(self.file), "--port", "0", "--host", "127.0.0.1",
            "--no-dashboard",
        )  # fmt: skip
        self.workers: list[subprocess.Popen] = []
        t0 = time.monotonic()
        while not self.file.exists():
            assert time.monotonic() - t0 < 30, "the scheduler did not start"
            time.sleep(0.05)
        time.sleep(0.2)  # the file is written before the scheduler listens
        import json

        self.address = json.loads(self.file.read_text())["address"]

    def add_workers(self, n: int) -> None:
        from distributed import Client

        for _ in range(n):
            self.workers.append(
                _dask(
                    *("worker", "--scheduler-file", str(self.file), "--no-nanny", "--nthreads", "1"),
                    "--no-dashboard",
                )
            )
        with Client(self.address, timeout=30) as client:
            client.wait_for_workers(sum(w.poll() is None for w in self.workers), timeout=60)

    def kill_workers(self) -> None:
        for w in self.workers:
            w.kill()
            w.wait()
        self.workers = []

    def close(self) -> None:
        for p in [*self.workers, self.scheduler]:
            with contextlib.suppress(OSError):
                p.kill()
            p.wait()


@pytest.fixture(scope="module")
def warm_cache():
    """One run here first, so that the workers start from imported modules and examples read once."""
    run_study(study_from_dict(metro_study(), "warm.yaml"), None, executor="serial")


@pytest.fixture
def cluster(tmp_path, warm_cache):
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.close()


def _run_in_thread(**kwargs) -> tuple[threading.Thread, dict]:
    box: dict = {}

    def target() -> None:
        t0 = time.monotonic()
        try:
            box["outcome"] = run_study(**kwargs)
        except BaseException as exc:  # handed to the test
            box["error"] = exc
        box["elapsed_s"] = time.monotonic() - t0

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    return thread, box


def _wait_for_parts(out: Path, n: int, thread: threading.Thread, box: dict, timeout_s: float = 60) -> int:
    """Wait until ``n`` chunks are written by the study running in ``thread``."""
    t0 = time.monotonic()
    while (k := len(list((out / "results").glob("part-*.parquet")))) < n:
        assert thread.is_alive(), f"the study ended after {k} chunks: {box}"
        assert time.monotonic() - t0 < timeout_s, f"no chunk was written for {timeout_s} s"
        time.sleep(0.01)
    return k


def _exactly_once(out: Path, s) -> None:
    df = read_results(out)
    expansion = s.expand()
    assert len(df) == len(expansion)
    assert sorted(df["run_id"]) == sorted(expansion.run_ids)
    assert list(df["run_index"]) == list(range(len(expansion)))
    assert (df["status"] == "ok").all()


def test_workers_lost_one_then_all_stops_in_bounded_time_then_resumes(cluster, tmp_path):
    s = study()
    out = tmp_path / "out"
    cluster.add_workers(2)
    thread, box = _run_in_thread(
        study=s, out=out, scheduler=cluster.address, chunk_size=10, worker_timeout_s=2.0
    )
    # one worker dies: the other one goes on (distributed reassigns the lost worker's chunks)
    _wait_for_parts(out, 2, thread, box)
    victim = cluster.workers.pop(0)
    victim.kill()
    victim.wait()
    n = _wait_for_parts(out, 0, thread, box)
    _wait_for_parts(out, n + 2, thread, box)
    # then the last one: the study stops, it does not wait for ever
    killed_at = time.monotonic()
    cluster.kill_workers()
    thread.join(timeout=60)
    assert not thread.is_alive(), "the study hangs after losing every worker"
    assert isinstance(box.get("error"), ClusterLostError), box
    assert "no worker connected for 2 s" in str(box["error"])
    assert time.monotonic() - killed_at < 20
    partial = read_results(out)
    assert n < len(partial) < RUNS and partial["run_id"].is_unique
    # a new worker: the study resumes where it stopped, every run exactly once
    cluster.add_workers(1)
    outcome = run_study(s, out, scheduler=cluster.address, chunk_size=100)
    assert outcome.already_done == len(partial) and outcome.complete
    _exactly_once(out, s)


def test_scheduler_lost_stops_at_once_with_exit_code_4_then_resumes(cluster, tmp_path):
    import dask.config
    import typer
    import yaml
    from typer.testing import CliRunner

    from trainsim.cli.batch import batch

    s = study()
    out = tmp_path / "out"
    cluster.add_workers(2)
    thread, box = _run_in_thread(study=s, out=out, scheduler=cluster.address, chunk_size=10)
    _wait_for_parts(out, 2, thread, box)
    killed_at = time.monotonic()
    cluster.scheduler.kill()
    thread.join(timeout=60)
    assert not thread.is_alive()
    # at once, not after distributed's 30 s of reconnection attempts
    assert time.monotonic() - killed_at < 10
    assert isinstance(box.get("error"), ClusterLostError), box
    assert "connection to the scheduler was lost" in str(box["error"])
    written = len(read_results(out))
    assert 0 < written < RUNS
    # the CLI, against the scheduler that is gone: the documented message and exit code 4, no traceback
    app = typer.Typer()
    app.command()(batch)
    study_file = tmp_path / "lost.yaml"
    study_file.write_text(yaml.safe_dump(metro_study()))
    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        result = CliRunner().invoke(
            app, [str(study_file), "--out", str(tmp_path / "cli"), "--scheduler", cluster.address]
        )
    assert result.exit_code == 4, result.output
    assert "Traceback" not in result.output and "cannot connect to the Dask scheduler" in result.output
    # a new cluster: the first study resumes, every run exactly once
    cluster.close()
    other = Cluster(tmp_path / "second")
    try:
        other.add_workers(2)
        outcome = run_study(s, out, scheduler=other.address, chunk_size=100)
    finally:
        other.close()
    assert outcome.already_done == written and outcome.complete
    _exactly_once(out, s)
