"""Errors of study files name the study file, the field and the value (issue 13): file names the
system cannot look up, and values the model classes refuse after the reader accepted the mapping."""

from __future__ import annotations

import pytest
from batchcases import METRO, metro_study

from trainsim.batch import load_study
from trainsim.errors import InputError

HEADER = {"schema": "trainsim/study", "version": 1, "name": "errors"}


@pytest.mark.parametrize("field", ["base", "runs[0].train"])
def test_a_file_name_too_long_for_the_system_is_an_input_error(write_study, field):
    long_name = "a" * 5000 + ".yaml"  # Path.exists raises OSError (ENAMETOOLONG) on this
    if field == "base":
        data = {**HEADER, "base": long_name}
    else:
        data = {**HEADER, "base": str(METRO / "scenario.yaml"), "runs": [{"name": "r", "train": long_name}]}
    path = write_study(data)
    with pytest.raises(InputError) as info:
        load_study(path)
    problem = info.value.problems[0]
    assert problem.file == str(path)
    assert problem.field == field
    assert problem.value.endswith(long_name)
    assert "255" in problem.allowed
    assert len(str(info.value)) < 400  # the 5,000-character name is cut


def test_a_value_refused_by_the_model_names_the_study_file_and_the_run(write_study):
    data = {
        **HEADER,
        "base": str(METRO / "scenario.yaml"),
        "runs": [{"name": "late", "dwell_s": {"S3": 1e308}}],
    }
    path = write_study(data)
    with pytest.raises(InputError) as info:
        load_study(path)
    problem = info.value.problems[0]
    assert problem.file == str(path)
    assert problem.field.startswith("runs[0] (late): ")
    assert "S3" in problem.field
    assert problem.value == 1e308
    assert problem.allowed
    assert str(path) in str(info.value)


def test_a_value_refused_by_the_model_in_an_inline_base_names_the_study_file(write_study):
    data = metro_study()
    data["base"]["dwell_s"] = {"S3": 1e308}
    path = write_study(data)
    with pytest.raises(InputError) as info:
        load_study(path)
    problem = info.value.problems[0]
    assert problem.file == str(path)
    assert problem.field.startswith("base: ")
