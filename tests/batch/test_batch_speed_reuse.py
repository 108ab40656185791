"""Runs that build the same scenario (a timetable entry's departures) are computed once per worker, and
each still gets the row it would have had when computed on its own (issue 14, batch throughput)."""

from __future__ import annotations

import pytest
from batchcases import metro_study

import trainsim.sim.fastest
from trainsim.batch import run_study, study_from_dict
from trainsim.batch import worker as worker_mod
from trainsim.batch.worker import Payload, WorkerState, scenario_key

#: Two services with three and two departures, one of them loaded; an axis doubles every run: 10 runs
#: of 4 distinct scenarios.
TIMETABLE = {
    "runs": [
        {"name": "all stops", "departures": ["06:00", "06:10", "06:20"]},
        {
            "name": "loaded",
            "departures": ["07:00", "07:30:30"],
            "set": {"train.formation[*].load_t": 16},
        },
    ],
    "axes": [{"field": "train.electrical.traction_efficiency", "values": [0.85, 0.9]}],
}


@pytest.fixture(scope="module")
def timetable():
    return study_from_dict(metro_study(**TIMETABLE), "timetable.yaml")


def _rows(study, cache_size: int, monkeypatch) -> tuple[list[dict], int]:
    """The rows of every run by one worker state, and how many fastest runs it computed."""
    calls = []
    original = trainsim.sim.fastest.run_fastest

    def counting(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(trainsim.sim.fastest, "run_fastest", counting)
        m.setattr(worker_mod, "RUN_CACHE_SIZE", cache_size)
        state = WorkerState(Payload.of(study))
        expansion = study.expand()
        rows = [state.run(expansion.task(i)) for i in range(len(expansion))]
    return rows, len(calls)


def test_departures_of_one_scenario_are_computed_once(timetable, monkeypatch):
    expansion = timetable.expand()
    assert len(expansion) == 10
    rows, computed = _rows(timetable, worker_mod.RUN_CACHE_SIZE, monkeypatch)
    assert computed == 4  # 2 services x 2 efficiencies
    alone, computed_alone = _rows(timetable, 0, monkeypatch)  # nothing kept: every run computed
    assert computed_alone == 10
    assert rows == alone  # bit for bit (no NaN in these rows)
    assert all(r["status"] == "ok" for r in rows)
    # each row has its own clock times, shifted by its departure
    departures = [expansion.task(i)[2] for i in range(10)]
    for row, dep in zip(rows, departures, strict=True):
        assert row["sections"][0]["departure_s"] == dep
        assert row["arrival_s"] == dep + row["total_time_s"]
    # run order: service, departure, then the axis: runs 0 and 2 are 06:00 and 06:10 at 0.85
    first, second = rows[0], rows[2]
    assert departures[2] - departures[0] == 600.0
    assert first["energy_net_kwh"] == second["energy_net_kwh"]
    assert second["sections"][-1]["arrival_s"] - first["sections"][-1]["arrival_s"] == pytest.approx(600.0)


def test_a_study_gives_the_same_results_with_processes(timetable, tmp_path):
    serial = run_study(timetable, None, executor="serial").table()
    processes = run_study(timetable, tmp_path / "p", executor="processes", workers=2, chunk_size=3)
    assert processes.table().equals(serial)


def test_scenario_key_ignores_index_and_departure_only():
    base = scenario_key((0, 1, 3600.0, (("train.formation[*].load_t", 2.0, False),)))
    assert base == scenario_key((7, 1, 7200.0, (("train.formation[*].load_t", 2.0, False),)))
    assert base == scenario_key((7, 1, None, (("train.formation[*].load_t", 2.0, False),)))
    others = [
        (0, 2, 3600.0, (("train.formation[*].load_t", 2.0, False),)),  # another entry
        (0, 1, 3600.0, (("train.formation[*].load_t", 2.0000000000000004, False),)),  # next double
        (0, 1, 3600.0, (("train.formation[*].load_t", 2, False),)),  # an int is written as an int
        (0, 1, 3600.0, (("train.formation[*].load_t", 2.0, True),)),  # a factor
        (0, 1, 3600.0, (("train.formation[0].load_t", 2.0, False),)),  # another path
        (0, 1, 3600.0, ()),
    ]
    keys = {scenario_key(t) for t in others}
    assert base not in keys and len(keys) == len(others)


def test_failed_runs_are_not_kept_and_name_their_run(monkeypatch):
    study = study_from_dict(
        metro_study(
            runs=[{"name": "bad", "departures": ["06:00", "06:10"]}],
            axes=[{"field": "settings.max_step_m", "values": [-5]}],  # rejected run by run
        ),
        "bad.yaml",
    )
    rows, _ = _rows(study, worker_mod.RUN_CACHE_SIZE, monkeypatch)
    assert [r["status"] for r in rows] == ["failed", "failed"]
    assert "run 0" in rows[0]["error"] and "run 1" in rows[1]["error"]
