"""Studies of energy-efficient driving: the scenario's ``driving`` block in the base, runs and axes."""

from __future__ import annotations

import pandas as pd
import pytest
import yaml
from batchcases import METRO, metro_study
from typer.testing import CliRunner

import trainsim
from trainsim.batch import load_study, read_results, run_study, study_from_dict
from trainsim.batch.worker import DRIVING_COLUMNS, Payload, WorkerState
from trainsim.errors import InputError
from trainsim.optimize.api import SCHEDULE_TOLERANCE_S, optimize

#: Supplement x strategy on the metro (20 m steps), with a supplement and a strategy the reader
#: rejects: 3 x 3 = 9 runs, 5 of them failed.
SWEEP = {
    "axes": [
        {"field": "driving.supplement", "values": ["5%", "20%", "ten"]},
        {"field": "driving.strategy", "values": ["optimal", "lesov", "bogus"]},
    ]
}


def _scenario_file(tmp_path, name: str, driving: dict | None, **extra) -> str:
    """A scenario file on the metro train and line (absolute paths) with a driving block."""
    data = {
        "schema": "trainsim/scenario",
        "version": 1,
        "name": name,
        "train": str(METRO / "train.yaml"),
        "route": str(METRO / "route.yaml"),
        **extra,
    }
    if driving is not None:
        data["driving"] = driving
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(path)


def test_supplement_sweep_energy_falls_and_schedules_are_met():
    data = metro_study(axes=[{"field": "driving.supplement", "values": ["0%", "5%", "10%", "20%", "30%"]}])
    data["base"]["driving"] = {"strategy": "optimal", "supplement": "12.8%"}
    study = study_from_dict(data, "s.yaml")
    df = run_study(study, None, executor="serial").results()
    assert df.status.tolist() == ["ok"] * 5 and df.warnings.isna().all()
    assert df.strategy.tolist() == ["optimal"] * 5
    energy = df.energy_net_kwh.to_numpy()
    assert all(energy[1:] < energy[:-1] - 1.0)  # each step of supplement saves at least 1 kWh
    # the schedule is met: the line's running time is the fastest run's plus the supplement
    fastest = df.fastest_running_time_s[0]
    assert df.fastest_running_time_s.nunique() == 1 and df.fastest_energy_net_kwh.nunique() == 1
    for x, row in zip([0.0, 0.05, 0.1, 0.2, 0.3], df.itertuples(), strict=True):
        assert row.scheduled_running_time_s == pytest.approx(fastest * (1 + x), abs=0.05)
        assert abs(row.running_time_s - row.scheduled_running_time_s) <= SCHEDULE_TOLERANCE_S
        assert 0 <= row.schedule_deviation_s <= SCHEDULE_TOLERANCE_S
        assert row.energy_saved_kwh == pytest.approx(row.fastest_energy_net_kwh - row.energy_net_kwh)
    # 0 %: the optimiser's fastest run (its own section solver, within 0.1 % of run_fastest's energy)
    assert df.energy_saved_kwh[0] == pytest.approx(0.0, abs=0.1)
    assert df.energy_saved_percent[4] > 40


def test_rows_are_what_trainsim_run_computes(tmp_path):
    # the example scenario itself (optimal, +12.8 %, 10 m steps) as the base
    study = study_from_dict(
        {
            "schema": "trainsim/study",
            "version": 1,
            "name": "eco",
            "base": str(METRO / "scenario_eco.yaml"),
            "axes": [
                {"field": "driving.strategy", "values": ["optimal", "lesov", "fastest"]},
                {"field": "driving.supplement", "values": ["12.8%", "25%"]},
            ],
        },
        "eco.yaml",
    )
    df = run_study(study, None, executor="serial").results()
    assert (df.status == "ok").all()
    eco = trainsim.load_scenario(METRO / "scenario_eco.yaml")
    for k, row in df.iterrows():
        strategy, supplement = row["driving.strategy"], row["driving.supplement"]
        scenario = trainsim.load_scenario(
            _scenario_file(tmp_path, f"s{k}", {"strategy": strategy, "supplement": supplement})
        )
        result = trainsim.run(scenario)
        assert row.strategy == strategy
        assert row.running_time_s == result.running_time_s
        assert row.energy_net_kwh == result.energy_kwh.net
        assert row.energy_traction_kwh == result.energy_kwh.traction
        assert [s["energy_net_kwh"] for s in row.sections] == [s.energy_kwh.net for s in result.sections]
        if strategy == "fastest":
            assert row.energy_saved_kwh == 0
            continue
        opt = optimize(scenario.train, scenario.route, scenario.timetable, strategy, scenario.settings)
        assert row.schedule_deviation_s == max(abs(d) for d in opt.schedule_deviation_s)
        assert row.scheduled_running_time_s == pytest.approx(sum(opt.scheduled_running_time_s), rel=1e-12)
        assert row.energy_saved_kwh == opt.energy_saved_kwh
        assert row.fastest_energy_net_kwh == opt.fastest.energy_kwh.net
    # the base run itself (optimal, 12.8 %) is the example scenario's run
    assert df.energy_net_kwh[0] == trainsim.run(eco).energy_kwh.net
    # a fastest run with a supplement is early by the supplement (shared as optimize's fastest strategy)
    fastest = df[df.strategy == "fastest"]
    assert fastest.schedule_deviation_s.iloc[1] > fastest.schedule_deviation_s.iloc[0] > 5


