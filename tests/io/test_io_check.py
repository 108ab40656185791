"""``trainsim check`` (io.loader.check_file) reads what ``run``, ``optimize`` and ``multipoint`` read:
every TTOBench file, both heavy-haul scenarios, a CSV folder; and says what it read."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import trainsim
from trainsim.io import loader
from trainsim.io.loader import CheckReport, check_file

REPO = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("TRAINSIM_SHARED", REPO.parent / "shared"))
TTOBENCH = SHARED / "data" / "ttobench"


def _ttobench(kind: str) -> list[Path]:
    files = sorted((TTOBENCH / kind).glob("*.json"))
    if not files:
        pytest.skip(f"TTOBench data not found ({TTOBENCH / kind})")
    return files


@pytest.mark.parametrize("kind", ["trains", "tracks", "journeys"])
def test_every_ttobench_file_checks_as_run_reads_it(kind: str) -> None:
    for path in _ttobench(kind):
        report = check_file(path)
        assert report.format.startswith("ttobench/"), path
        if kind == "trains":
            train = trainsim.load_train(path)
            assert report.kind == "train" and report.name == train.name
            assert report.figures["mass"] == f"{train.mass_kg / 1000:.1f} t"
        elif kind == "tracks":
            route = trainsim.load_route(path)
            assert report.kind == "route" and report.figures["length"].startswith(f"{route.length_m:.2f} m")
        else:
            assert report.kind == "timetable"
            assert int(report.figures["timing points"].split()[0]) >= 2


@pytest.mark.parametrize("name", ["scenario_dp.yaml", "scenario_head.yaml"])
def test_heavy_haul_scenarios_check(name: str) -> None:
    path = REPO / "examples" / "heavy_haul" / name
    report = check_file(path)
    scenario = trainsim.load_scenario(path)
    assert report.kind == "scenario" and report.name == scenario.name
    assert report.figures["model"] == "multi_point"
    assert report.figures["train mass"] == f"{scenario.train.mass_kg / 1000:.1f} t"


def test_csv_folder_checks() -> None:
    report = check_file(REPO / "tests" / "interchange" / "data" / "testline_csv")
    assert report.kind == "train and route" and report.format == "spreadsheet (CSV folder)"
    assert report.figures["train mass"] == "260.0 t"
    assert "testline_csv" in report.path


def test_checkers_of_higher_layers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(loader, "CHECKERS", {})
    path = tmp_path / "study.yaml"
    path.write_text("schema: trainsim/study\nversion: 1\n", encoding="utf-8")
    with pytest.raises(trainsim.InputError, match="unknown file format"):
        check_file(path)
    loader.register_checker(
        "trainsim/study", lambda p: CheckReport(str(p), "study", "trainsim/study v1", p.stem)
    )
    assert check_file(path).kind == "study"
