"""Approach distances of the train-separation systems that depend on the train's braking.

* ETCS Level 2 (fixed virtual blocks): a following train must be given a movement authority (MA)
  reaching beyond a block marker before its head reaches the **indication point** of an MA ending at
  that marker (ERA SUBSET-026-3 3.13.9.3.6: where the driver is told to start braking to stay below the
  permitted speed). The approach distance is ``EoA - indication point`` at the train's speed, computed
  with ``trainsim.operations.etcs.supervision_curves`` on level track (EoA at the marker, supervised
  location at the end of the overlap).
* Moving block: the service braking distance (``blocking.braking_distance_table``) plus the safety
  margin (added by ``blocking.approach_start_m``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from trainsim.errors import InputError
from trainsim.model import Train
from trainsim.operations.etcs import EtcsNationalValues, EtcsTrainData, supervision_curves


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


def etcs_approach_distance(
    train: Train, etcs: EtcsBraking | None, overlap_m: float
) -> Callable[[float], float]:
    """Distance from the indication point to the end of authority at speed ``v`` [m] (0 below the
    release speed, where no braking is asked for), tabulated over the train's speed range on level
    track, for an MA whose supervised location is ``overlap_m`` beyond its end."""
    if etcs is None:
        raise InputError(
            "ETCS Level 2 needs the trains' ETCS braking data",
            field="line.signalling.etcs",
            allowed="a_brake_emergency_mps2, a_brake_service_mps2, t_brake_emergency_s, t_brake_service_s, "
            "t_traction_cut_off_s",
        )
    curves = supervision_curves(
        etcs.train_data(train), etcs.national, None, 0.0, svl_position_m=max(overlap_m, 0.0)
    )
    v = np.linspace(0.0, train.max_speed_mps * 1.02, 120)
    point = np.asarray(curves.indication_point_m(v), dtype=float)
    distance = np.where(np.isfinite(point), np.maximum(-point, 0.0), 0.0)

    def approach(speed_mps: float) -> float:
        return float(np.interp(speed_mps, v, distance))

    return approach
