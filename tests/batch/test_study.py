"""Study files: validation, axes expansion, seeded samples, explicit runs and run ids."""

from __future__ import annotations

import numpy as np
import pytest
from batchcases import METRO, REPO, metro_study

from trainsim.batch import load_study, run_id, study_from_dict
from trainsim.batch.study import parse_clock
from trainsim.errors import InputError


def expand(data, base_dir=None):
    return study_from_dict(data, "study.yaml", base_dir).expand()


# ---------------------------------------------------------------------------------------- axes
def test_product_of_axes_first_axis_slowest():
    e = expand(
        metro_study(
            axes=[
                {"field": "train.formation[0].load_t", "values": [0, 5]},
                {"field": "train.electrical.traction_efficiency", "values": [0.8, 0.9, 0.95]},
            ]
        )
    )
    assert len(e) == 6
    assert e.values["train.formation[0].load_t"] == [0, 0, 0, 5, 5, 5]
    assert e.values["train.electrical.traction_efficiency"] == [0.8, 0.9, 0.95] * 2
    assert e.task(4) == (
        4,
        0,
        None,
        (("train.formation[0].load_t", 5, False), ("train.electrical.traction_efficiency", 0.9, False)),
    )


def test_zip_axes_and_coupled_fields():
    e = expand(
        metro_study(
            combine="zip",
            axes=[
                {"field": "train.electrical.traction_efficiency", "values": [0.8, 0.9]},
                {
                    "fields": ["train.formation[0].load_t", "train.formation[1].load_t"],
                    "values": [[1, 2], [3, 4]],
                },
            ],
        )
    )
    assert len(e) == 2
    assert e.params(1) == {
        "train.electrical.traction_efficiency": 0.9,
        "train.formation[0].load_t": 3,
        "train.formation[1].load_t": 4,
    }


def test_ranges_include_the_end_and_are_rounded():
    e = expand(
        metro_study(
            axes=[
                {
                    "field": "train.electrical.traction_efficiency",
                    "range": {"from": 0.8, "to": 0.95, "step": 0.05},
                }
            ]
        )
    )
    assert e.values["train.electrical.traction_efficiency"] == [0.8, 0.85, 0.9, 0.95]
    e = expand(
        metro_study(axes=[{"field": "train.formation[0].load_t", "range": {"from": 0, "to": 10, "count": 3}}])
    )
    assert e.values["train.formation[0].load_t"] == [0, 5, 10]
    e = expand(
        metro_study(axes=[{"field": "settings.max_step_m", "range": {"from": 5, "to": 20, "step": 10}}])
    )
    assert e.values["settings.max_step_m"] == [5, 15]


# ---------------------------------------------------------------------------------------- samples
SAMPLES = {
    "count": 400,
    "seed": 3,
    "fields": {
        "train.formation[*].load_t": {"distribution": "uniform", "low": 0, "high": 18},
        "train.electrical.traction_efficiency": {
            "distribution": "normal",
            "mean": 0.9,
            "std": 0.05,
            "max": 0.95,
        },
        "train.electrical.line_voltage_v": {
            "distribution": "choice",
            "values": [900, 1000],
            "weights": [1, 3],
        },
        "train.formation[0].mass_t": {
            "distribution": "triangular",
            "low": 0.9,
            "mode": 1.0,
            "high": 1.05,
            "relative": True,
        },
    },
}


def test_samples_are_seeded_bounded_and_distributed():
    a = expand(metro_study(samples=SAMPLES))
    b = expand(metro_study(samples=SAMPLES))
    assert a.values == b.values and a.run_ids == b.run_ids
    load = np.array(a.values["train.formation[*].load_t"])
    eff = np.array(a.values["train.electrical.traction_efficiency"])
    volt = np.array(a.values["train.electrical.line_voltage_v"])
    factor = np.array(a.values["train.formation[0].mass_t:factor"])
    assert load.min() >= 0 and load.max() <= 18 and 7 < load.mean() < 11
    assert eff.max() <= 0.95 and 0.86 < eff.mean() < 0.9  # truncated above the mean
    assert set(volt) == {900, 1000} and 0.65 < (volt == 1000).mean() < 0.85
    assert factor.min() >= 0.9 and factor.max() <= 1.05
    assert a.values["sample"] == list(range(400))
    other = expand(metro_study(samples={**SAMPLES, "seed": 4}))
    assert other.values["train.formation[*].load_t"] != a.values["train.formation[*].load_t"]


