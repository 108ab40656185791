"""ETCS braking curves and supervision limits after ERA SUBSET-026-3 section 3.13 (baseline 3).

The on-board speed and distance monitoring of ETCS computes, for every supervised target, braking
curves (EBD from the safe emergency deceleration, SBD from the expected service deceleration, GUI from
the normal service deceleration) and, from them, the supervision limits valid for a given speed: the
emergency brake intervention (EBI), service brake intervention (SBI1 from the SBD, SBI2 from the EBI),
warning (W), permitted speed (P) and indication (I) limits. This module computes them as functions of
the train's front-end position, from the train's braking model, the gradient profile and the national
and fixed values, with one function per equation citing its clause of SUBSET-026-3. The clause numbers
are those of the 3.13 text consulted (a baseline 4 issue, whose 3.13 keeps baseline 3's structure); the
formulas are baseline 3's: baseline 4's split of the build-up times into reaction and build-up parts
and their reduction per target (A.3.12) are not used.

Everything is SI: positions [m], speeds [m/s], decelerations [m/s^2], times [s]; gradients are in
per mille, positive uphill (3.13.4.3.2). Decelerations are positive numbers.

"Lambda" trains (brake percentage and brake position) get their models from the conversion model of
3.13.3 / A.3.7-A.3.9 (``EtcsTrainData.from_brake_percentage``) with the integrated correction factors.

Not modelled (see docs/ETCS.md): special brakes and their track conditions (A_brake_emergency(V, d)
depends on V only), Q_NVDRIVER_ADHES, the service brake feedback (T_bs2_locked, A.3.10), a position
confidence interval that grows with the distance run (one constant interval can be given) and the
level 1 terms (L_antenna, D41).
"""

from __future__ import annotations

import itertools
import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from trainsim.constants import KMH
from trainsim.errors import InfeasibleError, InputError
from trainsim.model.route import Route

__all__ = [
    "CONVERSION_AD_COEFFICIENTS",
    "BrakingCurve",
    "EtcsNationalValues",
    "EtcsTrainData",
    "StepFunction",
    "SupervisionCurves",
    "a_brake_safe_conversion_mps2",
    "a_brake_safe_gamma_mps2",
    "a_gradient_mps2",
    "a_max_reduced_adhesion_mps2",
    "a_normal_service_mps2",
    "basic_deceleration",
    "ceiling_offset_mps",
    "compensated_gradient_profile",
    "conversion_build_up_time_s",
    "conversion_kto",
    "conversion_v_lim_mps",
    "d_bec_m",
    "kv_int_passenger",
    "moving_block_ceiling",
    "select_normal_service_model",
    "supervision_curves",
    "t_berem_s",
    "t_indication_s",
    "t_traction_s",
    "v_bec_mps",
]

#: Net deceleration below which a braking curve cannot be built [m/s^2]: a train whose brakes do not
#: beat the downhill gradient cannot stop, and the curve would not be monotonic.
MIN_NET_DECELERATION_MPS2 = 1e-6
#: Speed above the train's highest possible supervision limit up to which curves are integrated [m/s];
#: above it every limit is reported as unconstrained (np.inf).
SPEED_HEADROOM_MPS = 5.0
#: Bisection steps for inverting a limit's position d(V) into a speed V(d); 64 halvings of a range of
#: at most a few hundred m/s reach the float64 resolution.
BISECTION_STEPS = 64
#: Speeds in the table that brackets a limit's inversion, and regula falsi steps refining the bracket.
TABLE_POINTS = 129
REGULA_FALSI_STEPS = 8
#: A limit's speed is accepted when its location is within this distance of the position asked [m].
ROOT_TOLERANCE_M = 1e-9

BrakePosition = Literal["passenger_p", "freight_p", "freight_g"]
LimitKind = Literal["ebi", "sbi", "warning", "permitted", "indication"]
LIMIT_KINDS: tuple[str, ...] = ("ebi", "sbi", "warning", "permitted", "indication")


# ----------------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------------


def _bad(message: str, field_name: str, value: Any, allowed: str) -> InputError:
    return InputError(message, field=field_name, value=value, allowed=allowed)


@dataclass(frozen=True)
class StepFunction:
    """A step function of speed (or of train length) after 3.13.2.2.3.1.3.

    ``values[0]`` applies for ``0 <= x <= upper_limits[0]``, ``values[k]`` for
    ``upper_limits[k-1] < x <= upper_limits[k]`` and the last value is open ended (3.13.2.2.3.1.4).

    Attributes:
        values: the step values (a deceleration [m/s^2] or a dimensionless factor).
        upper_limits: the step limits V1, V2, ... [m/s] (or L1, L2, ... [m] for Kr_int), strictly
            increasing and positive; one fewer than ``values``.
    """

    values: tuple[float, ...]
    upper_limits: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        values = tuple(float(v) for v in np.atleast_1d(np.asarray(self.values, dtype=float)))
        limits = tuple(float(v) for v in np.atleast_1d(np.asarray(self.upper_limits, dtype=float)))
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "upper_limits", limits)
        if not values or not all(math.isfinite(v) for v in values):
            raise _bad("step function values must be finite", "values", self.values, "finite numbers")
        if len(limits) != len(values) - 1:
            raise _bad(
                "a step function needs one step limit fewer than values",
                "upper_limits",
                limits,
                f"{len(values) - 1} limits for {len(values)} values",
            )
        if any(not (math.isfinite(x) and x > 0) for x in limits) or any(
            b <= a for a, b in itertools.pairwise(limits)
        ):
            raise _bad(
                "step limits must be positive, finite and strictly increasing",
                "upper_limits",
                limits,
                "0 < V1 < V2 < ...",
            )

    @classmethod
    def constant(cls, value: float) -> StepFunction:
        """A single open-ended step."""
        return cls((float(value),))

    @classmethod
    def from_kmh(cls, upper_limits_kmh: Sequence[float], values: Sequence[float]) -> StepFunction:
        """Build from step limits in km/h (as train data sheets give them) and the step values."""
        return cls(tuple(values), tuple(float(v) * KMH for v in upper_limits_kmh))

    def __call__(self, x: ArrayLike) -> NDArray[np.float64] | float:
        """The value at ``x`` (vectorised)."""
        index = np.searchsorted(np.asarray(self.upper_limits), np.asarray(x, dtype=float), side="left")
        out = np.asarray(self.values)[index]
        return float(out) if np.ndim(out) == 0 else out

    def minimum(self) -> float:
        """The smallest step value."""
        return min(self.values)


def _as_step(value: StepFunction | float | int, name: str) -> StepFunction:
    if isinstance(value, StepFunction):
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise _bad(f"{name} must be a StepFunction or a number", name, value, "a StepFunction or a number")
    return StepFunction.constant(float(value))


def _check_range(name: str, value: float, lo: float, hi: float, allowed: str | None = None) -> None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (lo <= value <= hi):
        raise _bad(f"{name} out of range", name, value, allowed or f"{lo} to {hi}")


def _check_steps(
    message: str, name: str, fn: StepFunction, ok: Callable[[float], bool], allowed: str, label: str = ""
) -> None:
    """Every value of the step function ``fn`` passes ``ok``; else an error naming the first bad value
    and, of a function of several steps, the speeds it applies to (not the whole tuple)."""
    for k, v in enumerate(fn.values):
        if ok(v):
            continue
        where = label
        if len(fn.values) > 1:
            lo = 0.0 if k == 0 else fn.upper_limits[k - 1]

            def speed(x: float) -> str:
                # files give the limits in km/h or m/s
                return f"{x:.4g} m/s ({x / KMH:.4g} km/h)"

            span = (
                f"{speed(lo)} to {speed(fn.upper_limits[k])}"
                if k < len(fn.upper_limits)
                else f"above {speed(lo)}"
            )
            where = f"{label}{', ' if label else ''}step {k + 1} of {len(fn.values)}: speeds {span}"
        raise _bad(f"{message}{f' ({where})' if where else ''}", name, v, allowed)


