"""Speed-dependent laws shared by the resistance families."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class Quadratic:
    """A force law ``F(v) = c0 + c1 v + c2 v^2``.

    Every running-resistance family trainsim knows (Davis, per-mass, RAV, specific N/kN,
    Strahl, Sauthoff, Wende) is a quadratic in speed once its constants are fixed, so the core
    only ever sees this form.

    Attributes:
        c0: constant term [N].
        c1: linear term [N s/m].
        c2: quadratic term [N s^2/m^2].
    """

    c0: float
    c1: float = 0.0
    c2: float = 0.0

    def __call__(self, speed_mps: ArrayLike) -> np.ndarray | float:
        """Force [N] at speed ``speed_mps`` [m/s]."""
        v = np.asarray(speed_mps, dtype=float)
        out = self.c0 + self.c1 * v + self.c2 * v * v
        return float(out) if out.ndim == 0 else out

    def __add__(self, other: Quadratic) -> Quadratic:
        return Quadratic(self.c0 + other.c0, self.c1 + other.c1, self.c2 + other.c2)

    def scaled(self, factor: float) -> Quadratic:
        """The law multiplied by ``factor``."""
        return Quadratic(self.c0 * factor, self.c1 * factor, self.c2 * factor)
