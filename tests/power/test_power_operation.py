"""A power file that names an operation file: the trains as operated, with their waits and delays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io.power_file import operated_train_loads, run_power_file

ROOT = Path(__file__).resolve().parents[2]
OPERATION = (ROOT / "examples" / "operations" / "metro_fixed_block.yaml").as_posix()


def _file(tmp_path: Path, operation: dict | None = None, **extra) -> Path:
    doc = yaml.safe_load((ROOT / "examples" / "power" / "metro_750v_reversible.yaml").read_text())
    del doc["trains"]
    doc["operation"] = operation or {
        "file": OPERATION,
        "tracks": {"up": "up", "down": "down"},
        "origin_km": 0,
    }
    doc.update(extra)
    path = tmp_path / "power.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture(scope="module")
def operated():
    return operated_train_loads(OPERATION, {"up": "up", "down": "down"})


def test_operated_loads_follow_the_operation(operated):
    """Every train is on the network from its departure to the end of its last dwell; its
    movements are the operation's own runs between standstills placed at the operated times
    (mismatch 0 for every train, the held one too: it approached its signal under the operation's
    approach ceiling, and that run is the one on the network); a down train runs towards
    decreasing chainage."""
    loads, info = operated
    assert len(loads) == len(info["trains"]) == 14  # 6 up, 8 down
    for load, t in zip(loads, info["trains"], strict=True):
        assert t["on_network"] and t["movements"] >= 3  # S1-S2, S2-S3, S3-S4 at least
        assert t["movement_time_mismatch_s"] < 1e-6
        assert np.all(np.diff(load.time_s) >= 0)
        assert np.all(load.traction_power_w >= 0) and np.all(load.regen_power_w >= 0)
        going_up = load.track == "up"
        assert (load.position_m[-1] > load.position_m[0]) == going_up
        assert load.position_m.min() >= 0.0 and load.position_m.max() <= 4590.97 + 1e-6


def test_a_train_held_at_a_signal_asks_more_traction_energy(operated):
    """'after' follows the 100 s late train and is held at a signal (the operation delays it): it
    has one movement more than its three stretches, and asks more traction energy than 'U.1' (same
    train, direction and stops) because it accelerates again from the signal."""
    loads, info = operated
    by_id = {t["id"]: (t, ld) for t, ld in zip(info["trains"], loads, strict=True)}

    def asked_j(ld):
        return float(np.sum(np.diff(ld.time_s) * (ld.traction_power_w[1:] + ld.traction_power_w[:-1]) / 2))

    after, plain = by_id["after"], by_id["U.1"]
    assert after[0]["movements"] == 4 and plain[0]["movements"] == 3
    assert after[0]["delay_s"] > 0
    assert after[0]["movement_time_mismatch_s"] < 1e-6
    assert asked_j(after[1]) > 1.05 * asked_j(plain[1])


@pytest.mark.slow
def test_power_file_with_an_operation_runs_with_its_balance(tmp_path):
    path = _file(tmp_path, simulation={"step_s": 1})
    summary, status = run_power_file(path)
    # SS-S1 goes beyond its overload power: ran, but not as asked (docs/POWER.md, "Status")
    assert status == "substation_overloaded" and summary["statuses"] == ["substation_overloaded"], summary
    assert summary["energy_balance_error"] < 1e-6
    assert summary["operation"]["file"] == OPERATION
    assert len(summary["trains"]) == 14
    # feedback on (the default): the reversible network limits no train, so one iteration and no cap
    assert summary["feedback"]["enabled"] is True and summary["feedback"]["iterations"] == 1
    assert all(t["traction_power_cap_kw"] is None and t["time_lost_s"] == 0.0 for t in summary["trains"])
    assert all(t["traction_demand_kwh"] > 0 for t in summary["trains"])


@pytest.mark.parametrize(
    ("changes", "field", "words"),
    [
        ({"operation": {"file": "missing.yaml", "tracks": {"up": "up"}}}, "operation.file", "not found"),
        ({"operation": {"file": OPERATION, "tracks": {"up": "middle"}}}, "operation.tracks", "unknown track"),
    ],
)
def test_bad_operation_links(tmp_path, changes, field, words):
    path = _file(tmp_path, **changes)
    with pytest.raises(InputError, match=words) as info:
        run_power_file(path)
    assert info.value.problems[0].field == field


def test_trains_and_operation_together_is_an_error(tmp_path):
    path = _file(tmp_path)
    doc = yaml.safe_load(path.read_text())
    doc["trains"] = [{"id": "x", "scenario": "s.yaml", "track": "up", "departures_s": [0]}]
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError, match="either trains"):
        run_power_file(path)
