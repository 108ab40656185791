"""On-board energy storage (battery or supercapacitor on the train) and its strategy.

Strategy, per time step of the network simulation:

1. traction assist: when the train asks more than ``assist_above_w`` at the pantograph, the
   storage gives the excess, within its converter power and what its state of charge allows
   above ``min_soc``; the line is asked only for the rest (this lowers the peaks the
   substations see and the voltage drops);
2. regeneration the line cannot take: after the network is solved, the regenerated power the
   line curtailed (EN 50163 / EN 50388, or none taken in a neutral section) is charged, within
   the converter power and the room below ``max_soc``; what is left is burnt in the on-board
   resistors as before.

The storage's books, with eta_c and eta_d its charge and discharge efficiencies (converter and
cells), P_c and P_d the powers at its terminals (the train's DC link):

    E(t + dt) = E(t) + (eta_c P_c - P_d / eta_d) dt,    E_min <= E <= E_max,

so that over a run  sum(eta_c P_c dt) - sum(P_d / eta_d dt) = E_end - E_start  exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trainsim.errors import InputError, Problem

__all__ = ["OnboardStorage", "assist_power_w", "charge_power_w"]


@dataclass(frozen=True)
class OnboardStorage:
    """A train's on-board storage.

    Attributes:
        capacity_j: energy content at state of charge 1 [J].
        max_power_w: converter power, charging or discharging [W].
        charge_efficiency: share of the power at its terminals that is stored [-].
        discharge_efficiency: share of the energy taken from the cells that reaches the terminals [-].
        min_soc, max_soc: state-of-charge window it is kept in [-].
        initial_soc: state of charge when the train enters the network [-].
        assist_above_w: it assists traction above this power at the pantograph [W].
    """

    capacity_j: float
    max_power_w: float
    charge_efficiency: float
    discharge_efficiency: float
    min_soc: float = 0.2
    max_soc: float = 0.9
    initial_soc: float = 0.5
    assist_above_w: float = 0.0

    def problems(self, where: str = "onboard_storage") -> list[Problem]:
        """Everything wrong with the storage's data (empty if fine)."""
        out = []
        checks = [
            ("capacity_kwh", self.capacity_j / 3.6e6, self.capacity_j > 0, "> 0"),
            ("max_power_kw", self.max_power_w / 1e3, self.max_power_w > 0, "> 0"),
            ("charge_efficiency", self.charge_efficiency, 0 < self.charge_efficiency <= 1, "0 < x <= 1"),
            ("discharge_efficiency", self.discharge_efficiency, 0 < self.discharge_efficiency <= 1, "0 < x <= 1"),
            ("min_soc", self.min_soc, 0 <= self.min_soc < self.max_soc, f"0 <= x < max_soc = {self.max_soc}"),
            ("max_soc", self.max_soc, self.max_soc <= 1, "<= 1"),
            ("initial_soc", self.initial_soc, self.min_soc <= self.initial_soc <= self.max_soc,
             f"{self.min_soc} .. {self.max_soc} (min_soc .. max_soc)"),
            ("assist_above_kw", self.assist_above_w / 1e3, self.assist_above_w >= 0, ">= 0"),
        ]  # fmt: skip
        for name, value, ok, allowed in checks:
            if not (np.isfinite(value) and ok):
                out.append(Problem("invalid on-board storage value", field=f"{where}.{name}", value=value,
                                   allowed=allowed))  # fmt: skip
        return out

    def check(self, where: str = "onboard_storage") -> None:
        """Raise an InputError listing every problem."""
        problems = self.problems(where)
        if problems:
            raise InputError.from_problems(problems)


def assist_power_w(
    traction_w: np.ndarray,
    energy_j: np.ndarray,
    threshold_w: np.ndarray,
    max_power_w: np.ndarray,
    min_energy_j: np.ndarray,
    discharge_efficiency: np.ndarray,
    dt_s: float,
) -> np.ndarray:
    """Power the storages give at their terminals during a step [W]: the traction above the
    threshold, within the converter power and the energy above the minimum state of charge
    (eta_d (E - E_min) / dt)."""
    room = np.maximum(energy_j - min_energy_j, 0.0) * discharge_efficiency / dt_s
    return np.clip(np.minimum(np.minimum(traction_w - threshold_w, max_power_w), room), 0.0, None)


def charge_power_w(
    curtailed_w: np.ndarray,
    energy_j: np.ndarray,
    max_power_w: np.ndarray,
    max_energy_j: np.ndarray,
    charge_efficiency: np.ndarray,
    dt_s: float,
) -> np.ndarray:
    """Power the storages take at their terminals during a step [W]: the regenerated power the
    line did not take, within the converter power and the room below the maximum state of charge
    ((E_max - E) / (eta_c dt))."""
    room = np.maximum(max_energy_j - energy_j, 0.0) / (charge_efficiency * dt_s)
    return np.clip(np.minimum(np.minimum(curtailed_w, max_power_w), room), 0.0, None)
