"""An operated power study beyond the full traces' cap is told what it can do (issue 18): compact
traces, which the cap suggests for a timetable, are refused for the trains of an operation."""

from __future__ import annotations

from pathlib import Path

import pytest

import trainsim.power.simulation as simulation
from trainsim.errors import InputError
from trainsim.io.power_file import run_power_file

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "power" / "metro_750v_operated.yaml"


def test_operated_trains_beyond_the_cap_are_told_to_shorten_the_span(monkeypatch):
    # a cap far below the example's train-steps stands for a day too long for full traces
    monkeypatch.setattr(simulation, "MAX_FULL_TRAIN_STEPS", 1000)
    with pytest.raises(InputError) as caught:
        run_power_file(EXAMPLE, plots=False)
    text = str(caught.value)
    assert "operated trains" in text
    assert "simulation.start_s" in text and "not of an operation" in text
    assert all(p.field == "simulation" for p in caught.value.problems)