def test_samples_repeat_at_every_sweep_point():
    e = expand(
        metro_study(
            axes=[{"field": "train.formation[1].load_t", "values": [0, 10]}], samples={**SAMPLES, "count": 4}
        )
    )
    loads = e.values["train.formation[*].load_t"]
    assert len(e) == 8 and loads[:4] == loads[4:]  # common random numbers across design points
    assert e.values["sample"] == [0, 1, 2, 3] * 2


# ---------------------------------------------------------------------------------------- run ids
def test_run_ids_are_stable_hashes_of_the_parameters():
    e = expand(metro_study(axes=[{"field": "train.formation[0].load_t", "values": [0, 5]}]))
    assert e.run_ids[1] == run_id({"train.formation[0].load_t": 5})
    assert len(e.run_ids[0]) == 24 and len(set(e.run_ids)) == 2
    # the same run in a larger study keeps its id
    bigger = expand(metro_study(axes=[{"field": "train.formation[0].load_t", "values": [5, 0, 10]}]))
    assert set(e.run_ids) < set(bigger.run_ids)


def test_repeated_values_are_an_error():
    with pytest.raises(InputError, match="same parameters"):
        expand(metro_study(axes=[{"field": "train.formation[0].load_t", "values": [1, 1]}]))


# ---------------------------------------------------------------------------------------- timetable
def test_explicit_runs_with_departures(tmp_path):
    data = metro_study(
        runs=[
            {"name": "all stops", "departures": {"first": "06:00", "last": "07:00", "every_min": 20}},
            {
                "name": "express",
                "stops": ["S1", "S3", "S4"],
                "departures": ["06:10", "06:40:30"],
                "set": {"train.formation[*].load_t": 10},
                "dwell_s": {"S3": 20},
            },
            {"name": "single", "departure": 3600, "route": str(METRO / "route.yaml")},
        ]
    )
    study = study_from_dict(data, "study.yaml")
    e = study.expand()
    assert e.values["run"] == ["all stops"] * 4 + ["express"] * 2 + ["single"]
    assert e.values["departure_s"] == [21600, 22800, 24000, 25200, 22200, 24030, 3600]
    express = study.entries[1].data
    assert express["stops"] == ["S1", "S3", "S4"] and express["dwell_s"] == {"S3": 20}
    assert [v["load_t"] for v in express["train"]["formation"]] == [10, 10]
    # the other runs keep the base's train (shared, not copied: one copy in the workers' payload)
    assert [v["load_t"] for v in study.entries[0].data["train"]["formation"]] == [0, 0]
    assert study.entries[2].data["train"] is study.entries[0].data["train"]


def test_clock_times():
    assert parse_clock("07:05") == 7 * 3600 + 300
    assert parse_clock("25:00:30.5") == 25 * 3600 + 30.5
    assert parse_clock(90) == 90.0
    for bad in ("7h", "07:60", -1, True):
        with pytest.raises(InputError, match="not a time"):
            parse_clock(bad)


def test_example_studies_load_and_expand():
    sizes = {}
    for path in sorted((REPO / "examples" / "studies").glob("*.yaml")):
        sizes[path.stem] = len(load_study(path).expand())
    assert sizes == {
        "heavy_haul_couplers": 12,
        "loco_adhesion": 300,
        "metro_eco_driving": 24,
        "metro_load_efficiency": 35,
        "metro_monte_carlo": 500,
        "metro_timetable": 187,
    }


