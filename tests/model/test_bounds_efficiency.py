"""Efficiencies have a physical floor, shares do not (issue 13): a traction efficiency of 0.001 gave
80,822 kWh and 4.9 MA with status ok, 1e-308 an infinite energy; both are now refused by every reader
with the allowed range and its reason, while a small traction share or braking fraction is still read."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

import trainsim
from trainsim.model import bounds

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_conversion_efficiencies_and_power_factors_are_at_least_a_tenth():
    for name in ("traction_efficiency", "power_factor", "efficiency", "charge_efficiency"):
        b = bounds.bound_for(name)
        assert b.quantity == "efficiency", name
        assert not b.contains(0.099) and b.contains(0.1) and b.contains(1.0) and not b.contains(1.0001)
    # the reason travels with the range into every message
    assert "0.6 to 0.95" in bounds.BOUNDS["efficiency"].allowed()


def test_shares_may_be_small_but_not_zero():
    for name in ("traction_share", "braking_fraction", "service_fraction"):
        b = bounds.bound_for(name)
        assert b.quantity == "share", name
        assert b.contains(0.01) and b.contains(1.0) and not b.contains(0.0) and not b.contains(1.5)
    # regeneration may be absent: 0 is a regenerative efficiency
    assert bounds.bound_for("regenerative_efficiency").contains(0.0)


def _train_with(tmp_path: Path, section: str, key: str, value: Any) -> Path:
    data = yaml.safe_load((EXAMPLES / "metro_b" / "train.yaml").read_text(encoding="utf-8"))
    data = copy.deepcopy(data)
    data[section][key] = value
    path = tmp_path / "train.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.parametrize("value", [1e-308, 0.001, 0.0999])
@pytest.mark.parametrize("key", ["traction_efficiency", "power_factor"])
def test_a_train_file_with_an_absurd_efficiency_is_refused_with_the_range_and_why(tmp_path, key, value):
    path = _train_with(tmp_path, "electrical", key, value)
    with pytest.raises(trainsim.InputError) as err:
        trainsim.load_train(path)
    text = str(err.value)
    assert f"electrical.{key}" in text and ">= 0.1 and <= 1" in text and "traction chains" in text, text


def test_a_train_file_with_a_low_but_possible_efficiency_is_read(tmp_path):
    train = trainsim.load_train(_train_with(tmp_path, "electrical", "traction_efficiency", 0.1))
    assert train.electrical.traction_efficiency == 0.1


def test_a_small_braking_fraction_is_still_read(tmp_path):
    data = yaml.safe_load((EXAMPLES / "metro_b" / "scenario.yaml").read_text(encoding="utf-8"))
    data["settings"]["braking_fraction"] = 0.05
    for name in ("train.yaml", "route.yaml"):
        (tmp_path / name).write_bytes((EXAMPLES / "metro_b" / name).read_bytes())
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    assert trainsim.load_scenario(path).settings.braking_fraction == 0.05
