"""What the kernel needs of a train: its parameter vector, its compiled effort curves and their kinks.

Shared by the fastest run, the exact energy integration and the optimal strategy.
"""

from __future__ import annotations

import numpy as np

from trainsim.model.effort import POWER_CAP_MIN_SPEED_MPS
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim import codes as kernel_codes

__all__ = ["kernel_parameters", "kink_speeds", "regenerative_arrays"]

_NO_CURVE = (np.zeros(1), np.zeros((1, 4)), 0.0, 0.0)


def kernel_parameters(train: Train, settings: RunSettings) -> tuple:
    """Scalar parameter vector and compiled effort curves of a train for the kernel."""
    law = train.resistance_law
    P = np.zeros(kernel_codes.N_PARAMS)
    P[kernel_codes.P_INERTIAL_MASS] = train.inertial_mass_kg
    # the compiled track's line resistance is per unit mass (ratio x the route's g) [N/kg]
    P[kernel_codes.P_MASS] = train.mass_kg
    P[kernel_codes.P_R0], P[kernel_codes.P_R1], P[kernel_codes.P_R2] = law.c0, law.c1, law.c2
    braking = train.braking
    if braking.deceleration_mps2 is not None:
        P[kernel_codes.P_DECEL] = braking.deceleration_mps2 * settings.braking_fraction
        brake_curve = _NO_CURVE
    else:
        brake_curve = braking.service_force.as_arrays()
    P[kernel_codes.P_BRAKE_FRACTION] = settings.braking_fraction
    P[kernel_codes.P_TRACTION_SCALE] = 1.0
    return P, train.traction.as_arrays(), brake_curve


def regenerative_arrays(train: Train) -> tuple:
    """The compiled regenerative braking curve (zero force when the train has none)."""
    regen = train.braking.regenerative
    return regen.as_arrays() if regen is not None else _NO_CURVE


def kink_speeds(starts: np.ndarray, coefs: np.ndarray, force_cap: float, power_cap: float) -> np.ndarray:
    """Speeds where an effort curve is not smooth: interval starts and where the power cap takes
    over from the force cap [m/s]."""
    kinks = np.asarray(starts, dtype=float)[1:]
    if np.isfinite(power_cap):
        # the power cap takes over at P / F_cap, and is itself held constant below 1 mm/s
        takeover = power_cap / force_cap if np.isfinite(force_cap) and force_cap > 0 else 0.0
        kinks = np.append(kinks, max(takeover, POWER_CAP_MIN_SPEED_MPS))
    # np.sort of the positive ones: the values of sorted() over a list (NaN fails k > 0 in both)
    return np.sort(kinks[kinks > 0])
