"""Chunks sized by the predicted and measured cost of each run, longest first; a killed worker loses
one run; the order of computation changes nothing in the results."""

from __future__ import annotations

import multiprocessing
import os
import signal
import time

import pytest
from batchcases import MIXED, REPO, metro_study

from trainsim.batch import load_study, read_results, run_study, study_from_dict
from trainsim.batch.runner import (
    CHUNK_TARGET_S,
    PREDICTED_RUN_S,
    _chunks,
    _Cost,
    longest_first,
    plan_chunks,
    run_work,
)

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
    """Two workers, two chunks of 9 runs of at least SEND_INTERVAL_S each (so that every run is sent
    on its own). The first worker is killed (SIGKILL) at the start of its fifth run: the four runs it
    sent are kept, the run being computed and the other four of its chunk
    are computed by a new worker, and the other worker's chunk is not disturbed. Every run is
    computed once, the killed one twice."""
    from trainsim.batch import executors
    from trainsim.batch.executors import _Processes
    from trainsim.batch.worker import SEND_INTERVAL_S, Payload, WorkerState

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
        time.sleep(SEND_INTERVAL_S)
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


def _makespan(chunk_costs: list[float], workers: int) -> float:
    """Wall time of chunks handed in order to the next idle worker (the processes executor)."""
    free = [0.0] * workers
    for c in chunk_costs:
        k = free.index(min(free))
        free[k] += c
    return max(free)


def test_plan_of_twelve_equal_expensive_runs_splits_them_evenly():
    """heavy_haul_couplers: 12 runs of 3 s on 2 workers, one per chunk in run order (x2.0), where the
    chunking by count gave [10, 2] (x1.2)."""
    costs = [3.0] * 12
    plan = plan_chunks(costs, 2)
    assert plan == [[k] for k in range(12)]
    serial = sum(costs)
    assert serial / _makespan([sum(costs[k] for k in c) for c in plan], 2) == pytest.approx(2.0)
    assert serial / _makespan([30.0, 6.0], 2) == pytest.approx(1.2)


def test_plan_of_mixed_costs_is_longest_first_and_cut_at_the_target():
    """Expensive runs first and alone, then runs of 0.4 and 0.3 s that cannot share a chunk, then the
    cheap runs up to CHUNK_TARGET_S (0.5 s) per chunk; the two workers end within 0.05 s of each other,
    where 10 runs per chunk in run order leave one worker idle for 3.7 s."""
    assert CHUNK_TARGET_S == 0.5
    costs = [0.1] * 20 + [0.3, 2.0, 0.4, 1.0]
    plan = plan_chunks(costs, 2)
    assert plan[:4] == [[21], [23], [22], [20, 0, 1]]  # 2.0, 1.0, 0.4, 0.3 + 0.1 + 0.1
    assert plan[4:] == [list(range(k, min(k + 5, 20))) for k in range(2, 20, 5)]  # 5, 5, 5, 3 runs of 0.1 s
    chunk_costs = [sum(costs[k] for k in c) for c in plan]
    assert max(chunk_costs[3:]) <= CHUNK_TARGET_S + 1e-12
    # the workers end at 2.9 and 2.8 s: 0.05 s above the lower bound sum / 2 = 2.85 s
    assert _makespan(chunk_costs, 2) == pytest.approx(2.9)
    by_count = [sum(costs[k : k + 10]) for k in range(0, 24, 10)]  # 1.0, 1.0, 3.7: ends at 1.0 and 4.7 s
    assert _makespan(by_count, 2) == pytest.approx(4.7)


def test_plan_of_cheap_runs_is_guided():
    """4000 runs of 2 ms: chunks of 200 (the most, 0.4 s) shrinking towards the end; order unchanged."""
    plan = plan_chunks([0.002] * 4000, 2)
    sizes = [len(c) for c in plan]
    assert sizes[0] == 200 and sizes[-1] == 10 and sizes == sorted(sizes, reverse=True)
    assert [k for c in plan for k in c] == list(range(4000))
    assert longest_first([]) == [] and longest_first([1.0, 1.0]) == [0, 1]


def test_results_do_not_depend_on_the_order_of_computation(tmp_path):
    """Runs with different stop patterns are computed longest predicted first on two processes: the
    rows are those of the serial study in run order, bit for bit, and a resumed study completes them."""
    study = study_from_dict(
        metro_study(
            axes=[
                {"field": "stops", "values": [["S1", "S4"], ["S1", "S2", "S3", "S4"], ["S1", "S3", "S4"]]},
                {"field": "train.formation[*].load_t", "values": [0, 6, 12, 18]},
            ]
        ),
        "stops.yaml",
    )
    expansion = study.expand()
    assert study.expand() is expansion  # expanded once: run_study does not compute the run ids again
    cost = _Cost(expansion, tuple(e.data for e in study.entries))
    order = cost.order(list(range(12)))
    assert order != list(range(12)) and sorted(order) == list(range(12))
    assert [len(expansion.values["stops"][i]) for i in order] == [4] * 4 + [3] * 4 + [2] * 4
    serial = run_study(study, None, executor="serial").table()
    assert serial.column("run_index").to_pylist() == list(range(12))
    out = tmp_path / "out"
    first = run_study(study, out, executor="processes", workers=2)
    assert first.computed == 12 and len(first.worker_cpu_s) == 2 and min(first.worker_cpu_s) > 0
    assert read_results(out, as_table=True).equals(serial)
    # resume: drop the written parts but one and run again
    parts = sorted((out / "results").glob("part-*.parquet"))
    for p in parts[1:]:
        p.unlink()
    again = run_study(study, out, executor="processes", workers=2)
    assert again.already_done > 0 and again.already_done + again.computed == 12
    assert read_results(out, as_table=True).equals(serial)
