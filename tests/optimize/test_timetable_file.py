"""The timetable file is read in io, within the document bounds, and its times are strict numbers in
range (issue 13: a timetable alias bomb ran out of memory; ``running_time_s: true`` was 1 s)."""

from __future__ import annotations

import time

import pytest

from trainsim.errors import InputError
from trainsim.io.timetable_file import read_timetable_yaml

HEAD = "schema: trainsim/timetable\nversion: 1\n"


def _write(tmp_path, text: str):
    path = tmp_path / "timetable.yaml"
    path.write_text(HEAD + text)
    return path


def test_a_valid_timetable_reads_as_before(tmp_path):
    path = _write(
        tmp_path,
        "sections:\n  - {running_time_s: 110}\n  - {supplement: '8%'}\n  - {departure_s: 100, arrival_s: 205}\n",
    )
    tt = read_timetable_yaml(path, n_sections=3)
    assert tt.sections[0].running_time_s == 110
    assert tt.sections[1].supplement_fraction == pytest.approx(0.08)
    assert tt.sections[2].running_time_s == 105
    assert tt.source == str(path)
    line = read_timetable_yaml(_write(tmp_path, "supplement: 2 min\n"))
    assert line.line.supplement_s == 120


def test_an_alias_bomb_is_refused_at_once(tmp_path):
    bomb = ['a: &a ["x","x","x","x","x","x","x","x","x","x"]']
    for k in range(1, 9):
        bomb.append(f"{chr(97 + k)}: &{chr(97 + k)} [" + ",".join([f"*{chr(96 + k)}"] * 10) + "]")
    path = _write(tmp_path, "\n".join(bomb) + "\nsupplement: '5%'\n")
    t0 = time.perf_counter()
    with pytest.raises(InputError) as info:
        read_timetable_yaml(path)
    assert time.perf_counter() - t0 < 2.0
    assert info.value.file == str(path)
    assert "alias" in str(info.value)


@pytest.mark.parametrize(
    ("row", "field"),
    [
        ("{running_time_s: true}", "sections[0].running_time_s"),
        ("{running_time_s: '110'}", "sections[0].running_time_s"),
        ("{running_time_s: .nan}", "sections[0].running_time_s"),
        ("{running_time_s: .inf}", "sections[0].running_time_s"),
        ("{running_time_s: 1e308}", "sections[0].running_time_s"),
        ("{running_time_s: 0}", "sections[0].running_time_s"),
        ("{departure_s: 100, arrival_s: .nan}", "sections[0].arrival_s"),
        ("{departure_s: false, arrival_s: 200}", "sections[0].departure_s"),
        ("{departure_s: 300, arrival_s: 200}", "sections[0].arrival_s"),
        ("{supplement: 1e400 s}", "sections[0].supplement"),
        ("{supplement: 10}", "sections[0].supplement"),
    ],
)
def test_bad_times_are_refused_naming_file_field_and_allowed(tmp_path, row, field):
    path = _write(tmp_path, f"sections:\n  - {row}\n")
    with pytest.raises(InputError) as info:
        read_timetable_yaml(path)
    problem = info.value.problems[0]
    assert (problem.file, problem.field) == (str(path), field)
    assert problem.allowed


def test_unknown_fields_and_duplicate_keys_are_refused(tmp_path):
    with pytest.raises(InputError) as info:
        read_timetable_yaml(_write(tmp_path, "supplment: '5%'\n"))
    assert info.value.field == "supplment"
    assert "supplement" in info.value.allowed
    with pytest.raises(InputError, match="duplicate"):
        read_timetable_yaml(_write(tmp_path, "supplement: '5%'\nsupplement: '6%'\n"))
