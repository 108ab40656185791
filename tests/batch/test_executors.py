"""The same study gives identical results serially, with local processes and on Dask."""

from __future__ import annotations

import pytest
from batchcases import MIXED, metro_study

from trainsim.batch import read_results, run_study, study_from_dict


@pytest.fixture(scope="module")
def study():
    return study_from_dict(metro_study(**MIXED), "mixed.yaml")


@pytest.fixture(scope="module")
def serial(study):
    outcome = run_study(study, None, executor="serial")
    table = outcome.table()
    # the reference itself: 18 runs, the 9 with efficiency 1.2 failed, the others ran
    assert outcome.computed == 18 and outcome.failed == 9
    status = table.column("status").to_pylist()
    assert status.count("ok") == 9 and status.count("failed") == 9
    return table


def test_processes_identical_to_serial(study, serial, tmp_path):
    outcome = run_study(study, tmp_path / "out", executor="processes", workers=2, chunk_size=4)
    assert outcome.chunks == 5 and outcome.failed == 9
    assert read_results(tmp_path / "out", as_table=True).equals(serial)


def test_processes_started_by_a_fork_server_when_threads_run(study, serial, tmp_path):
    # with another thread alive the pool is not forked from this process (see executors._pool_context)
    import threading

    from trainsim.batch.executors import _pool_context

    stop = threading.Event()
    thread = threading.Thread(target=stop.wait, daemon=True)
    thread.start()
    try:
        assert _pool_context().get_start_method() == "forkserver"
        outcome = run_study(study, tmp_path / "out", executor="processes", workers=2, chunk_size=4)
    finally:
        stop.set()
        thread.join()
    assert outcome.computed == 18
    assert read_results(tmp_path / "out", as_table=True).equals(serial)


def test_dask_identical_to_serial(study, serial, dask_cluster, tmp_path):
    # by scheduler address, as `trainsim batch --scheduler ADDRESS`
    outcome = run_study(study, tmp_path / "out", scheduler=dask_cluster.scheduler_address, chunk_size=4)
    assert outcome.executor == "dask" and outcome.computed == 18
    assert read_results(tmp_path / "out", as_table=True).equals(serial)
    # both workers took part
    from distributed import Client

    with Client(dask_cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        memory = run_study(study, None, scheduler=client, chunk_size=3)
    assert memory.table().equals(serial)


def test_memory_and_parquet_identical(study, serial, tmp_path):
    run_study(study, tmp_path / "out", executor="serial", chunk_size=5)
    table = read_results(tmp_path / "out", as_table=True)
    assert table.equals(serial)
    df = read_results(tmp_path / "out")
    assert list(df["run_index"]) == list(range(18))
    assert df.loc[df.status == "ok", "energy_net_kwh"].gt(0).all()


def test_cli_on_dask_by_address_and_by_dask_configuration(dask_cluster, write_study, tmp_path, monkeypatch):
    import dask.config
    import typer
    from typer.testing import CliRunner

    from trainsim.cli.batch import batch

    app = typer.Typer()
    app.command()(batch)
    study = write_study(metro_study(axes=[{"field": "train.formation[*].load_t", "values": [0, 10]}]))
    address = dask_cluster.scheduler_address
    result = CliRunner().invoke(app, [str(study), "--out", str(tmp_path / "a"), "--scheduler", address])
    assert result.exit_code == 0, result.output
    assert "2 computed" in result.output and "on dask" in result.output
    # no option: Dask's own configuration (here its environment variable) names the scheduler
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
    dask.config.refresh()
    try:
        result = CliRunner().invoke(app, [str(study), "--out", str(tmp_path / "b")])
    finally:
        monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
        dask.config.refresh()
    assert result.exit_code == 0, result.output
    assert "on dask" in result.output
    assert read_results(tmp_path / "a", as_table=True).equals(read_results(tmp_path / "b", as_table=True))


def test_a_killed_pool_process_is_replaced_and_its_chunks_computed_again(study, serial):
    """SIGKILL of a worker process: a new process takes its place and what it had not sent is computed."""
    import os
    import signal

    from trainsim.batch.executors import _Processes
    from trainsim.batch.runner import _chunks
    from trainsim.batch.worker import Payload

    expansion = study.expand()
    payload = Payload(study.fingerprint, study.name, tuple(e.data for e in study.entries))
    ex = _Processes(payload, 2)
    ex.start()
    try:
        rows = []
        for k, chunk_rows in enumerate(ex.results(_chunks(expansion, list(range(18)), 2, 2))):
            rows.extend(chunk_rows)
            if k == 1:  # after two chunks: kill a worker while others are in flight
                os.kill(ex.processes[0], signal.SIGKILL)
    finally:
        ex.close()
    assert ex.restarts == 1
    assert sorted(i for i, _ in rows) == list(range(18))  # every run exactly once
    by_index = dict(rows)
    assert [by_index[i]["status"] for i in range(18)] == serial.column("status").to_pylist()
