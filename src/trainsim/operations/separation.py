"""Approach distances of the train-separation systems that depend on the train's braking.

* ETCS Level 2 (fixed virtual blocks): a following train must be given a movement authority (MA)
  reaching beyond a block marker before its head reaches the **indication point** of an MA ending at
  that marker (ERA SUBSET-026-3 3.13.9.3.6: where the driver is told to start braking to stay below the
  permitted speed). The approach distance is ``EoA - indication point`` at the train's speed, computed
  with ``trainsim.operations.etcs.supervision_curves`` on level track (EoA at the marker, supervised
  location at the end of the overlap).
* Moving block: the service braking distance (``blocking.braking_distance_table``) plus the safety
  margin (added by ``blocking.approach_start_m``).

An ETCS train runs under its movement authority: ``ma_indication_steps`` gives the indication
supervision limit toward an EoA (the same curves, level track) as a staircase of extra speed limits
for the single-train core that never exceeds it, so that the driver brakes to the indication curve
and the train stays below the permitted speed (SUBSET-026-3 3.13.9.3.5, 3.13.9.3.6).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from trainsim.errors import InputError
from trainsim.model import SpeedLimit, Train
from trainsim.operations.ceiling import staircase
from trainsim.operations.etcs import EtcsNationalValues, EtcsTrainData, SupervisionCurves, supervision_curves

#: Step length of an ETCS ceiling handed to the core [m], and the speed step at which steps are also
#: cut [m/s] (the steep end of a braking curve gets shorter steps). Each step takes the curve's lowest
#: value on it, so the run stays below the curve by at most the curve's fall over one step.
ETCS_CEILING_STEP_M = 20.0
ETCS_CEILING_DV_MPS = 1.0


@dataclass(frozen=True)
class EtcsBraking:
    """The ETCS braking data of the trains (SUBSET-026-3 3.13.2.2), the same for every train of an
    operation; length and maximum speed come from each train.

    Attributes:
        a_brake_emergency_mps2: emergency brake deceleration A_brake_emergency [m/s^2].
        a_brake_service_mps2: full service brake deceleration A_brake_service [m/s^2].
        t_brake_emergency_s: emergency brake build-up time T_brake_emergency [s].
        t_brake_service_s: service brake build-up time T_brake_service [s].
        t_traction_cut_off_s: traction cut-off time T_traction_cut_off [s].
        national: national values (SUBSET-026-3 3.13.2.3 / chapter 7 defaults unless given).
    """

    a_brake_emergency_mps2: float
    a_brake_service_mps2: float
    t_brake_emergency_s: float
    t_brake_service_s: float
    t_traction_cut_off_s: float
    national: EtcsNationalValues = field(default_factory=EtcsNationalValues)

    def train_data(self, train: Train) -> EtcsTrainData:
        """The ETCS train data of ``train``."""
        return EtcsTrainData(
            a_brake_emergency=self.a_brake_emergency_mps2,
            a_brake_service=self.a_brake_service_mps2,
            t_brake_emergency_s=self.t_brake_emergency_s,
            t_brake_service_s=self.t_brake_service_s,
            t_traction_cut_off_s=self.t_traction_cut_off_s,
            length_m=train.length_m,
            max_speed_mps=train.max_speed_mps,
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


def ma_curves(train: Train, etcs: EtcsBraking | None, eoa_m: float, overlap_m: float) -> SupervisionCurves:
    """The supervision curves of ``train`` for a movement authority ending at ``eoa_m`` with its
    supervised location ``overlap_m`` beyond (running coordinate) [m], on level track as the approach
    distance (``etcs_approach_distance``), the train's maximum speed as the MRSP."""
    return supervision_curves(
        _require(etcs).train_data(train),
        etcs.national,
        None,
        float(eoa_m),
        svl_position_m=eoa_m + max(overlap_m, 0.0),
    )


def ma_indication_steps(
    train: Train, etcs: EtcsBraking | None, overlap_m: float
) -> Callable[[float, float, float], tuple[SpeedLimit, ...]]:
    """``steps(eoa_m, start_m, stop_m)``: the indication supervision limit of an MA ending at
    ``eoa_m`` (``ma_curves``) over head positions ``[start_m, stop_m)`` as extra speed limits
    (``ceiling.staircase``, each step the curve's lowest value on it): only where the curve is below
    the train's maximum speed, ending where it falls below what the core takes. Cached by the three
    positions (identical trains and stops share them)."""
    _require(etcs)
    v_max = float(train.max_speed_mps)
    curves: dict[float, SupervisionCurves] = {}
    found: dict[tuple[float, float, float], tuple[SpeedLimit, ...]] = {}

    def steps(eoa_m: float, start_m: float, stop_m: float) -> tuple[SpeedLimit, ...]:
        key = (round(eoa_m, 6), round(start_m, 6), round(stop_m, 6))
        if key in found:
            return found[key]
        c = curves.get(key[0])
        if c is None:
            c = curves[key[0]] = ma_curves(train, etcs, eoa_m, overlap_m)
        # the curve reaches the top speed here: no step before it is lower than the top speed
        first = float(c.limit_position_m("indication", v_max))
        a = max(start_m, first - ETCS_CEILING_STEP_M) if np.isfinite(first) else start_m
        out: tuple[SpeedLimit, ...] = ()
        if stop_m > a + 1e-6:
            n = max(1, int(np.ceil((stop_m - a) / ETCS_CEILING_STEP_M)))
            out = staircase(lambda x: c.indication(x), a, stop_m, n, "min", dv_mps=ETCS_CEILING_DV_MPS)
            out = tuple(x for x in out if x.limit_mps < v_max - 1e-9)
        found[key] = out
        return out

    return steps


def etcs_approach_distance(
    train: Train, etcs: EtcsBraking | None, overlap_m: float
) -> Callable[[float], float]:
    """Distance from the indication point to the end of authority at speed ``v`` [m] (0 below the
    release speed, where no braking is asked for), tabulated over the train's speed range on level
    track, for an MA whose supervised location is ``overlap_m`` beyond its end."""
    curves = ma_curves(train, etcs, 0.0, overlap_m)
    v = np.linspace(0.0, train.max_speed_mps * 1.02, 120)
    point = np.asarray(curves.indication_point_m(v), dtype=float)
    distance = np.where(np.isfinite(point), np.maximum(-point, 0.0), 0.0)

    def approach(speed_mps: float) -> float:
        return float(np.interp(speed_mps, v, distance))

    return approach
