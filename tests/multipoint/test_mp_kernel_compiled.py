"""The compiled multi-point kernel (multipoint/_mp_c.pyx) against independent computations (issue 14).

It replaced a numba kernel bit for bit (paired on every run and record call of real cases before the
numba code was deleted, commits f6b7180 and 18b6c78); these tests hold it to cases whose answers are known without
it: the Thomas solver against numpy.linalg.solve, two masses on a linear coupling against the implicit
midpoint rule's exact discrete solution (amplitude kept, phase 2 atan(omega h / 2) per step), the
energy of an oscillation with dampers (spring + kinetic energy + damper work constant), and bad
arguments refused naming the argument. The figures of the multi-point examples are checked by the
other tests of tests/multipoint.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from trainsim.multipoint import _mp_c as mpc
from trainsim.multipoint import kernel as mpk
from trainsim.sim import codes

H_S = 0.05  # time step [s]
K_N_PER_M = 8.4e6  # coupler stiffness [N/m]
M1_KG, M2_KG = 120e3, 80e3  # inertial masses of the two vehicles [kg]
DELTA0_M = 0.05  # initial extension of the coupling [m]
LENGTH_M = 20.0  # length over couplers of the front vehicle [m]


def two_masses(steps: int, damping_n_s_per_m: float = 0.0) -> dict[str, np.ndarray]:
    """Two vehicles on one linear coupling (no slack, no resistance, no brakes, level track), released
    at rest with the coupling stretched by DELTA0_M; fixed steps of H_S, a record at every step."""
    n = 2
    VP = np.zeros((n, mpk.N_V))
    VP[:, mpk.V_MASS] = VP[:, mpk.V_INERTIAL] = (M1_KG, M2_KG)
    VP[:, mpk.V_LENGTH] = LENGTH_M
    VP[:, mpk.V_CURVE] = -1
    CP = np.zeros((1, mpk.N_C))
    CP[0, [mpk.C_KD, mpk.C_KB, mpk.C_KS]] = K_N_PER_M
    CP[0, [mpk.C_CD, mpk.C_CB]] = damping_n_s_per_m
    CP[0, [mpk.C_TD, mpk.C_TB]] = 1e3  # the solid stage never engages
    CP[0, mpk.C_EPS] = 1e-3  # equal draft and buff stiffness: the rounded kinks cancel, the law is linear
    CP[0, mpk.C_VF] = 0.01
    SP = np.zeros(mpk.N_S)
    SP[[mpk.S_STEP, mpk.S_STEP_MIN, mpk.S_RECORD_DT]] = H_S
    SP[mpk.S_VEPS] = 1e-3
    SP[mpk.S_BRAKE_FRACTION] = SP[mpk.S_TAU] = SP[mpk.S_ETA_T] = 1.0
    SP[mpk.S_REST_SPEED] = 5e-3
    SP[mpk.S_STOP_WINDOW] = 2.0
    SP[mpk.S_REGEN_CURVE] = -1
    SP[mpk.S_G] = 9.81
    SP[mpk.S_STALL_S] = 60.0
    SP[mpk.S_NEWTON_TOL] = 1e-12
    bank = (np.zeros(1), np.zeros((1, 4)), np.array([0, 1]), np.array([np.inf]), np.array([np.inf]))
    prof = (np.array([0, 2]), np.array([-1e6, 1e6]), np.zeros((2, 4)))
    avail = (np.array([-1e6, 1e6]), np.ones(1))
    ref = (np.zeros(2), np.zeros(2), np.zeros(2, dtype=np.int8), 0.0)
    ceiling = (np.array([-1e6, 1e6]), np.full(1, 50.0), np.full(1, 50.0))
    x = np.array([0.0, -LENGTH_M - DELTA0_M])
    state = (x, np.zeros(n), np.zeros(n), np.zeros(1), np.zeros(n), np.zeros(1), np.zeros(n, dtype=np.int64),
             np.zeros((3, 1)), np.zeros(3))  # fmt: skip
    hist = np.zeros((8, 2))
    hist[0] = (-1e30, 0.0)
    acc = np.zeros(mpk.N_A)
    acc[mpk.A_PEAK_POWER] = -np.inf
    acc[mpk.A_REST_SINCE] = -1.0
    cap = steps + 2
    rec = {"t": np.zeros(cap), "x": np.zeros((cap, n)), "v": np.zeros((cap, n)), "a": np.zeros((cap, n)),
           "T": np.zeros((cap, 1)), "agg": np.zeros((cap, mpk.N_R))}  # fmt: skip
    ext = np.zeros(mpk.N_E + mpk.N_EK)
    ext[[mpk.E_DRAFT, mpk.N_E + mpk.EK_DRAFT]] = -np.inf
    ext[[mpk.E_BUFF, mpk.N_E + mpk.EK_BUFF]] = np.inf
    CMD = np.zeros(mpk.N_K)
    nrec = mpc.record(0, 0.0, x, state[1], state[4], VP, CP, CMD, np.zeros((n, 7)), acc, *rec.values())
    state[5][0] = H_S
    status, _, nrec = mpc.run(
        0, steps * H_S + 1e-9, state, VP, CP, SP, CMD, np.zeros(n), np.zeros(n), bank, prof, avail, ref,
        ceiling, hist, 1, acc, *rec.values(), nrec, ext, 1e9,
    )  # fmt: skip
    assert status == mpk.ST_TIME
    return {k: v[:nrec] for k, v in rec.items()} | {"acc": acc, "ext": ext}


@pytest.fixture(scope="module")
def oscillation():
    return two_masses(400)


def test_two_masses_on_a_coupling_follow_the_midpoint_rules_exact_discrete_solution(oscillation):
    r = oscillation
    steps = np.arange(len(r["t"]))
    assert np.allclose(r["t"], steps * H_S, rtol=0, atol=1e-9)
    omega = np.sqrt(K_N_PER_M * (1 / M1_KG + 1 / M2_KG))  # relative motion [rad/s]
    # the implicit midpoint rule turns a harmonic oscillator by 2 atan(omega h / 2) a step, amplitude kept
    theta = 2.0 * np.arctan(omega * H_S / 2.0)
    delta = r["x"][:, 0] - LENGTH_M - r["x"][:, 1]
    assert np.max(np.abs(delta - DELTA0_M * np.cos(steps * theta))) < 1e-9
    rate = r["v"][:, 0] - r["v"][:, 1]
    # speed of the discrete solution: delta_n+1 - delta_n = h (rate_n + rate_n+1) / 2
    assert np.max(np.abs(rate + DELTA0_M * (2.0 / H_S) * np.tan(theta / 2) * np.sin(steps * theta))) < 1e-8
    # the centre of mass stays at rest (momentum is zero), the coupling's force is k delta
    assert np.max(np.abs(M1_KG * r["v"][:, 0] + M2_KG * r["v"][:, 1])) < 1e-6
    assert np.allclose(r["T"][:, 0], K_N_PER_M * delta, rtol=1e-12, atol=1e-3)
    # the extremes taken at every step are the record's (a record at every step)
    assert r["ext"][mpk.E_DRAFT] == pytest.approx(r["T"][1:, 0].max(), rel=1e-15)
    assert r["ext"][mpk.E_BUFF] == pytest.approx(r["T"][1:, 0].min(), rel=1e-15)


def test_energy_of_an_undamped_oscillation_is_conserved(oscillation):
    agg = oscillation["agg"]
    energy = agg[:, mpk.R_KINETIC] + agg[:, mpk.R_SPRING]
    # the rounded kinks of draft and buff add k eps^2 / 6 to the linear spring's k delta^2 / 2
    assert energy[0] == pytest.approx(K_N_PER_M * (DELTA0_M**2 / 2 + 1e-3**2 / 6), rel=1e-12)
    assert np.max(np.abs(energy / energy[0] - 1.0)) < 1e-9
    # the spring work account is minus the change of the spring energy
    spring_work = agg[:, mpk.R_W0 + mpk.A_SPRING_WORK]
    assert np.allclose(
        spring_work, agg[0, mpk.R_SPRING] - agg[:, mpk.R_SPRING], rtol=0, atol=1e-9 * energy[0]
    )


def test_dampers_remove_what_the_damper_work_accounts_for():
    c = 2e5  # [N s/m]
    r = two_masses(400, damping_n_s_per_m=c)
    agg = r["agg"]
    energy = agg[:, mpk.R_KINETIC] + agg[:, mpk.R_SPRING]
    damper = agg[:, mpk.R_W0 + mpk.A_DAMPER]
    assert energy[-1] < 0.2 * energy[0]  # decays: zeta = c / (2 sqrt(k mu)) = 0.12
    assert np.max(np.abs(energy + damper - energy[0])) < 1e-9 * energy[0]


@pytest.mark.parametrize("n", [1, 2, 7, 60])
def test_thomas_solves_a_tridiagonal_system_as_numpy_linalg(n):
    rng = np.random.default_rng(n)
    off = rng.uniform(-2.0, 2.0, max(n - 1, 1))
    diag = rng.uniform(4.5, 9.0, n)
    rhs = rng.normal(0.0, 1.0, n)
    out = np.empty(n)
    mpc.thomas(diag, off, rhs, out, np.empty(n))
    a = np.diag(diag) + np.diag(off[: n - 1], 1) + np.diag(off[: n - 1], -1)
    assert np.allclose(out, np.linalg.solve(a, rhs), rtol=1e-13, atol=1e-14)


def test_constants_of_the_compiled_module_are_the_kernels_and_the_regime_codes():
    for name, value in mpc.CONSTANTS.items():
        where = codes if name in ("TRACTION", "CRUISE", "COAST", "BRAKE", "REGEN", "FOLLOW") else mpk
        assert getattr(where, name) == value, name


def test_tanh_shortcut_is_tanh_bit_for_bit():
    z = np.concatenate([np.random.default_rng(14).normal(0.0, s, 5000) for s in (1e-3, 1.0, 30.0)])
    z = np.concatenate([z, [22.0, -22.0, np.nextafter(22.0, 0.0), -np.nextafter(22.0, 0.0), 0.0, np.inf]])
    # against the C library's tanh (math.tanh), which the shortcut calls below the cut
    got = np.array([mpc.tanh(v) for v in z])
    assert np.array_equal(got.view(np.int64), np.array([math.tanh(v) for v in z]).view(np.int64))


def test_importing_the_multipoint_model_loads_no_numba():
    code = (
        "import sys, trainsim.multipoint.simulate; print('numba' in sys.modules, 'llvmlite' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.split() == ["False", "False"]