@dataclass(frozen=True)
class EtcsTrainData:
    """Train data for the ETCS speed and distance monitoring (3.13.2.2), SI units.

    Attributes:
        a_brake_emergency: emergency brake deceleration A_brake_emergency(V) [m/s^2], a step function of
            speed (3.13.2.2.3.1) or a constant.
        a_brake_service: full service brake deceleration A_brake_service(V) [m/s^2].
        t_brake_emergency_s: equivalent emergency brake build-up time T_brake_emergency [s]
            (3.13.2.2.3.2.4), used for targets with target speed 0 (T_brake_emergency_cm0 for a train
            whose data come from the conversion model).
        t_brake_service_s: equivalent full service brake build-up time T_brake_service [s].
        t_traction_cut_off_s: traction cut-off time T_traction_cut_off [s] (3.13.2.2.2.1).
        length_m: train length L_TRAIN [m] (3.13.2.2.11).
        max_speed_mps: maximum train speed [m/s] (3.13.2.2.13), part of the MRSP.
        a_brake_normal_service: normal service brake deceleration A_brake_normal_service(V) [m/s^2]
            for the guidance curve (3.13.2.2.3.1.6); default: ``a_brake_service``. One model only (the
            selection among three by A_brake_service(0), 3.13.2.2.3.1.10: give
            ``a_brake_normal_service_sets`` and the pivots instead).
        t_brake_emergency_cmt_s / t_brake_service_cmt_s: build-up times used for targets with a target
            speed above 0 (T_brake_*_cmt of 3.13.3.4.4.1); default: the values above.
        kdry_rst: rolling stock correction factor Kdry_rst(V, EBCL) (3.13.2.2.9.1.3): a step function
            (or a number) used whatever the confidence level, or a mapping from the EBCL index
            (0..9, the value of M_NVEBCL) to a step function. Default 1 (no correction).
        kwet_rst: rolling stock correction factor Kwet_rst(V) (3.13.2.2.9.1.5). Default 1.
        kn_plus / kn_minus: correction factors Kn+(V) and Kn-(V) for the gradient on the normal service
            brake [m/s^2] (3.13.2.2.9.2), 0 to 10. Default 0.
        m_rotating_nom_percent: nominal rotating mass [% of the train weight] (3.13.2.2.10); ``None``
            uses the fixed values M_rotating_max / M_rotating_min.
        conversion_model_used: the deceleration and build-up times come from the brake percentage
            conversion model (a "lambda" train); then Kdry_rst/Kwet_rst do not apply and the integrated
            correction factors Kv_int, Kr_int, Kt_int of the national values do (3.13.6.2.1.4,
            3.13.6.2.2.3). ``from_brake_percentage`` builds such a train from the conversion model.
        brake_position: ``passenger_p``, ``freight_p`` or ``freight_g`` (3.13.2.2.4); selects the
            Kv_int set with the conversion model.
        traction_cut_off_implemented: the traction cut-off command is implemented (3.13.2.2.8.1).
        service_brake_command: the service brake command is implemented (3.13.2.2.7.1).
        service_brake_feedback: the service brake feedback is implemented (3.13.2.2.7.2); only its
            effect on T_indication is modelled (3.13.9.3.6.4), not the reduction of T_bs (A.3.10).
        speed_under_reading_mps / speed_under_reading_ratio: speed under-reading amount
            V_ura = a + b V [m/s] used as V_delta0 (3.13.9.3.2.1) and as f41(V) (3.13.9.3.5.9 b,
            3.13.9.4.6 b). Default 0 (an exact speed measurement).
        a_brake_normal_service_sets / a_sb01_mps2 / a_sb12_mps2: the three A_brake_normal_service models
            of the train's brake position and their pivots A_SB01, A_SB12 [m/s^2]; the model is chosen by
            A_brake_service(0) (3.13.2.2.3.1.9-11).
        adhesion_independent_brake: the train has an active special/additional brake independent of
            the wheel/rail adhesion whose contribution may be counted under reduced adhesion
            (3.13.2.2.6.4-6); selects A_NVMAXREDADH1 instead of 2 for a passenger train in P.
    """

    a_brake_emergency: StepFunction | float
    a_brake_service: StepFunction | float
    t_brake_emergency_s: float
    t_brake_service_s: float
    t_traction_cut_off_s: float
    length_m: float
    max_speed_mps: float
    a_brake_normal_service: StepFunction | float | None = None
    t_brake_emergency_cmt_s: float | None = None
    t_brake_service_cmt_s: float | None = None
    kdry_rst: StepFunction | float | Mapping[int, StepFunction | float] = 1.0
    kwet_rst: StepFunction | float = 1.0
    kn_plus: StepFunction | float = 0.0
    kn_minus: StepFunction | float = 0.0
    m_rotating_nom_percent: float | None = None
    conversion_model_used: bool = False
    brake_position: BrakePosition = "passenger_p"
    traction_cut_off_implemented: bool = True
    service_brake_command: bool = True
    service_brake_feedback: bool = False
    speed_under_reading_mps: float = 0.0
    speed_under_reading_ratio: float = 0.0
    adhesion_independent_brake: bool = False
    a_brake_normal_service_sets: tuple[StepFunction | float, ...] | None = None
    a_sb01_mps2: float | None = None
    a_sb12_mps2: float | None = None

    def __post_init__(self) -> None:
        for name in ("a_brake_emergency", "a_brake_service", "kwet_rst", "kn_plus", "kn_minus"):
            object.__setattr__(self, name, _as_step(getattr(self, name), name))
        if self.a_brake_normal_service_sets is not None:
            sets = self.a_brake_normal_service_sets
            if self.a_brake_normal_service is not None:
                raise _bad(
                    "give either one normal service model or the three sets",
                    "a_brake_normal_service",
                    "both",
                    "a_brake_normal_service or a_brake_normal_service_sets with a_sb01_mps2, a_sb12_mps2",
                )
            if isinstance(sets, str) or not isinstance(sets, Sequence) or len(sets) != 3:
                raise _bad(
                    "the normal service brake needs three models",
                    "a_brake_normal_service_sets",
                    sets,
                    "three step functions (3.13.2.2.3.1.10)",
                )
            steps = tuple(_as_step(m, f"a_brake_normal_service_sets[{k}]") for k, m in enumerate(sets))
            object.__setattr__(self, "a_brake_normal_service_sets", steps)
            for name in ("a_sb01_mps2", "a_sb12_mps2"):
                if getattr(self, name) is None:
                    raise _bad(
                        f"{name} is needed with the three normal service models", name, None, "a deceleration"
                    )
                _check_range(name, getattr(self, name), 0.0, 10.0, "0 to 10 m/s^2")
            if self.a_sb12_mps2 < self.a_sb01_mps2:
                raise _bad(
                    "A_SB12 must not be below A_SB01", "a_sb12_mps2", self.a_sb12_mps2, ">= a_sb01_mps2"
                )
            chosen = select_normal_service_model(
                float(self.a_brake_service(0.0)),
                steps,
                float(self.a_sb01_mps2),
                float(self.a_sb12_mps2),
            )
            object.__setattr__(self, "a_brake_normal_service", chosen)
        if self.a_brake_normal_service is None:
            object.__setattr__(self, "a_brake_normal_service", self.a_brake_service)
        else:
            object.__setattr__(
                self,
                "a_brake_normal_service",
                _as_step(self.a_brake_normal_service, "a_brake_normal_service"),
            )
        for name in ("a_brake_emergency", "a_brake_service", "a_brake_normal_service"):
            fn: StepFunction = getattr(self, name)
            _check_steps(
                f"{name} must be a deceleration above 0", name, fn, lambda v: 0 < v <= 10, "0 < A <= 10 m/s^2"
            )
        if isinstance(self.kdry_rst, Mapping):
            kdry = {}
            for key, value in self.kdry_rst.items():
                if isinstance(key, bool) or not isinstance(key, int) or not 0 <= key <= 9:
                    raise _bad("Kdry_rst is keyed by the EBCL index", "kdry_rst", key, "integers 0 to 9")
                kdry[key] = _as_step(value, f"kdry_rst[{key}]")
            object.__setattr__(self, "kdry_rst", kdry)
            kdry_steps = [(f"EBCL {key}", fn) for key, fn in kdry.items()]
        else:
            object.__setattr__(self, "kdry_rst", _as_step(self.kdry_rst, "kdry_rst"))
            kdry_steps = [("", self.kdry_rst)]
        for label, fn in kdry_steps:
            _check_steps(
                "Kdry_rst out of range", "kdry_rst", fn, lambda v: 0 < v <= 1.5, "0 < Kdry_rst <= 1.5", label
            )
        _check_steps(
            "Kwet_rst out of range", "kwet_rst", self.kwet_rst, lambda v: 0 < v <= 1, "0 < Kwet_rst <= 1"
        )
        for name in ("kn_plus", "kn_minus"):
            _check_steps(
                f"{name} out of range", name, getattr(self, name), lambda v: 0 <= v <= 10,
                "0 to 10 m/s^2 (3.13.2.2.9.2.1)",
            )  # fmt: skip
        for name in ("t_brake_emergency_s", "t_brake_service_s", "t_traction_cut_off_s"):
            _check_range(name, getattr(self, name), 0.0, 300.0, "0 to 300 s")
        for name in ("t_brake_emergency_cmt_s", "t_brake_service_cmt_s"):
            if getattr(self, name) is not None:
                _check_range(name, getattr(self, name), 0.0, 300.0, "0 to 300 s or None")
        _check_range("length_m", self.length_m, 0.0, 5000.0, "0 to 5000 m")
        if (
            isinstance(self.max_speed_mps, bool)
            or not isinstance(self.max_speed_mps, numbers.Real)
            or not (0 < self.max_speed_mps <= 200)
        ):
            raise _bad("max_speed_mps out of range", "max_speed_mps", self.max_speed_mps, "0 < v <= 200 m/s")
        if self.m_rotating_nom_percent is not None:
            _check_range("m_rotating_nom_percent", self.m_rotating_nom_percent, 0.0, 100.0, "0 to 100 %")
        if self.brake_position not in ("passenger_p", "freight_p", "freight_g"):
            raise _bad(
                "unknown brake position",
                "brake_position",
                self.brake_position,
                "passenger_p, freight_p, freight_g",
            )
        _check_range("speed_under_reading_mps", self.speed_under_reading_mps, 0.0, 10.0, "0 to 10 m/s")
        _check_range("speed_under_reading_ratio", self.speed_under_reading_ratio, 0.0, 0.2, "0 to 0.2")

    @classmethod
    def from_brake_percentage(
        cls,
        brake_percentage: float,
        brake_position: BrakePosition,
        length_m: float,
        max_speed_mps: float,
        t_traction_cut_off_s: float,
        **changes: Any,
    ) -> EtcsTrainData:
        """A "lambda" train: its braking models from the conversion model (3.13.3, A.3.7-A.3.9).

        A_brake_emergency is the basic deceleration of the brake percentage, A_brake_service that of
        min(lambda, 135); the build-up times are T_brake_basic (target speed 0) and kto T_brake_basic
        (target speed above 0). The integrated correction factors Kv_int, Kr_int and Kt_int of the
        national values then apply (3.13.6.2.1.4, 3.13.6.2.2.3). Outside the validity limits of
        3.13.3.2.1 (V <= 200 km/h, 30 <= lambda <= 250 %, L <= 900 m in P / 1500 m freight) the model
        is not applicable and an ``InputError`` says so. ``changes`` sets further fields (kn_plus,
        a_brake_normal_service, speed_under_reading_mps, ...).
        """
        if brake_position not in CONVERSION_MAX_LENGTH_M:
            raise _bad(
                "unknown brake position",
                "brake_position",
                brake_position,
                "passenger_p, freight_p, freight_g",
            )
        lo, hi = CONVERSION_BRAKE_PERCENTAGE
        _check_range("brake_percentage", brake_percentage, lo, hi, f"{lo:g} to {hi:g} % (3.13.3.2.1)")
        max_length = CONVERSION_MAX_LENGTH_M[brake_position]
        _check_range("length_m", length_m, 0.0, max_length, f"0 to {max_length:g} m for {brake_position}")
        _check_range("max_speed_mps", max_speed_mps, 0.0, CONVERSION_MAX_SPEED_MPS, "up to 200 km/h")
        kto = conversion_kto(brake_position)
        t_eb = conversion_build_up_time_s("emergency", brake_position, length_m)
        t_sb = conversion_build_up_time_s("service", brake_position, length_m)
        service_lambda = min(float(brake_percentage), CONVERSION_SERVICE_MAX_BRAKE_PERCENTAGE)
        return cls(
            a_brake_emergency=basic_deceleration(brake_percentage),
            a_brake_service=basic_deceleration(service_lambda),
            t_brake_emergency_s=t_eb,
            t_brake_service_s=t_sb,
            t_traction_cut_off_s=t_traction_cut_off_s,
            length_m=length_m,
            max_speed_mps=max_speed_mps,
            t_brake_emergency_cmt_s=kto * t_eb,
            t_brake_service_cmt_s=kto * t_sb,
            conversion_model_used=True,
            brake_position=brake_position,
            **changes,
        )

    def v_ura_mps(self, v_mps: ArrayLike) -> NDArray[np.float64]:
        """Speed under-reading amount V_ura(V) = a + b V [m/s] (3.13.9.3.2.1)."""
        return self.speed_under_reading_mps + self.speed_under_reading_ratio * np.asarray(v_mps, float)

    def kdry_for(self, ebcl: int) -> StepFunction:
        """Kdry_rst(V, EBCL) for the confidence level index ``ebcl`` (3.13.6.2.1.7)."""
        if isinstance(self.kdry_rst, StepFunction):
            return self.kdry_rst
        if ebcl not in self.kdry_rst:
            raise _bad(
                "no Kdry_rst given for the confidence level M_NVEBCL",
                "kdry_rst",
                ebcl,
                f"one of {sorted(self.kdry_rst)}",
            )
        return self.kdry_rst[ebcl]


