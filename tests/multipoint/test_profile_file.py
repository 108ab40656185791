"""The speed-profile file of ``strategy: follow`` is read within bounds (issue 13): rows, columns and
size bounded, every number finite and in range, errors naming the file, the line and the column."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.io import documents
from trainsim.io import multipoint_spec as mps
from trainsim.sim.codes import REGIME_NAMES

GOOD = "position_m,speed_kmh,time_s,regime\n0,0,0,{a}\n100,36,20,{b}\n200,0,40,{c}\n"


def _write(tmp_path, text: str):
    path = tmp_path / "profile.csv"
    path.write_text(text)
    return path


def _good(tmp_path):
    return _write(tmp_path, GOOD.format(a=REGIME_NAMES[0], b=REGIME_NAMES[1], c=REGIME_NAMES[0]))


def test_a_valid_profile_in_si(tmp_path):
    profile = mps.read_profile(_good(tmp_path), "scenario.yaml")
    np.testing.assert_array_equal(profile.position_m, [0, 100, 200])
    np.testing.assert_allclose(profile.speed_mps, [0, 10, 0])  # 36 km/h is 10 m/s
    np.testing.assert_array_equal(profile.time_s, [0, 20, 40])
    np.testing.assert_array_equal(profile.regime, [0, 1, 0])


@pytest.mark.parametrize(
    ("row", "column", "reason"),
    [
        ("100,nan,20", "speed_kmh", "not a number"),
        ("100,inf,20", "speed_kmh", "not a number"),
        ('100,"1,500",20', "speed_kmh", "not a number"),
        ("100,1_0,20", "speed_kmh", "not a number"),
        ("100,,20", "speed_kmh", "not a number"),
        ("100,1e308,20", "speed_kmh", "out of range"),
        ("100,-5,20", "speed_kmh", "out of range"),
        ("1e308,36,20", "position_m", "out of range"),
        ("100,36,1e300", "time_s", "out of range"),
        ("100,36", "time_s", "not a number"),
    ],
)
def test_bad_cells_name_file_line_and_column(tmp_path, row, column, reason):
    path = _write(tmp_path, f"position_m,speed_kmh,time_s\n0,0,0\n{row}\n200,0,400\n")
    with pytest.raises(InputError) as info:
        mps.read_profile(path, "scenario.yaml")
    problem = info.value.problems[0]
    assert (problem.file, problem.line, problem.field) == (str(path), 3, column)
    assert problem.reason == reason
    assert problem.allowed


def test_positions_and_times_must_not_decrease(tmp_path):
    path = _write(tmp_path, "position_m,speed_mps\n0,0\n100,10\n90,0\n")
    with pytest.raises(InputError, match="position_m decreases") as info:
        mps.read_profile(path, "scenario.yaml")
    assert info.value.field == "position_m"
    path = _write(tmp_path, "position_m,speed_mps,time_s\n0,0,0\n100,10,20\n200,0,10\n")
    with pytest.raises(InputError, match="time_s decreases"):
        mps.read_profile(path, "scenario.yaml")


def test_rows_columns_and_size_are_bounded(tmp_path, monkeypatch):
    path = _good(tmp_path)
    monkeypatch.setattr(mps, "MAX_PROFILE_ROWS", 2)
    with pytest.raises(InputError, match="too many rows") as info:
        mps.read_profile(path, "scenario.yaml")
    assert info.value.line == 4
    monkeypatch.undo()
    wide = _write(tmp_path, ",".join(["position_m", "speed_kmh"] + [f"c{k}" for k in range(300)]) + "\n")
    with pytest.raises(InputError, match="too many columns"):
        mps.read_profile(wide, "scenario.yaml")
    monkeypatch.setattr(documents, "LIMITS", dataclasses.replace(documents.LIMITS, max_bytes=20))
    with pytest.raises(InputError, match="too large"):
        mps.read_profile(_good(tmp_path), "scenario.yaml")


def test_missing_columns_unknown_regimes_and_missing_files(tmp_path):
    with pytest.raises(InputError, match="needs the columns") as info:
        mps.read_profile(_write(tmp_path, "position,speed\n0,0\n"), "scenario.yaml")
    assert info.value.line == 1
    with pytest.raises(InputError, match="unknown regime") as info:
        mps.read_profile(_write(tmp_path, GOOD.format(a="warp", b="warp", c="warp")), "scenario.yaml")
    assert (info.value.line, info.value.field) == (2, "regime")
    with pytest.raises(InputError, match="at least two rows"):
        mps.read_profile(_write(tmp_path, "position_m,speed_kmh\n0,0\n"), "scenario.yaml")
    with pytest.raises(InputError, match="not found") as info:
        mps.read_profile(tmp_path / ("x" * 5000), "scenario.yaml")
    assert (info.value.file, info.value.field) == ("scenario.yaml", "multi_point.profile")
