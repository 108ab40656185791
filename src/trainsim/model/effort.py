"""Maximum traction and braking effort as a function of speed.

All effort laws of the sources reduce exactly to one representation, which the simulation
kernel evaluates without knowing where it came from:

    F(v) = min( c0_j + c1_j v + c2_j v^2 + ch_j / v,  force_cap,  power_cap / v ),   v in [v_j, v_j+1)

* a table interpolated linearly (source 002, eq. 1-2; TrainRuns.jl): c0 + c1 v per interval;
* piecewise quadratic laws (source 000, Wang et al.): c0 + c1 v + c2 v^2;
* hyperbolic constant-power laws (source 000): ch / v;
* power-limited traction with an adhesion limit (source 001): power_cap = eta P, force_cap = mu m g
  (mu m is kept as ``adhesion_limit_kg`` and multiplied by the route's g when the run starts).

The last interval extends to infinity; forces are never negative.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from trainsim.constants import STANDARD_GRAVITY
from trainsim.errors import InputError

#: The power cap P / v is evaluated at no less than this speed [m/s]. At standstill P / v is
#: infinite and the force cap binds, but with an absurdly small power (an efficiency of 1e-308) that
#: force would hold only below 1e-308 m/s, and a first integration step from rest would see it in
#: full: a train with no usable power would creep along instead of stalling. Real curves reach their
#: power cap above 1 m/s, so 1 mm/s changes none of them.
POWER_CAP_MIN_SPEED_MPS = 1e-3


@dataclass(frozen=True, eq=False)
class EffortCurve:
    """Maximum force [N] over speed [m/s].

    Attributes:
        interval_start_mps: start speed of each interval, increasing, first one 0 [m/s].
        coefficients: one row ``(c0 [N], c1 [N s/m], c2 [N s^2/m^2], ch [W])`` per interval.
        force_cap_n: upper bound on the force, e.g. an adhesion limit [N].
        power_cap_w: upper bound on force x speed [W].
        label: what the curve was built from, for reports.
        adhesion_limit_kg: adhesion coefficient x mass on driven axles, mu m_adh [kg]: the force is
            also capped at mu m_adh g, with g the route's gravity (``at_gravity``; evaluating the
            curve directly uses the standard 9.80665). Infinite: no adhesion limit.
    """

    interval_start_mps: np.ndarray
    coefficients: np.ndarray
    force_cap_n: float = float("inf")
    power_cap_w: float = float("inf")
    label: str = ""
    adhesion_limit_kg: float = float("inf")

    def __post_init__(self) -> None:
        starts = np.ascontiguousarray(self.interval_start_mps, dtype=float)
        coefs = np.ascontiguousarray(self.coefficients, dtype=float).reshape(-1, 4)
        object.__setattr__(self, "interval_start_mps", starts)
        object.__setattr__(self, "coefficients", coefs)
        if starts.ndim != 1 or len(starts) != len(coefs) or len(starts) == 0:
            raise InputError(
                "an effort curve needs one coefficient row per interval",
                field="effort",
                value=(len(starts), len(coefs)),
            )
        if starts[0] != 0.0 or np.any(np.diff(starts) <= 0):
            raise InputError(
                "effort curve speeds must start at 0 and increase strictly",
                field="effort.speed",
                value=starts.tolist(),
            )
        if not (np.all(np.isfinite(coefs)) and np.isfinite(starts).all()):
            raise InputError("effort curve values must be finite", field="effort")
        if not (self.force_cap_n >= 0 and self.power_cap_w >= 0 and self.adhesion_limit_kg >= 0):
            raise InputError(
                "effort caps must be >= 0",
                field="effort",
                value=(self.force_cap_n, self.power_cap_w, self.adhesion_limit_kg),
                allowed=">= 0",
            )
        if coefs[0, 3] != 0.0 and not np.isfinite(min(self.force_cap_n, self.adhesion_limit_kg)):
            raise InputError(
                "a hyperbolic (constant-power) law that starts at 0 km/h is infinite at standstill; "
                "give a force cap (e.g. an adhesion limit) or start the law at a speed above 0",
                field="effort",
            )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_table(cls, speed_mps: ArrayLike, force_n: ArrayLike, label: str = "table") -> EffortCurve:
        """Linear interpolation of a table (source 002 eq. 1 and 8), constant beyond its ends."""
        v = np.asarray(speed_mps, dtype=float)
        f = np.asarray(force_n, dtype=float)
        if v.ndim != 1 or v.shape != f.shape or len(v) < 1:
            raise InputError(
                "an effort table needs as many speeds as forces, at least one",
                field="effort",
                value=(v.shape, f.shape),
            )
        if np.any(np.diff(v) <= 0) or v[0] < 0:
            raise InputError(
                "effort table speeds must be >= 0 and strictly increasing",
                field="effort.speed",
                value=v.tolist(),
            )
        if np.any(f < 0) or not np.all(np.isfinite(f)):
            raise InputError(
                "effort table forces must be finite and >= 0 (give braking forces as positive magnitudes)",
                field="effort.force",
                value=f.tolist(),
            )
        starts: list[float] = []
        rows: list[tuple[float, float, float, float]] = []
        if v[0] > 0:
            starts.append(0.0)
            rows.append((f[0], 0.0, 0.0, 0.0))
        for j in range(len(v) - 1):
            slope = (f[j + 1] - f[j]) / (v[j + 1] - v[j])
            starts.append(v[j])
            rows.append((f[j] - slope * v[j], slope, 0.0, 0.0))
        starts.append(v[-1])
        rows.append((f[-1], 0.0, 0.0, 0.0))
        return cls(np.array(starts), np.array(rows), label=label)

    @classmethod
    def constant(cls, force_n: float, label: str = "constant") -> EffortCurve:
        """The same force at every speed."""
        return cls(np.array([0.0]), np.array([[force_n, 0.0, 0.0, 0.0]]), label=label)

    @classmethod
    def piecewise(
        cls,
        interval_start_mps: ArrayLike,
        coefficients: ArrayLike,
        *,
        force_cap_n: float = float("inf"),
        power_cap_w: float = float("inf"),
        label: str = "piecewise",
    ) -> EffortCurve:
        """Piecewise quadratic / hyperbolic law of source 000 (Wang et al.):
        ``c1 + c2 v + c3 v^2`` or ``ch / v`` on each interval, given as rows (c0, c1, c2, ch)."""
        return cls(
            np.asarray(interval_start_mps, dtype=float),
            np.asarray(coefficients, dtype=float),
            force_cap_n=force_cap_n,
            power_cap_w=power_cap_w,
            label=label,
        )

    @classmethod
    def power_limited(
        cls, power_w: float, force_cap_n: float, efficiency: float = 1.0, label: str = "power-limited"
    ) -> EffortCurve:
        """Constant power ``efficiency x power_w`` at the wheel, below a force cap (adhesion or
        starting effort): ``F = min(F_cap, eta P / v)`` (source 001; hyperbolic law of source 000)."""
        if power_w <= 0 or not 0 < efficiency <= 1 or force_cap_n <= 0:
            raise InputError(
                "power-limited traction needs power > 0, 0 < efficiency <= 1 and a force cap > 0",
                field="traction",
                value=(power_w, efficiency, force_cap_n),
            )
        return cls(
            np.array([0.0]),
            np.array([[force_cap_n, 0.0, 0.0, 0.0]]),
            force_cap_n=force_cap_n,
            power_cap_w=efficiency * power_w,
            label=label,
        )

    # ------------------------------------------------------------------ operations
    def scaled(self, factor: float, label: str | None = None) -> EffortCurve:
        """The curve times ``factor`` (number of motors; 0.75 for service braking; 0.8 for
        regenerative braking from the traction curve)."""
        if factor < 0:
            raise InputError("an effort scale factor must be >= 0", field="effort", value=factor)
        return EffortCurve(
            self.interval_start_mps,
            self.coefficients * factor,
            force_cap_n=self.force_cap_n * factor,
            power_cap_w=self.power_cap_w * factor,
            label=label if label is not None else f"{factor:g} x {self.label}",
            adhesion_limit_kg=self.adhesion_limit_kg * factor,
        )

    def capped(self, *, force_cap_n: float | None = None, power_cap_w: float | None = None) -> EffortCurve:
        """The curve with an additional force or power cap (adhesion, converter power)."""
        return EffortCurve(
            self.interval_start_mps,
            self.coefficients,
            force_cap_n=min(self.force_cap_n, force_cap_n if force_cap_n is not None else np.inf),
            power_cap_w=min(self.power_cap_w, power_cap_w if power_cap_w is not None else np.inf),
            label=self.label,
            adhesion_limit_kg=self.adhesion_limit_kg,
        )

    def at_gravity(self, gravity_mps2: float) -> EffortCurve:
        """The curve with its adhesion limit mu m_adh g applied for gravity g [m/s^2] (itself when
        it has none)."""
        if not np.isfinite(self.adhesion_limit_kg):
            return self
        return EffortCurve(
            self.interval_start_mps,
            self.coefficients,
            force_cap_n=min(self.force_cap_n, self.adhesion_limit_kg * gravity_mps2),
            power_cap_w=self.power_cap_w,
            label=self.label,
        )

    @property
    def _force_cap(self) -> float:
        """Force cap [N] including an unresolved adhesion limit at standard gravity."""
        return min(self.force_cap_n, self.adhesion_limit_kg * STANDARD_GRAVITY)

    def __call__(self, speed_mps: ArrayLike) -> np.ndarray | float:
        """Force [N] at speed [m/s] (vectorised)."""
        v = np.asarray(speed_mps, dtype=float)
        j = np.clip(np.searchsorted(self.interval_start_mps, v, side="right") - 1, 0, None)
        c = self.coefficients[j]
        with np.errstate(divide="ignore", invalid="ignore"):
            law = c[..., 0] + c[..., 1] * v + c[..., 2] * v * v
            law = law + np.where(c[..., 3] != 0.0, c[..., 3] / v, 0.0)
            power = self.power_cap_w / np.maximum(v, POWER_CAP_MIN_SPEED_MPS)
        out = np.maximum(np.minimum(np.minimum(law, self._force_cap), power), 0.0)
        return float(out) if out.ndim == 0 else out

    def as_arrays(self) -> tuple[np.ndarray, np.ndarray, float, float]:
        """``(interval_start_mps, coefficients, force_cap_n, power_cap_w)`` for the compiled kernel."""
        return self.interval_start_mps, self.coefficients, float(self._force_cap), float(self.power_cap_w)
