"""Messages of the network's checks state the range actually allowed; a step's loads are checked
(issue 18)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.power_file import load_power_file
from trainsim.power import Gap, Network, StepLoads, Substation, Track, solve_step, standard_limits

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"


def _allowed_accepts(allowed: str, value: float) -> bool:
    """Whether the range an error message states (``> 0``, ``>= 0``, ...) holds ``value``."""
    op, bound = allowed.split("(")[0].split()
    bound = float(bound)
    return {">": value > bound, ">=": value >= bound}[op]


def _file_error(tmp_path: Path, base: str, keys: tuple, value, every_track: bool = False) -> InputError:
    doc = yaml.safe_load((EXAMPLES / base).read_text())
    for t in doc["trains"]:
        t["scenario"] = (EXAMPLES / t["scenario"]).as_posix()
    for k in range(len(doc["network"]["tracks"])) if every_track else [keys[2]]:
        target = doc
        for key in (*keys[:2], k, *keys[3:-1]):
            target = target[key]
        target[keys[-1]] = value
    path = tmp_path / "power.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError) as err:
        load_power_file(path)
    return err.value


NETWORK_FIELDS = [
    ("metro_750v_diode.yaml", ("tracks", 0, "contact_resistance_ohm_per_km")),
    ("metro_750v_diode.yaml", ("tracks", 0, "rail_resistance_ohm_per_km")),
    ("metro_750v_diode.yaml", ("tracks", 0, "rail_to_earth_conductance_s_per_km")),
    ("metro_750v_diode.yaml", ("substations", 0, "internal_resistance_ohm")),
    ("metro_750v_diode.yaml", ("substations", 0, "no_load_voltage_v")),
    ("metro_750v_diode.yaml", ("substations", 0, "rated_power_kw")),
    ("main_line_25kv.yaml", ("tracks", 0, "contact_reactance_ohm_per_km")),
    ("main_line_25kv.yaml", ("substations", 0, "internal_reactance_ohm")),
]


@pytest.mark.parametrize(("base", "keys"), NETWORK_FIELDS)
def test_every_range_message_of_the_network_holds_what_it_allows(tmp_path, base, keys):
    """A negative value is refused with a range that excludes it, and if that range holds 0, then 0
    is accepted (the audit found ">= 0" stated where 0 was refused too)."""
    doc_keys = ("network", *keys)
    problem = _file_error(tmp_path, base, doc_keys, -1.0).problems[0]
    assert problem.field == "network." + ".".join(str(k) for k in keys).replace(".0.", "[0].")
    assert not _allowed_accepts(problem.allowed, -1.0), problem.allowed
    if _allowed_accepts(problem.allowed, 0.0):
        try:
            # a rail resistance of 0 is the ideal return, which holds for every track or none
            _file_error(tmp_path, base, doc_keys, 0.0, every_track="rail_resistance" in keys[-1])
        except pytest.fail.Exception:
            return  # 0 accepted, as the message says
        pytest.fail(f"{problem.field}: the message allows {problem.allowed!r} but 0 is refused")


def test_dc_contact_and_internal_resistance_state_greater_than_zero(tmp_path):
    for keys in (
        ("tracks", 0, "contact_resistance_ohm_per_km"),
        ("substations", 0, "internal_resistance_ohm"),
    ):
        for value in (-0.5, 0.0):
            p = _file_error(tmp_path, "metro_750v_diode.yaml", ("network", *keys), value).problems[0]
            assert p.allowed.startswith("> 0 (DC: ") and p.value == value


def test_ac_zero_resistance_is_allowed_with_a_reactance(tmp_path):
    doc = yaml.safe_load((EXAMPLES / "main_line_25kv.yaml").read_text())
    doc["network"]["tracks"][0]["contact_resistance_ohm_per_km"] = 0
    for t in doc["trains"]:
        t["scenario"] = (EXAMPLES / t["scenario"]).as_posix()
    path = tmp_path / "ac.yaml"
    path.write_text(yaml.safe_dump(doc))
    _, network, _ = load_power_file(path)
    assert network.tracks[0].contact_resistance_ohm_per_m == 0.0
    p = _file_error(
        tmp_path, "main_line_25kv.yaml", ("network", "tracks", 0, "contact_resistance_ohm_per_km"), -1
    )
    assert p.problems[0].allowed.startswith(">= 0 (AC: ")


def test_track_extent_and_gap_messages_in_the_file_units(tmp_path):
    err = _file_error(tmp_path, "metro_750v_diode.yaml", ("network", "tracks", 0, "end_km"), -1.0)
    # one problem: the elements on the track are not reported off a track that has no extent
    first = err.problems[0]
    assert (
        first.field == "network.tracks[0].end_km"
        and first.value == -1.0
        and first.allowed == "> start_km = 0"
    )
    assert not any("off track" in p.reason for p in err.problems)
    doc = yaml.safe_load((EXAMPLES / "metro_750v_diode.yaml").read_text())
    doc["network"]["gaps"] = [{"id": "NS", "track": "up", "start_km": 4.5, "end_km": 4.8}]
    for t in doc["trains"]:
        t["scenario"] = (EXAMPLES / t["scenario"]).as_posix()
    path = tmp_path / "gap.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError, match="gap NS lies off its track up") as gap:
        load_power_file(path)
    assert gap.value.problems[0].field == "network.gaps[0].start_km"


@pytest.fixture(scope="module")
def line():
    return Network(
        "one track",
        "dc",
        standard_limits("dc_750"),
        (Track("A", 0.0, 4000.0, 0.02e-3, 0.015e-3), Track("B", 1000.0, 3000.0, 0.02e-3, 0.015e-3)),
        (
            Substation("S1", 0.0, ("A",), 835.0, 0.03),
            Substation("S2", 2000.0, ("A", "B"), 825.0, 0.05),
            Substation("S3", 4000.0, ("A",), 825.0, 0.05),
        ),
        gaps=(Gap("NS", "A", 2500.0, 2600.0),),
    )


def _loads(track: int, x: float, p: float = 1e6, ids=("T1",)) -> StepLoads:
    one = np.ones(1)
    return StepLoads(np.array([track]), np.array([x]), p * one, 0 * one, 0 * one, 0 * one, train_ids=ids)


@pytest.mark.parametrize(
    ("track", "x", "match"),
    [
        (0, 4500.0, r"train T1 is off its track A.*allowed: track A's extent 0.000 \.\. 4000.000 m"),
        (1, 500.0, r"train T1 is off its track B.*allowed: track B's extent 1000.000 \.\. 3000.000 m"),
        (0, float("nan"), "train T1 is off its track A"),
        (2, 100.0, r"train T1 is on an unknown track.*allowed: a track index 0 \.\. 1"),
        (0, 2550.0, "train T1 stands inside neutral section NS of track A"),
    ],
)
def test_solve_step_refuses_a_train_off_its_track(line, track, x, match):
    with pytest.raises(InputError, match=match) as err:
        solve_step(line, _loads(track, x))
    assert err.value.problems[0].field in ("loads.position_m[0]", "loads.track[0]")


def test_solve_step_names_a_train_by_place_and_checks_powers(line):
    with pytest.raises(InputError, match="train 0 of the step is off its track A"):
        solve_step(line, _loads(0, 4000.5, ids=None))
    with pytest.raises(InputError, match="train T1 has an invalid power"):
        solve_step(line, _loads(0, 1000.0, p=-1.0))
    # the track's end itself (and round-off beyond it) and a section insulator's place are on the wire
    assert solve_step(line, _loads(0, 4000.0 + 1e-7)).converged
    assert solve_step(line, _loads(0, 2500.0)).converged
