"""Every TrainRuns.jl train on every TrainRuns.jl path, with its conventions (mass point or
homogeneous strip, constant braking deceleration, Wende / Strahl / Sauthoff resistance)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.constants import KMH
from trainsim.io.loader import load_route, load_train
from trainsim.sim.codes import BRAKE

DATA = Path(__file__).resolve().parents[1] / "data" / "trainruns"
TRAINS = ["freight.yaml", "local.yaml", "longdistance.yaml"]
PATHS = ["const.yaml", "slope.yaml", "speed.yaml", "realworld.yaml"]


def load(train_file: str, path_file: str, mass_model: str = "mass_point"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the default-deceleration notice is tested in tests/io
        return load_train(DATA / "trains" / train_file), load_route(
            DATA / "paths" / path_file, mass_model=mass_model
        )


@pytest.mark.parametrize("mass_model", ["mass_point", "homogeneous_strip"])
@pytest.mark.parametrize("path_file", PATHS)
@pytest.mark.parametrize("train_file", TRAINS)
def test_every_train_runs_every_path(train_file, path_file, mass_model):
    train, route = load(train_file, path_file, mass_model)
    result = trainsim.run_fastest(train, route)
    assert result.status == "ok", result.warnings
    tr = result.trace
    assert np.all(np.isfinite(tr.speed_mps)) and np.all(tr.speed_mps >= 0)
    assert np.all(np.diff(tr.position_m) >= 0)
    assert np.all(tr.speed_mps <= tr.speed_limit_mps + 1e-6)
    assert abs(result.energy_balance["relative_error"]) < 1e-3
    # plausible: slower than running the whole way at the train's top speed, faster than walking
    assert route.length_m / train.max_speed_mps < result.running_time_s < route.length_m / (5 * KMH)


def test_constant_braking_deceleration_is_the_trainruns_convention():
    train, route = load("local.yaml", "const.yaml")
    tr = trainsim.run_fastest(train, route).trace
    braking = tr.regime[:-1] == BRAKE
    decel = -np.diff(tr.speed_mps**2)[braking] / (2 * np.diff(tr.position_m)[braking])
    assert np.allclose(decel, 0.4253, rtol=1e-6)  # a_braking of the Desiro in local.yaml


#: Running times [s] TrainRuns.jl computes for its own test data (test/snapshots/default/*.csv in
#: railtoolkit/TrainRuns.jl, default settings: mass point, distance steps of 20 m).
TRAINRUNS_SNAPSHOTS = {
    ("freight.yaml", "const.yaml"): 745.0704270565875,
    ("freight.yaml", "slope.yaml"): 840.8168602923618,
    ("freight.yaml", "speed.yaml"): 750.452847474394,
    ("freight.yaml", "realworld.yaml"): 8795.025357673,
    ("local.yaml", "const.yaml"): 391.6152532734451,
    ("local.yaml", "slope.yaml"): 395.5151496271005,
    ("local.yaml", "speed.yaml"): 523.3145700077272,
    ("local.yaml", "realworld.yaml"): 3437.5286204688355,
    ("longdistance.yaml", "const.yaml"): 330.7461710917806,
    ("longdistance.yaml", "slope.yaml"): 331.608618035596,
    ("longdistance.yaml", "speed.yaml"): 501.0209113692228,
    ("longdistance.yaml", "realworld.yaml"): 2913.10853000548,
}


@pytest.mark.parametrize(("train_file", "path_file"), sorted(TRAINRUNS_SNAPSHOTS))
def test_running_times_agree_with_trainruns(train_file, path_file):
    """Within 0.7 %: the remaining difference is TrainRuns.jl's first-order 20 m steps (see the
    next test), not a different model."""
    train, route = load(train_file, path_file)
    ours = trainsim.run_fastest(train, route).running_time_s
    assert ours == pytest.approx(TRAINRUNS_SNAPSHOTS[(train_file, path_file)], rel=7e-3)


def first_order_run(train, length_m: float, step_m: float) -> float:
    """An independent re-implementation of TrainRuns.jl's scheme on a level line with one speed
    limit: explicit steps of ``step_m`` with the acceleration of the step's start (Wende 2003,
    p. 37), cruising at the limit, braking at constant deceleration at the last moment."""
    M, vmax, b = train.inertial_mass_kg, train.max_speed_mps, train.braking.deceleration_mps2
    s = v = t = 0.0
    while v * v / (2 * b) < length_m - s:
        h = min(step_m, length_m - s - v * v / (2 * b))
        if v >= vmax - 1e-9:
            s, t = s + h, t + h / v
            continue
        a = (float(train.traction(v)) - float(train.running_resistance_n(v))) / M
        v1 = np.sqrt(v * v + 2 * h * a)
        if v1 > vmax:
            h, v1 = (vmax**2 - v * v) / (2 * a), vmax
        s, t, v = s + h, t + (v1 - v) / a, v1
    return t + v / b


@pytest.mark.parametrize("train_file", TRAINS)
def test_trainruns_difference_is_its_step_size(train_file):
    train, route = load(train_file, "const.yaml")
    ours = trainsim.run_fastest(train, route).running_time_s
    snapshot = TRAINRUNS_SNAPSHOTS[(train_file, "const.yaml")]
    # with TrainRuns.jl's 20 m steps the independent scheme reproduces its published time ...
    assert first_order_run(train, 10_000.0, 20.0) == pytest.approx(snapshot, rel=2e-4)
    # ... and with fine steps it converges to trainsim's result
    assert first_order_run(train, 10_000.0, 0.5) == pytest.approx(ours, rel=2e-4)


def test_homogeneous_strip_smooths_grade_changes():
    """Averaged over its length the train feels a grade change gradually: its gradient force ramps
    over one train length instead of jumping."""
    train, route = load("freight.yaml", "slope.yaml", "homogeneous_strip")
    tr = trainsim.run_fastest(train, route).trace
    near = (tr.position_m > 1000.0) & (tr.position_m < 1000.0 + train.length_m)
    g = tr.gradient_resistance_n[near]
    weight = train.mass_kg * 9.81
    assert g.min() > 0.0 * weight and g.max() < 0.002 * weight  # between the 0 and 2 per mille steps
    assert np.all(np.diff(g) >= -1e-6)
