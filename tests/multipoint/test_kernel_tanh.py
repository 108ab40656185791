"""The kernel's tanh shortcut (issue 14) is the C library's tanh bit for bit, on both sides of the cut at
|z| = 22 (the compiled kernel, multipoint/_mp_c.pyx, calls libm's tanh below the cut; math.tanh is
the same function)."""

import math

import numpy as np

from trainsim.multipoint import kernel as mpk


def test_tanh_shortcut_is_library_tanh_bit_for_bit():
    rng = np.random.default_rng(14)
    cut = 22.0
    z = np.concatenate(
        [rng.normal(0.0, scale, 20_000) for scale in (1e-3, 1.0, 10.0, 30.0, 1e3)]
        + [np.array([cut, -cut, np.nextafter(cut, 0.0), -np.nextafter(cut, 0.0), 0.0, -0.0, np.inf, -np.inf])]
    )
    a = np.array([mpk.tanh(v) for v in z])
    b = np.array([math.tanh(v) for v in z])
    assert np.array_equal(a.view(np.int64), b.view(np.int64))
    assert np.isnan(mpk.tanh(np.nan))
    # the shortcut is taken often enough to matter: every speed above 22 mm/s at v_eps = 1 mm/s
    assert mpk.tanh(0.022 / 1e-3) == 1.0
