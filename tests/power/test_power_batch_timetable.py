"""Issue 18: a power file takes its trains from a batch study's timetable (``timetable:``), read with
the batch layer's own study reader; the same figures as the power file with ``departures_s`` lists."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from trainsim.batch.power_timetable import load_power_file, read_study_trains, run_power_file
from trainsim.errors import InputError
from trainsim.io import power_file

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples" / "power"
POWER = EXAMPLES / "metro_750v_diode_peak_study.yaml"
#: the study's runs: (entry, load per car [t], departures [s since midnight])
ENTRIES = (("peak", 16, [25200.0 + 240 * k for k in range(6)]), ("off-peak", 6, [26640.0, 27000.0, 27360.0]))


def _close(a, b, path="summary"):
    """Every number of two summaries within 1e-9 (relative), every other value equal."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{path}[{k}]")
    elif isinstance(a, float) and not isinstance(b, bool):
        assert math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), (path, a, b)
    else:
        assert a == b, path


def _equivalent(tmp: Path) -> Path:
    """The example written with trains: and departures_s lists, one scenario file per study entry."""
    doc = yaml.safe_load(POWER.read_text())
    del doc["timetable"]
    scenario = yaml.safe_load((EXAMPLES / "metro_scenario.yaml").read_text())
    trains = []
    for name, load_t, departures in ENTRIES:
        train = yaml.safe_load((EXAMPLES / scenario["train"]).read_text())
        for vehicle in train["formation"]:
            vehicle["load_t"] = load_t
        (tmp / f"train_{name}.yaml").write_text(yaml.safe_dump(train))
        own = {**scenario, "name": name, "train": f"train_{name}.yaml"}
        own["route"] = (EXAMPLES / scenario["route"]).resolve().as_posix()
        (tmp / f"scenario_{name}.yaml").write_text(yaml.safe_dump(own))
        trains.append((name, departures))
    doc["trains"] = [
        {"id": f"{track}/{name}", "scenario": f"scenario_{name}.yaml", "track": track, "origin_km": origin,
         "direction": direction, "departures_s": departures}
        for track, origin, direction in (("up", 0, 1), ("down", 4.59097, -1))
        for name, departures in trains
    ]  # fmt: skip
    path = tmp / "power_lists.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("lists")
    return run_power_file(POWER, plots=False), power_file.run_power_file(_equivalent(tmp), plots=False)


def test_the_study_s_trains_give_the_figures_of_the_departures_lists(both):
    (study, study_status), (lists, lists_status) = both
    assert study_status == lists_status == study["status"]
    # the crowded peak every 4 minutes loads the middle substation beyond its overload power
    assert study_status == "substation_overloaded"
    # one row per departure: 6 peak and 3 off-peak runs each way
    ids = [t["id"] for t in study["trains"]]
    assert len(ids) == 18 and ids[0] == "up/peak#0" and ids[-1] == "down/off-peak#2"
    study.pop("name"), lists.pop("name")
    _close(study, lists)
    assert study["substations_energy_kwh"] > 1000


def test_each_study_entry_is_one_service_with_its_runs_departures():
    _, _, services = load_power_file(POWER)
    assert [(s.id, s.track, s.direction, s.departures_s) for s in services] == [
        (f"{track}/{name}", track, direction, tuple(deps))
        for track, direction in (("up", 1), ("down", -1))
        for name, _, deps in ENTRIES
    ]
    masses = {s.id: s.scenario.train.mass_kg for s in services}
    # 6 cars: 16 t and 6 t of load per car
    assert masses["up/peak"] - masses["up/off-peak"] == pytest.approx(6 * 10_000)
    # the scenario is built once per entry: both directions share it
    assert services[0].scenario is services[2].scenario


def test_the_day_of_the_metro_timetable_study_is_six_services_of_187_runs():
    groups = read_study_trains(ROOT / "examples" / "studies" / "metro_timetable.yaml")
    assert len(groups) == 6
    assert sum(len(g.departures_s) for g in groups) == 187
    assert groups[0].departures_s[0] == 5.5 * 3600 and groups[-1].departures_s[-1] == 23 * 3600 + 50 * 60
    assert [g.name for g in groups][2] == "morning peak express"
    # the express skips S2: its route has one stop fewer than the all-stops'
    assert len(groups[2].scenario.route.stops) == len(groups[1].scenario.route.stops) - 1


def _with(tmp_path: Path, **link) -> Path:
    doc = yaml.safe_load(POWER.read_text())
    doc["timetable"] = [
        {**doc["timetable"][0], "study": (EXAMPLES / "metro_peak_study.yaml").as_posix(), **link}
    ]
    path = tmp_path / "power.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize(
    ("link", "field", "words"),
    [
        ({"study": "no_such_study.yaml"}, "timetable[0].study", "study file not found"),
        ({"origin_km": 1.0}, "timetable[0].origin_km", "study entry runs[0] 'peak' of"),
        ({"track": "middle"}, "timetable[0].track", "unknown track"),
        ({"direction": True}, "timetable[0].direction", "1 or -1"),
        ({"tracks": "up"}, "timetable[0].tracks", "unknown field"),
    ],
)
def test_a_bad_study_reference_names_the_field(tmp_path, link, field, words):
    path = _with(tmp_path, **link)
    with pytest.raises(InputError) as info:
        load_power_file(path)
    problem = info.value.problems[0]
    assert (problem.file, problem.field) == (str(path), field)
    assert words in str(info.value)


def test_a_study_run_without_departure_is_refused_naming_the_study_entry(tmp_path):
    study = yaml.safe_load((EXAMPLES / "metro_peak_study.yaml").read_text())
    study["base"] = (EXAMPLES / "metro_scenario.yaml").as_posix()
    del study["runs"][1]["departures"]
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    with pytest.raises(InputError) as info:
        load_power_file(_with(tmp_path, study="study.yaml"))
    problem = info.value.problems[0]
    assert (problem.file, problem.field) == (str(tmp_path / "study.yaml"), "runs[1].departures")


def test_the_file_layer_alone_says_the_study_needs_the_batch_layer(tmp_path):
    path = _with(tmp_path)
    with pytest.raises(InputError) as info:
        power_file.load_power_file(path)
    assert info.value.problems[0].field == "timetable[0].study"
    assert "batch layer" in str(info.value)
