"""The multi-point kernel's Newton solve of one implicit step against a plain Python Newton (issue 14).

The compiled step (``kernel.implicit_step``) assembles the residual and the Jacobian in one pass and
gives a step up as soon as its damped iterations can no longer reach the tolerance
(``kernel.HOPELESS_MARGIN``); the reference below does neither: it assembles as the equations are
written (kernel's module docstring) from the compiled force laws and runs all ``MAX_NEWTON``
iterations. On states of a train with slack and draft-gear friction (where Newton cycles and steps are
halved) both must return the same iterations and the same midpoint speeds bit for bit, and every step
the kernel gave up early must be one the full iteration does not solve either.
"""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.multipoint import kernel as mpk

N = 12  # vehicles
MASS_KG, INERTIAL_KG, LENGTH_M = 100e3, 104e3, 12.0
TOL_MPS = 1e-9
VEPS_MPS = 1e-3


def model():
    """A train of N wagons on level track (running resistance only) and the heavy-haul example's
    couplers: 25 mm slack, draft gears with friction ratio 0.667 at 5 mm/s, solid at 166 mm."""
    VP = np.zeros((N, mpk.N_V))
    VP[:, mpk.V_MASS] = MASS_KG
    VP[:, mpk.V_INERTIAL] = INERTIAL_KG
    VP[:, mpk.V_LENGTH] = LENGTH_M
    VP[:, mpk.V_R0] = 900.0
    VP[:, mpk.V_R1] = 17.0
    VP[:, mpk.V_R2] = 1.6
    VP[:, mpk.V_CURVE] = -1
    CP = np.zeros((N - 1, mpk.N_C))
    CP[:, [mpk.C_KD, mpk.C_KB]] = 8.4e6
    CP[:, mpk.C_HALF_SLACK] = 0.0125
    CP[:, [mpk.C_TD, mpk.C_TB]] = 0.166
    CP[:, mpk.C_KS] = 1.4e8
    CP[:, mpk.C_EPS] = 1e-3
    CP[:, mpk.C_MU] = 0.667
    CP[:, mpk.C_VF] = 0.005
    SP = np.zeros(mpk.N_S)
    SP[mpk.S_STEP] = 0.05
    SP[mpk.S_VEPS] = VEPS_MPS
    SP[mpk.S_BRAKE_FRACTION] = 1.0
    SP[mpk.S_REGEN_CURVE] = -1
    SP[mpk.S_G] = 9.80665
    SP[mpk.S_NEWTON_TOL] = TOL_MPS
    bank = (np.zeros(1), np.zeros((1, 4)), np.array([0, 1]), np.array([np.inf]), np.array([np.inf]))
    prof = (np.array([0, 2]), np.array([-1e6, 1e6]), np.zeros((2, 4)))
    avail = (np.array([-1e6, 1e6]), np.ones(1))
    return VP, CP, SP, np.zeros(mpk.N_K), np.zeros(N), np.zeros(N), bank, prof, avail


