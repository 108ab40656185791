"""The kernel's tanh shortcut (issue 14) is np.tanh bit for bit, on both sides of the cut at |z| = 22."""

import numpy as np
from numba import njit

from trainsim.multipoint import kernel as mpk


@njit(cache=False)
def _both(z, a, b):
    for i in range(len(z)):
        a[i] = mpk.tanh(z[i])
        b[i] = np.tanh(z[i])


def test_tanh_shortcut_is_library_tanh_bit_for_bit():
    rng = np.random.default_rng(14)
    cut = 22.0
    z = np.concatenate(
        [rng.normal(0.0, scale, 20_000) for scale in (1e-3, 1.0, 10.0, 30.0, 1e3)]
        + [np.array([cut, -cut, np.nextafter(cut, 0.0), -np.nextafter(cut, 0.0), 0.0, -0.0, np.inf, -np.inf])]
    )
    a, b = np.empty_like(z), np.empty_like(z)
    _both(z, a, b)
    assert np.array_equal(a.view(np.int64), b.view(np.int64))
    assert np.isnan(mpk.tanh(np.nan))
    # the shortcut is taken often enough to matter: every speed above 22 mm/s at v_eps = 1 mm/s
    assert mpk.tanh(0.022 / 1e-3) == 1.0
