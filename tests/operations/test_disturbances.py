"""Sampled entry, dwell and running-time disturbances: seeded, given as data, delays propagating."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import monte_carlo, run_operation
from trainsim.operations.disturbances import Distribution, disturbances_from_dict

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "operations" / "metro_fixed_block.yaml"


def _file(tmp_path: Path, block: str) -> Path:
    text = EXAMPLE.read_text().replace("../metro_b/", f"{ROOT / 'examples' / 'metro_b'}/")
    path = tmp_path / "op.yaml"
    path.write_text(text + "\n" + block + "\n")
    return path


def test_distributions_draw_what_their_parameters_say() -> None:
    rng = np.random.default_rng(0)
    assert Distribution("fixed", (42.0,)).draw(rng) == 42.0
    assert Distribution("fixed", (42.0,), probability=0.0).draw(rng) == 0.0
    draws = np.array([Distribution("exponential", (60.0,)).draw(rng) for _ in range(20000)])
    assert draws.mean() == pytest.approx(60.0, rel=0.03)
    draws = np.array([Distribution("uniform", (10.0, 20.0)).draw(rng) for _ in range(20000)])
    assert draws.min() >= 10 and draws.max() <= 20 and draws.mean() == pytest.approx(15.0, rel=0.01)
    draws = np.array([Distribution("lognormal", (30.0, 0.5)).draw(rng) for _ in range(20000)])
    assert np.median(draws) == pytest.approx(30.0, rel=0.03)
    # a normal draw below zero is no disturbance
    assert min(Distribution("normal", (0.0, 10.0)).draw(rng) for _ in range(100)) == 0.0


def test_fixed_disturbances_land_where_they_belong_and_delays_propagate(tmp_path) -> None:
    plain = read_operation(_file(tmp_path, ""))
    op = read_operation(
        _file(
            tmp_path,
            "disturbances: {seed: 1, dwell: {kind: fixed, value_s: 40}, running: {kind: fixed, value_s: 5}}",
        )
    )
    first = op.services[0]
    base = plain.services[0]
    assert first.entry_delay_s == base.entry_delay_s  # running time is lost on the run, not at the origin
    assert first.running_extra_s == (5.0, 5.0, 5.0)
    assert [s.dwell_s for s in first.stops] == [s.dwell_s for s in base.stops]
    assert [s.extra_dwell_s for s in first.stops] == [40.0 for s in base.stops]
    res, ref = run_operation(op), run_operation(plain)
    delay = {t.id: t.delay_s for t in res.trains}
    ref_delay = {t.id: t.delay_s for t in ref.trains}
    # the lone down train loses what it was given: 5 s per stretch (3) and 40 s per stop (2)
    assert delay["D.1"] == pytest.approx(ref_delay["D.1"] + 3 * 5.0 + 2 * 40.0, abs=1e-6)
    # the up trains follow each other at 150 s: later ones are also hindered by those before them
    ups = sorted((t for t in res.trains if t.direction == "up"), key=lambda t: t.id)
    assert any(h.kind in ("signal", "slowed", "stop") for t in ups[1:] for h in t.hindrances)
    assert max(delay[t.id] for t in ups) > 3 * 5.0 + 2 * 40.0


def test_time_scaled_running_time_disturbances_are_spread_along_the_run(tmp_path) -> None:
    """Delays only (``disturbed_energy=False``): a sampled running-time extension makes the stretch's
    run slower, not its departure later: the train is late at every point of the stretch by the
    extension's share of the running time it has run, and arrives exactly the sampled extension later;
    the trajectory says it is time-scaled. (Driven as capped runs: test_disturbed_runs.py.)"""
    block = "disturbances: {seed: 3, running: {kind: uniform, low_s: 2, high_s: 30}}"
    op = read_operation(_file(tmp_path, block))
    down = next(s for s in op.services if s.id == "D.1")
    extra = np.array(down.running_extra_s)
    assert extra.shape == (3,) and np.all((extra >= 2) & (extra <= 30)) and len(set(extra)) == 3
    outcome = next(t for t in run_operation(op, [down], disturbed_energy=False).trains if t.id == "D.1")
    assert outcome.hindrances == [] and down.entry_delay_s == 0.0
    assert "time-scaled" in outcome.trajectory_note
    plan, real = outcome.planned_trajectory, outcome.trajectory
    np.testing.assert_array_equal(plan.position_m, real.position_m)  # the same path, driven slower
    path = op.line.paths["down"]
    stops_m = [path.stop_m[n] for n in (down.origin, *(x.station for x in down.stops), down.destination)]
    stops_m = sorted(set(stops_m))
    assert len(stops_m) == 4
    lost = 0.0
    for p0, p1, e in zip(stops_m[:-1], stops_m[1:], extra, strict=True):
        # from leaving p0 (the last point there) to arriving at p1 (the first point there)
        a = int(np.flatnonzero(plan.position_m <= p0 + 1e-9)[-1])
        b = int(np.flatnonzero(plan.position_m >= p1 - 1e-9)[0])
        t_plan = plan.time_s[a : b + 1]
        rt = t_plan[-1] - t_plan[0]
        share = e * (t_plan - t_plan[0]) / rt
        np.testing.assert_allclose(real.time_s[a : b + 1] - t_plan, lost + share, atol=1e-9)
        # the slower run: speed divided by the time factor at every point
        np.testing.assert_allclose(
            real.speed_mps[a : b + 1] * (1 + e / rt), plan.speed_mps[a : b + 1], atol=1e-12
        )
        lost += e
    assert outcome.delay_s == pytest.approx(extra.sum(), abs=1e-6)
    arrival = outcome.stops[-1]
    assert arrival.arrival_s - arrival.scheduled_arrival_s == pytest.approx(extra.sum(), abs=1e-6)


def test_running_time_disturbances_of_the_wrong_length_are_refused(tmp_path) -> None:
    op = read_operation(_file(tmp_path, ""))
    bad = replace(op.services[0], running_extra_s=(1.0, 2.0))
    with pytest.raises(InputError, match="running_extra_s"):
        run_operation(op, [bad])


def test_the_same_seed_gives_the_same_days(tmp_path) -> None:
    block = (
        "disturbances: {seed: 7, entry: {kind: exponential, mean_s: 60, probability: 0.3}, "
        "dwell: {kind: lognormal, median_s: 10, sigma: 0.5, probability: 0.5}}"
    )
    a, b = read_operation(_file(tmp_path, block)), read_operation(_file(tmp_path, block))

    def drawn(op):
        return [(s.entry_delay_s, [x.extra_dwell_s for x in s.stops]) for s in op.services]

    assert drawn(a) == drawn(b) and any(d[0] > 0 for d in drawn(a))
    mc1, mc2 = monte_carlo(a, 3), monte_carlo(b, 3)
    assert mc1["total_delay_s"] == mc2["total_delay_s"] and mc1["seed"] == 7
    assert monte_carlo(a, 3, seed=8)["trains"] != mc1["trains"]


@pytest.mark.parametrize(
    ("block", "field"),
    [
        ({"seed": 1, "dwell": {"kind": "gamma", "mean_s": 3}}, "disturbances.dwell.kind"),
        ({"seed": 1, "dwell": {"kind": "exponential"}}, "disturbances.dwell.mean_s"),
        ({"seed": 1, "dwell": {"kind": "uniform", "low_s": 5, "high_s": 1}}, "disturbances.dwell.high_s"),
        (
            {"seed": 1, "entry": {"kind": "fixed", "value_s": 1, "probability": 2}},
            "disturbances.entry.probability",
        ),
        ({"seed": -1}, "disturbances.seed"),
        ({"seed": 1, "wind": {}}, "disturbances.wind"),
    ],
)
def test_bad_disturbances_name_the_field(block, field) -> None:
    with pytest.raises(InputError) as err:
        disturbances_from_dict(block, "op.yaml")
    assert field in str(err.value)


def test_delays_and_disturbances_together_are_an_input_error(tmp_path) -> None:
    block = "delays: {seed: 1, probability: 0.2, mean_s: 60}\ndisturbances: {seed: 1}"
    with pytest.raises(InputError, match="either 'delays' or 'disturbances'"):
        read_operation(_file(tmp_path, block))
