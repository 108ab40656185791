"""``trainsim batch`` (the command function the CLI registers) and its report."""

from __future__ import annotations

import typer
from batchcases import MIXED, metro_study
from typer.testing import CliRunner

from trainsim.cli.batch import batch

app = typer.Typer()
app.command()(batch)
runner = CliRunner()


def test_batch_runs_resumes_and_reports(write_study, tmp_path):
    study = write_study(metro_study(**MIXED))
    out = tmp_path / "out"
    result = runner.invoke(app, [str(study), "--out", str(out), "--executor", "serial", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "18 runs (18 computed, 0 already done), 9 failed, 0 stalled" in result.output
    result = runner.invoke(app, [str(study), "--out", str(out), "--report", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "(0 computed, 18 already done)" in result.output
    report = out / "report"
    for name in ("report.md", "statistics.csv", "failures.csv", "by_train_formation_load_t.png"):
        assert (report / name).is_file(), name
    text = (report / "report.md").read_text()
    assert "| ok | 9 |" in text and "| failed | 9 |" in text and "out of range (got 1.2)" in text
    assert len((report / "failures.csv").read_text().splitlines()) == 10


def test_dry_run(write_study, tmp_path):
    study = write_study(metro_study(**MIXED))
    result = runner.invoke(app, [str(study), "--out", str(tmp_path / "o"), "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "test study: 18 runs, 0 already in" in result.output
    assert "train.formation[0].mass_t:factor" in result.output
    assert not (tmp_path / "o").exists()


def test_user_errors_exit_2(write_study, tmp_path):
    bad = write_study(metro_study(axes=[{"field": "train.formation[9].load_t", "values": [1]}]))
    result = runner.invoke(app, [str(bad), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert "error:" in result.output and "no item [9]" in result.output
    result = runner.invoke(app, [str(tmp_path / "missing.yaml")])
    assert result.exit_code == 2 and "file not found" in result.output
    result = runner.invoke(app, [str(bad), "--scheduler", "tcp://127.0.0.1:1", "--executor", "serial"])
    assert result.exit_code == 2 and "--scheduler runs on Dask" in result.output


def test_timetable_report(write_study, tmp_path):
    study = write_study(
        metro_study(
            runs=[
                {"name": "all stops", "departures": {"first": "07:00", "last": "08:00", "every_min": 15}},
                {"name": "express", "stops": ["S1", "S3", "S4"], "departures": ["07:05", "07:35"]},
            ]
        )
    )
    out = tmp_path / "out"
    result = runner.invoke(app, [str(study), "--out", str(out), "--executor", "serial", "--report"])
    assert result.exit_code == 0, result.output
    assert (out / "report" / "timetable.png").is_file()
    text = (out / "report" / "report.md").read_text()
    assert "first departure 07:00:00" in text and "| express | 2 |" in text
