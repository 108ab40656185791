"""A power study that ran, but not as asked, says so in ``status`` / ``statuses``, in the table and in the
exit code (docs/POWER.md, "Status"); informational conditions stay warnings.

Small cases solve one train standing between two substations for ten seconds (each condition made on
purpose); the shipped examples check the rule end to end: the weak line (time lost, a substation beyond
its overload power) exits with 3, a strong line with 0."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.power import Network, Substation, Track, standard_limits
from trainsim.power.simulation import TrainLoad, simulate
from trainsim.power.study import STATUSES, TIME_LOST_TOLERANCE_S, with_status

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "power"


def _network(
    *, rated_w: float | None = None, overload_w: float | None = None, traction_full_v=None
) -> Network:
    """4 km of 750 V line fed from both ends by diode rectifiers (EN 50163 limits of dc_750)."""
    limits = standard_limits("dc_750").with_overrides(traction_full_v=traction_full_v)
    subs = tuple(
        Substation(name, x, ("A",), e, r, rated_power_w=rated_w, overload_power_w=overload_w)
        for name, x, e, r in (("S1", 0.0, 835.0, 0.03), ("S2", 4000.0, 825.0, 0.05))
    )
    return Network(
        "two", "dc", limits, (Track("A", 0.0, 4000.0, 0.02e-3, 0.015e-3),), subs, contact_leakage_s=1e-12
    )


def _train(traction_w: float = 1e6, regen_w: float = 0.0, aux_w: float = 0.0) -> TrainLoad:
    """One train standing mid-line for 10 s asking constant traction and offering constant regeneration."""
    t = np.array([0.0, 10.0])
    return TrainLoad("T", "A", t, np.full(2, 2000.0), np.full(2, traction_w), np.full(2, regen_w), aux_w)


def _summary(network: Network, load: TrainLoad, **extra) -> dict:
    result = simulate(network, [load])
    if extra:
        result = dataclasses.replace(result, extra=extra)
    return with_status(result).summary()


def test_a_train_fed_in_full_is_ok():
    s = _summary(_network(), _train())
    assert s["status"] == "ok" and s["statuses"] == [] and s["warnings"] == []


def test_beyond_the_overload_power_is_a_status_above_the_rating_a_warning():
    # 3 MW shared by two substations: each gives about 1.5 MW
    beyond = _summary(_network(rated_w=0.5e6, overload_w=0.8e6), _train(3e6))
    assert "substation_overloaded" in beyond["statuses"]
    within = _summary(_network(rated_w=0.5e6, overload_w=5e6), _train(3e6, aux_w=0.0))
    assert "substation_overloaded" not in within["statuses"]
    assert any("above its rated power" in w for w in within["warnings"])


def test_limited_traction_not_fed_back_is_a_status():
    # full traction only above 830 V: the loaded line sits below it, so the train gets less than it asks
    s = _summary(_network(traction_full_v=830.0), _train(2e6))
    assert s["statuses"] == ["traction_limited"] and s["status"] == "traction_limited"
    assert s["trains"][0]["traction_delivered_kwh"] < s["trains"][0]["traction_demand_kwh"]


def test_curtailed_regeneration_is_information_only():
    # a lone braking train on diode rectifiers: the line takes only what its auxiliaries use
    s = _summary(_network(), _train(0.0, regen_w=3e6, aux_w=50e3))
    assert s["regen_kwh"]["dissipated"] > 0.9 * s["regen_kwh"]["offered"]
    assert s["status"] == "ok" and s["statuses"] == []
    assert any("regenerative braking curtailed" in w for w in s["warnings"])


@pytest.mark.parametrize(
    ("lost_s", "status"),
    [(0.0, "ok"), (TIME_LOST_TOLERANCE_S * 0.99, "ok"), (TIME_LOST_TOLERANCE_S * 1.01, "time_lost")],
)
def test_time_lost_beyond_the_tolerance_is_a_status(lost_s, status):
    trains = [{"id": "T", "time_lost_s": lost_s}]
    feedback = {"enabled": True, "consistent": True, "iterations": 2}
    s = _summary(_network(), _train(), trains=trains, feedback=feedback)
    assert s["status"] == status and s["trains"][0]["status"] == status
    assert s["statuses"] == ([] if status == "ok" else ["time_lost"])


def test_every_condition_is_listed_most_severe_first_and_twice_gives_the_same():
    result = simulate(_network(rated_w=0.5e6, overload_w=0.8e6), [_train(3e6)])
    extra = {
        "trains": [{"id": "T", "time_lost_s": 30.0}],
        "feedback": {"enabled": True, "consistent": False, "iterations": 10},
    }
    result = dataclasses.replace(result, converged=np.zeros_like(result.converged), extra=extra)
    once = with_status(result)
    s = once.summary()
    want = ["not_converged", "feedback_not_converged", "substation_overloaded", "time_lost"]
    assert s["statuses"] == want and s["status"] == "not_converged"
    assert list(STATUSES).index("not_converged") == 0 and list(STATUSES)[-1] == "ok"
    assert with_status(once).summary() == s


@pytest.fixture(scope="module")
def weak(tmp_path_factory) -> tuple[int, dict, str]:
    out = tmp_path_factory.mktemp("weak")
    run = CliRunner().invoke(
        app, ["power", str(EXAMPLES / "metro_750v_weak_per_step.yaml"), "--out", str(out), "--no-plots"]
    )
    return run.exit_code, json.loads((out / "summary.json").read_text()), run.output


def test_weak_line_time_lost_shows_in_status_table_json_and_exit_code(weak):
    code, s, printed = weak
    assert code == 3, printed
    assert "time_lost" in s["statuses"] and s["status"] == s["statuses"][0] != "ok"
    lost = [t for t in s["trains"] if t["time_lost_s"] > TIME_LOST_TOLERANCE_S]
    assert lost, "the weak line must cost running time, else this test shows nothing"
    for t in s["trains"]:
        assert t["status"] == ("time_lost" if t in lost else "ok")
        assert f"train {t['id']}: time_lost" in printed or t not in lost
    assert f"status: {s['status']}" in printed and "time_lost" in printed.split("status:")[-1]


def test_strong_line_is_ok_and_exits_0():
    run = CliRunner().invoke(app, ["power", str(EXAMPLES / "metro_750v_reversible.yaml"), "--json"])
    assert run.exit_code == 0, run.output
    s = json.loads(run.stdout)
    assert s["status"] == "ok" and s["statuses"] == []
    assert all(t["status"] == "ok" for t in s["trains"])
    assert max(t["time_lost_s"] for t in s["trains"]) <= TIME_LOST_TOLERANCE_S
