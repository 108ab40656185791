"""The compiled exact energy integration (``sim/_energy_c.pyx``, Cython) gives the same bits as the
numba ``energy.stretch_works`` on the arguments real runs hand it (issue 14)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model.scenario import RunSettings
from trainsim.sim import _energy_c, codes, energy
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[2]
TRAINRUNS = next(
    (
        d
        for d in (ROOT.parent / "shared" / "data" / "trainruns", ROOT / "tests" / "data" / "trainruns")
        if (d / "paths" / "realworld.yaml").exists()
    ),
    None,
)
EXAMPLES = (
    "metro_b/scenario.yaml",
    "heavy_haul/scenario_head.yaml",
    "loco_001/scenario.yaml",
    "freight_000/scenario.yaml",
)


def _recorded(monkeypatch_target, run) -> list[tuple]:
    """The arguments of every compiled ``stretch_works`` call that ``run()`` makes (``run_works``)."""
    calls: list[tuple] = []
    original = _energy_c.stretch_works

    def record(*args):
        calls.append(args)
        return original(*args)

    monkeypatch_target.setattr(_energy_c, "stretch_works", record)
    run()
    monkeypatch_target.undo()
    return calls


@pytest.fixture(scope="module")
def cases() -> dict[str, tuple]:
    """name -> stretch_works arguments of the fastest runs of the examples and of the TrainRuns.jl
    freight train on realworld, and of the optimal run of the metro with regenerative braking."""
    out: dict[str, tuple] = {}
    mp = pytest.MonkeyPatch()
    for example in EXAMPLES:
        sc = trainsim.load_scenario(ROOT / "examples" / example)
        (out[example],) = _recorded(mp, lambda sc=sc: run_fastest(sc.train, sc.route, sc.settings))
    if TRAINRUNS is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            train = load_train(TRAINRUNS / "trains" / "freight.yaml")
        route = load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="mass_point")
        (out["freight realworld"],) = _recorded(mp, lambda: run_fastest(train, route, RunSettings()))
    from trainsim.optimize.api import optimize

    sc = trainsim.load_scenario(ROOT / "examples/metro_b/scenario_eco.yaml")
    regen = sc.train.traction.scaled(0.8)
    train = dataclasses.replace(sc.train, braking=dataclasses.replace(sc.train.braking, regenerative=regen))
    calls = _recorded(mp, lambda: optimize(train, sc.route, sc.timetable, "optimal", sc.settings))
    for j, args in enumerate(calls):
        out[f"metro optimal regenerative {j}"] = args
    return out


def _variants(args: tuple) -> dict[str, tuple]:
    """The recorded arguments, and the same points with every stretch prescribed (FOLLOW), with the
    driver's level at 0.7 (most stretches then do not follow their regime and are integrated as
    their recorded motion), with coasting instead of cruising, and with a constant service
    deceleration instead of a braking force law."""
    s, v, regime, level, lx, laws, P, curves, tk, bk, rk = args
    P_decel = P.copy()
    P_decel[codes.P_DECEL] = 0.8
    coast = np.where(regime == codes.CRUISE, codes.COAST, regime)
    return {
        "recorded": args,
        "follow": (s, v, np.where(regime == codes.DWELL, regime, codes.FOLLOW), level, *args[4:]),
        "level 0.7": (s, v, regime, np.full_like(level, 0.7), *args[4:]),
        "coast": (s, v, coast, level, *args[4:]),
        "deceleration": (s, v, regime, level, lx, laws, P_decel, curves, tk, bk, rk),
    }


def _assert_same_bits(want: tuple, got: tuple, case: str) -> None:
    assert len(got) == len(want) == 3
    for w, g in zip(want, got, strict=True):
        assert g.dtype == w.dtype and g.shape == w.shape, case
        assert np.array_equal(w, g), (case, np.max(np.abs(w.astype(float) - g.astype(float))))


def test_every_stretch_has_the_same_works_as_the_numba_integration(cases):
    assert len(cases) >= len(EXAMPLES) + 1
    off_regime = 0
    for name, args in cases.items():
        for variant, a in _variants(args).items():
            want = energy.stretch_works(*a)
            off_regime += int(want[2].sum())
            _assert_same_bits(want, _energy_c.stretch_works(*a), f"{name}, {variant}")
    # the variants reach the integration of recorded motions, not only the regimes' own
    assert off_regime > 100


def test_the_compiled_settings_are_the_modules():
    got = _energy_c.integration_settings()
    for name in (
        "MAX_SUBSTEP_M",
        "LENGTH_SCALE_FRACTION",
        "MIN_SUBSTEP_M",
        "MAX_SUBSTEPS",
        "KINK_MARGIN_MPS",
        "OFF_REGIME_SPEED_MPS",
        "OFF_REGIME_RELATIVE",
        "N_WORKS",
    ):
        assert got[name] == getattr(energy, name), name
    assert got["POSITION_TOLERANCE"] == codes.POSITION_TOLERANCE
    assert got["GL_X"] == energy._GL_X.tolist()
    assert got["GL_W"] == energy._GL_W.tolist()


def test_bad_arguments_are_refused_with_what_is_allowed(cases):
    args = list(cases["metro_b/scenario.yaml"])
    with pytest.raises(ValueError, match="v has 3 values, needs"):
        _energy_c.stretch_works(args[0], args[1][:3], *args[2:])
    bad_regime = args[2].copy()
    bad_regime[1] = 9
    with pytest.raises(ValueError, match=r"regime codes must be 0\.\.6"):
        _energy_c.stretch_works(*args[:2], bad_regime, *args[3:])
    with pytest.raises(ValueError, match="tk must be sorted increasing"):
        _energy_c.stretch_works(*args[:8], np.array([2.0, 1.0]), *args[9:])
    with pytest.raises(ValueError, match="laws must be"):
        _energy_c.stretch_works(*args[:5], args[5][:6], *args[6:])
    P = args[6].copy()
    P[codes.P_INERTIAL_MASS] = 0.0
    with pytest.raises(ValueError, match="inertial mass"):
        _energy_c.stretch_works(*args[:6], P, *args[7:])
    with pytest.raises(ValueError, match="s has 0 values"):
        _energy_c.stretch_works(np.zeros(0), np.zeros(0), np.zeros(0, int), np.zeros(0), *args[4:])
    works, v_end, off = _energy_c.stretch_works(
        np.zeros(1), np.zeros(1), np.zeros(1, int), np.ones(1), *args[4:]
    )
    assert works.shape == (0, 6) and v_end.shape == (0,) and off.dtype == np.bool_
