"""Approach distances of the train-separation systems that depend on the train's braking.

* ETCS Level 2 (fixed virtual blocks): a following train must be given a movement authority (MA)
  reaching beyond a block marker before its head reaches the **indication point** of an MA ending at
  that marker (ERA SUBSET-026-3 3.13.9.3.6: where the driver is told to start braking to stay below the
  permitted speed). The approach distance is ``EoA - indication point`` at the train's speed, computed
  with ``trainsim.operations.etcs.supervision_curves`` (EoA at the marker, supervised location at the
  end of the overlap) on the line's gradients as the train runs them, by speed and marker
  (``EtcsApproach.at_eoa``); on level track where no line is given.
* Moving block: the service braking distance (``blocking.braking_distance_table``) plus the safety
  margin (added by ``blocking.approach_start_m``).

An ETCS train runs under its movement authority: ``ma_indication_steps`` gives the indication
supervision limit toward an EoA as a staircase of extra speed limits for the single-train core that
never exceeds it, so that the driver brakes to the indication curve and the train stays below the
permitted speed (SUBSET-026-3 3.13.9.3.5, 3.13.9.3.6). Given the train's directed route, the curves use
its gradients (compensated for the train length, 3.13.4) and its most restrictive speed profile (the
line's limits, held until the rear has cleared them, capped by the train's maximum speed, 3.13.7);
without it, level track and the train's maximum speed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from trainsim.errors import InputError
from trainsim.model import Route, SpeedLimit, Train
from trainsim.operations.ceiling import staircase
from trainsim.operations.etcs import (
    EtcsNationalValues,
    EtcsTrainData,
    StepFunction,
    SupervisionCurves,
    supervision_curves,
)

#: Step length of an ETCS ceiling handed to the core [m], and the speed step at which steps are also
#: cut [m/s] (the steep end of a braking curve gets shorter steps). Each step takes the curve's lowest
#: value on it, so the run stays below the curve by at most the curve's fall over one step.
ETCS_CEILING_STEP_M = 20.0
ETCS_CEILING_DV_MPS = 1.0
#: A step that is not below the line's own limit by this much adds nothing the core does not already
#: do [m/s].
ETCS_STEP_MARGIN_MPS = 1e-9
#: The braking-model fields of ``EtcsTrainData`` that ``EtcsBraking`` gives itself (the rest, length
#: and maximum speed come from the train or from ``train_fields``).
_OWN_FIELDS = ("a_brake_emergency", "a_brake_service", "t_brake_emergency_s", "t_brake_service_s")
#: Fields of ``EtcsTrainData`` that come from the train, never from the braking data.
_FROM_TRAIN = ("length_m", "max_speed_mps")

ReleaseSpeed = Literal["calculated", "national"] | float


@dataclass(frozen=True)
class EtcsBraking:
    """The ETCS data of an operation (SUBSET-026-3 3.13.2): one train type's braking data, the national
    and fixed values, the release speed, and other braking data for some trains.

    Attributes:
        a_brake_emergency_mps2: emergency brake deceleration A_brake_emergency(V) [m/s^2], a number or a
            ``StepFunction`` of speed; None with ``brake_percentage``.
        a_brake_service_mps2: full service brake deceleration A_brake_service(V) [m/s^2].
        t_brake_emergency_s: emergency brake build-up time T_brake_emergency [s].
        t_brake_service_s: service brake build-up time T_brake_service [s].
        t_traction_cut_off_s: traction cut-off time T_traction_cut_off [s].
        national: national and fixed values (SUBSET-026-3 A.3.1 / A.3.2 defaults unless given).
        train_fields: further ``EtcsTrainData`` fields as (name, value) pairs: ``kdry_rst``,
            ``kwet_rst``, ``kn_plus``, ``brake_position``, ... (not the length and maximum speed, which
            are each train's).
        brake_percentage: a "lambda" train: its braking models from the conversion model (3.13.3,
            ``EtcsTrainData.from_brake_percentage``) instead of the decelerations and build-up times.
        release_speed: ``"calculated"`` (3.13.9.4.8), ``"national"`` (V_NVREL) or a value given by
            trackside [m/s] (3.13.9.4.3), for every MA.
        per_train: other braking data for some trains, matched by identity (``train is t``); their
            ``national``, ``release_speed`` and ``per_train`` are not used (the line's are).
    """

    a_brake_emergency_mps2: StepFunction | float | None = None
    a_brake_service_mps2: StepFunction | float | None = None
    t_brake_emergency_s: float | None = None
    t_brake_service_s: float | None = None
    t_traction_cut_off_s: float | None = None
    national: EtcsNationalValues = field(default_factory=EtcsNationalValues)
    train_fields: tuple[tuple[str, Any], ...] = ()
    brake_percentage: float | None = None
    release_speed: ReleaseSpeed = "calculated"
    per_train: tuple[tuple[Train, EtcsBraking], ...] = ()

    def for_train(self, train: Train) -> EtcsBraking:
        """The braking data of ``train``: its own entry of ``per_train``, else these."""
        return next((b for t, b in self.per_train if t is train), self)

    def train_data(self, train: Train) -> EtcsTrainData:
        """The ETCS train data of ``train`` (its length and maximum speed, the braking data of
        ``for_train(train)``). InputError if the braking data are incomplete or out of range."""
        b = self.for_train(train)
        extra = dict(b.train_fields)
        bad = [k for k in extra if k in _FROM_TRAIN or k in _OWN_FIELDS or k == "t_traction_cut_off_s"]
        if bad:
            raise InputError(
                "these ETCS train data come from the train or from EtcsBraking's own fields",
                field="train_fields",
                value=bad,
                allowed="other EtcsTrainData fields",
            )
        if b.t_traction_cut_off_s is None:
            raise _missing(train, ["t_traction_cut_off_s"])
        if b.brake_percentage is not None:
            given = [
                n
                for n in ("a_brake_emergency_mps2", "a_brake_service_mps2", "t_brake_emergency_s",
                          "t_brake_service_s")
                if getattr(b, n) is not None
            ]  # fmt: skip
            if given:
                raise InputError(
                    "a brake percentage (conversion model) replaces the braking models and build-up times",
                    field="brake_percentage",
                    value=given,
                    allowed="either brake_percentage or a_brake_emergency_mps2, a_brake_service_mps2, "
                    "t_brake_emergency_s, t_brake_service_s",
                )
            position = extra.pop("brake_position", "passenger_p")
            return EtcsTrainData.from_brake_percentage(
                b.brake_percentage, position, train.length_m, train.max_speed_mps, b.t_traction_cut_off_s,
                **extra,
            )  # fmt: skip
        own = {
            "a_brake_emergency": b.a_brake_emergency_mps2,
            "a_brake_service": b.a_brake_service_mps2,
            "t_brake_emergency_s": b.t_brake_emergency_s,
            "t_brake_service_s": b.t_brake_service_s,
        }
        missing = [
            n if n.endswith("_s") else f"{n}_mps2" for n, v in own.items() if v is None
        ]  # fmt: skip
        if missing:
            raise _missing(train, missing)
        return EtcsTrainData(
            **own,
            t_traction_cut_off_s=b.t_traction_cut_off_s,
            length_m=train.length_m,
            max_speed_mps=train.max_speed_mps,
            **extra,
        )


def _missing(train: Train, names: list[str]) -> InputError:
    return InputError(
        f"the ETCS braking data of train '{train.name}' are incomplete",
        field="line.signalling.etcs",
        value=names,
        allowed="a_brake_emergency_mps2, a_brake_service_mps2, t_brake_emergency_s, t_brake_service_s, "
        "t_traction_cut_off_s (or brake_percentage and t_traction_cut_off_s)",
    )


def _require(etcs: EtcsBraking | None) -> EtcsBraking:
    if etcs is None:
        raise InputError(
            "ETCS Level 2 needs the trains' ETCS braking data",
            field="line.signalling.etcs",
            allowed="a_brake_emergency_mps2, a_brake_service_mps2, t_brake_emergency_s, t_brake_service_s, "
            "t_traction_cut_off_s",
        )
    return etcs


def mrsp_profile(
    directed: Route, train: Train, start_m: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The most restrictive speed profile of ``train`` on ``directed`` over its front-end position
    (SUBSET-026-3 3.13.7): ``(positions_m, speeds_mps)``, speed k from position k on. Each line limit
    binds front-end positions from its start to its end plus the train length (an increase is taken
    only once the rear has cleared the lower limit, as the single-train core does), the whole capped
    by the train's maximum speed; limits that end before ``start_m`` are left out."""
    length, v_max = float(train.length_m), float(train.max_speed_mps)
    spans = [
        (float(x.start_m), float(x.end_m) + length, min(float(x.limit_mps), v_max))
        for x in directed.speed_limits
        if start_m is None or x.end_m + length > start_m
    ]
    cuts = sorted({p for a, b, _v in spans for p in (a, b)})
    if not cuts:
        return np.array([0.0]), np.array([v_max])
    xs = np.asarray(cuts)
    mid = np.append(0.5 * (xs[:-1] + xs[1:]), xs[-1] + 1.0)
    speeds = np.full(len(xs), v_max)
    for a, b, v in spans:
        inside = (mid >= a) & (mid < b)
        speeds[inside] = np.minimum(speeds[inside], v)
    keep = np.concatenate(([True], np.diff(speeds) != 0))
    return xs[keep], speeds[keep]


def ma_curves(
    train: Train,
    etcs: EtcsBraking | None,
    eoa_m: float,
    overlap_m: float,
    directed: Route | None = None,
    start_m: float | None = None,
) -> SupervisionCurves:
    """The supervision curves of ``train`` for a movement authority ending at ``eoa_m`` with its
    supervised location (the danger point at the end of the overlap) ``overlap_m`` beyond (running
    coordinate) [m], with the operation's release speed. ``directed``: the line as the train runs it
    (gradients and speed limits in running positions); None: level track and the train's maximum speed
    as the MRSP (the approach distance, ``etcs_approach_distance``). ``start_m``: speed limits ending
    before it are left out of the MRSP (fewer targets to build)."""
    braking = _require(etcs)
    mrsp = None if directed is None else mrsp_profile(directed, train, start_m)
    return supervision_curves(
        braking.train_data(train),
        braking.national,
        directed,
        float(eoa_m),
        svl_position_m=eoa_m + max(overlap_m, 0.0),
        mrsp=mrsp,
        release_speed=braking.release_speed,
    )


def ma_indication_steps(
    train: Train, etcs: EtcsBraking | None, overlap_m: float, directed: Route | None = None
) -> Callable[[float, float, float], tuple[SpeedLimit, ...]]:
    """``steps(eoa_m, start_m, stop_m)``: the indication supervision limit of an MA ending at
    ``eoa_m`` (``ma_curves`` on ``directed``) over head positions ``[start_m, stop_m)`` as extra speed
    limits (``ceiling.staircase``, each step the curve's lowest value on it): only where the curve is
    below the train's most restrictive speed profile (the line limits the core applies itself), ending
    where it falls below what the core takes. Cached by the three positions (identical trains and stops
    share them)."""
    _require(etcs)
    v_max = float(train.max_speed_mps)
    curves: dict[tuple[float, float], SupervisionCurves] = {}
    found: dict[tuple[float, float, float], tuple[SpeedLimit, ...]] = {}
    if directed is None:
        mrsp_x, mrsp_v = np.array([0.0]), np.array([v_max])
    else:
        mrsp_x, mrsp_v = mrsp_profile(directed, train)

    def mrsp_at(x: np.ndarray) -> np.ndarray:
        k = np.searchsorted(mrsp_x, x, side="right") - 1
        return mrsp_v[np.clip(k, 0, len(mrsp_v) - 1)]

    def steps(eoa_m: float, start_m: float, stop_m: float) -> tuple[SpeedLimit, ...]:
        key = (round(eoa_m, 6), round(start_m, 6), round(stop_m, 6))
        if key in found:
            return found[key]
        c = curves.get(key[:2])
        if c is None:
            c = curves[key[:2]] = ma_curves(train, etcs, eoa_m, overlap_m, directed, start_m)
        out: tuple[SpeedLimit, ...] = ()
        if stop_m > start_m + 1e-6:
            # the first place where the curve is below the line's own limit: no step before it adds
            # anything
            if directed is None:  # the curve reaches the top speed here (None: nowhere)
                first = float(c.limit_position_m("indication", v_max))
                first = first if np.isfinite(first) else start_m
            else:  # sampled: the MRSP varies
                dense = np.linspace(start_m, stop_m, max(2, int(np.ceil((stop_m - start_m) / 5.0)) + 1))
                below = np.asarray(c.indication(dense)) < mrsp_at(dense) - ETCS_STEP_MARGIN_MPS
                first = float(dense[np.argmax(below)]) if below.any() else np.inf
            a = max(start_m, first - ETCS_CEILING_STEP_M)
            if stop_m > a + 1e-6:
                n = max(1, int(np.ceil((stop_m - a) / ETCS_CEILING_STEP_M)))
                raw = staircase(lambda x: c.indication(x), a, stop_m, n, "min", dv_mps=ETCS_CEILING_DV_MPS)
                out = tuple(
                    x
                    for x in raw
                    if x.limit_mps
                    < float(np.min(mrsp_at(np.linspace(x.start_m, x.end_m, 9)))) - ETCS_STEP_MARGIN_MPS
                )
        found[key] = out
        return out

    return steps


class EtcsApproach:
    """Distance from the indication point to the end of authority at speed ``v`` [m] (0 below the
    release speed, where no braking is asked for), tabulated over the train's speed range, for an MA
    whose supervised location is ``overlap_m`` beyond its end.

    ``approach(v)``: on level track (the EoA anywhere). ``approach.at_eoa(eoa_m)``: the same for an EoA
    at running position ``eoa_m`` of ``directed`` (the line as the train runs it), on its gradients
    compensated for the train length (3.13.4); level track without ``directed``. The MA's own targets
    only (EoA and SvL): a speed decrease of the line asks the driver to brake but not for a route, and
    the line's speed limits enter through the speed the dispatcher asks it at (the train's run obeys
    them). Tabulated once per EoA (block markers: a few dozen per line)."""

    def __init__(
        self, train: Train, etcs: EtcsBraking | None, overlap_m: float, directed: Route | None = None
    ) -> None:
        self._braking = _require(etcs)
        self._train = train
        self._overlap_m = float(overlap_m)
        self._directed = directed
        self._v = np.linspace(0.0, train.max_speed_mps * 1.02, 120)
        self._level = self._table(None, 0.0)
        self._tables: dict[float, np.ndarray] = {}

    def _table(self, directed: Route | None, eoa_m: float) -> np.ndarray:
        b = self._braking
        curves = supervision_curves(
            b.train_data(self._train),
            b.national,
            directed,
            float(eoa_m),
            svl_position_m=eoa_m + max(self._overlap_m, 0.0),
            release_speed=b.release_speed,
        )
        point = np.asarray(curves.indication_point_m(self._v), dtype=float)
        return np.where(np.isfinite(point), np.maximum(eoa_m - point, 0.0), 0.0)

    def __call__(self, speed_mps: float) -> float:
        return float(np.interp(speed_mps, self._v, self._level))

    def at_eoa(self, eoa_m: float) -> Callable[[float], float]:
        """The approach distance over speed [m] for an EoA at running position ``eoa_m`` [m]."""
        if self._directed is None:
            return self
        key = round(float(eoa_m), 3)
        table = self._tables.get(key)
        if table is None:
            table = self._tables[key] = self._table(self._directed, key)
        v = self._v
        return lambda speed_mps: float(np.interp(speed_mps, v, table))

    def max_m(self, eoa_m: float) -> float:
        """The longest approach distance for an EoA at ``eoa_m`` (at 1.02 times the train's maximum
        speed) [m]."""
        return self.at_eoa(eoa_m)(float(self._v[-1]))


def etcs_approach_distance(
    train: Train, etcs: EtcsBraking | None, overlap_m: float, directed: Route | None = None
) -> EtcsApproach:
    """The approach distance of ``train`` under ETCS Level 2 (``EtcsApproach``): by speed on level
    track, and by speed and EoA on ``directed``'s gradients when it is given."""
    return EtcsApproach(train, etcs, overlap_m, directed)
