"""The heavy-haul example of issue 4 (2 locomotives + 104 wagons, 10,700 t, 50 km): distributed power
against all power at the head. Slow (two runs of the full example)."""

from __future__ import annotations

from pathlib import Path

import pytest

import trainsim
from trainsim.io.multipoint_spec import load_multipoint_scenario, run_multipoint_scenario

HEAVY = Path(__file__).resolve().parents[2] / "examples" / "heavy_haul"


@pytest.mark.slow
def test_distributed_power_lowers_the_in_train_forces_of_the_heavy_haul_example():
    results = {}
    for name in ("scenario_dp.yaml", "scenario_head.yaml"):
        scenario, spec = load_multipoint_scenario(HEAVY / name)
        results[name] = run_multipoint_scenario(scenario, spec, base_dir=HEAVY)
    single = trainsim.run(scenario)
    dp, head = results["scenario_dp.yaml"], results["scenario_head.yaml"]
    assert scenario.train.mass_kg > 10_000e3
    assert sum(not v.powered for v in scenario.train.vehicles) >= 100
    for result in (dp, head):
        assert result.status == "ok", result.warnings
        assert not result.warnings
        assert abs(result.energy.balance_error) < 5e-3
        # slack, brake delay and a traction ramp cost a little time against the single-point model
        assert result.running_time_s == pytest.approx(single.running_time_s, rel=0.03)
        assert result.energy_kwh.traction == pytest.approx(single.energy_kwh.traction, rel=0.02)
    # distributed power: lower draft (half the train behind each locomotive) and lower buff forces
    assert dp.max_draft.force_n < 0.8 * head.max_draft.force_n
    assert dp.max_buff.force_n > 0.8 * head.max_buff.force_n
    # all power at the head: the draft force is largest in the front half of the train
    assert head.max_draft.coupler < 53