def test_timetable_files_are_read_once_by_the_study(tmp_path):
    scenarios, studies = tmp_path / "scenarios", tmp_path / "studies"
    scenarios.mkdir()
    studies.mkdir()

    def timetable(path, times):
        sections = [{"running_time_s": t} for t in times]
        path.write_text(yaml.safe_dump({"schema": "trainsim/timetable", "version": 1, "sections": sections}))

    timetable(scenarios / "base_tt.yaml", [100, 110, 110])  # relative to the base scenario
    timetable(studies / "slow.yaml", [110, 120, 120])  # relative to the study
    timetable(studies / "base_tt.yaml", [100, 110, 110])
    base = _scenario_file(scenarios, "base", {"strategy": "optimal", "timetable": "base_tt.yaml"})
    data = {
        "schema": "trainsim/study",
        "version": 1,
        "name": "timetables",
        "base": base,
        "axes": [
            {"field": "driving.timetable", "values": ["base_tt.yaml", "slow.yaml", "missing.yaml"]},
            {"field": "stops", "values": [["S1", "S2", "S3", "S4"], ["S1", "S3", "S4"]]},
        ],
    }
    (studies / "study.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    study = load_study(studies / "study.yaml")
    fingerprint = study.fingerprint
    # the workers get the timetables with the study: nothing is read from files while it runs
    timetable(studies / "base_tt.yaml", [105, 110, 110])  # the axis's 'base_tt.yaml' is this one
    study = load_study(studies / "study.yaml")
    assert study.fingerprint != fingerprint  # a timetable's content is part of the study
    for name in ("base_tt.yaml", "slow.yaml"):
        (studies / name).rename(studies / f"{name}.moved")
    df = run_study(study, None, executor="serial").results()
    assert df.status.tolist() == ["ok", "failed", "ok", "failed", "failed", "failed"]
    # three sections' schedules on a route stopping twice: a failure row, not a stopped study
    assert "run 1, field 'driving.timetable': one schedule per section is needed (got 3)" in df.error[1]
    assert "run 4, field 'driving.timetable': timetable missing.yaml: file not found" in df.error[4]
    for k, name in ((0, "base_tt.yaml"), (2, "slow.yaml")):
        (studies / f"{name}.moved").rename(scenarios / f"{k}_{name}")
        scenario = trainsim.load_scenario(
            _scenario_file(scenarios, f"s{k}", {"strategy": "optimal", "timetable": f"{k}_{name}"})
        )
        assert df.energy_net_kwh[k] == trainsim.run(scenario).energy_kwh.net
        sections = [s["running_time_s"] for s in df.sections[k]]
        times = [105, 110, 110] if k == 0 else [110, 120, 120]
        assert sections == pytest.approx(times, abs=SCHEDULE_TOLERANCE_S)
        assert df.scheduled_running_time_s[k] == sum(times)


def test_a_schedule_that_cannot_be_met_is_a_warning(write_study, tmp_path):
    tight = {"schema": "trainsim/timetable", "version": 1, "sections": [{"running_time_s": 60}] * 3}
    (tmp_path / "tight.yaml").write_text(yaml.safe_dump(tight))
    data = metro_study(axes=[{"field": "driving.strategy", "values": ["optimal", "lesov"]}])
    data["base"]["driving"] = {"timetable": "tight.yaml"}  # relative to the study file
    df = run_study(load_study(write_study(data)), None, executor="serial").results()
    # as trainsim.run: the run is the fastest run, status ok; the optimiser's warning says by how much
    assert df.status.tolist() == ["ok", "ok"]
    assert all("cannot be met" in w for w in df.warnings)
    assert (df.schedule_deviation_s > 20).all() and (df.scheduled_running_time_s == 180).all()


def test_bad_driving_values_are_failure_rows():
    df = run_study(study_from_dict(metro_study(**SWEEP), "s.yaml"), None, executor="serial").results()
    assert df.status.tolist() == ["ok", "ok", "failed", "ok", "ok", "failed", "failed", "failed", "failed"]
    assert df.error[2] == (
        "run 2, field 'driving.strategy': not an allowed value (got 'bogus'); "
        "allowed: fastest, optimal, lesov or reference."
    )
    assert df.error[6] == (
        "run 6, field 'driving.supplement': cannot read the supplement (got 'ten'); allowed: \"10%\" or \"30 s\"."
    )
    assert set(df.error_type.dropna()) == {"InputError"}
    assert df.strategy.tolist()[:2] == ["optimal", "lesov"] and pd.isna(df.strategy[2])
    # a strategy without a schedule (no supplement in the base), as the scenario reader says
    df = run_study(
        study_from_dict(
            metro_study(axes=[{"field": "driving.strategy", "values": ["fastest", "lesov"]}]), "s"
        ),
        None,
        executor="serial",
    ).results()
    assert df.status.tolist() == ["ok", "failed"]
    assert (
        "run 1, field 'driving': an energy-efficient strategy needs a supplement or a timetable"
        in df.error[1]
    )
    assert df.schedule_deviation_s.isna()[0] and df.energy_saved_kwh[0] == 0  # a fastest run, no schedule


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            {"axes": [{"field": "driving.suplement", "values": ["5%"]}]},
            "did you mean 'supplement'",
        ),
        ({"axes": [{"field": "driving.supplement", "values": [1.1], "relative": True}]}, "scales a number"),
        (
            {
                "axes": [
                    {"field": "model", "values": ["multi_point"]},
                    {"field": "driving.supplement", "values": ["5%"]},
                ]
            },
            "the multi-point model is not driven by a 'driving' block",
        ),
        (
            {"axes": [{"field": "multi_point.couplers.slack_m", "values": [0.01]}]},
            "is a setting of the multi-point model",
        ),
    ],
)
def test_bad_driving_paths_are_study_errors(extra, message):
    with pytest.raises(InputError) as info:
        study_from_dict(metro_study(**extra), "study.yaml")
    assert message in str(info.value) and str(info.value).startswith("study.yaml")


