"""A bad ETCS braking value in an operation file is named alone, with the range allowed (issue 17)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.operations.etcs import EtcsTrainData, StepFunction

ROOT = Path(__file__).resolve().parents[2]


def _file(tmp_path: Path, **etcs: object) -> Path:
    spec = {
        "schema": "trainsim/operation",
        "version": 1,
        "name": "etcs messages",
        "line": {
            "route": str(ROOT / "examples/metro_b/route.yaml"),
            "layout": "double_track",
            "block_length_m": 400,
            "stations": [{"name": "S1"}, {"name": "S2"}, {"name": "S3"}],
            "signalling": {
                "system": "etcs_l2",
                "overlap_m": 50,
                "etcs": {
                    "a_brake_emergency_mps2": 1.0,
                    "a_brake_service_mps2": 0.7,
                    "t_brake_emergency_s": 1.5,
                    "t_brake_service_s": 2.0,
                    "t_traction_cut_off_s": 1.0,
                    **etcs,
                },
            },
        },
        "trains": [
            {
                "id": "L",
                "train": str(ROOT / "examples/metro_b/train.yaml"),
                "direction": "up",
                "origin": "S1",
                "destination": "S3",
                "departure": "07:00:00",
            }
        ],
    }
    p = tmp_path / "op.yaml"
    p.write_text(yaml.safe_dump(spec))
    return p


@pytest.mark.parametrize(
    ("kwet", "where"),
    [
        (1.5, None),
        ({"upper_limits_kmh": [50], "values": [0.9, 1.5]}, "step 2 of 2: speeds above 13.89 m/s (50 km/h)"),
    ],
)
def test_a_bad_kwet_is_named_alone_with_its_range(tmp_path: Path, kwet, where) -> None:
    p = _file(tmp_path, kwet_rst=kwet)
    with pytest.raises(InputError) as e:
        read_operation(p)
    (pr,) = e.value.problems
    assert pr.field == "line.signalling.etcs.kwet_rst" and pr.file == str(p)
    assert pr.value == 1.5 and pr.allowed == "0 < Kwet_rst <= 1"
    text = str(e.value)
    assert "got 1.5)" in text and "(1.5,)" not in text and "0.9" not in text
    assert (where in text) if where else ("step" not in text)


def test_each_step_function_check_names_the_first_bad_value() -> None:
    base = {
        "a_brake_emergency": 1.0,
        "a_brake_service": 0.7,
        "t_brake_emergency_s": 1.5,
        "t_brake_service_s": 2.0,
        "t_traction_cut_off_s": 1.0,
        "length_m": 100.0,
        "max_speed_mps": 30.0,
    }
    cases = [
        ("a_brake_service", StepFunction((0.7, 0.0, -1.0), (10.0, 20.0)), 0.0, "step 2 of 3: speeds 10 m/s"),
        ("kdry_rst", {9: StepFunction((0.9, 2.0), (10.0,))}, 2.0, "EBCL 9, step 2 of 2: speeds above 10 m/s"),
        ("kdry_rst", 0.0, 0.0, None),
        ("kn_plus", StepFunction((11.0, 0.1), (10.0,)), 11.0, "step 1 of 2: speeds 0 m/s (0 km/h) to 10 m/s"),
    ]
    for name, value, bad, where in cases:
        with pytest.raises(InputError) as e:
            EtcsTrainData(**{**base, name: value})
        (pr,) = e.value.problems
        assert pr.field == name and pr.value == bad, (name, pr)
        assert (where in pr.reason) if where else ("step" not in pr.reason), pr.reason
