"""TTOBench files are read strictly: every malformed value is an InputError naming the file, the
field, the value and what is allowed; ETCS data and tunnel resistance are read and kept."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from trainsim.constants import KMH, TTOBENCH_GRAVITY
from trainsim.errors import InputError
from trainsim.io.ttobench import read_ttobench_journey, read_ttobench_track, read_ttobench_train

TTOBENCH = Path(__file__).resolve().parents[3] / "shared" / "data" / "ttobench"

TRAIN = {
    "metadata": {"id": "T", "library version": "TTOBench v1.5"},
    "mass": {"unit": "kg", "value": 100000.0},
    "rho": {"unit": "%", "value": 6},
    "max traction power": {"unit": "kW", "value": 2000.0},
    "max reg braking power": {"unit": "kW", "value": 2000.0},
    "max traction force": {"unit": "kN", "value": 150.0},
    "max reg braking force": {"unit": "kN", "value": 150.0},
    "max pn braking force": {"unit": "kN", "value": 300.0},
    "max deceleration": {"unit": "m/s^2", "value": 1.0},
    "max speed": {"unit": "km/h", "value": 140},
    "rolling resistance r0": {"unit": "kN", "value": 2.0},
    "rolling resistance r1": {"unit": "kN/(km/h)", "value": 0.01},
    "rolling resistance r2": {"unit": "kN/(km/h)^2", "value": 0.0005},
    "efficiency traction": {"unit": "%", "value": 90.0},
    "efficiency reg brake": {"unit": "%", "value": 80.0},
    "tunnel resistance": {
        "units": {"cross section": "m^2", "coefficient": "kN/(km/h)^2"},
        "values": [[24, 0.001], [40, 0.0005]],
    },
    "ETCS braking data": {
        "A_brake_emergency": {"units": {"velocity": "m/s", "deceleration": "m/s^2"}, "values": [[0, 0.9]]},
        "A_brake_service": {"units": {"velocity": "m/s", "deceleration": "m/s^2"}, "values": [[0, 0.5]]},
        "K_dry_rst": {"unit": "-", "value": 0.8},
        "K_wet_rst": {"unit": "-", "value": 0.9},
        "T_traction": {"unit": "s", "value": 1},
        "T_be": {"unit": "s", "value": 4},
        "T_bs": {"unit": "s", "value": 3},
        "v_uncertainty": {"unit": "%", "value": 2.98},
    },
}

TRACK = {
    "metadata": {"id": "L", "library version": "TTOBench v1.5"},
    "stops": {"unit": "m", "values": [0, 5000]},
    "speed limits": {"units": {"position": "m", "velocity": "km/h"}, "values": [[0, 100], [3000, 80]]},
    "gradients": {"units": {"position": "m", "slope": "permil"}, "values": [[0, 0], [1000, 5.0]]},
    "curvatures": {
        "units": {"position": "m", "radius at start": "m", "radius at end": "m"},
        "values": [[0, "infinity", "infinity"], [2000, -800, -800], [2500, "infinity", "infinity"]],
    },
    "tunnels": {
        "units": {"position": "m", "length": "m", "cross section": "m^2"},
        "values": [[4000, 500, 40]],
    },
    "ETCS braking data": {"M_NVAVADH": {"unit": "-", "value": 0}, "Kt_int": {"unit": "-", "value": 1.15}},
}

JOURNEY = {
    "metadata": {"id": "L_Journey", "associated track": "L", "library version": "TTOBench v1.5"},
    "timing points": {
        "units": {
            "position": "m",
            "lower time constraint": "s",
            "upper time constraint": "s",
            "lower speed constraint": "km/h",
            "upper speed constraint": "km/h",
        },
        "values": [[0, 0, 0, 0, 0], [2500, 100, 150, 10, None], [5000, 300, 330, 0, 0]],
    },
}


def write(tmp_path: Path, data: dict, name: str = "f.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data, allow_nan=True), encoding="utf-8")
    return path


def names_field(err: InputError, field: str) -> bool:
    """The error names the field, or (NaN / Infinity, refused when the JSON is parsed) the line."""
    if err.field == field:
        return True
    return err.field is None and err.line is not None and ("NaN" in str(err) or "Infinity" in str(err))


def mutated(base: dict, keys: tuple, value) -> dict:
    data = copy.deepcopy(base)
    target = data
    for k in keys[:-1]:
        target = target[k]
    target[keys[-1]] = value
    return data


def test_well_formed_files_are_read_with_etcs_tunnels_and_ttobench_gravity(tmp_path):
    tt = read_ttobench_train(write(tmp_path, TRAIN))
    assert tt.etcs is not None and tt.etcs.values["T_be"] == 4.0
    assert tt.etcs.values["v_uncertainty"] == pytest.approx(0.0298)
    assert tt.etcs.curves["A_brake_service"] == ((0.0, 0.5),)
    assert tt.tunnel_drag[40.0] == pytest.approx(0.0005 * 1000 / KMH**2)
    route = read_ttobench_track(write(tmp_path, TRACK, "t.json"), tt)
    assert route.gravity_mps2 == TTOBENCH_GRAVITY
    assert len(route.curves) == 1 and route.curves[0].radius_m == pytest.approx(800.0)
    assert route.tunnels[0].extra_drag_n_s2_per_m2 == pytest.approx(0.0005 * 1000 / KMH**2)
    journey = read_ttobench_journey(write(tmp_path, JOURNEY, "j.json"))
    assert journey.points[1].min_speed_mps == pytest.approx(10 * KMH)
    assert journey.points[1].max_speed_mps is None
    assert [p.is_stop for p in journey.points] == [True, False, True]


@pytest.mark.parametrize(
    ("keys", "value", "field"),
    [
        (("mass",), None, "mass"),
        (("mass", "value"), None, "mass.value"),
        (("mass", "value"), "100 t", "mass.value"),
        (("mass", "value"), {"a": 1}, "mass.value"),
        (("mass", "value"), float("nan"), "mass.value"),
        (("mass", "value"), float("inf"), "mass.value"),
        (("mass", "value"), True, "mass.value"),
        (("mass", "value"), -5.0, "mass.value"),
        (("mass", "unit"), "stone", "mass.unit"),
        (("metadata",), None, "metadata"),
        (("metadata", "id"), 5, "metadata.id"),
        (("rolling resistance r1", "value"), [1], "rolling resistance r1.value"),
        (("efficiency traction", "value"), 120.0, "efficiency traction"),
        (("tunnel resistance", "values"), [[24, "x"]], "tunnel resistance.values[0][1] (coefficient)"),
        (("tunnel resistance",), None, "tunnel resistance"),
        (("ETCS braking data", "T_be"), None, "ETCS braking data.T_be"),
        (
            ("ETCS braking data", "A_brake_service", "values"),
            [[0]],
            "ETCS braking data.A_brake_service.values[0]",
        ),
    ],
)
def test_malformed_train_values_name_file_and_field(tmp_path, keys, value, field):
    path = write(tmp_path, mutated(TRAIN, keys, value))
    with pytest.raises(InputError) as err:
        read_ttobench_train(path)
    assert err.value.file == str(path)
    assert names_field(err.value, field), str(err.value)
    assert err.value.allowed or "missing" in str(err.value)


@pytest.mark.parametrize(
    ("keys", "value", "field"),
    [
        (("metadata",), None, "metadata"),
        (("stops", "values"), [0, None], "stops.values[1]"),
        (("stops", "values"), [0, "5000"], "stops.values[1]"),
        (("stops",), None, "stops"),
        (("speed limits", "values"), [[0, None]], "speed limits.values[0][1] (velocity)"),
        (("speed limits", "values"), [[0, 100], [3000, {"v": 1}]], "speed limits.values[1][1] (velocity)"),
        (("speed limits", "values"), [[0, 0]], "speed limits.values[0][1]"),
        (("speed limits", "units", "velocity"), "mph", "speed limits.units.velocity"),
        (("gradients", "values"), [[0, 0], [1000, float("nan")]], "gradients.values[1][1] (slope)"),
        (("gradients", "values"), [[0, 0], [0, 1]], "gradients.values[1][0]"),
        (("curvatures", "values"), [[0, 0, 0]], "curvatures.values[0][1]"),
        (("curvatures", "values"), [[0, None, 500]], "curvatures.values[0][1]"),
        (("curvatures", "values"), [[0, "straight", 500]], "curvatures.values[0][1]"),
        (("tunnels", "values"), [[4000, 5000, 40]], "tunnels.values[0][1]"),
        (("tunnels", "values"), [[4000, 500, 0]], "tunnels.values[0][2]"),
        (("ETCS braking data",), None, "ETCS braking data"),
    ],
)
def test_malformed_track_values_name_file_and_field(tmp_path, keys, value, field):
    path = write(tmp_path, mutated(TRACK, keys, value))
    with pytest.raises(InputError) as err:
        read_ttobench_track(path)
    assert err.value.file == str(path)
    assert names_field(err.value, field), str(err.value)


@pytest.mark.parametrize(
    ("row", "field"),
    [
        ([2500, float("nan"), 150, 10, None], "timing points.values[1][1] (lower time constraint)"),
        ([2500, 100, float("inf"), 10, None], "timing points.values[1][2] (upper time constraint)"),
        ([2500, "100", 150, 10, None], "timing points.values[1][1] (lower time constraint)"),
        ([2500, 160, 150, 10, None], "timing points.values[1]"),
        ([2500, 100, 150, 30, 10], "timing points.values[1]"),
        ([None, 100, 150, 10, None], "timing points.values[1][0] (position)"),
        ([2500, 100, 150], "timing points.values[1]"),
        ([6000, 100, 150, 10, None], "timing points.values[2][0]"),
        ([0, 100, 150, 10, None], "timing points.values[1][0]"),
    ],
)
def test_malformed_journey_rows_name_file_and_field(tmp_path, row, field):
    data = copy.deepcopy(JOURNEY)
    data["timing points"]["values"][1] = row
    path = write(tmp_path, data)
    with pytest.raises(InputError) as err:
        read_ttobench_journey(path)
    assert err.value.file == str(path)
    assert names_field(err.value, field), str(err.value)


def test_null_metadata_and_non_object_files_are_input_errors(tmp_path):
    for reader, base in ((read_ttobench_journey, JOURNEY), (read_ttobench_track, TRACK)):
        with pytest.raises(InputError, match="metadata"):
            reader(write(tmp_path, mutated(base, ("metadata",), None)))
    path = tmp_path / "list.json"
    path.write_text("[1, 2]", encoding="utf-8")
    with pytest.raises(InputError):
        read_ttobench_train(path)


def test_every_shipped_ttobench_file_reads():
    if not TTOBENCH.exists():
        pytest.skip("TTOBench data not found beside the checkout")
    trains = {p.stem: read_ttobench_train(p) for p in sorted((TTOBENCH / "trains").glob("*.json"))}
    assert trains["CH_Stadler_FLIRT_TPF"].etcs is not None
    for p in sorted((TTOBENCH / "tracks").glob("*.json")):
        assert read_ttobench_track(p, trains["CH_Stadler_FLIRT_TPF"]).gravity_mps2 == TTOBENCH_GRAVITY
    journey = read_ttobench_journey(TTOBENCH / "journeys" / "CH_StGallen_Wil_Journey_01.json")
    assert len(journey.points) == 6 and journey.track_id == "CH_StGallen_Wil"
