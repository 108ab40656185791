"""The return rails as a uniformly leaking line: rail potential profile and stray current.

Between two nodes a track's running rails are a line of resistance r [ohm/m] with a conductance
g [S/m] to earth all along it. The rail potential V(x) and current i(x) obey

    dV/dx = -r i,   di/dx = -g V,   so   V'' = alpha^2 V,   alpha = sqrt(r g)  [1/m]

(the telegrapher's equations of a DC line; EN 50122-2 models the return circuit this way for
stray-current assessment). A segment of length L between nodes a and b is therefore exactly the
pi-equivalent two-port of series admittance alpha / (r sinh(alpha L)) and a shunt of
(alpha / r) tanh(alpha L / 2) to earth at each end (:func:`leaky_rail_pi`); the nodal solution is
exact at the nodes, and between them

    V(x) = (V_a sinh(alpha (L - x)) + V_b sinh(alpha x)) / sinh(alpha L)

(:func:`rail_profile_v`). The stray current is what leaves the rails into the earth, the
integral of g V over where V > 0 (:func:`segment_leakage_a`); with floating substation negatives
the same current comes back elsewhere.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from trainsim.power._rail_c import segment_leakage_total_a

__all__ = [
    "leaky_rail_pi",
    "rail_profile_v",
    "segment_leakage_a",
    "segment_leakage_total_a",
    "train_substation_rail_potential_v",
]

#: below this alpha L the hyperbolic forms are replaced by their limits (a rail without leakage)
_SMALL = 1e-9


def leaky_rail_pi(r_ohm_per_m: float, g_s_per_m: float, length_m: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(series admittance [S], shunt admittance at each end [S]) of the exact pi-equivalent of a
    uniformly leaking rail segment: alpha / (r sinh(alpha L)) and (alpha / r) tanh(alpha L / 2).
    Without leakage (g = 0): 1 / (r L) and 0."""
    length = np.asarray(length_m, dtype=float)
    alpha = np.sqrt(r_ohm_per_m * g_s_per_m)
    al = alpha * length
    if alpha * float(np.max(length, initial=0.0)) < _SMALL:
        return 1.0 / (r_ohm_per_m * length), g_s_per_m * length / 2
    return alpha / (r_ohm_per_m * np.sinh(al)), alpha / r_ohm_per_m * np.tanh(al / 2)


def rail_profile_v(
    va_v: float, vb_v: float, length_m: float, r_ohm_per_m: float, g_s_per_m: float, x_m: ArrayLike
) -> np.ndarray:
    """Rail-to-earth potential at distances x from node a along a segment [V], from the node
    potentials V_a, V_b (no current injected inside the segment)."""
    x = np.asarray(x_m, dtype=float)
    alpha = np.sqrt(r_ohm_per_m * g_s_per_m)
    if alpha * length_m < _SMALL:
        return va_v + (vb_v - va_v) * x / length_m
    return (va_v * np.sinh(alpha * (length_m - x)) + vb_v * np.sinh(alpha * x)) / np.sinh(alpha * length_m)


def segment_leakage_a(
    va_v: ArrayLike, vb_v: ArrayLike, length_m: ArrayLike, r_ohm_per_m: ArrayLike, g_s_per_m: ArrayLike
) -> np.ndarray:
    """Current leaving each rail segment into the earth [A]: g times the integral of max(V, 0) over
    the segment, exactly for the profile of :func:`rail_profile_v` (where V changes sign, at
    tanh(alpha x0) = V_a sinh(alpha L) / (V_a cosh(alpha L) - V_b), the positive part only)."""
    va, vb, length, r, g = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in
                                                  (va_v, vb_v, length_m, r_ohm_per_m, g_s_per_m)))  # fmt: skip
    shape = va.shape
    va, vb, length, r, g = (np.ravel(a) for a in (va, vb, length, r, g))
    alpha = np.sqrt(r * g)
    al = alpha * length
    lin = al < 1e-4
    a_safe = np.where(lin, 1.0, alpha)
    total = np.where(lin, (va + vb) * length / 2, (va + vb) * np.tanh(al / 2) / a_safe)
    change = va * vb < 0
    positive = np.where(va + vb > 0, total, 0.0)
    if change.any():
        # the integral of V from 0 to the sign change x0, on the few segments where V changes sign
        # (elementwise, so the same values as computed over every segment)
        c = np.flatnonzero(change)
        va_c, vb_c, len_c, al_c, alpha_c, as_c, lin_c = (
            va[c],
            vb[c],
            length[c],
            al[c],
            alpha[c],
            a_safe[c],
            lin[c],
        )
        sh, ch = np.sinh(al_c), np.cosh(al_c)
        with np.errstate(all="ignore"):  # each branch is computed on all of them, used where it applies
            x0_lin = len_c * va_c / (va_c - vb_c)
            x0_hyp = np.arctanh(np.clip(va_c * sh / (va_c * ch - vb_c), -1 + 1e-16, 1 - 1e-16)) / as_c
            x0 = np.where(lin_c, x0_lin, x0_hyp)
            first_lin = va_c * x0 / 2
            # cosh(aL) - cosh(a (L - x0)) and cosh(a x0) - 1 as products of sinh: no cancellation on
            # short segments (the differences of cosh lost up to 7 digits at aL = 5e-4)
            half = np.sinh(alpha_c * x0 / 2)
            first_hyp = (
                va_c * 2 * np.sinh(alpha_c * (2 * len_c - x0) / 2) * half + vb_c * 2 * half * half
            ) / (as_c * sh)
        first = np.where(lin_c, first_lin, first_hyp)
        positive[c] = np.where(va_c > 0, first, total[c] - first)
    return (g * np.maximum(positive, 0.0)).reshape(shape)


def train_substation_rail_potential_v(
    current_a: float, r_ohm_per_m: float, g_s_per_m: float, length_m: float, x_m: ArrayLike
) -> np.ndarray:
    """Closed form for one train and one substation (floating negative) L apart on a uniformly
    leaking rail: the train injects I into the rails at x = 0, the substation draws it out at
    x = L; V(x) = (I r / alpha) (cosh(alpha (L - x)) - cosh(alpha x)) / sinh(alpha L), so the
    train's rail potential is (I r / alpha) tanh(alpha L / 2) and the substation's its opposite,
    and the stray current (leaving the rails over the train's half) is I (1 - 1 / cosh(alpha L / 2))."""
    x = np.asarray(x_m, dtype=float)
    alpha = np.sqrt(r_ohm_per_m * g_s_per_m)
    return (
        current_a * r_ohm_per_m / alpha
        * (np.cosh(alpha * (length_m - x)) - np.cosh(alpha * x)) / np.sinh(alpha * length_m)
    )  # fmt: skip
