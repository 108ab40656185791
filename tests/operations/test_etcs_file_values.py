"""ETCS data of an operation file (issue 17): every value given reaches the supervision curves, trains
find their own braking data, and a bad value is an InputError naming file, field, value and range."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.operations.etcs import EtcsNationalValues, EtcsTrainData, StepFunction, supervision_curves
from trainsim.operations.runs import direction_route
from trainsim.operations.separation import ma_curves, mrsp_profile

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "operations" / "main_line_etcs.yaml"
ROUTE = str(ROOT / "examples" / "operations" / "main_line_route.yaml")
LOCAL = str(ROOT / "tests" / "data" / "trainruns" / "trains" / "local.yaml")
FREIGHT = str(ROOT / "tests" / "data" / "trainruns" / "trains" / "freight.yaml")
KINDS = ("ebd", "sbd", "guidance", "ebi", "sbi", "warning", "permitted", "indication")
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")  # TrainRuns.jl's documented defaults

BASE_ETCS: dict[str, Any] = {
    "a_brake_emergency_mps2": 1.0,
    "a_brake_service_mps2": 0.8,
    "t_brake_emergency_s": 2.0,
    "t_brake_service_s": 3.0,
    "t_traction_cut_off_s": 1.0,
}


def _write(tmp_path: Path, etcs: dict[str, Any], trains: list[dict[str, Any]] | None = None) -> Path:
    doc = {
        "schema": "trainsim/operation",
        "version": 1,
        "name": "etcs file test",
        "line": {
            "route": ROUTE,
            "layout": "double_track",
            "block_length_m": 1350,
            "stations": [{"name": n} for n in "ABCDE"],
            "signalling": {"system": "etcs_l2", "overlap_m": 100, "etcs": etcs},
        },
        "trains": trains
        or [
            {
                "id": "RB1",
                "train": LOCAL,
                "direction": "up",
                "origin": "A",
                "destination": "E",
                "departure": "06:00",
            }
        ],
    }
    path = tmp_path / "op.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _same_curves(a, b, positions: np.ndarray) -> None:
    for kind in KINDS:
        np.testing.assert_allclose(
            getattr(a, kind)(positions), getattr(b, kind)(positions), rtol=1e-12, atol=0
        )
    assert a.release_speed_mps == pytest.approx(b.release_speed_mps, rel=1e-12, abs=0)


# each case: what the file gives, the EtcsTrainData fields and national/fixed values it must mean
CASES = {
    "kdry_rst step (km/h)": (
        {"kdry_rst": {"upper_limits_kmh": [80], "values": [0.95, 0.9]}},
        {"kdry_rst": StepFunction.from_kmh([80], [0.95, 0.9])},
        {},
    ),
    "kdry_rst by EBCL": (
        {"kdry_rst_by_ebcl": {9: 0.9, 5: 0.97}, "national": {"m_nvebcl": 5}},
        {"kdry_rst": {9: 0.9, 5: 0.97}},
        {"m_nvebcl": 5},
    ),
    "kwet_rst and M_NVAVADH": (
        {"kwet_rst": {"upper_limits_mps": [20.0], "values": [0.8, 0.7]}, "national": {"m_nvavadh": 0.4}},
        {"kwet_rst": StepFunction((0.8, 0.7), (20.0,))},
        {"m_nvavadh": 0.4},
    ),
    "Kn and guidance": (
        {
            "kn_plus_mps2": 0.3,
            "kn_minus_mps2": 0.5,
            "a_brake_normal_service_mps2": 0.6,
            "national": {"q_nvguiperm": True},
        },
        {"kn_plus": 0.3, "kn_minus": 0.5, "a_brake_normal_service": 0.6},
        {"q_nvguiperm": True},
    ),
    "fixed values": (
        {"fixed": {"t_warning_s": 3.0, "t_driver_s": 6.0, "dv_ebi_min_mps": 3.0, "gravity_mps2": 9.80665}},
        {},
        {"t_warning_s": 3.0, "t_driver_s": 6.0, "dv_ebi_min_mps": 3.0, "gravity_mps2": 9.80665},
    ),
    "train data switches": (
        {
            "traction_cut_off_implemented": False,
            "service_brake_feedback": True,
            "speed_under_reading_mps": 0.5,
            "speed_under_reading_ratio": 0.02,
            "m_rotating_nom_percent": 8.0,
            "t_brake_emergency_cmt_s": 2.5,
            "national": {"q_nvsbfbperm": True, "q_nvsbtsmperm": False},
        },
        {
            "traction_cut_off_implemented": False,
            "service_brake_feedback": True,
            "speed_under_reading_mps": 0.5,
            "speed_under_reading_ratio": 0.02,
            "m_rotating_nom_percent": 8.0,
            "t_brake_emergency_cmt_s": 2.5,
        },
        {"q_nvsbfbperm": True, "q_nvsbtsmperm": False},
    ),
    "lambda train and Kv_int/Kr_int/Kt_int": (
        {
            "brake_percentage": 120,
            "brake_position": "passenger_p",
            "t_traction_cut_off_s": 1.0,
            "national": {
                "kv_int_passenger_a": {"upper_limits_kmh": [100], "values": [0.75, 0.7]},
                "kr_int": {"upper_limits_m": [100.0], "values": [1.0, 0.9]},
                "kt_int": 1.2,
            },
        },
        None,
        {
            "kv_int_passenger_a": StepFunction.from_kmh([100], [0.75, 0.7]),
            "kr_int": StepFunction((1.0, 0.9), (100.0,)),
            "kt_int": 1.2,
        },
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_value_in_the_file_reaches_the_curves(tmp_path: Path, case: str) -> None:
    given, train_fields, national_fields = CASES[case]
    etcs = {**BASE_ETCS, **given} if train_fields is not None else given
    op = read_operation(_write(tmp_path, etcs))
    svc = op.services[0]
    train = svc.train
    if train_fields is None:  # the conversion model from the brake percentage
        data = EtcsTrainData.from_brake_percentage(
            120, "passenger_p", train.length_m, train.max_speed_mps, 1.0
        )
    else:
        data = EtcsTrainData(
            a_brake_emergency=1.0,
            a_brake_service=0.8,
            t_brake_emergency_s=2.0,
            t_brake_service_s=3.0,
            t_traction_cut_off_s=1.0,
            length_m=train.length_m,
            max_speed_mps=train.max_speed_mps,
            **train_fields,
        )
    national = EtcsNationalValues(**national_fields)
    assert op.etcs.train_data(train) == data and op.etcs.national == national
    directed = direction_route(op.geometry, op.line.length_m, "down")  # the line's gradients, mirrored
    eoa, overlap = 34_000.0, 100.0
    from_file = ma_curves(train, op.etcs, eoa, overlap, directed)
    direct = supervision_curves(
        data, national, directed, eoa, svl_position_m=eoa + overlap, mrsp=mrsp_profile(directed, train)
    )
    s = np.linspace(25_000.0, eoa + overlap, 301)
    _same_curves(from_file, direct, s)
    # and the value matters: the same curves with the defaults differ
    plain = supervision_curves(
        EtcsTrainData(1.0, 0.8, 2.0, 3.0, 1.0, train.length_m, train.max_speed_mps),
        EtcsNationalValues(),
        directed,
        eoa,
        svl_position_m=eoa + overlap,
        mrsp=mrsp_profile(directed, train),
    )
    assert any(not np.allclose(getattr(plain, k)(s), getattr(direct, k)(s), rtol=1e-9) for k in KINDS)


@pytest.mark.parametrize(
    ("given", "expected"),
    [({}, "calculated"), ({"release_speed": "national"}, "national"), ({"release_speed_mps": 5.0}, 5.0)],
)
def test_the_release_speed_of_the_file_is_the_curves(tmp_path: Path, given, expected) -> None:
    op = read_operation(_write(tmp_path, {**BASE_ETCS, **given}))
    train = op.services[0].train
    assert op.etcs.release_speed == expected
    c = ma_curves(train, op.etcs, 5000.0, 100.0)
    direct = supervision_curves(
        op.etcs.train_data(train),
        EtcsNationalValues(),
        None,
        5000.0,
        svl_position_m=5100.0,
        release_speed=expected,
    )
    _same_curves(c, direct, np.linspace(3000.0, 5100.0, 201))
    assert c.release_speed_mps == (
        40 * KMH if expected == "national" else pytest.approx(direct.release_speed_mps)
    )
    if expected == 5.0:
        assert c.release_speed_mps == 5.0 and float(c.permitted(4999.0)) == 5.0


@pytest.fixture(scope="module")
def example():
    return read_operation(EXAMPLE)


def test_the_example_gives_each_train_type_its_own_braking_data(example) -> None:
    by_id = {s.id: s for s in example.services}
    ic, rb, gt = by_id["IC1"].train, by_id["RB1"].train, by_id["GT1"].train
    ic_data = example.etcs.train_data(ic)
    assert ic_data == EtcsTrainData(
        a_brake_emergency=StepFunction.from_kmh([100, 140], [1.10, 1.00, 0.90]),
        a_brake_service=StepFunction.from_kmh([100], [0.90, 0.80]),
        t_brake_emergency_s=2.5,
        t_brake_service_s=3.0,
        t_traction_cut_off_s=1.0,
        length_m=ic.length_m,
        max_speed_mps=ic.max_speed_mps,
        kdry_rst={
            9: StepFunction.from_kmh([100, 140], [0.95, 0.92, 0.90]),
            6: StepFunction.from_kmh([100, 140], [0.97, 0.95, 0.93]),
        },
        kwet_rst=StepFunction.from_kmh([120], [0.85, 0.80]),
        kn_plus=0.2,
        kn_minus=0.3,
        m_rotating_nom_percent=6.0,
    )
    # the regional train falls back to the line's block
    rb_data = example.etcs.train_data(rb)
    assert rb_data.a_brake_emergency == StepFunction.from_kmh([100], [1.0, 0.9])
    assert rb_data.kdry_rst == StepFunction.from_kmh([100], [0.95, 0.92]) and rb_data.kwet_rst.values == (
        0.85,
    )
    # GT1 by its id: a lambda train (conversion model, freight P)
    gt_data = example.etcs.train_data(gt)
    assert gt_data == EtcsTrainData.from_brake_percentage(65, "freight_p", gt.length_m, gt.max_speed_mps, 2.0)
    assert example.etcs.release_speed == pytest.approx(8.333) and example.etcs.national.t_driver_s == 4.0


def test_the_example_ebd_on_its_down_gradient_is_the_hand_value(example) -> None:
    """IC1's EBD in the down direction on the mirrored 4 per mille up-gradient (31 - 35 km: 4 per mille
    down), SvL at 34.9 km, by hand: A_brake_safe = Kdry(9) Kwet A_e = 0.95 x 0.85 x 1.10 = 0.888250
    (below 100 km/h), A_gradient = 9.81 x (-4) / (1000 + 10 x 6) = -0.0370189 (M_rotating_nom 6 %),
    A_safe = 0.8512311 m/s^2; 400 m before the SvL v = sqrt(2 x 0.8512311 x 400) = 26.0957 m/s
    (93.9 km/h, below the 100 km/h step)."""
    ic = next(s.train for s in example.services if s.id == "IC1")
    down = direction_route(example.geometry, example.line.length_m, "down")
    c = ma_curves(ic, example.etcs, 34_800.0, 100.0, down)
    a_safe = 0.95 * 0.85 * 1.10 + 9.81 * (-4.0) / 1060.0
    assert a_safe == pytest.approx(0.8512311, abs=1e-7)
    assert float(c.ebd(34_500.0)) == pytest.approx(np.sqrt(2 * a_safe * 400.0), rel=1e-12)
    assert float(c.ebd(34_500.0)) == pytest.approx(26.0957, abs=1e-4)
    # the same MA on the level up direction at the same place: a higher curve
    level = ma_curves(ic, example.etcs, 34_800.0, 100.0, example.geometry)
    assert float(level.ebd(34_500.0)) == pytest.approx(np.sqrt(2 * 0.95 * 0.85 * 1.10 * 400.0), rel=1e-12)


def test_the_example_curves_use_each_trains_speed_profile(example) -> None:
    ic = next(s.train for s in example.services if s.id == "IC1")
    rb = next(s.train for s in example.services if s.id == "RB1")
    up = example.geometry
    c = ma_curves(ic, example.etcs, 38_000.0, 100.0, up)
    # the 120 km/h section 19.5 - 22.5 km binds IC1's head until its rear (153 m) has left it
    assert float(c.permitted(21_000.0)) == pytest.approx(120 * KMH, rel=1e-12)
    assert float(c.permitted(22_500.0 + 0.5 * ic.length_m)) == pytest.approx(120 * KMH, rel=1e-12)
    assert float(c.permitted(22_500.0 + ic.length_m + 1.0)) == pytest.approx(160 * KMH, rel=1e-12)
    # before the decrease the permitted speed is below 160 km/h (a speed-decrease target), and the
    # indication curve lower still
    assert 120 * KMH < float(c.permitted(19_000.0)) < 160 * KMH
    assert float(c.indication(19_000.0)) < float(c.permitted(19_000.0))
    # the regional train's own top speed (120 km/h) is its MRSP on the 160 km/h line
    c_rb = ma_curves(rb, example.etcs, 38_000.0, 100.0, up)
    assert float(c_rb.permitted(10_000.0)) == pytest.approx(rb.max_speed_mps, rel=1e-12)


def test_the_example_runs_with_every_train_ok(example) -> None:
    from trainsim.io.operation_run import run_operation

    res = run_operation(example)
    assert res.status == "ok"
    assert {t.id: t.status for t in res.trains} == {"IC1": "ok", "RB1": "ok", "GT1": "ok"}


BAD = [
    ({"kwet_rst": 1.2}, "line.signalling.etcs.kwet_rst", "0 < Kwet_rst <= 1"),
    ({"a_brake_emergency_mps2": 0.0}, "line.signalling.etcs.a_brake_emergency_mps2", "0 < A <= 10"),
    (
        {"kdry_rst": {"upper_limits_kmh": [80, 60], "values": [1, 0.9, 0.8]}},
        "line.signalling.etcs.kdry_rst.upper_limits_kmh",
        "increasing",
    ),
    (
        {"kdry_rst": {"upper_limits_kmh": [80], "values": [1, 0.9, 0.8]}},
        "line.signalling.etcs.kdry_rst.upper_limits_kmh",
        "2 limits for 3 values",
    ),
    (
        {"kdry_rst": {"upper_limits_m": [80], "values": [1, 0.9]}},
        "line.signalling.etcs.kdry_rst.upper_limits_m",
        "upper_limits_kmh",
    ),
    ({"kdry_rst_by_ebcl": {12: 0.9}}, "line.signalling.etcs.kdry_rst_by_ebcl", "integers 0 to 9"),
    ({"kdry_rst_by_ebcl": {5: 0.9}}, "line.signalling.etcs.kdry_rst_by_ebcl", "one of [5]"),
    ({"kn_minus_mps2": -1}, "line.signalling.etcs.kn_minus_mps2", "0 to 10"),
    ({"t_brake_service_s": 400}, "line.signalling.etcs.t_brake_service_s", "0 to 300 s"),
    ({"national": {"m_nvebcl": 12}}, "line.signalling.etcs.national.m_nvebcl", "integers 0 to 9"),
    ({"national": {"m_nvavadh": 1.5}}, "line.signalling.etcs.national.m_nvavadh", "0.0 to 1.0"),
    (
        {"national": {"kr_int": {"upper_limits_kmh": [100], "values": [1, 0.9]}}},
        "line.signalling.etcs.national.kr_int.upper_limits_kmh",
        "upper_limits_m",
    ),
    ({"fixed": {"t_driver_s": -1}}, "line.signalling.etcs.fixed.t_driver_s", "0 to 60 s"),
    ({"fixed": {"v_ebi_max_mps": 10.0}}, "line.signalling.etcs.fixed.v_ebi_max_mps", "> v_ebi_min_mps"),
    ({"release_speed_mps": 150}, "line.signalling.etcs.release_speed_mps", "0 to 100 m/s"),
    ({"release_speed_mps": 5, "release_speed": "national"}, "line.signalling.etcs.release_speed_mps", "once"),
    ({"trains": {"nobody": dict(BASE_ETCS)}}, "line.signalling.etcs.trains.nobody", "trains[i].id"),
    ({"brake_percentage": 300}, "line.signalling.etcs.brake_percentage", "30 to 250 %"),
]


@pytest.mark.parametrize(
    ("given", "field", "allowed"), BAD, ids=[b[1].split(".", 2)[-1] + str(i) for i, b in enumerate(BAD)]
)
def test_a_bad_etcs_value_names_file_field_value_and_range(tmp_path: Path, given, field, allowed) -> None:
    etcs = {**BASE_ETCS, **given}
    if "brake_percentage" in given:
        etcs = {"brake_percentage": given["brake_percentage"], "t_traction_cut_off_s": 1.0}
    path = _write(tmp_path, etcs)
    with pytest.raises(InputError) as e:
        read_operation(path)
    problems = [p for p in e.value.problems if p.field == field]
    assert problems, [p.field for p in e.value.problems]
    assert problems[0].file == str(path)
    text = str(e.value)
    assert allowed in text and field in text


def test_a_train_without_braking_data_is_named(tmp_path: Path) -> None:
    """The line's block lacks the build-up times: the regional train that uses it is named; the
    freight train with its own entry is not."""
    trains = [
        {
            "id": "RB1",
            "train": LOCAL,
            "direction": "up",
            "origin": "A",
            "destination": "E",
            "departure": "06:00",
        },
        {
            "id": "GT1",
            "train": FREIGHT,
            "direction": "down",
            "origin": "E",
            "destination": "A",
            "departure": "06:00",
        },
    ]
    etcs = {
        "a_brake_emergency_mps2": 1.0,
        "a_brake_service_mps2": 0.8,
        "t_traction_cut_off_s": 1.0,
        "trains": {"GT1": dict(BASE_ETCS)},
    }
    with pytest.raises(InputError) as e:
        read_operation(_write(tmp_path, etcs, trains))
    assert len(e.value.problems) == 1
    p = e.value.problems[0]
    assert p.field == "line.signalling.etcs" and "trains[0]" in p.reason
    assert p.value == ["t_brake_emergency_s", "t_brake_service_s"]


def test_the_file_offers_every_national_fixed_and_train_value_of_the_core() -> None:
    """A field added to EtcsNationalValues or EtcsTrainData must be given a place in the file."""
    from dataclasses import fields

    from trainsim.io.operation_file import _ETCS_TRAIN_DATA, _EtcsFixed, _EtcsNational, _EtcsTrain

    national = {f.name for f in fields(EtcsNationalValues)}
    assert set(_EtcsNational.model_fields) | set(_EtcsFixed.model_fields) == national
    assert not set(_EtcsNational.model_fields) & set(_EtcsFixed.model_fields)
    core = {f.name for f in fields(EtcsTrainData)} - {"length_m", "max_speed_mps", "conversion_model_used"}
    own = {
        "a_brake_emergency",
        "a_brake_service",
        "t_brake_emergency_s",
        "t_brake_service_s",
        "t_traction_cut_off_s",
    }
    assert set(_ETCS_TRAIN_DATA.values()) | own == core
    assert set(_ETCS_TRAIN_DATA) | {f"{n}_mps2" if n.startswith("a_") else n for n in own} | {
        "brake_percentage"
    } == set(_EtcsTrain.model_fields)