@dataclass(frozen=True)
class EtcsNationalValues:
    """National values (SUBSET-026-3 A.3.2 defaults) and fixed values (A.3.1) for the monitoring.

    Fixed values are settings here so that studies can vary them; their defaults are A.3.1's.

    National values:
        m_nvebcl: confidence level index on the emergency brake safe deceleration, 0..9 (9 is
            1 - 1e-9, the default).
        m_nvavadh: weighting factor for the available wheel/rail adhesion, 0..1 (default 0).
        q_nvinhsmicperm: inhibit the compensation of the speed measurement inaccuracy (default no).
        q_nvguiperm: permit the guidance curve (default no).
        q_nvsbtsmperm: permit the service brake in target speed monitoring (default yes).
        q_nvsbfbperm: permit the service brake feedback (default no).
        v_nvrel_mps: national release speed [m/s] (default 40 km/h).
        kv_int_freight / kv_int_passenger_a / kv_int_passenger_b: integrated correction factor
            Kv_int(V) (3.13.2.3.7.11); defaults 0.7 (A.3.2 default set).
        a_nvp12_mps2 / a_nvp23_mps2: the pivot decelerations of the passenger Kv_int sets [m/s^2].
        kr_int: integrated correction factor Kr_int(L), a step function of the train length [m]
            (default 0.9).
        kt_int: integrated correction factor Kt_int for the build-up time (default 1.1).
        a_nvmaxredadh1_mps2 / 2 / 3: maximum emergency deceleration under reduced adhesion
            A_NVMAXREDADH1..3 [m/s^2] (defaults 1.0, 0.7, 0.7); ``None`` where the national value
            asks for DMI information instead of a limit (3.13.2.3.7.7).

    Fixed values (A.3.1):
        dv_ebi_min_mps, dv_ebi_max_mps, v_ebi_min_mps, v_ebi_max_mps: 7.5 km/h, 15 km/h, 110 km/h,
            210 km/h.
        dv_sbi_min_mps, dv_sbi_max_mps, v_sbi_min_mps, v_sbi_max_mps: 5.5, 10, 110, 210 km/h.
        dv_warning_min_mps, dv_warning_max_mps, v_warning_min_mps, v_warning_max_mps: 4, 5, 110,
            140 km/h.
        t_warning_s: 2 s; t_driver_s: 4 s.
        m_rotating_max_percent: 15 %; m_rotating_min_percent: 2 %.
        gravity_mps2: g = 9.81 m/s^2 of 3.13.4.3.2.
        a_est2_max_mps2: upper bound of A_est2, 0.4 m/s^2 (3.13.9.3.2.9).
        t_indication_min_s: 5 s and t_indication_bs_factor 0.8 of 3.13.9.3.6.2.
    """

    m_nvebcl: int = 9
    m_nvavadh: float = 0.0
    q_nvinhsmicperm: bool = False
    q_nvguiperm: bool = False
    q_nvsbtsmperm: bool = True
    q_nvsbfbperm: bool = False
    v_nvrel_mps: float = 40 * KMH
    kv_int_freight: StepFunction | float = 0.7
    kv_int_passenger_a: StepFunction | float = 0.7
    kv_int_passenger_b: StepFunction | float = 0.7
    a_nvp12_mps2: float = 0.0
    a_nvp23_mps2: float = 0.0
    kr_int: StepFunction | float = 0.9
    kt_int: float = 1.1
    a_nvmaxredadh1_mps2: float | None = 1.0
    a_nvmaxredadh2_mps2: float | None = 0.7
    a_nvmaxredadh3_mps2: float | None = 0.7
    dv_ebi_min_mps: float = 7.5 * KMH
    dv_ebi_max_mps: float = 15.0 * KMH
    v_ebi_min_mps: float = 110.0 * KMH
    v_ebi_max_mps: float = 210.0 * KMH
    dv_sbi_min_mps: float = 5.5 * KMH
    dv_sbi_max_mps: float = 10.0 * KMH
    v_sbi_min_mps: float = 110.0 * KMH
    v_sbi_max_mps: float = 210.0 * KMH
    dv_warning_min_mps: float = 4.0 * KMH
    dv_warning_max_mps: float = 5.0 * KMH
    v_warning_min_mps: float = 110.0 * KMH
    v_warning_max_mps: float = 140.0 * KMH
    t_warning_s: float = 2.0
    t_driver_s: float = 4.0
    m_rotating_max_percent: float = 15.0
    m_rotating_min_percent: float = 2.0
    gravity_mps2: float = 9.81
    a_est2_max_mps2: float = 0.4
    t_indication_min_s: float = 5.0
    t_indication_bs_factor: float = 0.8

    def __post_init__(self) -> None:
        if (
            isinstance(self.m_nvebcl, bool)
            or not isinstance(self.m_nvebcl, int)
            or not 0 <= self.m_nvebcl <= 9
        ):
            raise _bad("M_NVEBCL is an index 0..9", "m_nvebcl", self.m_nvebcl, "integers 0 to 9")
        _check_range("m_nvavadh", self.m_nvavadh, 0.0, 1.0)
        for name in ("kv_int_freight", "kv_int_passenger_a", "kv_int_passenger_b", "kr_int"):
            fn = _as_step(getattr(self, name), name)
            if not all(0 < v <= 2 for v in fn.values):
                raise _bad(f"{name} out of range", name, fn.values, "0 < K <= 2")
            object.__setattr__(self, name, fn)
        _check_range("kt_int", self.kt_int, 0.1, 5.0)
        for name in ("a_nvmaxredadh1_mps2", "a_nvmaxredadh2_mps2", "a_nvmaxredadh3_mps2"):
            if getattr(self, name) is not None:
                _check_range(name, getattr(self, name), 0.0, 10.0, "0 to 10 m/s^2, or None (no limit)")
        _check_range("v_nvrel_mps", self.v_nvrel_mps, 0.0, 100.0, "0 to 100 m/s")
        for name in (
            "dv_ebi_min_mps",
            "dv_ebi_max_mps",
            "v_ebi_min_mps",
            "v_ebi_max_mps",
            "dv_sbi_min_mps",
            "dv_sbi_max_mps",
            "v_sbi_min_mps",
            "v_sbi_max_mps",
            "dv_warning_min_mps",
            "dv_warning_max_mps",
            "v_warning_min_mps",
            "v_warning_max_mps",
            "a_nvp12_mps2",
            "a_nvp23_mps2",
        ):
            _check_range(name, getattr(self, name), 0.0, 200.0, "0 to 200 (m/s or m/s^2)")
        for kind in ("ebi", "sbi", "warning"):
            if getattr(self, f"v_{kind}_max_mps") <= getattr(self, f"v_{kind}_min_mps"):
                raise _bad(
                    f"V_{kind}_max must be above V_{kind}_min",
                    f"v_{kind}_max_mps",
                    getattr(self, f"v_{kind}_max_mps"),
                    f"> v_{kind}_min_mps",
                )
        for name in ("t_warning_s", "t_driver_s", "t_indication_min_s"):
            _check_range(name, getattr(self, name), 0.0, 60.0, "0 to 60 s")
        _check_range("t_indication_bs_factor", self.t_indication_bs_factor, 0.0, 2.0)
        _check_range("m_rotating_max_percent", self.m_rotating_max_percent, 0.0, 100.0)
        _check_range("m_rotating_min_percent", self.m_rotating_min_percent, 0.0, 100.0)
        _check_range("gravity_mps2", self.gravity_mps2, 9.7, 9.9)
        _check_range("a_est2_max_mps2", self.a_est2_max_mps2, 0.0, 5.0)


# ----------------------------------------------------------------------------------------------------
# Equations
# ----------------------------------------------------------------------------------------------------


def ceiling_offset_mps(
    v_mrsp_mps: ArrayLike, dv_min_mps: float, dv_max_mps: float, v_min_mps: float, v_max_mps: float
) -> NDArray[np.float64]:
    """Ceiling supervision offset dV(V_MRSP) [m/s] (SUBSET-026-3 3.13.9.2.3, 3.13.9.2.5-6).

    dV = dV_min for V_MRSP <= V_min, else min(dV_min + C (V_MRSP - V_min), dV_max) with
    C = (dV_max - dV_min) / (V_max - V_min). The same law gives dV_ebi, dV_sbi and dV_warning.
    """
    v = np.asarray(v_mrsp_mps, dtype=float)
    slope = (dv_max_mps - dv_min_mps) / (v_max_mps - v_min_mps)
    return np.where(v > v_min_mps, np.minimum(dv_min_mps + slope * (v - v_min_mps), dv_max_mps), dv_min_mps)


def _dv(kind: str, v_mps: ArrayLike, national: EtcsNationalValues) -> NDArray[np.float64]:
    n = national
    return ceiling_offset_mps(
        v_mps,
        getattr(n, f"dv_{kind}_min_mps"),
        getattr(n, f"dv_{kind}_max_mps"),
        getattr(n, f"v_{kind}_min_mps"),
        getattr(n, f"v_{kind}_max_mps"),
    )


def select_normal_service_model(
    a_brake_service_at_0_mps2: float, models: Sequence[StepFunction], a_sb01_mps2: float, a_sb12_mps2: float
) -> StepFunction:
    """The normal service brake model of a set of three (SUBSET-026-3 3.13.2.2.3.1.10): model 0 when
    A_brake_service(V = 0) <= A_SB01, model 1 when A_SB01 < A_brake_service(0) <= A_SB12, else model 2."""
    if a_brake_service_at_0_mps2 <= a_sb01_mps2:
        return models[0]
    if a_brake_service_at_0_mps2 <= a_sb12_mps2:
        return models[1]
    return models[2]


def a_gradient_mps2(
    gradient_permille: ArrayLike,
    m_rotating_nom_percent: float | None = None,
    m_rotating_max_percent: float = 15.0,
    m_rotating_min_percent: float = 2.0,
    gravity_mps2: float = 9.81,
) -> NDArray[np.float64]:
    """Deceleration due to the gradient A_gradient [m/s^2] (SUBSET-026-3 3.13.4.3.2).

    A_gradient = g grad / (1000 + 10 M_rotating) with grad in per mille (positive uphill: a positive
    A_gradient adds to the braking deceleration) and M_rotating the nominal rotating mass [%] if
    known, else M_rotating_max uphill and M_rotating_min downhill.
    """
    grad = np.asarray(gradient_permille, dtype=float)
    if m_rotating_nom_percent is not None:
        rotating = np.full_like(grad, float(m_rotating_nom_percent))
    else:
        rotating = np.where(grad > 0, m_rotating_max_percent, m_rotating_min_percent)
    return gravity_mps2 * grad / (1000.0 + 10.0 * rotating)


def a_brake_safe_gamma_mps2(
    a_brake_emergency_mps2: ArrayLike, kdry_rst: ArrayLike, kwet_rst: ArrayLike, m_nvavadh: float
) -> NDArray[np.float64]:
    """Safe emergency brake deceleration with train-data braking models [m/s^2] (3.13.6.2.1.4).

    A_brake_safe = Kdry_rst(V, M_NVEBCL) (Kwet_rst(V) + M_NVAVADH (1 - Kwet_rst(V))) A_brake_emergency(V).
    """
    kwet = np.asarray(kwet_rst, dtype=float)
    return (
        np.asarray(kdry_rst, float) * (kwet + m_nvavadh * (1.0 - kwet)) * np.asarray(a_brake_emergency_mps2)
    )


def a_brake_safe_conversion_mps2(
    a_brake_emergency_mps2: ArrayLike, kv_int: ArrayLike, kr_int: float
) -> NDArray[np.float64]:
    """Safe emergency brake deceleration with the conversion model [m/s^2] (3.13.6.2.1.4).

    A_brake_safe = Kv_int(V) Kr_int(L_TRAIN) A_brake_emergency(V).
    """
    return np.asarray(kv_int, float) * kr_int * np.asarray(a_brake_emergency_mps2, float)


def kv_int_passenger(
    a_ebmax_mps2: float, kv_a: ArrayLike, kv_b: ArrayLike, a_p12_mps2: float, a_p23_mps2: float
) -> NDArray[np.float64]:
    """Kv_int of a passenger train in P from its two sets (3.13.6.2.1.8.1).

    Kv_int_x_a when A_ebmax <= A_P12, Kv_int_x_b when A_ebmax >= A_P23, linear in A_ebmax between.
    """
    a = np.asarray(kv_a, float)
    b = np.asarray(kv_b, float)
    if a_ebmax_mps2 <= a_p12_mps2:
        return a
    if a_ebmax_mps2 >= a_p23_mps2:
        return b
    return a + (a_ebmax_mps2 - a_p12_mps2) / (a_p23_mps2 - a_p12_mps2) * (b - a)


def a_normal_service_mps2(
    a_brake_normal_service_mps2: ArrayLike,
    a_gradient: ArrayLike,
    gradient_permille: ArrayLike,
    kn_plus_mps2: ArrayLike,
    kn_minus_mps2: ArrayLike,
) -> NDArray[np.float64]:
    """Normal service brake deceleration for the guidance curve [m/s^2] (3.13.6.4.3).

    A_normal_service = A_brake_normal_service(V) + A_gradient(d) - Kn(V) grad(d)/1000 with Kn = Kn+
    uphill (grad > 0) and Kn- downhill.
    """
    grad = np.asarray(gradient_permille, float)
    kn = np.where(grad > 0, kn_plus_mps2, kn_minus_mps2)
    return np.asarray(a_brake_normal_service_mps2, float) + np.asarray(a_gradient, float) - kn * grad / 1000


