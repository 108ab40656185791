"""Substation regulation curves: output voltage as a piecewise-linear function of the current.

A rectifier substation's output voltage falls with its load current, faster at high currents
(commutation overlap, transformer reactance, the rectifier's regulation class), which one
internal resistance cannot describe. A regulation curve gives the busbar voltage at a few
currents, (I_0, U_0), (I_1, U_1), ... with I increasing and U strictly decreasing; between points
the voltage is linear, beyond the ends the end segments continue (EN 50328, rectifier regulation
characteristic, given as data by the manufacturer). The curve must pass through I = 0: there U is
the no-load voltage E and the slope of the segment starting there is the small-current internal
resistance R_1.

The nodal solver needs the inverse, the current the substation drives at busbar voltage U, and
its derivative: both are piecewise linear in U and exact (no smoothing at the kinks: Newton takes
the slope of the segment the iterate is on, and backtracking handles an iterate that crosses a
kink).
"""

from __future__ import annotations

import numpy as np

__all__ = ["regulation_current_a", "regulation_voltage_v"]


def _segment(x: float, points: np.ndarray) -> int:
    """Index k of the segment [points[k], points[k + 1]] holding x (points increasing), with the
    end segments extended beyond the ends."""
    return int(np.clip(np.searchsorted(points, x, side="right") - 1, 0, len(points) - 2))


def regulation_voltage_v(current_a: float, curve_current_a: np.ndarray, curve_voltage_v: np.ndarray) -> float:
    """Busbar voltage U(I) of a substation with a regulation curve [V] (linear between points,
    end segments extended).

    Args:
        current_a: output current I [A] (negative: taken back, reversible substations).
        curve_current_a: currents of the curve's points, increasing [A].
        curve_voltage_v: voltages of the curve's points, strictly decreasing [V].
    """
    k = _segment(current_a, curve_current_a)
    i0, i1 = curve_current_a[k], curve_current_a[k + 1]
    u0, u1 = curve_voltage_v[k], curve_voltage_v[k + 1]
    return float(u0 + (u1 - u0) * (current_a - i0) / (i1 - i0))


def regulation_current_a(
    voltage_v: float, curve_current_a: np.ndarray, curve_voltage_v: np.ndarray
) -> tuple[float, float]:
    """Inverse of :func:`regulation_voltage_v`: the current I(U) [A] a substation drives at busbar
    voltage U, and dI/dU [A/V] (negative: the slope of the segment U lies on; at a breakpoint, the
    segment on the higher-current side)."""
    u_desc = -np.asarray(curve_voltage_v)  # increasing
    k = _segment(-voltage_v, u_desc)
    i0, i1 = curve_current_a[k], curve_current_a[k + 1]
    u0, u1 = curve_voltage_v[k], curve_voltage_v[k + 1]
    slope = (i1 - i0) / (u1 - u0)
    return float(i0 + slope * (voltage_v - u0)), float(slope)