def reference_step(md, x0, v0, h, w, bm):
    """Newton on ``2 M (w - v0) / h - F(x0 + h w / 2, w) = 0`` as kernel's docstring writes it, with the
    compiled force laws and Thomas solver, all MAX_NEWTON iterations (full updates, then halves).
    Returns the iterations (-1: not converged) and the first iteration whose update the kernel's early
    give-up criterion calls hopeless (None if none)."""
    VP, CP, SP, CMD, trac, elec, bank, prof, avail = md
    mi = VP[:, mpk.V_INERTIAL]
    pcache = np.zeros(N, dtype=np.int64)
    F, D, parts = np.zeros(N), np.zeros(N), np.zeros((N, 7))
    hopeless = None
    for it in range(mpk.MAX_NEWTON):
        xm = x0 + 0.5 * h * w
        mpk.vehicle_forces(
            xm, w, v0, VP, SP, CMD, trac, elec, bm, bank, prof, avail, pcache, F, D, True, parts
        )
        T, kc = np.zeros(N - 1), np.zeros(N - 1)
        for k in range(N - 1):
            delta = xm[k] - VP[k, mpk.V_LENGTH] - xm[k + 1]
            spring, damper, dk, dc = mpk.coupler_force(delta, w[k] - w[k + 1], CP[k])
            T[k] = spring + damper
            kc[k] = 0.5 * h * max(dk, 0.0) + dc
        G = 2.0 * mi * (w - v0) / h - (F + np.concatenate([[0.0], T]) - np.concatenate([T, [0.0]]))
        diag = 2.0 * mi / h + D + np.concatenate([[0.0], kc]) + np.concatenate([kc, [0.0]])
        dw = np.zeros(N)
        mpk.thomas(diag, -kc, G, dw, np.zeros(N))
        w_new = w - (1.0 if it < mpk.DAMPED_FROM else 0.5) * dw
        # an end speed carried across 0 from outside the dry-friction zone stops at 0 first
        ve_old, ve_new = 2.0 * w - v0, 2.0 * w_new - v0
        w_new = np.where((ve_old * ve_new < 0.0) & (np.abs(ve_old) > 2.0 * VEPS_MPS), 0.5 * v0, w_new)
        big = float(np.max(np.abs(w_new - w)))
        w[:] = w_new
        if big < TOL_MPS:
            return it + 1, hopeless
        limit = mpk.HOPELESS_MARGIN * TOL_MPS * 2.0 ** (mpk.MAX_NEWTON - 1 - it)
        if hopeless is None and it >= mpk.DAMPED_FROM + 1 and big > limit:
            hopeless = it
    return -1, hopeless


def states(count: int):
    """Step starts with couplings spread over slack, springs and solid stage, relative speeds of a few
    cm/s to dm/s, guesses from a previous acceleration, steps of 0.05 - 0.2 s."""
    rng = np.random.default_rng(14)
    for _ in range(count):
        delta = rng.uniform(-0.12, 0.12, N - 1)
        x0 = -np.concatenate([[0.0], np.cumsum(LENGTH_M + delta)])
        v0 = 8.0 + rng.normal(0.0, rng.choice([0.003, 0.01, 0.03, 0.1]), N)
        h = float(rng.choice([0.02, 0.05, 0.1]))
        w = v0 + 0.5 * h * rng.normal(0.0, 0.1, N)
        yield x0, v0, h, w


@pytest.fixture(scope="module")
def outcomes():
    md = model()
    out = []
    for x0, v0, h, w in states(300):
        bm = np.zeros(N)
        w_kernel = w.copy()
        its = mpk.implicit_step(x0, v0, h, w_kernel, bm, *md[:7], md[7], md[8], np.zeros(N, dtype=np.int64),
                                np.zeros(N - 1), np.zeros(N - 1))  # fmt: skip
        w_ref = w.copy()
        its_ref, hopeless = reference_step(md, x0, v0, h, w_ref, bm)
        out.append((its, w_kernel, its_ref, w_ref, hopeless))
    return out


def test_compiled_step_is_the_plain_newton_bit_for_bit(outcomes):
    converged = [o for o in outcomes if o[2] > 0]
    assert len(converged) > 50
    for its, w_kernel, its_ref, w_ref, _ in converged:
        assert its == its_ref
        assert np.array_equal(w_kernel.view(np.int64), w_ref.view(np.int64))
    # the cases include slow convergence: damped iterations
    assert max(o[2] for o in converged) > mpk.DAMPED_FROM + 1


def test_a_step_given_up_early_would_not_have_converged(outcomes):
    failed = [o for o in outcomes if o[2] < 0]
    assert all(o[0] == -1 for o in failed)
    assert sum(1 for o in failed if o[4] is not None) > 10, "no state exercises the early give-up"
    # a step that converges is never called hopeless on the way
    assert all(o[4] is None for o in outcomes if o[2] > 0)
