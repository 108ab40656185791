"""Running studies: failure rows, stalled runs, figures against single runs, timetables."""

from __future__ import annotations

import pytest
from batchcases import METRO, REPO, metro_study

import trainsim
from trainsim.batch import run_study, study_from_dict
from trainsim.batch.runner import auto_chunk_size
from trainsim.errors import InputError


def test_failed_runs_are_rows_and_never_stop_the_study():
    study = study_from_dict(
        metro_study(
            axes=[
                # a whole list as a value: level, or a 150 per mille climb from 2 km on
                {
                    "field": "route.gradients",
                    "values": [
                        [{"from_m": 0, "gradient_permille": 0}],
                        [{"from_m": 0, "gradient_permille": 0}, {"from_m": 2000, "gradient_permille": 150}],
                    ],
                },
                {"field": "dwell_s.S2", "values": [10, -5]},
                {"field": "train.electrical.traction_efficiency", "values": [0.9, 1.5]},
            ]
        ),
        "s.yaml",
    )
    outcome = run_study(study, None, executor="serial", chunk_size=3)
    df = outcome.results()
    assert outcome.computed == 8 and outcome.failed == 6 and outcome.stalled == 1
    assert df.status.tolist() == ["ok", "failed", "failed", "failed", "stalled", "failed", "failed", "failed"]
    # the last axis varies fastest: run 1 has efficiency 1.5, run 2 the dwell of -5 s
    assert "run 1, field 'train.electrical.traction_efficiency': out of range (got 1.5)" in df.error[1]
    assert df.error[2] == "run 2, field 'dwell_s.S2': invalid dwell time (got -5); allowed: >= 0 s."
    assert set(df.error_type.dropna()) == {"InputError"}
    assert df.energy_net_kwh[1] != df.energy_net_kwh[1]  # NaN: a failed run has no figures
    assert (
        "the train stalls at" in df.warnings[4] and 2000 < df.distance_m[4] < 4000
    )  # momentum carries it up
    assert df["route.gradients"][0] == '[{"from_m": 0, "gradient_permille": 0}]'  # stored as JSON
    assert df.sections[1] is None or len(df.sections[1]) == 0


def test_rows_match_single_runs():
    study = study_from_dict(
        metro_study(
            axes=[
                {"field": "train.formation[*].load_t", "values": [0, 12]},
                {"field": "dwell_s.S3", "values": [20]},
            ]
        ),
        "s.yaml",
    )
    df = run_study(study, None, executor="serial").results()
    # the same run by hand, through the normal readers
    scenario = trainsim.load_scenario(METRO / "scenario.yaml")
    import dataclasses

    from trainsim.io.trainsim_yaml import apply_stops, read_yaml, train_from_dict

    data = read_yaml(METRO / "train.yaml")
    for v in data["formation"]:
        v["load_t"] = 12
    route = apply_stops(scenario.route, None, {"S3": 20})
    settings = dataclasses.replace(scenario.settings, max_step_m=20)
    result = trainsim.run_fastest(train_from_dict(data), route, settings)
    row = df.iloc[1]
    assert row["running_time_s"] == result.running_time_s
    assert row["energy_net_kwh"] == result.energy_kwh.net
    assert row["peak_current_a"] == result.peak_current_a
    assert [s["dwell_s"] for s in row["sections"]] == pytest.approx([51, 20, 0])
    assert df.energy_net_kwh[1] > df.energy_net_kwh[0]


def test_timetable_rows_have_clock_times():
    study = study_from_dict(
        metro_study(
            runs=[
                {"name": "a", "departures": ["07:00", "07:10"]},
                {"name": "b", "departure": "08:00", "stops": ["S1", "S4"]},
            ]
        ),
        "s.yaml",
    )
    df = run_study(study, None, executor="serial").results()
    assert df.run.tolist() == ["a", "a", "b"]
    assert df.departure_s.tolist() == [25200, 25800, 28800]
    assert df.arrival_s.tolist() == pytest.approx((df.departure_s + df.total_time_s).tolist())
    sections = df.sections[0]
    assert sections[0]["departure_s"] == 25200 and sections[-1]["arrival_s"] == pytest.approx(df.arrival_s[0])
    assert sections[1]["departure_s"] == pytest.approx(sections[0]["arrival_s"] + sections[0]["dwell_s"])
    assert [(s["from"], s["to"]) for s in df.sections[2]] == [("S1", "S4")]


def test_chunk_sizes_shrink_towards_the_end():
    assert auto_chunk_size(100_000, 2) == 200
    assert auto_chunk_size(400, 2) == 50
    assert auto_chunk_size(5, 2) == 10


def test_chunks_hold_at_most_half_a_second_of_work():
    # runs of a few seconds (multi-point) go one per chunk, 0.05 s runs ten per chunk
    assert auto_chunk_size(12, 2, run_s=3.0) == 1
    assert auto_chunk_size(100, 2, run_s=0.3) == 1
    assert auto_chunk_size(1000, 2, run_s=0.05) == 10
    assert auto_chunk_size(100_000, 2, run_s=0.0025) == 200


def test_a_multi_point_study_is_cut_into_one_run_chunks():
    """The heavy-haul coupler study (12 multi-point runs of seconds each) was split [10, 2]: one worker
    of two did almost everything. Predicted from the kind of run, then measured, every chunk is one run."""
    from trainsim.batch import load_study
    from trainsim.batch.runner import PREDICTED_RUN_S, _chunks, _Cost

    study = load_study(REPO / "examples" / "studies" / "heavy_haul_couplers.yaml")
    expansion = study.expand()
    cost = _Cost(expansion)
    assert cost.run_s == PREDICTED_RUN_S["multi_point"]
    assert [len(c) for c in _chunks(expansion, list(range(12)), None, 2, cost)] == [1] * 12
    # measured costs take over: cheap runs after all -> larger chunks
    metro = study_from_dict(
        metro_study(
            axes=[{"field": "train.formation[0].load_t", "range": {"from": 0, "to": 10, "count": 1000}}]
        ),
        "m.yaml",
    ).expand()
    cost = _Cost(metro)
    assert cost.run_s == PREDICTED_RUN_S["fastest"]
    cost.run_s = 0.05  # as if measured
    sizes = [len(c) for c in _chunks(metro, list(range(1000)), None, 2, cost)]
    assert set(sizes) == {10} and sum(sizes) == 1000


def test_bad_arguments():
    study = study_from_dict(metro_study(), "s.yaml")
    with pytest.raises(InputError, match="unknown executor"):
        run_study(study, None, executor="threads")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="at least one worker"):
        run_study(study, None, workers=0)
