"""Studies of multi-point scenarios (docs/MULTIPOINT.md): multi-point bases, axes over ``multi_point``
fields and ``model``, coupler-force columns, and the combinations studies refuse."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path
from typing import Any

import pytest
import yaml
from batchcases import REPO

import trainsim
from trainsim.batch import run_study, study_from_dict
from trainsim.batch.worker import METRICS, MULTI_POINT_COLUMNS
from trainsim.errors import InputError
from trainsim.io import trainsim_yaml as tsy
from trainsim.io.multipoint_spec import multipoint_settings_from_dict

HEAVY = REPO / "examples" / "heavy_haul"
BLOCK = {
    "locomotive_positions": [0],
    "time_step_s": 0.1,
    "traction_ramp_s": 10,
    "couplers": {"slack_m": 0.025},
}


def _short_train() -> dict[str, Any]:
    """The heavy-haul train shrunk to 1 locomotive + 10 wagons (a run takes about 15 ms)."""
    train = tsy.read_yaml(HEAVY / "train.yaml")
    train["formation"][0]["count"] = 1
    train["formation"][1]["count"] = 10
    train["traction"].update(power_kw=7200, max_force_kn=570)
    train["braking"]["force_kn"] = [f / 10 for f in train["braking"]["force_kn"]]
    return train


ROUTE = {
    "schema": "trainsim/route",
    "version": 1,
    "name": "3 km with a hump",
    "length_m": 3000,
    "line_resistance": {
        "curve_formula": "tbt1407",
        "tunnel_formula": "tbt1407",
        "gradient_formula": "small_angle",
        "apply_over": "train_length",
    },
    "stations": [{"name": "A", "position_m": 0}, {"name": "B", "position_m": 3000}],
    "speed_limits": [{"from_m": 0, "limit_kmh": 60}],
    "gradients": [
        {"from_m": 0, "gradient_permille": 0},
        {"from_m": 1000, "gradient_permille": 5},
        {"from_m": 2000, "gradient_permille": -3},
    ],
}


def _scenario(tmp_path: Path, **extra: Any) -> Path:
    """A multi-point scenario file with its train and route files next to it."""
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(_short_train(), sort_keys=False))
    (tmp_path / "route.yaml").write_text(yaml.safe_dump(ROUTE, sort_keys=False))
    data = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": "short heavy haul",
        "train": "train.yaml",
        "route": "route.yaml",
        "settings": {"max_step_m": 20},
        "model": "multi_point",
        "multi_point": copy.deepcopy(BLOCK),
        **extra,
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _study(base: Any, **extra: Any) -> dict[str, Any]:
    return {"schema": "trainsim/study", "version": 1, "name": "mp study", "base": base, **extra}


SLACK = [0.0, 0.025, 0.05]


def test_slack_sweep_matches_trainsim_run(tmp_path):
    base = _scenario(tmp_path)
    study = study_from_dict(
        _study(str(base), axes=[{"field": "multi_point.couplers.slack_m", "values": SLACK}]),
        "s.yaml",
        tmp_path,
    )
    assert study.multi_point and not study.driving
    df = run_study(study, None, executor="serial").results()
    assert df.status.tolist() == ["ok"] * 3
    scenario = trainsim.load_scenario(base)
    for slack, row in zip(SLACK, df.itertuples(), strict=True):
        block = copy.deepcopy(BLOCK)
        block["couplers"]["slack_m"] = slack
        ref = trainsim.run(dataclasses.replace(scenario, multi_point=multipoint_settings_from_dict(block)))
        summary = ref.run.summary()
        assert row.running_time_s == summary["running_time_s"]
        assert row.energy_net_kwh == ref.energy_kwh.net
        assert row.max_draft_force_n == ref.max_draft.force_n
        assert row.max_buff_force_n == ref.max_buff.force_n
        assert row.max_draft_coupler == ref.max_draft.coupler
        assert row.max_buff_coupler_position_m == ref.max_buff.coupler_position_m
    # the swept field reaches the model: every slack gives other coupler forces
    assert df.max_draft_force_n.nunique() == 3 and df["multi_point.couplers.slack_m"].tolist() == SLACK
    assert (df.max_buff_force_n < 0).all()


def test_serial_and_processes_identical(tmp_path):
    base = _scenario(tmp_path)
    data = _study(
        str(base),
        axes=[
            {"field": "multi_point.couplers.draft_stiffness_n_per_m", "values": [7e6, 1.4e7]},
            {"field": "model", "values": ["single_point", "multi_point"]},
        ],
    )
    study = study_from_dict(data, "s.yaml", tmp_path)
    serial = run_study(study, None, executor="serial").results()
    procs = run_study(study, None, executor="processes", workers=2).results()
    pd_testing = pytest.importorskip("pandas.testing")
    pd_testing.assert_frame_equal(serial, procs)
    assert serial.status.tolist() == ["ok"] * 4


def test_model_axis_single_and_multi_point(tmp_path):
    base = _scenario(tmp_path)
    study = study_from_dict(
        _study(str(base), axes=[{"field": "model", "values": ["single_point", "multi_point"]}]), "s.yaml"
    )
    df = run_study(study, None, executor="serial").results()
    assert df.model.tolist() == ["single_point", "multi_point"]
    single, multi = df.iloc[0], df.iloc[1]
    scenario = trainsim.load_scenario(base)
    ref_single = trainsim.run(dataclasses.replace(scenario, model="single_point", multi_point=None))
    assert single.energy_net_kwh == ref_single.energy_kwh.net
    assert single.running_time_s == ref_single.running_time_s
    assert all(single[c] is None or single[c] != single[c] for c in MULTI_POINT_COLUMNS)  # empty
    assert multi.energy_net_kwh == trainsim.run(scenario).energy_kwh.net
    assert multi.max_draft_force_n > 0
    assert single.running_time_s == pytest.approx(multi.running_time_s, rel=0.05)


def test_single_point_studies_keep_their_columns(tmp_path):
    base = _scenario(tmp_path)
    data = tsy.read_yaml(base)
    for key in ("model", "multi_point"):
        data.pop(key)
    data["train"], data["route"] = str(tmp_path / "train.yaml"), str(tmp_path / "route.yaml")
    study = study_from_dict(_study(data, axes=[{"field": "settings.max_step_m", "values": [10, 20]}]), "s")
    assert not study.multi_point
    df = run_study(study, None, executor="serial").results()
    assert not set(MULTI_POINT_COLUMNS) & set(df.columns)
    assert set(METRICS) <= set(df.columns)


def test_inline_multipoint_base_and_explicit_runs(tmp_path):
    base = tsy.read_yaml(_scenario(tmp_path))
    base["train"], base["route"] = _short_train(), copy.deepcopy(ROUTE)
    data = _study(
        base,
        runs=[
            {"name": "stiff", "set": {"multi_point.couplers.slack_m": 0}},
            {"name": "single", "set": {"model": "single_point"}},
        ],
    )
    df = run_study(study_from_dict(data, "s.yaml"), None, executor="serial").results()
    assert df.status.tolist() == ["ok", "ok"]
    assert df.max_draft_force_n.notna().tolist() == [True, False]


def test_rejected_values_make_failure_rows(tmp_path):
    base = _scenario(tmp_path)
    data = _study(
        str(base),
        axes=[{"field": "multi_point.couplers.slack_m", "values": [0.01, -1]}],
    )
    df = run_study(study_from_dict(data, "s.yaml"), None, executor="serial").results()
    assert df.status.tolist() == ["ok", "failed"]
    assert "multi_point.couplers.slack_m" in df.error[1]


def test_profile_file_relative_to_the_base_read_by_the_study(tmp_path):
    base = _scenario(tmp_path)
    ref = trainsim.run(trainsim.load_scenario(base))
    ref.run.to_dataframe()[["position_m", "speed_kmh"]].to_csv(tmp_path / "profile.csv", index=False)
    sub = tmp_path / "sub"
    sub.mkdir()
    base2 = _scenario(sub, multi_point={**BLOCK, "strategy": "follow", "profile": "../profile.csv"})
    study = study_from_dict(
        _study(str(base2), axes=[{"field": "multi_point.couplers.slack_m", "values": [0.0, 0.025]}]), "s"
    )
    assert list(study.profiles) == [str((tmp_path / "profile.csv").resolve())]
    (tmp_path / "profile.csv").rename(tmp_path / "gone.csv")  # the workers need no file system
    df = run_study(study, None, executor="serial").results()
    assert df.status.tolist() == ["ok", "ok"]
    assert df.max_draft_force_n.notna().all()


def test_profile_file_is_relative_to_the_scenario_from_any_directory(tmp_path, monkeypatch):
    base = _scenario(tmp_path)
    ref = trainsim.run(trainsim.load_scenario(base))
    ref.run.to_dataframe()[["position_m", "speed_kmh"]].to_csv(tmp_path / "profile.csv", index=False)
    sub = tmp_path / "sub"
    sub.mkdir()
    follow = _scenario(sub, multi_point={**BLOCK, "strategy": "follow", "profile": "../profile.csv"})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # the profile is found from the scenario's folder, not the working one
    direct = trainsim.run(trainsim.load_scenario(follow))
    assert direct.run.status == "ok"
    df = run_study(study_from_dict(_study(str(follow)), "s"), None, executor="serial").results()
    assert df.running_time_s[0] == pytest.approx(direct.run.running_time_s, rel=1e-12)
    assert df.max_draft_force_n[0] == pytest.approx(direct.summary()["multi_point"]["max_draft"]["force_n"])


def test_driving_with_multipoint_is_refused(tmp_path):
    base = _scenario(tmp_path, driving={"strategy": "optimal", "supplement": "10%"})
    with pytest.raises(InputError, match="not driven by a 'driving' block") as info:
        study_from_dict(_study(str(base)), "s.yaml")
    assert "driving" in str(info.value.field)
    # a driving axis on a multi-point base, and a model axis on a base with driving
    with pytest.raises(InputError, match="not driven") as info:
        study_from_dict(
            _study(str(_scenario(tmp_path)), axes=[{"field": "driving.supplement", "values": ["5%"]}]), "s"
        )
    assert info.value.field == "axes[0].field"
    single = tsy.read_yaml(_scenario(tmp_path, driving={"strategy": "optimal", "supplement": "10%"}))
    single["model"] = "single_point"
    single.pop("multi_point")
    with pytest.raises(InputError, match="not driven"):
        study_from_dict(
            _study(single, axes=[{"field": "model", "values": ["single_point", "multi_point"]}]),
            "s",
            tmp_path,
        )


def test_multipoint_field_on_single_point_runs_is_refused(tmp_path):
    data = tsy.read_yaml(_scenario(tmp_path))
    data.pop("model")
    data.pop("multi_point")
    with pytest.raises(InputError, match="setting of the multi-point model") as info:
        study_from_dict(
            _study(data, axes=[{"field": "multi_point.couplers.slack_m", "values": [0.0]}]), "s", tmp_path
        )
    assert info.value.field == "axes[0].field"


def test_misspelt_multipoint_field_is_an_error_of_the_study(tmp_path):
    with pytest.raises(InputError, match="unknown field"):
        study_from_dict(
            _study(str(_scenario(tmp_path)), axes=[{"field": "multi_point.couplers.slak_m", "values": [0]}]),
            "s",
        )


def test_dask_gives_the_serial_rows_with_a_profile_file(tmp_path, dask_cluster):
    base = _scenario(tmp_path)
    ref = trainsim.run(trainsim.load_scenario(base))
    ref.run.to_dataframe()[["position_m", "speed_kmh"]].to_csv(tmp_path / "profile.csv", index=False)
    follow = _scenario(tmp_path, multi_point={**BLOCK, "strategy": "follow", "profile": "profile.csv"})
    data = _study(str(follow), axes=[{"field": "multi_point.couplers.slack_m", "values": [0.0, 0.025, -1]}])
    study = study_from_dict(data, "s.yaml")
    serial = run_study(study, None, executor="serial").results()
    dask = run_study(study, None, executor="dask", scheduler=dask_cluster.scheduler_address).results()
    pytest.importorskip("pandas.testing").assert_frame_equal(serial, dask)
    assert serial.status.tolist() == ["ok", "ok", "failed"]
