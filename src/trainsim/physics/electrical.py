"""Electrical power and line current (vectorised over numpy arrays).

Forces are magnitudes at the wheel [N] and speeds [m/s]; powers come out in W. Two conventions
coexist because source 002 (Cui et al.) writes ``P = F V eta`` (eq. 14) for the power the train
draws in traction, which is physically the wrong way round: the line must supply the wheel power
*plus* the losses, ``F v / eta``. trainsim computes the physical one (``traction_line_power_w``,
``regenerated_line_power_w``) and keeps the paper's (``paper_power_w``) to reproduce its figures.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from trainsim.errors import InputError

__all__ = [
    "line_current_a",
    "mechanical_power_w",
    "paper_power_w",
    "regenerated_line_power_w",
    "traction_line_power_w",
]


def _as_output(values: np.ndarray) -> np.ndarray | float:
    return float(values) if values.ndim == 0 else values


def _check_ratio(name: str, value: float, allow_zero: bool = False) -> None:
    ok = (0 <= value <= 1) if allow_zero else (0 < value <= 1)
    if not ok:
        allowed = "0 <= x <= 1" if allow_zero else "0 < x <= 1"
        raise InputError("ratio out of range", field=f"electrical.{name}", value=value, allowed=allowed)


def mechanical_power_w(force_n: ArrayLike, speed_mps: ArrayLike) -> np.ndarray | float:
    """Mechanical power at the wheel ``P = F v`` [W].

    Args:
        force_n: force at the wheel [N].
        speed_mps: speed [m/s].
    """
    return _as_output(np.asarray(force_n, dtype=float) * np.asarray(speed_mps, dtype=float))


def traction_line_power_w(force_n: ArrayLike, speed_mps: ArrayLike, efficiency: float) -> np.ndarray | float:
    """Power drawn from the line in traction ``P = F v / eta`` [W] (physical convention).

    Args:
        force_n: tractive force at the wheel [N].
        speed_mps: speed [m/s].
        efficiency: line-to-wheel efficiency eta, 0 < eta <= 1 [-].
    """
    _check_ratio("traction_efficiency", efficiency)
    return _as_output(np.asarray(mechanical_power_w(force_n, speed_mps)) / efficiency)


def regenerated_line_power_w(
    force_n: ArrayLike, speed_mps: ArrayLike, efficiency: float
) -> np.ndarray | float:
    """Power returned to the line in regenerative braking ``P = F v eta`` [W].

    Args:
        force_n: electric braking force at the wheel, as a magnitude [N].
        speed_mps: speed [m/s].
        efficiency: wheel-to-line efficiency eta, 0 <= eta <= 1 [-] (0: no regeneration).
    """
    _check_ratio("regenerative_efficiency", efficiency, allow_zero=True)
    return _as_output(np.asarray(mechanical_power_w(force_n, speed_mps)) * efficiency)


def paper_power_w(force_n: ArrayLike, speed_mps: ArrayLike, efficiency: float) -> np.ndarray | float:
    """Power as source 002 eq. 14 writes it, ``P = F V eta`` [W], in traction too.

    This multiplies by eta where the physical line power divides by it (see
    :func:`traction_line_power_w`); with source 002's eta = 0.98 the two differ by 4 %. Use it only
    to reproduce the paper's figures (its peak current, its energy).

    Args:
        force_n: force at the wheel [N].
        speed_mps: speed [m/s].
        efficiency: the paper's "energy conversion efficiency" eta [-].
    """
    _check_ratio("traction_efficiency", efficiency)
    return _as_output(np.asarray(mechanical_power_w(force_n, speed_mps)) * efficiency)


def line_current_a(power_w: ArrayLike, voltage_v: ArrayLike, power_factor: float = 1.0) -> np.ndarray | float:
    """Line current ``I = P / (U cos phi)`` [A] (source 002 eq. 15).

    The paper prints ``I = P / U x cos phi``; it is read as ``P / (U cos phi)``, the current of a
    load drawing active power P at power factor cos phi (0.95 in the paper). The literal left-to-
    right reading, ``P cos phi / U``, would make a worse power factor *lower* the current.

    Args:
        power_w: electrical power [W] (negative when feeding back).
        voltage_v: line voltage U [V], > 0 (one value, or one per power value).
        power_factor: cos phi, 0 < cos phi <= 1 [-].
    """
    if not np.all(np.asarray(voltage_v) > 0):
        raise InputError("line voltage must be > 0", field="electrical.line_voltage_v", value=voltage_v)
    _check_ratio("power_factor", power_factor)
    return _as_output(np.asarray(power_w, dtype=float) / (voltage_v * power_factor))