def t_traction_s(
    t_traction_cut_off_s: float, t_warning_s: float, t_bs2_s: float, cut_off_implemented: bool
) -> float:
    """Time with traction still present after an EB command, T_traction [s] (3.13.9.3.2.3).

    MAX(T_traction_cut_off - (T_warning + T_bs2), 0) when the traction cut-off is implemented (it is
    commanded at the warning limit), else T_traction_cut_off.
    """
    if cut_off_implemented:
        return max(t_traction_cut_off_s - (t_warning_s + t_bs2_s), 0.0)
    return t_traction_cut_off_s


def t_berem_s(t_be_s: float, t_traction: float) -> float:
    """Remaining brake build-up time without traction, T_berem = MAX(T_be - T_traction, 0) (3.13.9.3.2.6)."""
    return max(t_be_s - t_traction, 0.0)


def t_indication_s(
    t_bs_s: float,
    t_driver_s: float,
    service_brake_feedback: bool,
    minimum_s: float = 5.0,
    bs_factor: float = 0.8,
) -> float:
    """Time between the indication and the permitted limits, T_indication [s] (3.13.9.3.6.2, .4).

    max(0.8 T_bs, 5 s) + T_driver without service brake feedback, 5 s + T_driver with it.
    """
    if service_brake_feedback:
        return minimum_s + t_driver_s
    return max(bs_factor * t_bs_s, minimum_s) + t_driver_s


def v_bec_mps(
    v_est_mps: ArrayLike, v_target_mps: float, v_delta0: ArrayLike, v_delta1: float, v_delta2: float
) -> NDArray[np.float64]:
    """Compensated speed at the end of the brake build-up, V_bec [m/s] (3.13.9.3.2.10).

    V_bec = max(V_est + V_delta0 + V_delta1, V_target) + V_delta2.
    """
    return np.maximum(np.asarray(v_est_mps, float) + v_delta0 + v_delta1, v_target_mps) + v_delta2


def d_bec_m(
    v_est_mps: ArrayLike,
    v_target_mps: float,
    v_delta0: ArrayLike,
    v_delta1: float,
    v_delta2: float,
    t_traction: float,
    t_berem: float,
) -> NDArray[np.float64]:
    """Distance run during the brake build-up, D_bec [m] (3.13.9.3.2.10).

    D_bec = max(V_est + V_delta0 + V_delta1/2, V_target) T_traction
    + (max(V_est + V_delta0 + V_delta1, V_target) + V_delta2/2) T_berem.
    """
    v = np.asarray(v_est_mps, float) + v_delta0
    return (
        np.maximum(v + v_delta1 / 2, v_target_mps) * t_traction
        + (np.maximum(v + v_delta1, v_target_mps) + v_delta2 / 2) * t_berem
    )


# ----------------------------------------------------------------------------------------------------
# Conversion model of the brake percentage and brake position ("lambda" trains, 3.13.3, A.3.7-A.3.9)
# ----------------------------------------------------------------------------------------------------

#: A.3.7: coefficients (a0, a1, a2, a3) of AD_n(lambda) = a3 lambda^3 + a2 lambda^2 + a1 lambda + a0
#: [m/s^2], n = 1..5 (the same in two independent on-board implementations consulted).
CONVERSION_AD_COEFFICIENTS: tuple[tuple[float, float, float, float], ...] = (
    (0.0663, 4.72e-3, 6.10e-5, -6.30e-7),
    (0.1300, 5.14e-3, -4.54e-6, 2.73e-7),
    (0.0479, 5.81e-3, -6.76e-6, 5.58e-8),
    (0.0480, 5.52e-3, -3.85e-6, 3.00e-8),
    (0.0559, 5.06e-3, 1.66e-6, 3.23e-9),
)
#: A.3.7: upper speed limits of AD_1 .. AD_4 [km/h]; AD_5 is open ended.
CONVERSION_SPEED_LIMITS_KMH: tuple[float, ...] = (100.0, 120.0, 150.0, 180.0)
#: A.3.8.1-3 (emergency) and A.3.9.1-3 (service): T_brake_basic = a + b (L/100) + c (L/100)^2 [s], L in
#: m, per brake position: ((longest train length [m] of the row, (a, b, c), length floored at 400 m), ...).
#: Every row read against the text of SUBSET-026-3 v4.0.0 A.3.8-A.3.9, including freight P in
#: emergency above 900 m, a = -0.40 (A.3.8.2; so also open-etcs/openetcs-sdm, src/ETCS/SDM/Intern.hs;
#: cesarBLG/ETCS, EVC/Supervision/conversion_model.cpp, has -0.5 there, against the text).
CONVERSION_BUILD_UP: dict[str, dict[str, tuple[tuple[float, tuple[float, float, float], bool], ...]]] = {
    "emergency": {
        "passenger_p": ((math.inf, (2.30, 0.0, 0.17), True),),
        "freight_p": ((900.0, (2.30, 0.0, 0.17), True), (math.inf, (-0.40, 1.60, 0.03), False)),
        "freight_g": ((900.0, (12.0, 0.0, 0.05), False), (math.inf, (-0.40, 1.60, 0.03), False)),
    },
    "service": {
        "passenger_p": ((math.inf, (3.00, 1.50, 0.10), False),),
        "freight_p": ((900.0, (3.00, 2.77, 0.0), False), (math.inf, (10.50, 0.32, 0.18), False)),
        "freight_g": ((900.0, (3.00, 2.77, 0.0), True), (math.inf, (10.50, 0.32, 0.18), True)),
    },
}
#: A.3.8.4-5: kto = 1 + Ct for targets with a target speed above 0; Ct per brake position.
CONVERSION_CT: dict[str, float] = {"passenger_p": 0.20, "freight_p": 0.20, "freight_g": 0.16}
#: 3.13.3.2.1: validity limits of the conversion model: maximum speed [m/s], brake percentage [%],
#: train length [m] (900 m for a passenger train in P, 1500 m for freight trains).
CONVERSION_MAX_SPEED_MPS = 200.0 * KMH
CONVERSION_BRAKE_PERCENTAGE = (30.0, 250.0)
CONVERSION_MAX_LENGTH_M: dict[str, float] = {"passenger_p": 900.0, "freight_p": 1500.0, "freight_g": 1500.0}
#: The brake percentage above which the service brake model no longer grows: A_brake_service is the
#: basic deceleration of min(lambda, 135) (3.13.3.3.3 with A.3.7).
CONVERSION_SERVICE_MAX_BRAKE_PERCENTAGE = 135.0


def conversion_v_lim_mps(brake_percentage: float) -> float:
    """Upper speed of the first step of the basic deceleration, V_lim = 16.85 lambda^0.428 km/h [m/s]
    (SUBSET-026-3 A.3.7)."""
    return 16.85 * float(brake_percentage) ** 0.428 * KMH


def basic_deceleration(brake_percentage: float) -> StepFunction:
    """The basic deceleration A_basic(V) of a train of brake percentage lambda [m/s^2] (3.13.3.3.2, A.3.7).

    AD_0 = 0.0075 lambda + 0.076 from 0 to V_lim; above V_lim, AD_n(lambda) (a cubic in lambda) up to
    the first of 100, 120, 150, 180 km/h above V_lim, and so on; AD_5 above 180 km/h.
    """
    lam = float(brake_percentage)
    v_lim = conversion_v_lim_mps(lam)
    values = [0.0075 * lam + 0.076]
    limits = [v_lim]
    for n, (a0, a1, a2, a3) in enumerate(CONVERSION_AD_COEFFICIENTS):
        upper = CONVERSION_SPEED_LIMITS_KMH[n] * KMH if n < len(CONVERSION_SPEED_LIMITS_KMH) else math.inf
        if upper > v_lim:
            values.append(a3 * lam**3 + a2 * lam**2 + a1 * lam + a0)
            if math.isfinite(upper):
                limits.append(upper)
    return StepFunction(tuple(values), tuple(limits))


def conversion_build_up_time_s(
    kind: Literal["emergency", "service"], brake_position: str, length_m: float
) -> float:
    """Basic equivalent build-up time T_brake_basic_eb / T_brake_basic_sb [s] of the brake position
    conversion model: a + b (L/100) + c (L/100)^2 (SUBSET-026-3 A.3.8.1-3, A.3.9.1-3)."""
    for longest, (a, b, c), floor_400 in CONVERSION_BUILD_UP[kind][brake_position]:
        if length_m <= longest:
            x = max(length_m, 400.0) / 100 if floor_400 else length_m / 100
            return a + b * x + c * x * x
    raise AssertionError("unreachable: the last row is open ended")


def conversion_kto(brake_position: str) -> float:
    """kto = 1 + Ct, the factor on the build-up times for targets with a target speed above 0
    (SUBSET-026-3 A.3.8.4-5, A.3.9.4)."""
    return 1.0 + CONVERSION_CT[brake_position]


# ----------------------------------------------------------------------------------------------------
# Gradient profile
# ----------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Piecewise:
    """A piecewise constant function of position: ``values[0]`` below ``breaks[0]``, ``values[k]`` on
    ``[breaks[k-1], breaks[k])``, ``values[-1]`` from ``breaks[-1]`` on."""

    breaks: NDArray[np.float64]
    values: NDArray[np.float64]

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        return self.values[np.searchsorted(self.breaks, np.asarray(x, float), side="right")]


GradientProfile = Route | tuple[Sequence[float], Sequence[float]] | None


def _gradient_piecewise(profile: GradientProfile) -> _Piecewise:
    """The gradient [per mille] as a piecewise constant function; 0 outside the profile (3.13.4.1.3 b)."""
    if profile is None:
        return _Piecewise(np.zeros(0), np.zeros(1))
    if isinstance(profile, Route):
        breaks: list[float] = []
        values: list[float] = [0.0]
        for section in sorted(profile.gradients, key=lambda g: g.start_m):
            if not breaks or section.start_m > breaks[-1] + 1e-6:  # first section, or after a level gap
                breaks.append(section.start_m)
                values.append(section.gradient_permille)
            elif section.start_m < breaks[-1] - 1e-6:
                raise _bad(
                    "gradient sections overlap", "gradients", section.start_m, "non-overlapping sections"
                )
            else:  # adjacent to the previous section
                values[-1] = section.gradient_permille
            breaks.append(section.end_m)
            values.append(0.0)
        return _Piecewise(np.asarray(breaks, float), np.asarray(values, float))
    try:
        positions, gradients = profile
        pos = np.asarray(positions, dtype=float).ravel()
        grad = np.asarray(gradients, dtype=float).ravel()
    except (TypeError, ValueError) as exc:
        raise _bad(
            "gradient profile not understood",
            "gradient_profile",
            profile,
            "a trainsim Route, None, or a pair (positions_m, gradients_permille)",
        ) from exc
    if pos.size == 0 or pos.size != grad.size:
        raise _bad(
            "gradient profile needs as many gradients as positions (at least one)",
            "gradient_profile",
            (pos.size, grad.size),
            "equal, non-zero lengths",
        )
    if not (np.all(np.isfinite(pos)) and np.all(np.diff(pos) > 0)):
        raise _bad(
            "gradient positions must be finite and increasing",
            "gradient_profile.positions_m",
            pos,
            "increasing",
        )
    if not np.all(np.abs(grad) < 200):
        raise _bad(
            "gradient out of range", "gradient_profile.gradients_permille", grad, "-200 to 200 per mille"
        )
    return _Piecewise(pos, np.concatenate([[0.0], grad]))