def test_model_and_multi_point_block_are_read_as_the_scenario_reader_does(tmp_path):
    # multi-point studies: tests/batch/test_multipoint.py
    data = metro_study()
    data["base"]["model"] = "multi_point"
    assert study_from_dict(data, "s.yaml").multi_point
    data["base"]["model"] = "single_point"
    study = study_from_dict(data, "s.yaml")
    assert len(study.expand()) == 1 and not study.multi_point
    data["base"]["model"] = "multipoint"
    with pytest.raises(InputError, match=r"field 'model': unknown model"):
        study_from_dict(data, "s.yaml")
    del data["base"]["model"]
    data["base"]["multi_point"] = {}
    with pytest.raises(
        InputError, match=r"field 'multi_point': a 'multi_point' block needs 'model: multi_point'"
    ):
        study_from_dict(data, "s.yaml")


def test_explicit_runs_merge_their_driving_over_the_base():
    base = {**metro_study()["base"], "driving": {"strategy": "optimal", "supplement": "10%"}}
    study = study_from_dict(
        metro_study(
            base=base,
            runs=[
                {"name": "base"},
                {"name": "more time", "driving": {"supplement": "20%"}},
                {"name": "lesov", "driving": {"strategy": "lesov"}},
                {"name": "fastest", "driving": {"strategy": "fastest"}},
                {"name": "set", "set": {"driving.supplement": "30 s"}},
            ],
        ),
        "s.yaml",
    )
    df = run_study(study, None, executor="serial").results().set_index("run")
    assert (df.status == "ok").all()
    assert df.strategy.tolist() == ["optimal", "optimal", "lesov", "fastest", "optimal"]
    fastest = df.fastest_running_time_s["base"]
    assert df.running_time_s["base"] == pytest.approx(1.1 * fastest, abs=0.1)
    assert df.running_time_s["more time"] == pytest.approx(1.2 * fastest, abs=0.1)
    assert df.running_time_s["lesov"] == pytest.approx(1.1 * fastest, abs=0.2)
    assert df.running_time_s["set"] == pytest.approx(fastest + 30, abs=0.1)
    # the fastest run keeps the schedule of the base: it is early by the supplement
    assert df.running_time_s["fastest"] == fastest
    assert df.scheduled_running_time_s["fastest"] == pytest.approx(1.1 * fastest)
    assert df.energy_net_kwh["more time"] < df.energy_net_kwh["base"] < df.energy_net_kwh["fastest"]


