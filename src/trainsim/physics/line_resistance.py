"""Line resistances (gradient, curve, tunnel) as dimensionless ratios: force = ratio x m g.

A ratio of 0.001 is 1 per mille = 1 N/kN. Sources:

* 000: ATO train dynamic models (Wang et al.): exact gradient, curve and tunnel laws.
* 001: acceleration of a locomotive-hauled train: curve resistance 800/R per mille.
* 002: Cui et al., eq. 5 (gradient), 6 (curve, TB/T 1407), 7 (tunnel).
* Roeckl's curve formula (650/(R-55), 500/(R-30) per mille), the usual German/UIC form.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from trainsim.constants import PERMILLE, STANDARD_GRAVITY
from trainsim.errors import InputError

__all__ = [
    "CURVE_FORMULAS",
    "GRADIENT_FORMULAS",
    "TUNNEL_FORMULAS",
    "curve_radius_from_angle",
    "curve_ratio",
    "curve_ratio_tbt1407_from_angle",
    "gradient_ratio",
    "tunnel_ratio",
]

GRADIENT_FORMULAS: dict[str, str] = {
    "small_angle": "i / 1000: i per mille = i N/kN (source 002 eq. 5)",
    "exact": "sin(atan(i / 1000)) (source 000, m g sin(beta))",
}

CURVE_FORMULAS: dict[str, str] = {
    "roeckl": "Roeckl: 650/(R-55) per mille for R >= 300 m, 500/(R-30) below; R > 30 m",
    "wang": "source 000: 6.3 m/(r-55) kN (m in t) for r >= 300 m, 4.91 m/(r-30) below; r > 30 m",
    "tbt1407": "TB/T 1407: 600/R per mille (source 002 eq. 6); R > 0 m",
    "french800": "800/R per mille (source 001); R > 0 m",
    "none": "no curve resistance",
}

TUNNEL_FORMULAS: dict[str, str] = {
    "wang": "source 000: 1.3e-7 l_t (no limiting gradient) or 1.296e-9 l_t v^2 (limiting gradient, v in m/s)",
    "tbt1407": "w_s = 0.00013 L_s N/kN (source 002 eq. 7)",
    "none": "no tunnel resistance",
}

#: Radius below which the two-branch formulas switch to their small-radius law [m].
_SMALL_RADIUS_M = 300.0

#: Pole of each curve formula: the radius must be strictly greater [m].
_CURVE_POLE_M: dict[str, float] = {"roeckl": 30.0, "wang": 30.0, "tbt1407": 0.0, "french800": 0.0}


def _as_output(values: np.ndarray) -> np.ndarray | float:
    return float(values) if values.ndim == 0 else values


def _unknown_formula(kind: str, formula: str, known: dict[str, str]) -> InputError:
    return InputError(
        f"unknown {kind} formula",
        field=f"line_resistance.{kind}_formula",
        value=formula,
        allowed=", ".join(known),
    )


def gradient_ratio(gradient_permille: ArrayLike, formula: str = "small_angle") -> np.ndarray | float:
    """Gradient resistance as a ratio of the weight m g [-], positive uphill.

    ``small_angle``: i / 1000, since tan(theta) ~ sin(theta) on railway grades (source 002 eq. 5).
    ``exact``: sin(atan(i / 1000)), the ``m g sin(beta)`` of source 000 with i = 1000 tan(beta).

    Args:
        gradient_permille: gradient i [per mille = m/km], positive uphill.
        formula: ``small_angle`` or ``exact``.
    """
    i = np.asarray(gradient_permille, dtype=float) * PERMILLE
    if formula == "small_angle":
        return _as_output(i)
    if formula == "exact":
        return _as_output(np.sin(np.arctan(i)))
    raise _unknown_formula("gradient", formula, GRADIENT_FORMULAS)


def _check_radius(radius: np.ndarray, formula: str) -> None:
    pole = _CURVE_POLE_M[formula]
    if np.any(~(radius > pole)):
        bad = radius[~(radius > pole)]
        raise InputError(
            f"curve radius too small for the '{formula}' curve formula",
            field="curves.radius",
            value=float(bad.flat[0]),
            allowed=f"R > {pole:g} m",
        )


def _two_branch_permille(
    radius: np.ndarray, large: tuple[float, float], small: tuple[float, float]
) -> np.ndarray:
    """``k / (R - R0)`` with (k, R0) = ``large`` for R >= 300 m and ``small`` below."""
    is_large = radius >= _SMALL_RADIUS_M
    k = np.where(is_large, large[0], small[0])
    r0 = np.where(is_large, large[1], small[1])
    return k / (radius - r0)


def curve_ratio(
    radius_m: ArrayLike, formula: str, *, gravity_mps2: float = STANDARD_GRAVITY
) -> np.ndarray | float:
    """Curve resistance as a ratio of the weight m g [-].

    Formulas (see ``CURVE_FORMULAS``):

    * ``roeckl``: 650/(R-55) per mille for R >= 300 m, 500/(R-30) for R < 300 m (Roeckl).
    * ``wang``: source 000, ``f_c = 6.3 m/(r-55)`` kN with m in t for r >= 300 m and
      ``4.91 m/(r-30)`` below. The seed prints (r-55) in both branches; 4.91/g = 500.5, so the
      small-radius branch is Roeckl's 500/(R-30) and the second 55 a misprint. kN per t of mass
      becomes a ratio of the weight on dividing by g (m [t] x g = weight [kN]).
    * ``tbt1407``: 600/R per mille (source 002 eq. 6, TB/T 1407).
    * ``french800``: 800/R per mille (source 001, ``M g/1000 x 800/rho``).
    * ``none``: 0.

    Args:
        radius_m: curve radius R [m]; must exceed the formula's pole (30 m or 0 m).
        formula: one of ``CURVE_FORMULAS``.
        gravity_mps2: g [m/s^2] dividing ``wang``'s force per mass into a ratio of the weight (the
            route's gravity); the other formulas are ratios already.

    Raises:
        InputError: unknown formula, or a radius at or below the formula's pole (field
            ``curves.radius``).
    """
    radius = np.asarray(radius_m, dtype=float)
    if formula == "none":
        return _as_output(np.zeros_like(radius))
    if formula not in _CURVE_POLE_M:
        raise _unknown_formula("curve", formula, CURVE_FORMULAS)
    _check_radius(radius, formula)
    if formula == "roeckl":
        permille = _two_branch_permille(radius, (650.0, 55.0), (500.0, 30.0))
    elif formula == "wang":
        g = gravity_mps2
        permille = _two_branch_permille(radius, (6.3 / g / PERMILLE, 55.0), (4.91 / g / PERMILLE, 30.0))
    elif formula == "tbt1407":
        permille = 600.0 / radius
    else:  # french800
        permille = 800.0 / radius
    return _as_output(permille * PERMILLE)


def _check_curve_geometry(curve_length_m: float, central_angle_deg: float) -> None:
    if not (curve_length_m > 0 and central_angle_deg > 0):
        raise InputError(
            "a curve needs a positive length and central angle",
            field="curves",
            value=(curve_length_m, central_angle_deg),
            allowed="L_r > 0 m, alpha > 0 deg",
        )


def curve_radius_from_angle(curve_length_m: float, central_angle_deg: float) -> float:
    """Curve radius from its length and central angle, ``R = (360 / (2 pi)) L_r / alpha`` [m]
    (source 002 eq. 6).

    Args:
        curve_length_m: curve length L_r [m].
        central_angle_deg: central angle alpha [deg].
    """
    _check_curve_geometry(curve_length_m, central_angle_deg)
    return 360.0 / (2.0 * math.pi) * curve_length_m / central_angle_deg


def curve_ratio_tbt1407_from_angle(curve_length_m: float, central_angle_deg: float) -> float:
    """TB/T 1407 curve resistance from the central angle, ``w_r = 10.5 alpha / L_r`` [N/kN], as a
    ratio of the weight [-] (source 002 eq. 6).

    10.5 is 600 x 2 pi / 360 = 10.47 rounded, so this is 0.3 % above ``curve_ratio(R, "tbt1407")``.

    Args:
        curve_length_m: curve length L_r [m].
        central_angle_deg: central angle alpha [deg].
    """
    _check_curve_geometry(curve_length_m, central_angle_deg)
    return 10.5 * central_angle_deg / curve_length_m * PERMILLE


def tunnel_ratio(
    tunnel_length_m: float, formula: str, limiting_gradient: bool = False
) -> tuple[float, float]:
    """Tunnel resistance as ``(constant_ratio [-], v2_coefficient [s^2/m^2])``: the force in the
    tunnel is ``m g (constant_ratio + v2_coefficient v^2)`` with v in m/s.

    * ``wang`` (source 000): ``1.3e-7 l_t m g`` without a limiting gradient;
      ``1.296e-9 l_t m g v^2`` with one, read with v in m/s (1 per mille for a 1 km tunnel at
      100 km/h, a plausible value; with v in km/h it would be 13 times larger).
    * ``tbt1407`` (source 002 eq. 7): ``w_s = 0.00013 L_s`` N/kN, the same law as Wang's first one;
      ``limiting_gradient`` is ignored.
    * ``none``: no resistance.

    Args:
        tunnel_length_m: tunnel length l_t = L_s [m].
        formula: one of ``TUNNEL_FORMULAS``.
        limiting_gradient: whether the tunnel lies on a limiting (ruling) gradient (``wang`` only).
    """
    if not tunnel_length_m >= 0:
        raise InputError(
            "tunnel length must be >= 0", field="tunnels.length", value=tunnel_length_m, allowed=">= 0 m"
        )
    if formula == "wang":
        if limiting_gradient:
            return 0.0, 1.296e-9 * tunnel_length_m
        return 1.3e-7 * tunnel_length_m, 0.0
    if formula == "tbt1407":
        return 0.00013 * tunnel_length_m * PERMILLE, 0.0
    if formula == "none":
        return 0.0, 0.0
    raise _unknown_formula("tunnel", formula, TUNNEL_FORMULAS)
