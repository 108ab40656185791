"""The compiled multi-point kernel (multipoint/_mp_c.pyx) gives the numba kernel's bits (issue 14).

Every call of the kernel's ``run`` and ``record`` in a run is made twice, once by the numba kernel
and once by the compiled one, on copies of the same arrays; every array and every returned value
must be the same bits.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpcases import freight_train, hilly_route

from trainsim.multipoint import (
    BrakePropagation,
    CouplerModel,
    MultiPointSession,
    MultiPointSettings,
    run_multipoint_fastest,
    simulate,
)
from trainsim.multipoint import _mp_c as mpc
from trainsim.multipoint import kernel as mpk


def _copy(a):
    if isinstance(a, np.ndarray):
        return a.copy()
    if isinstance(a, tuple):
        return tuple(_copy(x) for x in a)
    return a


def _differences(a, b, path="") -> list[str]:
    if isinstance(a, np.ndarray):
        same = (
            a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))
        )
        return [] if same else [path]
    if isinstance(a, tuple):
        return [
            d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in _differences(x, y, f"{path}[{i}]")
        ]
    same = (a == b or (a != a and b != b)) and isinstance(b, type(a) if not isinstance(a, int) else int)
    return [] if same else [f"{path}: {a!r} != {b!r}"]


def _write_back(dst, src):
    if isinstance(dst, np.ndarray):
        dst[...] = src
    elif isinstance(dst, tuple):
        for d, s in zip(dst, src, strict=True):
            _write_back(d, s)


@pytest.fixture
def both(monkeypatch):
    """Route simulate's kernel calls through a comparison of the numba and the compiled kernel."""
    seen = {"run": 0, "record": 0, "differences": []}

    def paired(name, numba_fn, compiled_fn):
        def call(*args):
            a1, a2 = _copy(args), _copy(args)
            r1, r2 = numba_fn(*a1), compiled_fn(*a2)
            seen[name] += 1
            seen["differences"] += [f"{name}: {d}" for d in _differences((a1, r1), (a2, r2))]
            _write_back(args, a1)
            return r1

        return call

    monkeypatch.setattr(simulate, "_mp_c", _KernelProxy(paired))
    return seen


class _KernelProxy:
    """The compiled kernel with ``run`` and ``record`` paired with numba's."""

    def __init__(self, paired):
        self.run = paired("run", mpk.run, mpc.run)
        self.record = paired("record", mpk.record, mpc.record)

    def __getattr__(self, name):
        return getattr(mpc, name)


def test_fastest_run_with_stops_slack_delay_and_step_control_is_the_numba_run(both):
    train = freight_train(30, locos=2, regen_fraction=0.8, electrical=True)
    settings = MultiPointSettings(
        couplers=CouplerModel(slack_m=0.025, friction_ratio=0.3),
        locomotive_positions=(0, 16),
        brake_propagation=BrakePropagation(speed_mps=250.0, build_up_s=3.0),
        force_tolerance_n=2e4,
        initial_couplers="bunched",
        traction_ramp_s=20.0,
    )
    r = run_multipoint_fastest(train, hilly_route(6_000.0, stop_at=3_000.0, dwell_s=20.0), settings)
    assert r.status == "ok"
    assert both["run"] >= 2 and both["record"] >= 2
    assert both["differences"] == []


def test_session_with_fixed_and_per_locomotive_commands_is_the_numba_run(both):
    session = MultiPointSession(
        freight_train(12, locos=2, regen_fraction=0.8),
        hilly_route(4_000.0, stop_at=1_500.0, dwell_s=10.0, curves=True),
        MultiPointSettings(couplers=CouplerModel(slack_m=0.02), locomotive_positions=(0, 7)),
    )
    for _ in range(40):
        session.step(1.0, 1.0)
    for _ in range(10):
        session.step(0.0, 1.0, loco_commands=[1.0, -0.5])
    for _ in range(30):
        session.step(-0.6, 1.0)
    assert both["run"] >= 80
    assert both["differences"] == []


def test_forces_and_coupler_laws_are_the_numba_ones():
    rng = np.random.default_rng(14)
    for row in (CouplerModel().as_row(), CouplerModel(slack_m=0.05, friction_ratio=0.3).as_row()):
        for d, v in zip(rng.normal(0.0, 0.05, 2000), rng.normal(0.0, 0.3, 2000), strict=True):
            assert mpk.coupler_force(d, v, row) == mpc.coupler_force(d, v, row)
            assert mpk.coupler_energy(d, row) == mpc.coupler_energy(d, row)
    z = np.concatenate([rng.normal(0.0, s, 2000) for s in (1e-3, 1.0, 30.0)] + [np.array([22.0, -22.0, 0.0])])
    assert all(mpk.tanh(x) == mpc.tanh(x) for x in z)
    n = 40
    diag, off, rhs = rng.uniform(5.0, 9.0, n), rng.uniform(-2.0, 2.0, n - 1), rng.normal(0.0, 1.0, n)
    out1, out2 = np.empty(n), np.empty(n)
    mpk.thomas(diag, off, rhs, out1, np.empty(n))
    mpc.thomas(diag, off, rhs, out2, np.empty(n))
    assert np.array_equal(out1, out2)


def test_bad_arrays_are_refused_naming_the_argument():
    with pytest.raises(ValueError, match=r"cp: need a C-contiguous float64 array of shape \(11,\)"):
        mpc.coupler_force(0.0, 0.0, np.zeros(10))
    with pytest.raises(
        ValueError, match=r"rhs: need a C-contiguous float64 array of shape \(3,\).*format 'l'"
    ):
        mpc.thomas(np.ones(3), np.zeros(2), np.zeros(3, dtype=np.int64), np.empty(3), np.empty(3))
    with pytest.raises(ValueError, match=r"out: need a C-contiguous writable float64"):
        out = np.empty(3)
        out.flags.writeable = False
        mpc.thomas(np.ones(3), np.zeros(2), np.zeros(3), out, np.empty(3))