def test_a_supplement_sweep_rebuilds_only_the_driving():
    study = study_from_dict(metro_study(**SWEEP), "s.yaml")
    expansion = study.expand()
    state = WorkerState(Payload(study.fingerprint, study.name, tuple(e.data for e in study.entries)))
    train, route, settings = state.entry(0)
    for i in range(len(expansion)):
        task = expansion.task(i)
        try:
            t, r, s, driving = state.scenario(task)
        except InputError:
            continue
        assert t is train and r is route and s is settings  # the same objects: nothing rebuilt
        assert driving.strategy == task[3][1][1]


def test_studies_without_driving_keep_their_columns():
    df = run_study(
        study_from_dict(metro_study(axes=[{"field": "dwell_s.S2", "values": [10, 20]}]), "s"),
        None,
        executor="serial",
    ).results()
    assert not set(DRIVING_COLUMNS) & set(df.columns)


@pytest.fixture(scope="module")
def sweep_serial():
    study = study_from_dict(metro_study(**SWEEP), "s.yaml")
    table = run_study(study, None, executor="serial").table()
    assert table.column("status").to_pylist().count("failed") == 5
    return study, table


def test_identical_results_serially_and_with_processes(sweep_serial, tmp_path):
    study, serial = sweep_serial
    processes = run_study(study, tmp_path / "p", executor="processes", workers=2, chunk_size=2)
    assert processes.chunks == 5
    assert read_results(tmp_path / "p", as_table=True).equals(serial)


def test_identical_results_on_dask(sweep_serial, dask_cluster, tmp_path):
    study, serial = sweep_serial
    on_dask = run_study(study, tmp_path / "d", scheduler=dask_cluster.scheduler_address, chunk_size=2)
    assert on_dask.executor == "dask" and on_dask.computed == 9
    assert read_results(tmp_path / "d", as_table=True).equals(serial)


def test_report_plots_energy_against_the_supplement(write_study, tmp_path):
    import typer

    from trainsim.cli.batch import batch

    app = typer.Typer()
    app.command()(batch)
    study = write_study(metro_study(**SWEEP))
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app, [str(study), "--out", str(out), "--executor", "serial", "--report", "--no-progress"]
    )
    assert result.exit_code == 0, result.output
    report = out / "report"
    assert (report / "by_driving_supplement.png").is_file()
    text = (report / "report.md").read_text()
    assert "against driving.supplement [%], one line per driving.strategy" in text
    assert "| energy_saved_kwh | 4 |" in text and "cannot read the supplement" in text
    table = pd.read_csv(report / "energy_net_kwh_by_driving_supplement.csv", index_col=0)
    assert list(table.index) == [5.0, 20.0] and list(table.columns) == ["lesov", "optimal"]
    assert (table.loc[20.0] < table.loc[5.0]).all() and (table["optimal"] < table["lesov"]).all()
    stats = pd.read_csv(report / "statistics.csv").set_index("figure")
    assert stats.loc["schedule_deviation_s", "max"] <= SCHEDULE_TOLERANCE_S


@pytest.mark.slow
def test_example_driving_study_runs():
    from batchcases import REPO

    study = load_study(REPO / "examples" / "studies" / "metro_eco_driving.yaml")
    df = run_study(study, None, executor="processes", workers=2).results()
    assert (df.status == "ok").all()
    for strategy in ("optimal", "lesov"):
        energy = df[df.strategy == strategy].energy_net_kwh.to_numpy()
        assert all(energy[1:] < energy[:-1])
    # the optimal strategy needs the least energy at every supplement
    by = df.pivot_table(index="driving.supplement", columns="strategy", values="energy_net_kwh")
    assert (by["optimal"] <= by["lesov"] + 1e-9).all()
    driven = by.drop(index="0%")  # at 0 % every strategy drives the fastest run
    assert (driven["lesov"] < driven["fastest"] - 1.0).all()
