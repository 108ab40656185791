"""Power-limited acceleration analysis of source 001 ("Modeling a train's acceleration").

A locomotive of nominal power P_nom delivers ``eta P_nom`` at the wheel; what the running
resistance does not take accelerates the train:

    P_available(v) = eta P_nom - R(v) v
    (1/2) k M (v_{i+1}^2 - v_i^2) = P_available dt    =>    dv = sqrt(v^2 + 2 P_available dt / (k M)) - v

with k ~ 1.1 the ratio of inertial (static + rotating) to static mass. The analysis ignores the
adhesion limit and the line resistances (the source assumes straight, level track), so at low
speed it overstates what a real train can do; it is a quick look at a train's power margin.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from trainsim.errors import InputError
from trainsim.model import Train

__all__ = [
    "AccelerationAnalysis",
    "acceleration_analysis",
    "available_power_w",
    "balancing_speed_mps",
    "speed_increment_mps",
]

#: A running resistance R(v) [N] of speed [m/s], e.g. ``Train.running_resistance_n``.
ResistanceFn = Callable[[ArrayLike], np.ndarray | float]

#: Search limit for the balancing speed [m/s] (3600 km/h: far beyond any train).
_MAX_BALANCING_SPEED_MPS = 1000.0


def _as_output(values: np.ndarray) -> np.ndarray | float:
    return float(values) if values.ndim == 0 else values


def _check(field: str, value: float, ok: bool, allowed: str) -> None:
    if not (ok and np.isfinite(value)):
        raise InputError("invalid acceleration analysis input", field=field, value=value, allowed=allowed)


def _check_power(nominal_power_w: float, efficiency: float) -> None:
    _check("nominal_power", nominal_power_w, nominal_power_w > 0, "> 0 W")
    _check("efficiency", efficiency, 0 < efficiency <= 1, "0 < eta <= 1")


def available_power_w(
    speed_mps: ArrayLike, nominal_power_w: float, efficiency: float, resistance: ResistanceFn
) -> np.ndarray | float:
    """Power left for acceleration ``P_available = eta P_nom - R(v) v`` [W] (source 001).

    Negative above the balancing speed, where the resistance takes more than the wheel power.

    Args:
        speed_mps: speed v [m/s].
        nominal_power_w: nominal power of the traction unit P_nom [W].
        efficiency: efficiency from nominal to wheel power eta [-].
        resistance: running resistance R(v) [N] of speed [m/s].
    """
    _check_power(nominal_power_w, efficiency)
    v = np.asarray(speed_mps, dtype=float)
    return _as_output(efficiency * nominal_power_w - np.asarray(resistance(v), dtype=float) * v)


def speed_increment_mps(
    speed_mps: ArrayLike,
    dt_s: float,
    nominal_power_w: float,
    efficiency: float,
    resistance: ResistanceFn,
    mass_kg: float,
    mass_factor: float = 1.1,
) -> np.ndarray | float:
    """Speed gained in ``dt_s`` at constant available power,
    ``dv = sqrt(v^2 + 2 P_available dt / (k M)) - v`` [m/s] (source 001, energy balance over a step).

    Where the radicand is negative (a step so long above the balancing speed that the resistance
    would take more than the whole kinetic energy) the result is NaN, not 0 or -v: the explicit
    energy step has no solution there and a shorter ``dt_s`` is needed; a number would hide that.

    Args:
        speed_mps: speed v at the start of the step [m/s].
        dt_s: time step dt [s], > 0.
        nominal_power_w: nominal power P_nom [W].
        efficiency: efficiency eta [-].
        resistance: running resistance R(v) [N] of speed [m/s].
        mass_kg: static mass M [kg].
        mass_factor: k, inertial over static mass [-] (source 001: about 1.1).
    """
    _check("dt", dt_s, dt_s > 0, "> 0 s")
    _check("mass", mass_kg, mass_kg > 0, "> 0 kg")
    _check("mass_factor", mass_factor, 1 <= mass_factor <= 2, "1 <= k <= 2")
    v = np.asarray(speed_mps, dtype=float)
    power = np.asarray(available_power_w(v, nominal_power_w, efficiency, resistance))
    radicand = v * v + 2.0 * power * dt_s / (mass_factor * mass_kg)
    root = np.sqrt(np.where(radicand >= 0, radicand, np.nan))
    return _as_output(root - v)


def balancing_speed_mps(nominal_power_w: float, efficiency: float, resistance: ResistanceFn) -> float | None:
    """Speed where the available power reaches 0, ``eta P_nom = R(v) v`` [m/s], or None if the
    resistance never takes the whole power below 1000 m/s.

    The bracket starts at 10 m/s and doubles until the available power is negative; the root is
    then refined by Brent's method (``scipy.optimize.brentq``).
    """

    def power(v: float) -> float:
        return float(available_power_w(v, nominal_power_w, efficiency, resistance))

    high = 10.0
    while power(high) > 0:
        if high >= _MAX_BALANCING_SPEED_MPS:
            return None
        high = min(2.0 * high, _MAX_BALANCING_SPEED_MPS)
    return float(brentq(power, 0.0, high, xtol=1e-9, rtol=1e-12))


@dataclass(frozen=True)
class AccelerationAnalysis:
    """Result of :func:`acceleration_analysis` (source 001's P_available(v) and dv(v) curves).

    Attributes:
        speed_mps: speeds analysed [m/s].
        available_power_w: eta P_nom - R(v) v at each speed [W].
        delta_v_mps: speed gained in one step of ``dt_s`` from each speed [m/s] (NaN: no solution).
        balancing_speed_mps: speed where the available power is 0 [m/s], None if not found.
        nominal_power_w: P_nom [W].
        efficiency: eta [-].
        dt_s: time step [s].
        mass_factor: k [-].
    """

    speed_mps: np.ndarray
    available_power_w: np.ndarray
    delta_v_mps: np.ndarray
    balancing_speed_mps: float | None
    nominal_power_w: float
    efficiency: float
    dt_s: float
    mass_factor: float

    @property
    def mean_acceleration_mps2(self) -> np.ndarray:
        """Mean acceleration over each step, ``dv / dt`` [m/s^2]."""
        return self.delta_v_mps / self.dt_s


def acceleration_analysis(
    train: Train,
    nominal_power_w: float,
    efficiency: float,
    dt_s: float = 1.0,
    speeds_mps: ArrayLike | None = None,
    mass_factor: float | None = None,
) -> AccelerationAnalysis:
    """Source 001's power-limited acceleration analysis for any train.

    Args:
        train: the train; its running resistance and static mass are used.
        nominal_power_w: nominal power of the traction P_nom [W].
        efficiency: nominal-to-wheel efficiency eta [-].
        dt_s: time step of the speed increment [s].
        speeds_mps: speeds to analyse [m/s]; default 101 points from 0 to the train's maximum speed.
        mass_factor: k [-]; default the train's rotating mass factor.
    """
    speeds = (
        np.linspace(0.0, train.max_speed_mps, 101)
        if speeds_mps is None
        else np.atleast_1d(np.asarray(speeds_mps, dtype=float))
    )
    if speeds.size == 0 or not np.all(np.isfinite(speeds) & (speeds >= 0)):
        raise InputError(
            "speeds must be finite and >= 0", field="speeds", value=speeds.tolist(), allowed=">= 0 m/s"
        )
    k = train.rotating_mass_factor if mass_factor is None else mass_factor
    resistance = train.running_resistance_n
    return AccelerationAnalysis(
        speed_mps=speeds,
        available_power_w=np.asarray(available_power_w(speeds, nominal_power_w, efficiency, resistance)),
        delta_v_mps=np.asarray(
            speed_increment_mps(speeds, dt_s, nominal_power_w, efficiency, resistance, train.mass_kg, k)
        ),
        balancing_speed_mps=balancing_speed_mps(nominal_power_w, efficiency, resistance),
        nominal_power_w=nominal_power_w,
        efficiency=efficiency,
        dt_s=dt_s,
        mass_factor=k,
    )
