"""Diverging-switch speeds read from railML 2 (``switch/connection@maxSpeed``), railML 3
(``switchIS/leftBranch|rightBranch@branchingSpeed,@joiningSpeed`` of ``@branchCourse``) and the
spreadsheet ``switches`` table (issue 17); a bad value is an InputError naming the element and
attribute, or the sheet and cell."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.io.railml_signalling import read_signalling
from trainsim.io.spreadsheet import read_spreadsheet_signalling

ROOT = Path(__file__).resolve().parents[2]
RAILML = ROOT / "tests" / "io" / "railml_signalling"
SHEETS = ROOT / "examples" / "operations" / "sheets_double_track" / "line"


def _edited(tmp_path: Path, name: str, edits: list[tuple[str, str]]) -> Path:
    text = (RAILML / name).read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    out = tmp_path / name
    out.write_text(text)
    return out


def _speeds(read) -> dict[str, float | None]:
    return {w.name: w.diverging_speed_mps for w in read.switches}


def test_railml2_connection_max_speed(tmp_path) -> None:
    path = _edited(
        tmp_path,
        "double_track_railml2.xml",
        [
            (
                'ref="c_tr_l_b" orientation="outgoing" course="left"',
                'ref="c_tr_l_b" orientation="outgoing" course="left" maxSpeed="40"',
            )
        ],
    )
    read = read_signalling(path, ocps=["A", "B", "C"], double_track=True)
    speeds = _speeds(read)
    assert speeds["W D1"] == pytest.approx(40 * KMH)
    assert speeds["W D2"] is None  # not given: line speed


def test_railml2_bad_max_speed_names_the_element(tmp_path) -> None:
    path = _edited(
        tmp_path,
        "double_track_railml2.xml",
        [
            (
                'ref="c_tr_l_b" orientation="outgoing" course="left"',
                'ref="c_tr_l_b" orientation="outgoing" course="left" maxSpeed="-5"',
            )
        ],
    )
    with pytest.raises(InputError) as e:
        read_signalling(path, ocps=["A", "B", "C"], double_track=True)
    text = str(e.value)
    assert "maxSpeed" in text and "-5" in text


def test_railml3_branch_of_the_branch_course(tmp_path) -> None:
    path = _edited(
        tmp_path,
        "line_railml3.xml",
        [
            (
                '<switchIS id="sw1" type="ordinarySwitch">',
                '<switchIS id="sw1" type="ordinarySwitch" branchCourse="left" continueCourse="right">'
                '<leftBranch netRelationRef="nr_al" branchingSpeed="60" joiningSpeed="40"/>'
                '<rightBranch netRelationRef="nr_ab" branchingSpeed="100"/>',
            ),
            (
                # no branch course: the slower branch is the diverging one
                '<switchIS id="sw2" type="ordinarySwitch">',
                '<switchIS id="sw2" type="ordinarySwitch">'
                '<leftBranch netRelationRef="nr_lc" branchingSpeed="50"/>'
                '<rightBranch netRelationRef="nr_bc" branchingSpeed="80"/>',
            ),
        ],
    )
    speeds = _speeds(read_signalling(path, ocps=["A", "B", "C"]))
    assert speeds["W1"] == pytest.approx(40 * KMH)  # the lower of branching and joining
    assert speeds["W2"] == pytest.approx(50 * KMH)


def test_spreadsheet_switches_table_diverging_speed(tmp_path) -> None:
    folder = tmp_path / "line"
    shutil.copytree(SHEETS, folder)
    (folder / "switches.csv").write_text(
        "Name,Position (m),Clearance (m),Diverging speed (km/h)\nB1,2600,2640,40\nB2,3400,3360,\n"
    )
    speeds = _speeds(read_spreadsheet_signalling(folder))
    assert speeds == {"B1": pytest.approx(40 * KMH), "B2": None}
    (folder / "switches.csv").write_text("Name,Position (m),Diverging speed (km/h)\nB1,2600,0\n")
    with pytest.raises(InputError) as e:
        read_spreadsheet_signalling(folder)
    assert "diverging speed" in str(e.value).lower() and "switches" in str(e.value)
