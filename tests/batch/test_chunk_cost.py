"""Chunks sized by the predicted and measured cost of each run; a killed worker loses one run."""

from __future__ import annotations

import multiprocessing
import os
import signal

import pytest
from batchcases import MIXED, REPO, metro_study

from trainsim.batch import load_study, study_from_dict
from trainsim.batch.runner import CHUNK_TARGET_S, PREDICTED_RUN_S, _chunks, _Cost, run_work

HEAVY = REPO / "examples" / "studies" / "heavy_haul_couplers.yaml"


def test_run_work_from_the_scenario_data():
    """Multi-point: vehicles x km x (0.05 s / step); single point: km + stops; swept values count."""
    heavy = load_study(HEAVY).entries[0].data
    # 2 locomotives + 104 wagons over 50 km at 0.05 s steps
    assert run_work(heavy) == ("multi_point", pytest.approx(106 * 50.0))
    assert run_work(heavy, (("multi_point.time_step_s", 0.02, False),))[1] == pytest.approx(106 * 50 * 2.5)
    assert run_work(heavy, (("train.formation[1].count", 52, False),))[1] == pytest.approx(54 * 50.0)
    assert run_work(heavy, (("model", "single_point", False),)) == ("fastest", pytest.approx(50.0 + 3))
    metro = study_from_dict(metro_study(), "m.yaml")
    # the metro line: 4590.97 m, 4 stations
    assert run_work(metro.entries[0].data) == ("fastest", pytest.approx(4.59097 + 4))


def test_heavy_haul_costs_predicted_then_measured():
    study = load_study(HEAVY)
    expansion = study.expand()
    cost = _Cost(expansion, tuple(e.data for e in study.entries))
    assert cost.seconds(0) == pytest.approx(PREDICTED_RUN_S["multi_point"])
    assert [len(c) for c in _chunks(expansion, list(range(12)), None, 2, cost)] == [1] * 12
    # measured: 1.5 s of CPU for runs predicted at 3 s -> every prediction halves
    cost.measured([(0, 1.0), (1, 2.0)])
    assert cost.seconds(5) == pytest.approx(1.5)


def test_chunks_are_cut_by_cost_not_by_count():
    """A study mixing one-minute multi-point runs and millisecond single-point runs (a model axis):
    the multi-point runs go first, one per chunk, the cheap ones together, each chunk holding at most
    CHUNK_TARGET_S of predicted work (or one run)."""
    data = load_study(HEAVY).entries[0].data
    study = study_from_dict(
        {
            "schema": "trainsim/study",
            "version": 1,
            "name": "mixed models",
            "base": str(REPO / "examples" / "heavy_haul" / "scenario_dp.yaml"),
            "axes": [
                {"field": "model", "values": ["single_point", "multi_point"]},
                {"field": "multi_point.couplers.slack_m", "values": [0, 0.01, 0.02, 0.03, 0.04, 0.05]},
            ],
        },
        str(REPO / "examples" / "studies" / "mixed.yaml"),
    )
    assert data["model"] == "multi_point"
    expansion = study.expand()
    cost = _Cost(expansion, tuple(e.data for e in study.entries))
    model = expansion.values["model"]
    order = cost.order(list(range(len(expansion))))
    assert [model[i] for i in order] == ["multi_point"] * 6 + ["single_point"] * 6
    chunks = list(_chunks(expansion, order, None, 2, cost))
    sizes = [len(c) for c in chunks]
    assert sizes == [1] * 6 + [6]  # 6 single-point runs of 50 km: 6 x 0.015 s predicted
    for chunk in chunks:
        predicted = sum(cost.seconds(t[0]) for t in chunk)
        assert len(chunk) == 1 or predicted <= CHUNK_TARGET_S


def test_equal_costs_keep_the_run_order():
    study = study_from_dict(metro_study(**MIXED), "mixed.yaml")
    expansion = study.expand()
    cost = _Cost(expansion, tuple(e.data for e in study.entries))
    assert cost.order(list(range(18))) == list(range(18))


def test_a_killed_worker_loses_only_the_run_it_was_computing(tmp_path, monkeypatch):
    """Two workers, two chunks of 9 runs. The first worker is killed (SIGKILL) at the start of its
    fifth run: the four runs it sent are kept, the run being computed and the other four of its chunk
    are computed by a new worker, and the other worker's chunk is not disturbed. Every run is
    computed once, the killed one twice."""
    from trainsim.batch import executors
    from trainsim.batch.executors import _Processes
    from trainsim.batch.worker import Payload, WorkerState

    log = tmp_path / "computed.log"
    marker = tmp_path / "killed"
    victim = 4
    original = WorkerState.run

    def run(self, task):
        with open(log, "a") as fh:
            fh.write(f"{task[0]}\n")
        if task[0] == victim and not marker.exists():
            marker.touch()
            os.kill(os.getpid(), signal.SIGKILL)
        return original(self, task)

    # forked workers inherit the patched method
    monkeypatch.setattr(WorkerState, "run", run)
    monkeypatch.setattr(executors, "_pool_context", lambda: multiprocessing.get_context("fork"))
    study = study_from_dict(metro_study(**MIXED), "mixed.yaml")
    expansion = study.expand()
    payload = Payload(study.fingerprint, study.name, tuple(e.data for e in study.entries))
    ex = _Processes(payload, 2)
    ex.start()
    try:
        rows = [r for chunk in ex.results(_chunks(expansion, list(range(18)), 9, 2)) for r in chunk]
    finally:
        ex.close()
    assert marker.exists() and ex.restarts == 1
    assert sorted(i for i, _ in rows) == list(range(18))  # every run written exactly once
    counts = [int(x) for x in log.read_text().split()]
    assert sorted(counts) == sorted([*range(18), victim])  # computed once each, the killed run twice
    assert {i for i, _ in ex.measured} == set(range(18))
