"""Dotted field paths into scenario data."""

from __future__ import annotations

import pytest

from trainsim.batch.paths import get_values, parse_path, set_value
from trainsim.errors import InputError


def data():
    return {
        "train": {"formation": [{"name": "Mc", "load_t": 0, "mass_t": 50.0}, {"name": "T", "mass_t": 40.0}]},
        "route": {"stations": [{"name": "S1", "dwell_s": 0}, {"name": "S2", "dwell_s": 30}]},
    }


def test_parse_path_steps():
    p = parse_path("route.stations[name=S2].dwell_s")
    assert [str(s) for s in p.steps] == ["route", "stations", "[name=S2]", "dwell_s"]
    assert p.root == "route"
    assert p.tail().text == "stations[name=S2].dwell_s"
    assert [str(s) for s in parse_path("a[1][*].b").steps] == ["a", "[1]", "[*]", "b"]


@pytest.mark.parametrize("bad", ["", "train..mass", "train.", "[0].a", "a[1", "a[x]", "a[=1]", "a[0]b"])
def test_malformed_paths_are_input_errors(bad):
    with pytest.raises(InputError, match="invalid field path"):
        parse_path(bad)


def test_set_by_index_negative_index_and_get():
    d = data()
    set_value(d, "train.formation[1].load_t", 7)
    assert d["train"]["formation"][1]["load_t"] == 7
    set_value(d, "train.formation[-1].mass_t", 41.0)
    assert get_values(d, "train.formation[1].mass_t") == [41.0]


def test_every_item_and_match_selector():
    d = data()
    set_value(d, "train.formation[*].load_t", 3)
    assert [v["load_t"] for v in d["train"]["formation"]] == [3, 3]
    set_value(d, "route.stations[name=S2].dwell_s", 45)
    assert d["route"]["stations"] == [{"name": "S1", "dwell_s": 0}, {"name": "S2", "dwell_s": 45}]


def test_relative_scales_each_item():
    d = data()
    set_value(d, "train.formation[*].mass_t", 1.1, scale=True)
    assert get_values(d, "train.formation[*].mass_t") == pytest.approx([55.0, 44.0])


def test_missing_mapping_keys_are_created_list_items_never():
    d = data()
    set_value(d, "dwell_s.S2", 20)
    set_value(d, "settings.max_step_m", 5)
    assert d["dwell_s"] == {"S2": 20} and d["settings"] == {"max_step_m": 5}
    with pytest.raises(InputError, match="no item"):
        set_value(d, "train.formation[2].load_t", 1)
    with pytest.raises(InputError, match="not a list"):
        set_value(d, "train[0]", 1)
    with pytest.raises(InputError, match=r"no item of 'route\.stations' has name = S9"):
        set_value(d, "route.stations[name=S9].dwell_s", 1)
    with pytest.raises(InputError, match="no field"):
        get_values(d, "train.electrical.line_voltage_v")


def test_relative_needs_a_number():
    d = data()
    with pytest.raises(InputError, match="relative value needs a number"):
        set_value(d, "train.formation[1].load_t", 2.0, scale=True)