# ---------------------------------------------------------------------------------------- bad studies
BAD = [
    ({"axis": []}, "field 'axis': unknown field (did you mean 'axes'?)"),
    ({"axes": [{"field": "trian.mass_t", "values": [1]}]}, "starts with the part of the scenario"),
    (
        {"axes": [{"field": "train.electrcal.traction_efficiency", "values": [1]}]},
        "did you mean 'electrical'",
    ),
    ({"axes": [{"field": "train.formation[5].load_t", "values": [1]}]}, "has 2 item(s): no item [5]"),
    ({"axes": [{"field": "dwell_s.S9", "values": [1]}]}, "no station of that name"),
    ({"axes": [{"field": "train.name", "values": [1.1], "relative": True}]}, "scales a number"),
    (
        {
            "axes": [
                {
                    "field": "train.formation[0].load_t",
                    "values": [1],
                    "range": {"from": 0, "to": 1, "step": 1},
                }
            ]
        },
        "exactly one of 'values' or 'range'",
    ),
    ({"axes": [{"field": "train.formation[0].load_t", "range": {"from": 2, "to": 1, "step": 1}}]}, "below"),
    (
        {"axes": [{"fields": ["train.formation[0].load_t", "train.formation[1].load_t"], "values": [[1]]}]},
        "must be a list of 2 values",
    ),
    (
        {
            "combine": "zip",
            "axes": [
                {"field": "train.formation[0].load_t", "values": [1, 2]},
                {"field": "train.formation[1].load_t", "values": [1]},
            ],
        },
        "same number of values",
    ),
    (
        {
            "axes": [
                {"field": "train.formation[0].load_t", "values": [1]},
                {"field": "train.formation[0].load_t", "values": [2]},
            ]
        },
        "varied twice",
    ),
    (
        {
            "samples": {
                "count": 3,
                "fields": {"train.formation[0].load_t": {"distribution": "uniform", "low": 0, "high": 1}},
            }
        },
        "samples.seed",
    ),
    (
        {
            "samples": {
                "count": 3,
                "seed": 1,
                "fields": {"train.formation[0].load_t": {"distribution": "normal", "mean": 1}},
            }
        },
        "needs std",
    ),
    (
        {
            "samples": {
                "count": 3,
                "seed": 1,
                "fields": {
                    "train.formation[0].load_t": {"distribution": "uniform", "low": 0, "high": 1, "std": 1}
                },
            }
        },
        "std not used by a uniform",
    ),
    ({"runs": [{"name": "a"}, {"name": "a"}]}, "two runs have the same name"),
    ({"runs": [{"name": "a", "departure": "7h"}]}, "runs[0].departure"),
    (
        {"runs": [{"name": "a", "set": {"train.electrical.traction_efficiency": 3}}]},
        "runs[0] (a), field 'train.electrical.traction_efficiency': out of range",
    ),
    ({"runs": [{"name": "a", "departure": "07:00", "departures": ["08:00"]}]}, "not both"),
]


@pytest.mark.parametrize(("extra", "message"), BAD)
def test_bad_studies_name_the_field(extra, message):
    with pytest.raises(InputError) as info:
        expand(metro_study(**extra))
    assert message in str(info.value)
    assert str(info.value).startswith("study.yaml")


def test_bad_headers_and_bases(write_study, tmp_path):
    with pytest.raises(InputError, match="not a study file"):
        study_from_dict({"schema": "trainsim/scenario", "version": 1}, "s.yaml")
    with pytest.raises(InputError, match="unsupported study version"):
        study_from_dict({**metro_study(), "version": 2}, "s.yaml")
    with pytest.raises(InputError, match="needs a 'base' scenario, a list of 'runs'"):
        study_from_dict({"schema": "trainsim/study", "version": 1, "name": "x"}, "s.yaml")
    with pytest.raises(InputError, match="base scenario file not found"):
        load_study(write_study(metro_study(base="nope.yaml")))
    with pytest.raises(InputError, match="the base must be a scenario"):
        load_study(write_study(metro_study(base=str(METRO / "train.yaml"))))
    with pytest.raises(InputError, match="the run has no train"):
        study_from_dict({"schema": "trainsim/study", "version": 1, "name": "x", "runs": [{"name": "a"}]}, "s")
    # an invalid base is an error of the study (naming the scenario's field), not of every run
    broken = metro_study()
    broken["base"]["settings"] = {"max_step_m": -1}
    with pytest.raises(InputError, match=r"settings\.max_step_m"):
        study_from_dict(broken, "s.yaml")
    (tmp_path / "bad.yaml").write_text("schema: trainsim/study\nversion: 1\nname: [x\n")
    with pytest.raises(InputError, match="line"):
        load_study(tmp_path / "bad.yaml")


@pytest.mark.filterwarnings("ignore")  # the TrainRuns.jl defaults the loader reports
def test_railtoolkit_parts_cannot_be_varied():
    trainruns = REPO / "tests" / "data" / "trainruns"
    if not (trainruns / "trains" / "freight.yaml").exists():
        pytest.skip("TrainRuns.jl test data not found")
    data = {
        "schema": "trainsim/study",
        "version": 1,
        "name": "rtk",
        "base": {
            "name": "rtk",
            "train": str(trainruns / "trains" / "freight.yaml"),
            "route": str(trainruns / "paths" / "realworld.yaml"),
        },
        "axes": [{"field": "train.mass_t", "values": [1]}],
    }
    with pytest.raises(InputError, match="not a trainsim file"):
        study_from_dict(data, "s.yaml")
    data["axes"] = [{"field": "settings.max_step_m", "values": [10, 20]}]
    assert len(study_from_dict(data, "s.yaml").expand()) == 2