def compensated_gradient_profile(
    gradient_profile: GradientProfile, train_length_m: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gradient profile compensated in location for the train length (SUBSET-026-3 3.13.4.2.1).

    For a (fictive) front end at d, the gradient used is the lowest gradient between d - L_TRAIN and
    d. Returns ``(breaks_m, gradients_permille)``: ``gradients[0]`` applies below ``breaks[0]``,
    ``gradients[k]`` on ``[breaks[k-1], breaks[k])`` and the last one from ``breaks[-1]`` on.
    """
    raw = _gradient_piecewise(gradient_profile)
    return _compensate(raw, train_length_m)


def _compensate(raw: _Piecewise, length_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if length_m <= 0 or raw.breaks.size == 0:
        return raw.breaks.copy(), raw.values.copy()
    points = np.unique(np.concatenate([raw.breaks, raw.breaks + length_m]))
    # one representative front position inside each interval between candidate points
    mids = np.concatenate([[points[0] - 1.0], (points[:-1] + points[1:]) / 2, [points[-1] + 1.0]])
    first = np.searchsorted(raw.breaks, mids - length_m, side="right")
    last = np.searchsorted(raw.breaks, mids, side="right")
    values = np.array([raw.values[i : j + 1].min() for i, j in zip(first, last, strict=True)])
    keep = np.concatenate([[True], values[1:] != values[:-1]])  # merge equal neighbours
    return points[keep[1:]], values[keep]


def _window_min(fn: _Piecewise, behind_m: float, ahead_m: float) -> _Piecewise:
    """x -> the lowest value of ``fn`` on [x - behind_m, x + ahead_m]."""
    breaks, values = _compensate(fn, behind_m + ahead_m)
    return _Piecewise(breaks - ahead_m, values)


# ----------------------------------------------------------------------------------------------------
# Braking curves: interconnected arcs of parabola (3.13.8.1.3)
# ----------------------------------------------------------------------------------------------------


def _representative_speeds(limits: NDArray[np.float64]) -> NDArray[np.float64]:
    """One speed inside each speed cell (0, V1], (V1, V2], ..., (Vn, inf)."""
    if limits.size == 0:
        return np.zeros(1)
    lows = np.concatenate([[0.0], limits])
    highs = np.concatenate([limits, [limits[-1] + 2.0]])
    return (lows + highs) / 2


@dataclass(frozen=True)
class BrakingCurve:
    """A braking deceleration curve: arcs of parabola through a reference point (3.13.8.1.3).

    Nodes ``positions_m`` (increasing) and ``speeds_mps`` (decreasing) with the constant deceleration
    ``decelerations_mps2[k]`` between nodes k and k+1 (v^2 = v_k^2 - 2 A_k (s - s_k)). The curve ends
    at its foot (last node); before the first node the speed is above the range it was built for.
    """

    positions_m: NDArray[np.float64]
    speeds_mps: NDArray[np.float64]
    decelerations_mps2: NDArray[np.float64]

    @classmethod
    def build(
        cls,
        speed_limits_mps: NDArray[np.float64],
        position_breaks_m: NDArray[np.float64],
        deceleration_table: NDArray[np.float64],
        ref_position_m: float,
        ref_speed_mps: float,
        cap_speed_mps: float,
        foot_speed_mps: float,
        name: str = "braking curve",
    ) -> BrakingCurve:
        """Integrate exactly, backwards from the reference point up to ``cap_speed_mps`` and forwards
        down to ``foot_speed_mps``, with the deceleration ``deceleration_table[i, j]`` in speed cell i
        (of ``speed_limits_mps``) and position cell j (of ``position_breaks_m``)."""
        b, p, table = speed_limits_mps, position_breaks_m, deceleration_table
        max_steps = 4 * (b.size + p.size + 4)

        def decel(i: int, j: int, x: float) -> float:
            a = float(table[i, j])
            if not a > MIN_NET_DECELERATION_MPS2:
                raise InfeasibleError(
                    f"{name}: the net deceleration at {x:.1f} m is {a:.4f} m/s^2; the train cannot brake "
                    "there (downhill gradient steeper than its brakes)"
                )
            return a

        back_x, back_v, back_a = [ref_position_m], [ref_speed_mps], []
        x, v = ref_position_m, ref_speed_mps
        for _ in range(max_steps):
            if v >= cap_speed_mps:
                break
            i = int(np.searchsorted(b, v, side="right"))
            j = int(np.searchsorted(p, x, side="left"))
            a = decel(i, j, x)
            v_goal = min(float(b[i]) if i < b.size else math.inf, cap_speed_mps)
            x_low = float(p[j - 1]) if j > 0 else -math.inf
            dx = (v_goal * v_goal - v * v) / (2 * a)
            if x - dx >= x_low:
                x, v = x - dx, v_goal
            else:
                v = math.sqrt(v * v + 2 * a * (x - x_low))
                x = x_low
            back_x.append(x)
            back_v.append(v)
            back_a.append(a)
        fwd_x, fwd_v, fwd_a = [], [], []
        x, v = ref_position_m, ref_speed_mps
        for _ in range(max_steps):
            if v <= foot_speed_mps:
                break
            i = int(np.searchsorted(b, v, side="left"))
            j = int(np.searchsorted(p, x, side="right"))
            a = decel(i, j, x)
            v_goal = max(float(b[i - 1]) if i > 0 else 0.0, foot_speed_mps)
            x_high = float(p[j]) if j < p.size else math.inf
            dx = (v * v - v_goal * v_goal) / (2 * a)
            if x + dx <= x_high:
                x, v = x + dx, v_goal
            else:
                v = math.sqrt(max(v * v - 2 * a * (x_high - x), 0.0))
                x = x_high
            fwd_x.append(x)
            fwd_v.append(v)
            fwd_a.append(a)
        xs = np.asarray(back_x[::-1] + fwd_x)
        vs = np.asarray(back_v[::-1] + fwd_v)
        accs = np.asarray(back_a[::-1] + fwd_a)
        return cls(xs, vs, accs)

    def speed_mps(self, s_m: ArrayLike) -> NDArray[np.float64]:
        """Curve speed at position ``s_m`` [m/s]: np.inf before the built range, the foot speed after."""
        s = np.asarray(s_m, dtype=float)
        xs, vs, accs = self.positions_m, self.speeds_mps, self.decelerations_mps2
        if accs.size == 0:
            return np.where(s < xs[0], np.inf, vs[0])
        k = np.clip(np.searchsorted(xs, s, side="right") - 1, 0, accs.size - 1)
        v2 = vs[k] ** 2 - 2 * accs[k] * (s - xs[k])
        out = np.sqrt(np.maximum(v2, 0.0))
        out = np.where(s >= xs[-1], vs[-1], out)
        return np.where(s < xs[0], np.inf, out)

    def position_m(self, v_mps: ArrayLike) -> NDArray[np.float64]:
        """Position where the curve has speed ``v_mps`` [m]: -inf above its range, the foot below it."""
        v = np.asarray(v_mps, dtype=float)
        xs, vs, accs = self.positions_m, self.speeds_mps, self.decelerations_mps2
        if accs.size == 0:
            return np.where(v > vs[0], -np.inf, xs[0])
        # speeds decrease along the nodes: search the reversed (increasing) array
        rev = vs[::-1]
        k = (vs.size - 1) - np.searchsorted(rev, v, side="left")  # last node with speed >= v
        k = np.clip(k, 0, accs.size - 1)
        x = xs[k] + (vs[k] ** 2 - v**2) / (2 * accs[k])
        x = np.where(v <= vs[-1], xs[-1], x)
        return np.where(v > vs[0], -np.inf, x)


# ----------------------------------------------------------------------------------------------------
# Targets and supervision limits
# ----------------------------------------------------------------------------------------------------


@dataclass
class _Times:
    t_be: float
    t_bs: float
    t_bs1: float
    t_bs2: float
    t_traction: float
    t_berem: float
    t_indication: float


@dataclass
class _Target:
    """One supervised target: EBD based (SvL, MRSP decrease) or SBD based (EoA)."""

    kind: Literal["svl", "mrsp", "eoa"]
    position_m: float
    v_target_mps: float
    curve: BrakingCurve  # EBD or SBD
    times: _Times
    a_est_mps2: float
    v_delta0: Callable[[ArrayLike], NDArray[np.float64]]
    national: EtcsNationalValues
    gui: BrakingCurve | None = None
    gui_in_p: bool = False
    #: estimated-front to max-safe-front distance for EBD targets, 0 for the EoA [m] (3.13.9.3.1)
    offset_m: float = 0.0
    _tables: dict[tuple[str, float], tuple[NDArray[np.float64], NDArray[np.float64]]] = field(
        default_factory=dict, repr=False
    )

    @property
    def ebd_based(self) -> bool:
        return self.kind != "eoa"

    # positions of the supervision limits for the speed v (3.13.9.3.2 - 3.13.9.3.6)
    def d_ebi(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """d_EBI(V_est) = d_EBD(V_bec) - D_bec (3.13.9.3.2.12)."""
        t = self.times
        a_est1 = max(0.0, self.a_est_mps2)
        a_est2 = min(max(0.0, self.a_est_mps2), self.national.a_est2_max_mps2)
        dv0 = self.v_delta0(v)
        dv1 = a_est1 * t.t_traction
        dv2 = a_est2 * t.t_berem
        vbec = v_bec_mps(v, self.v_target_mps, dv0, dv1, dv2)
        dbec = d_bec_m(v, self.v_target_mps, dv0, dv1, dv2, t.t_traction, t.t_berem)
        return self.curve.position_m(vbec) - dbec

    def d_sbi(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """SBI1 = d_SBD(V) - V T_bs1 for the EoA, SBI2 = d_EBI(V) - V T_bs2 otherwise (3.13.9.3.3.1-2)."""
        if self.ebd_based:
            return self.d_ebi(v) - v * self.times.t_bs2
        return self.curve.position_m(v) - v * self.times.t_bs1

    def d_warning(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """d_W = d_SBI - V T_warning (3.13.9.3.4.1)."""
        return self.d_sbi(v) - v * self.national.t_warning_s

    def d_permitted(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """d_P = d_SBI - V T_driver, not beyond the target for an EBD target, and not beyond the GUI
        curve when it is enabled (3.13.9.3.5.1, 3.13.9.3.5.4)."""
        d = self.d_sbi(v) - v * self.national.t_driver_s
        if self.ebd_based:
            d = np.minimum(d, self.position_m)
        if self.gui_in_p and self.gui is not None:
            d = np.minimum(d, self.gui.position_m(v))
        return d

    def d_indication(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """d_I = d_P - V T_indication (3.13.9.3.6.1)."""
        return self.d_permitted(v) - v * self.times.t_indication

    def d_limit(self, kind: str, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """The limit's location for the estimated front end: an EBD target is supervised with the max
        safe front end, ``offset_m`` ahead of it; the EoA with the estimated front end."""
        if kind == "ebi":
            if not self.ebd_based:
                return np.full_like(v, np.inf)
            return self.d_ebi(v) - self.offset_m
        return getattr(self, f"d_{'sbi' if kind == 'sbi' else kind}")(v) - self.offset_m

    def _table(self, kind: str, v_high: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The limit's location on a speed grid from V_target to ``v_high`` (cached)."""
        key = (kind, v_high)
        if key not in self._tables:
            speeds = np.linspace(self.v_target_mps, v_high, TABLE_POINTS)
            self._tables[key] = (speeds, self.d_limit(kind, speeds))
        return self._tables[key]

    def speed_limit(self, kind: str, s: NDArray[np.float64], v_high: float) -> NDArray[np.float64]:
        """The limit's speed at the positions ``s``: the highest V >= V_target whose limit location
        is at or beyond s; V_target beyond the location for V_target; np.inf above ``v_high``.

        d(V) does not increase with V: a table brackets the root, regula falsi (Illinois) refines it,
        and bisection finishes the few points that did not converge to ``ROOT_TOLERANCE_M``.
        """
        speeds, locations = self._table(kind, v_high)
        out = np.where(s >= locations[0], self.v_target_mps, np.inf)
        if self.kind == "mrsp":  # passed by the max safe front end: the ceiling limits take over (3.13.8.2.3)
            out = np.where(s >= self.position_m - self.offset_m, np.inf, out)
        inside = (s < locations[0]) & (s >= locations[-1])
        if not np.any(inside):
            return out
        x = s[inside]
        i = np.clip(np.searchsorted(-locations, -x, side="right"), 1, speeds.size - 1)
        lo, hi = speeds[i - 1], speeds[i]
        f_lo, f_hi = locations[i - 1] - x, locations[i] - x  # >= 0 and < 0
        v = hi.copy()
        done = np.zeros(x.shape, dtype=bool)
        last = np.zeros(x.shape, dtype=int)  # which end moved last: -1 lo, +1 hi, 0 none
        for _ in range(REGULA_FALSI_STEPS):
            denom = f_hi - f_lo
            v = np.where(denom != 0, hi - f_hi * (hi - lo) / np.where(denom != 0, denom, 1.0), lo)
            v = np.clip(v, lo, hi)
            f = self.d_limit(kind, v) - x
            right = f < 0  # the root lies between lo and v: v replaces hi
            # Illinois: when the same end moves twice in a row, halve the stale end's value
            f_lo = np.where(right & (last == 1), f_lo / 2, f_lo)
            f_hi = np.where(~right & (last == -1), f_hi / 2, f_hi)
            f_lo = np.where(right, f_lo, f)
            lo = np.where(right, lo, v)
            f_hi = np.where(right, f, f_hi)
            hi = np.where(right, v, hi)
            last = np.where(right, 1, -1)
            done = np.abs(f) <= ROOT_TOLERANCE_M
            if np.all(done):
                break
        if not np.all(done):
            b_lo, b_hi = lo[~done], hi[~done]
            xb = x[~done]
            for _ in range(BISECTION_STEPS):
                mid = (b_lo + b_hi) / 2
                ok = self.d_limit(kind, mid) >= xb
                b_lo = np.where(ok, mid, b_lo)
                b_hi = np.where(ok, b_hi, mid)
            v[~done] = b_lo
        out[inside] = v
        return out

    def curve_speed(self, curve: BrakingCurve, s: NDArray[np.float64]) -> NDArray[np.float64]:
        """A braking curve of this target: inf beyond the foot of a speed-decrease target's curve."""
        out = curve.speed_mps(s)
        if self.kind == "mrsp":
            out = np.where(s > curve.positions_m[-1], np.inf, out)
        return out


@dataclass(frozen=True)
class SupervisionCurves:
    """ETCS braking curves and supervision limits toward one end of authority or target.

    Every method takes the train's front-end position ``s`` [m] (a number or an array) and returns
    speeds [m/s], ``np.inf`` where the limit does not constrain (far ahead of the target, above any
    speed the train can reach). ``ebd``, ``sbd`` and ``guidance`` are the braking curves (the minimum
    over the targets); ``ebi``, ``sbi``, ``warning``, ``permitted`` and ``indication`` are the
    supervision limits: the minimum over the targets (the EoA and SvL, and every speed decrease of the
    MRSP) and the ceiling supervision limits of the MRSP (3.13.9.2), with the release speed applied
    from the start of release speed monitoring (3.13.9.4).

    Attributes:
        eoa_position_m / svl_position_m: the end of authority and the supervised location [m] (for a
            speed-decrease target both are its location).
        target_speed_mps: target speed [m/s] (0 for an EoA/SvL).
        release_speed_mps: release speed [m/s] (0: none).
        release_start_m: start location of release speed monitoring [m], or None.
        trip_position_m: the trip location related to the EoA [m]: beyond it every limit is 0.
        times: the time intervals used (t_be, t_bs, t_bs1, t_bs2, t_traction, t_berem, t_indication) [s].
    """

    eoa_position_m: float
    svl_position_m: float
    target_speed_mps: float
    release_speed_mps: float
    release_start_m: float | None
    trip_position_m: float | None
    times: dict[str, float]
    _targets: tuple[_Target, ...] = field(repr=False)
    _mrsp: _Piecewise = field(repr=False)
    _national: EtcsNationalValues = field(repr=False)
    _v_high: float = field(repr=False)

    # --- braking curves ---
    def ebd(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Emergency brake deceleration curve EBD [m/s] (3.13.8.3): the lowest over the EBD targets."""
        return self._curve_min(s, lambda t: t.ebd_based, lambda t, x: t.curve_speed(t.curve, x))

    def sbd(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Service brake deceleration curve SBD toward the EoA [m/s] (3.13.8.4); inf without an EoA."""
        return self._curve_min(s, lambda t: not t.ebd_based, lambda t, x: t.curve_speed(t.curve, x))

    def guidance(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Guidance curve GUI [m/s] (3.13.8.5): the lowest over the targets."""
        return self._curve_min(s, lambda t: t.gui is not None, lambda t, x: t.curve_speed(t.gui, x))

    # --- supervision limits ---
    def ebi(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Emergency brake intervention supervision limit EBI [m/s] (3.13.9.2, 3.13.9.3.2, 3.13.9.4.1)."""
        return self._limit("ebi", s)

    def sbi(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Service brake intervention supervision limit SBI [m/s]: min of SBI1 and SBI2 (3.13.9.3.3)."""
        return self._limit("sbi", s)

    def warning(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Warning supervision limit W [m/s] (3.13.9.2, 3.13.9.3.4)."""
        return self._limit("warning", s)

    def permitted(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Permitted speed supervision limit P [m/s] (3.13.9.2, 3.13.9.3.5)."""
        return self._limit("permitted", s)

    def indication(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """Indication supervision limit I [m/s] (3.13.9.3.6); the MRSP where no target is indicated."""
        return self._limit("indication", s)

    def limit_position_m(self, kind: LimitKind, v_mps: ArrayLike) -> NDArray[np.float64] | float:
        """Where the supervision limit ``kind`` is reached by a train at speed ``v_mps`` [m]: the first
        location over the targets that supervise that speed (np.inf if there is none).

        A speed-decrease target supervises speeds above V_target + dV(V_target) (dV_ebi, dV_sbi,
        dV_warning; 0 for P and I), the EoA and SvL speeds above the release speed (Tables 8 and 9,
        3.13.10.4.10.1)."""
        if kind not in LIMIT_KINDS:
            raise _bad("unknown supervision limit", "kind", kind, ", ".join(LIMIT_KINDS))
        v = np.asarray(v_mps, dtype=float)
        out = np.full(v.shape, np.inf)
        for target in self._targets:
            if kind == "ebi" and not target.ebd_based:
                continue
            d = target.d_limit(kind, np.atleast_1d(v).astype(float)).reshape(v.shape)
            out = np.where(v > self._floor(kind, target), np.minimum(out, d), out)
        return float(out) if out.ndim == 0 else out

    def _floor(self, kind: str, target: _Target) -> float:
        """The speed up to which a target never triggers the limit ``kind`` (Tables 8, 9)."""
        if target.kind == "mrsp":
            if kind in ("ebi", "sbi", "warning"):
                return target.v_target_mps + float(_dv(kind, target.v_target_mps, self._national))
            return target.v_target_mps
        return self.release_speed_mps

    def indication_point_m(self, v_mps: ArrayLike) -> NDArray[np.float64] | float:
        """Where a train at speed ``v_mps`` reaches the indication limit, i.e. must start braking to stay
        below the permitted speed [m] (3.13.9.3.6.1); np.inf if no target asks it to brake."""
        return self.limit_position_m("indication", v_mps)

    def v_mrsp(self, s: ArrayLike) -> NDArray[np.float64] | float:
        """The most restrictive speed profile V_MRSP at ``s`` [m/s] (train maximum speed included)."""
        out = self._mrsp(np.asarray(s, float))
        return float(out) if np.ndim(out) == 0 else out

    # --- internals ---
    def _curve_min(
        self,
        s: ArrayLike,
        select: Callable[[_Target], bool],
        speed: Callable[[_Target, NDArray[np.float64]], NDArray[np.float64]],
    ) -> NDArray[np.float64] | float:
        x = np.asarray(s, dtype=float)
        out = np.full(x.shape, np.inf)
        for target in self._targets:
            if select(target):
                out = np.minimum(out, speed(target, x))
        return float(out) if out.ndim == 0 else out

    def _limit(self, kind: str, s: ArrayLike) -> NDArray[np.float64] | float:
        x = np.asarray(s, dtype=float)
        flat = np.atleast_1d(x).astype(float).ravel()
        v_mrsp = self._mrsp(flat)
        n = self._national
        offsets = {
            "ebi": _dv("ebi", v_mrsp, n),
            "sbi": _dv("sbi", v_mrsp, n),
            "warning": _dv("warning", v_mrsp, n),
            "permitted": 0.0,
            "indication": 0.0,
        }
        out = v_mrsp + offsets[kind]
        for target in self._targets:
            if kind == "ebi" and not target.ebd_based:
                continue
            limit = target.speed_limit(kind, flat, self._v_high)
            floor = self._floor(kind, target)
            if target.kind != "mrsp":  # the EoA and SvL limits hold up to the EoA (or its trip location)
                floor = np.where(flat < self.eoa_position_m, floor, 0.0)
            out = np.minimum(out, np.maximum(limit, floor))
        if kind == "ebi" and self.release_start_m is not None and self.trip_position_m is not None:
            # release speed monitoring: the EBI is the release speed up to the trip location (3.13.9.4.1)
            in_rsm = (flat >= self.release_start_m) & (flat < self.trip_position_m)
            out = np.where(in_rsm, np.minimum(self.release_speed_mps, v_mrsp + offsets[kind]), out)
        if kind == "ebi" and self.trip_position_m is not None:
            out = np.where(flat >= self.trip_position_m, 0.0, out)  # train trip beyond the EoA (3.13.10.2.6)
        out = out.reshape(x.shape)
        return float(out) if out.ndim == 0 else out


# ----------------------------------------------------------------------------------------------------
# Construction
# ----------------------------------------------------------------------------------------------------


def _mrsp_piecewise(mrsp: Any, v_max: float) -> _Piecewise:
    """The MRSP as a piecewise constant function, capped by the train's maximum speed."""
    if mrsp is None:
        return _Piecewise(np.zeros(0), np.asarray([v_max]))
    if isinstance(mrsp, Route):
        limits = sorted(mrsp.speed_limits, key=lambda lim: lim.start_m)
        if not limits:
            return _Piecewise(np.zeros(0), np.asarray([v_max]))
        breaks = [lim.start_m for lim in limits] + [limits[-1].end_m]
        values = (
            [lim.limit_mps for lim in limits[:1]]
            + [lim.limit_mps for lim in limits]
            + [lim.limit_mps for lim in limits[-1:]]
        )
        pos, speeds = np.asarray(breaks, float), np.asarray(values, float)
    else:
        try:
            positions, speed_values = mrsp
            pos = np.asarray(positions, dtype=float).ravel()
            spd = np.asarray(speed_values, dtype=float).ravel()
        except (TypeError, ValueError) as exc:
            raise _bad(
                "MRSP not understood",
                "mrsp",
                mrsp,
                "a trainsim Route, None, or a pair (positions_m, speeds_mps)",
            ) from exc
        if pos.size == 0 or pos.size != spd.size:
            raise _bad(
                "MRSP needs as many speeds as positions", "mrsp", (pos.size, spd.size), "equal lengths"
            )
        if not (np.all(np.isfinite(pos)) and np.all(np.diff(pos) > 0)):
            raise _bad("MRSP positions must be finite and increasing", "mrsp.positions_m", pos, "increasing")
        speeds = np.concatenate([spd[:1], spd])
    if not np.all((speeds > 0) | np.isinf(speeds)):
        raise _bad("MRSP speeds must be above 0", "mrsp.speeds_mps", speeds, "speeds > 0 m/s")
    return _Piecewise(pos, np.minimum(speeds, v_max))


def _representative_positions(breaks: NDArray[np.float64]) -> NDArray[np.float64]:
    """One position inside each cell (-inf, b0), [b0, b1), ..., [bn, inf) of the position breaks."""
    if breaks.size == 0:
        return np.zeros(1)
    return np.concatenate([[breaks[0] - 1.0], (breaks[:-1] + breaks[1:]) / 2, [breaks[-1] + 1.0]])


def _reduced_adhesion_piecewise(reduced: bool | Sequence[tuple[float, float]], length_m: float) -> _Piecewise:
    """1 where the adhesion is reduced, else 0 (3.13.5.3: a trackside section up to its end plus the
    train length; 3.13.5.4: slippery rail selected by the driver, everywhere)."""
    if reduced is True:
        return _Piecewise(np.zeros(0), np.ones(1))
    if reduced is False or reduced is None:
        return _Piecewise(np.zeros(0), np.zeros(1))
    try:
        spans = [(float(a), float(b)) for a, b in reduced]
    except (TypeError, ValueError) as exc:
        raise _bad(
            "reduced adhesion not understood",
            "reduced_adhesion",
            reduced,
            "True, False, or sections [(start_m, end_m), ...]",
        ) from exc
    for a, b in spans:
        if not (math.isfinite(a) and math.isfinite(b) and b > a):
            raise _bad(
                "a reduced adhesion section must end after it starts",
                "reduced_adhesion",
                (a, b),
                "start < end",
            )
    points = np.unique([x for a, b in spans for x in (a, b + length_m)])
    mids = _representative_positions(points)
    flags = np.array([any(a <= x < b + length_m for a, b in spans) for x in mids], dtype=float)
    return _Piecewise(points, flags)


def a_max_reduced_adhesion_mps2(train: EtcsTrainData, national: EtcsNationalValues) -> float:
    """A_MAXREDADH [m/s^2]: A_NVMAXREDADH1 for a passenger train in P whose adhesion-independent brakes
    may count, A_NVMAXREDADH2 for one without, A_NVMAXREDADH3 for freight trains (3.13.6.2.1.6);
    np.inf if that national value does not limit the deceleration."""
    if train.brake_position != "passenger_p":
        value = national.a_nvmaxredadh3_mps2
    elif train.adhesion_independent_brake:
        value = national.a_nvmaxredadh1_mps2
    else:
        value = national.a_nvmaxredadh2_mps2
    return math.inf if value is None else float(value)


def _speed_table(
    fns: Sequence[StepFunction], combine: Callable[..., NDArray[np.float64]]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Merge step functions of speed onto common cells: (limits, combined value per cell)."""
    limits = np.unique(np.concatenate([np.asarray(f.upper_limits, float) for f in fns] + [np.zeros(0)]))
    reps = _representative_speeds(limits)
    return limits, np.asarray(combine(*[np.atleast_1d(f(reps)) for f in fns]), float)


def supervision_curves(
    train: EtcsTrainData,
    national: EtcsNationalValues,
    gradient_profile: GradientProfile,
    eoa_position_m: float,
    svl_position_m: float | None = None,
    target_speed_mps: float = 0.0,
    mrsp: Any = None,
    *,
    release_speed: float | Literal["calculated", "national"] = "calculated",
    estimated_acceleration_mps2: float = 0.0,
    eoa_trip_margin_m: float = 0.0,
    reduced_adhesion: bool | Sequence[tuple[float, float]] = False,
    position_confidence_m: float = 0.0,
) -> SupervisionCurves:
    """ETCS braking curves and supervision limits toward a target (SUBSET-026-3 3.13.8, 3.13.9).

    Args:
        train: the train's braking data.
        national: national and fixed values.
        gradient_profile: the gradient [per mille, positive uphill] as a function of position: a
            trainsim ``Route`` (its gradient sections), a pair ``(positions_m, gradients_permille)``
            (gradient k applies from position k to position k+1, the last one onwards; level before
            the first position) or ``None`` (level).
        eoa_position_m: with ``target_speed_mps == 0`` the end of authority (EoA) [m]; otherwise the
            location of a speed-decrease target [m].
        svl_position_m: the supervised location (end of the overlap / danger point) [m] >= the EoA;
            default the EoA itself. Only for target speed 0.
        target_speed_mps: 0 for an EoA/SvL, or the target speed of a speed decrease [m/s].
        mrsp: the most restrictive speed profile: a ``Route`` (its speed limits), a pair
            ``(positions_m, speeds_mps)`` (speed k from position k on; the first speed also before
            the first position) or ``None``; the train maximum speed caps it (3.13.7.2). Its decreases are supervised
            as targets and its ceiling limits cap every supervision limit.
        release_speed: ``"calculated"`` (3.13.9.4.8), ``"national"`` (V_NVREL) or a value [m/s]
            given by trackside (3.13.9.4.3); ignored for a speed-decrease target.
        estimated_acceleration_mps2: A_est used for V_delta1 and V_delta2 [m/s^2]; default 0, the
            value Subset-026 uses for limits computed in advance (3.13.9.3.5.9 a, 3.13.9.4.8.1).
        eoa_trip_margin_m: distance from the EoA to its trip location [m] (the position confidence
            part of d_tripEOA in 3.13.9.4.8.2); default 0.

        reduced_adhesion: ``True`` for slippery rail selected by the driver (everywhere,
            3.13.5.4), or the reduced adhesion sections ``[(start_m, end_m), ...]`` given by trackside
            (each applied up to its end plus the train length, 3.13.5.3); there A_brake_safe is limited
            to A_NVMAXREDADH (3.13.6.2.1.3, 3.13.6.2.1.6). Default none.

        position_confidence_m: distance between the estimated front end and the max (and min) safe
            front end [m] (L_DOUBTOVER = L_DOUBTUNDER, 3.6.4); default 0. The supervision limits are
            then for the estimated front end: EBD targets are supervised with the max safe front end,
            the EoA with the estimated one (3.13.9.3.1, Tables 8-9), V_MRSP is the lowest MRSP speed
            between the min and max safe front ends (3.13.7.2), the train trips when the min safe
            front end passes the EoA (3.13.10.2.6) and d_tripEOA is at least the confidence interval
            beyond the EoA (3.13.9.4.8.2). The braking curves (ebd, sbd, guidance) stay in track
            coordinates.

    Raises:
        InputError: bad input (naming the field, the value and what is allowed).
        InfeasibleError: the net deceleration is not positive somewhere on a curve (brakes weaker than
            the downhill gradient).
    """
    for name, value in (("eoa_position_m", eoa_position_m), ("target_speed_mps", target_speed_mps)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            raise _bad(f"{name} must be a finite number", name, value, "a finite number")
    if target_speed_mps < 0:
        raise _bad("target speed must not be negative", "target_speed_mps", target_speed_mps, ">= 0 m/s")
    if svl_position_m is None:
        svl_position_m = eoa_position_m
    if isinstance(svl_position_m, bool) or not isinstance(svl_position_m, numbers.Real):
        raise _bad("svl_position_m must be a number", "svl_position_m", svl_position_m, "a number >= the EoA")
    if not (math.isfinite(svl_position_m) and svl_position_m >= eoa_position_m):
        raise _bad(
            "the SvL must not be before the EoA", "svl_position_m", svl_position_m, f">= {eoa_position_m}"
        )
    if target_speed_mps > 0 and svl_position_m != eoa_position_m:
        raise _bad(
            "a speed-decrease target has no SvL",
            "svl_position_m",
            svl_position_m,
            "None when target_speed_mps > 0",
        )
    _check_range("estimated_acceleration_mps2", estimated_acceleration_mps2, -10.0, 10.0, "-10 to 10 m/s^2")
    _check_range("eoa_trip_margin_m", eoa_trip_margin_m, 0.0, 10000.0, "0 to 10000 m")
    _check_range("position_confidence_m", position_confidence_m, 0.0, 10000.0, "0 to 10000 m")
    confidence = float(position_confidence_m)
    if isinstance(release_speed, str):
        if release_speed not in ("calculated", "national"):
            raise _bad(
                "unknown release speed variant", "release_speed", release_speed, "calculated, national or m/s"
            )
    else:
        _check_range("release_speed", release_speed, 0.0, 100.0, "calculated, national or 0 to 100 m/s")

    n = national
    v_max = train.max_speed_mps
    mrsp_fn = _mrsp_piecewise(mrsp, v_max)
    if target_speed_mps > 0:  # the speed decrease is an element of the MRSP from its location on
        values = mrsp_fn.values.copy()
        breaks = mrsp_fn.breaks
        idx = int(np.searchsorted(breaks, eoa_position_m, side="right"))
        new_breaks = np.concatenate([breaks[:idx], [eoa_position_m], breaks[idx:]])
        new_values = np.concatenate([values[: idx + 1], [values[idx]], values[idx + 1 :]])
        new_values[idx + 1 :] = np.minimum(new_values[idx + 1 :], target_speed_mps)
        mrsp_fn = _Piecewise(new_breaks, new_values)
    v_ceiling_top = float(np.max(mrsp_fn.values))
    v_high = v_ceiling_top + float(_dv("ebi", v_ceiling_top, n)) + SPEED_HEADROOM_MPS

    # gradient: compensated in location (3.13.4.2) and value (3.13.4.3)
    grad_breaks, grad_values = compensated_gradient_profile(gradient_profile, train.length_m)
    adhesion = _reduced_adhesion_piecewise(reduced_adhesion, train.length_m)
    # position cells: every change of the compensated gradient and of the adhesion conditions
    pos_breaks = np.unique(np.concatenate([grad_breaks, adhesion.breaks]))
    where = _representative_positions(pos_breaks)
    grad = _Piecewise(grad_breaks, grad_values)(where)
    a_grad = a_gradient_mps2(
        grad, train.m_rotating_nom_percent, n.m_rotating_max_percent, n.m_rotating_min_percent, n.gravity_mps2
    )
    a_maxredadh = a_max_reduced_adhesion_mps2(train, n)
    safe_cap = np.where(adhesion(where) > 0, a_maxredadh, np.inf)

    # safe emergency deceleration (3.13.6.2.1.4)
    if train.conversion_model_used:
        if train.brake_position == "passenger_p":
            kv_a, kv_b = n.kv_int_passenger_a, n.kv_int_passenger_b
            limits = _limits_of(kv_a, kv_b)
            kv_values = kv_int_passenger(
                _a_ebmax_mps2(train.a_brake_emergency, v_max),
                kv_a(_representative_speeds(limits)),
                kv_b(_representative_speeds(limits)),
                n.a_nvp12_mps2,
                n.a_nvp23_mps2,
            )
            kv_fn = StepFunction(tuple(np.atleast_1d(kv_values)), tuple(limits))
        else:
            kv_fn = n.kv_int_freight
        kr = float(n.kr_int(train.length_m))
        ebr_limits, a_brake_safe = _speed_table(
            [train.a_brake_emergency, kv_fn],
            lambda a, k: a_brake_safe_conversion_mps2(a, k, kr),
        )
    else:
        ebr_limits, a_brake_safe = _speed_table(
            [train.a_brake_emergency, train.kdry_for(n.m_nvebcl), train.kwet_rst],
            lambda a, kd, kw: a_brake_safe_gamma_mps2(a, kd, kw, n.m_nvavadh),
        )
    # A_safe = MIN(A_brake_safe, A_MAXREDADH) + A_gradient, the cap only with reduced adhesion (3.13.6.2.1.3)
    safe_table = np.minimum(a_brake_safe[:, None], safe_cap[None, :]) + a_grad[None, :]
    sb_limits, a_service = _speed_table([train.a_brake_service], lambda a: a)
    expected_table = a_service[:, None] + a_grad[None, :]  # A_expected (3.13.6.3.1.3)
    ns_limits = np.unique(
        np.concatenate(
            [
                np.asarray(f.upper_limits, float)
                for f in (train.a_brake_normal_service, train.kn_plus, train.kn_minus)
            ]
        )
    )
    reps = _representative_speeds(ns_limits)
    normal_table = a_normal_service_mps2(
        np.atleast_1d(train.a_brake_normal_service(reps))[:, None],
        a_grad[None, :],
        grad[None, :],
        np.atleast_1d(train.kn_plus(reps))[:, None],
        np.atleast_1d(train.kn_minus(reps))[:, None],
    )

    # times (3.13.6.2.2.3, 3.13.6.3.2.4, 3.13.9.3.2.3, 3.13.9.3.2.6, 3.13.9.3.3, 3.13.9.3.6)
    def times_for(v_target: float) -> _Times:
        t_emergency = train.t_brake_emergency_s
        t_service = train.t_brake_service_s
        if v_target > 0:
            if train.t_brake_emergency_cmt_s is not None:
                t_emergency = train.t_brake_emergency_cmt_s
            if train.t_brake_service_cmt_s is not None:
                t_service = train.t_brake_service_cmt_s
        t_be = n.kt_int * t_emergency if train.conversion_model_used else t_emergency
        sb_available = train.service_brake_command and n.q_nvsbtsmperm
        t_bs12 = t_service if sb_available else 0.0
        t_tr = t_traction_s(
            train.t_traction_cut_off_s, n.t_warning_s, t_bs12, train.traction_cut_off_implemented
        )
        feedback = train.service_brake_feedback and n.q_nvsbfbperm
        return _Times(
            t_be=t_be,
            t_bs=t_service,
            t_bs1=t_bs12,
            t_bs2=t_bs12,
            t_traction=t_tr,
            t_berem=t_berem_s(t_be, t_tr),
            t_indication=t_indication_s(
                t_service, n.t_driver_s, feedback, n.t_indication_min_s, n.t_indication_bs_factor
            ),
        )

    def v_delta0(v: ArrayLike) -> NDArray[np.float64]:
        """V_delta0 = V_ura, or 0 when inhibited by Q_NVINHSMICPERM (3.13.9.3.2.1)."""
        if n.q_nvinhsmicperm:
            return np.zeros_like(np.asarray(v, float))
        return train.v_ura_mps(v)

    a_est = float(estimated_acceleration_mps2)
    ebd_cap = v_high + float(v_delta0(v_high)) + max(a_est, 0.0) * 1000.0 + SPEED_HEADROOM_MPS
    ebd_cap = min(ebd_cap, v_high + 300.0)

    def ebd_curve(position: float, speed: float, foot: float) -> BrakingCurve:
        return BrakingCurve.build(
            ebr_limits, pos_breaks, safe_table, position, speed, max(ebd_cap, speed), foot, "EBD"
        )

    def gui_curve(foot_position: float, v_target: float) -> BrakingCurve:
        return BrakingCurve.build(
            ns_limits, pos_breaks, normal_table, foot_position, v_target, v_high, v_target, "GUI"
        )

    targets: list[_Target] = []
    common = {
        "a_est_mps2": a_est,
        "v_delta0": v_delta0,
        "national": n,
        "gui_in_p": n.q_nvguiperm,
        "offset_m": confidence,
    }

    # MRSP speed decreases before the SvL (3.13.8.2.1 a), EBD through V_target + dV_ebi at the target
    # location down to V_target (3.13.8.3.1); GUI foot at d_P(V_target) (3.13.9.3.5.9-10)
    for k, location in enumerate(mrsp_fn.breaks):
        before, after = float(mrsp_fn.values[k]), float(mrsp_fn.values[k + 1])
        if not after < before or (target_speed_mps == 0 and location >= svl_position_m):
            continue
        times = times_for(after)
        curve = ebd_curve(float(location), after + float(_dv("ebi", after, n)), after)
        target = _Target("mrsp", float(location), after, curve, times, **common)
        v0t = float(v_delta0(after))
        d_ebi_t = float(curve.position_m(after + v0t)) - (after + v0t) * (times.t_berem + times.t_traction)
        foot = min(d_ebi_t - after * (n.t_driver_s + times.t_bs2), float(location))
        target.gui = gui_curve(foot, after)
        targets.append(target)

    release_v = 0.0
    release_start: float | None = None
    trip: float | None = None
    times0 = times_for(0.0)
    if target_speed_mps == 0:
        svl_target = _Target(
            "svl", svl_position_m, 0.0, ebd_curve(svl_position_m, 0.0, 0.0), times0, **common
        )
        svl_target.gui = gui_curve(svl_position_m, 0.0)
        sbd = BrakingCurve.build(
            sb_limits, pos_breaks, expected_table, eoa_position_m, 0.0, v_high, 0.0, "SBD"
        )
        eoa_target = _Target("eoa", eoa_position_m, 0.0, sbd, times0, **{**common, "offset_m": 0.0})
        eoa_target.gui = gui_curve(eoa_position_m, 0.0)
        targets += [svl_target, eoa_target]
        # d_tripEOA: at least the confidence interval (d_maxsafefront - d_minsafefront) beyond the EoA
        d_trip = eoa_position_m + max(eoa_trip_margin_m, 2 * confidence)
        # the train trips when its min safe front end passes the EoA (3.13.10.2.6 a)
        trip = eoa_position_m + confidence
        # EBD targets for the release speed: the SvL and, when calculated, those between the trip
        # location and the SvL (3.13.9.4.6, 3.13.9.4.8)
        release_targets = [svl_target]
        if release_speed == "calculated":
            release_targets += [
                t for t in targets if t.kind == "mrsp" and d_trip < t.position_m <= svl_position_m
            ]
            release_v = min(
                _calculated_release_speed(t, train, n, d_trip, v_high, v_delta0) for t in release_targets
            )
        elif release_speed == "national":
            release_v = n.v_nvrel_mps
        else:
            release_v = float(release_speed)
        if release_v > 0:
            release_start = _release_start(eoa_target, release_targets, release_v, v_delta0)
            # 3.13.9.4.9: not above the MRSP between the start of release speed monitoring and the trip
            lo, hi = min(release_start, d_trip), d_trip
            inside = (mrsp_fn.breaks > lo) & (mrsp_fn.breaks < hi)
            speeds = np.concatenate([mrsp_fn(np.asarray([lo, hi])), mrsp_fn.values[1:][inside]])
            v_cap = float(np.min(speeds))
            if release_v > v_cap:
                release_v = v_cap
                release_start = _release_start(eoa_target, release_targets, release_v, v_delta0)
    else:
        svl_position_m = eoa_position_m

    t = times0 if target_speed_mps == 0 else times_for(target_speed_mps)
    if confidence > 0:  # V_MRSP: the lowest MRSP speed between the min and max safe front ends (3.13.7.2)
        mrsp_fn = _window_min(mrsp_fn, confidence, confidence)
    return SupervisionCurves(
        eoa_position_m=float(eoa_position_m),
        svl_position_m=float(svl_position_m),
        target_speed_mps=float(target_speed_mps),
        release_speed_mps=float(release_v),
        release_start_m=release_start,
        trip_position_m=trip,
        times={
            "t_be": t.t_be,
            "t_bs": t.t_bs,
            "t_bs1": t.t_bs1,
            "t_bs2": t.t_bs2,
            "t_traction": t.t_traction,
            "t_berem": t.t_berem,
            "t_indication": t.t_indication,
        },
        _targets=tuple(targets),
        _mrsp=mrsp_fn,
        _national=n,
        _v_high=v_high,
    )


def _a_ebmax_mps2(a_brake_emergency: StepFunction, v_max_mps: float) -> float:
    """A_ebmax: the maximum of A_brake_emergency between 0 and the train's maximum speed (3.13.6.2.1.8.2)."""
    lows = np.concatenate([[0.0], np.asarray(a_brake_emergency.upper_limits, float)])
    return float(np.max(np.asarray(a_brake_emergency.values)[lows < v_max_mps]))


def _limits_of(*fns: StepFunction) -> NDArray[np.float64]:
    return np.unique(np.concatenate([np.asarray(f.upper_limits, float) for f in fns] + [np.zeros(0)]))


def _calculated_release_speed(
    target: _Target,
    train: EtcsTrainData,
    national: EtcsNationalValues,
    d_trip_m: float,
    v_high: float,
    v_delta0: Callable[[ArrayLike], NDArray[np.float64]],
) -> float:
    """Release speed calculated on-board for one EBD-based target (3.13.9.4.8.2), level 2 (alpha = 0).

    The V_release solving V_release = V_EBD(d_tripEOA + D_bec) - V_delta0rsob with
    D_bec = (V_release + V_delta0rsob) (T_traction + T_berem), T_traction as if the traction cut-off
    were not implemented, and d_tripEOA + D_bec <= d_EBD(V_target); V_target if no higher speed
    fulfils it. Solved exactly (bisection) rather than to the 1 km/h tolerance the clause allows.
    """
    t_tr = t_traction_s(train.t_traction_cut_off_s, national.t_warning_s, 0.0, cut_off_implemented=False)
    t_rem = t_berem_s(target.times.t_be, t_tr)
    foot = float(target.curve.position_m(target.v_target_mps))

    def excess(v: float) -> float:
        dv0 = float(v_delta0(v))
        d = d_trip_m + (v + dv0) * (t_tr + t_rem)
        if d > foot:
            return -1.0
        return float(target.curve.speed_mps(d)) - dv0 - v

    lo, hi = target.v_target_mps, v_high
    if excess(lo) <= 0:
        return lo
    if excess(hi) > 0:
        return hi
    for _ in range(BISECTION_STEPS):
        mid = (lo + hi) / 2
        if excess(mid) > 0:
            lo = mid
        else:
            hi = mid
    return lo


def _release_start(
    eoa: _Target,
    ebd_targets: Sequence[_Target],
    v_release: float,
    v_delta0: Callable[[ArrayLike], NDArray[np.float64]],
) -> float:
    """Start location of release speed monitoring (3.13.9.4.6-7): the most restrictive of SBI1(V_release)
    of the EoA and SBI2(V_release) of the SvL (and of the other EBD targets between the EoA trip location
    and the SvL), with A_est = 0 and V_delta0rs = f41(V_release)."""
    dv0 = float(v_delta0(v_release))
    start = float(eoa.curve.position_m(v_release)) - v_release * eoa.times.t_bs1
    for target in ebd_targets:
        t = target.times
        v_bec = max(v_release + dv0, target.v_target_mps)
        d_ebi = float(target.curve.position_m(v_bec)) - (v_release + dv0) * (t.t_berem + t.t_traction)
        start = min(start, d_ebi - v_release * t.t_bs2 - target.offset_m)
    return start


def moving_block_ceiling(
    train: EtcsTrainData,
    national: EtcsNationalValues,
    gradient_profile: GradientProfile,
    rear_of_train_ahead_m: float,
    safety_margin_m: float,
    mrsp: Any = None,
    *,
    estimated_acceleration_mps2: float = 0.0,
) -> SupervisionCurves:
    """Supervision toward the rear of the train ahead for moving block (ETCS level 3, CBTC).

    The end of authority and the supervised location are both at the rear of the train ahead minus
    the safety margin; no release speed. ``permitted(s)`` is the speed a following train may run at
    with its front end at ``s``; ``indication_point_m(v)`` where it must start braking.
    """
    for name, value in (
        ("rear_of_train_ahead_m", rear_of_train_ahead_m),
        ("safety_margin_m", safety_margin_m),
    ):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            raise _bad(f"{name} must be a finite number", name, value, "a finite number")
    if safety_margin_m < 0:
        raise _bad("the safety margin must not be negative", "safety_margin_m", safety_margin_m, ">= 0 m")
    limit = float(rear_of_train_ahead_m) - float(safety_margin_m)
    return supervision_curves(
        train,
        national,
        gradient_profile,
        eoa_position_m=limit,
        svl_position_m=limit,
        mrsp=mrsp,
        release_speed=0.0,
        estimated_acceleration_mps2=estimated_acceleration_mps2,
    )
