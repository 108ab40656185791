"""Timetable synchronisation: shift departures within windows to minimise substation energy.

Braking trains regenerate; on a line with diode rectifiers their energy is only worth something
when another train accelerates nearby at the same time. :func:`synchronise` shifts every departure
of a train service by one offset within a window (coordinate search: each service in turn over a
grid of offsets, a few rounds) and keeps the offsets with the least energy delivered by the
substations, every candidate timetable solved on the network with the trains' real runs. Feedback of
voltage-limited traction is left out of the search and applied to the best timetable.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trainsim.errors import InputError
from trainsim.power.network import Network
from trainsim.power.simulation import PowerResult
from trainsim.power.study import FeedbackSettings, TrainService, run_study

__all__ = ["SyncResult", "synchronise"]


@dataclass(frozen=True)
class SyncResult:
    """Outcome of a synchronisation.

    Attributes:
        offsets_s: the chosen shift of each service's departures [s] (by service id).
        baseline_kwh: substation energy of the timetable as given [kWh].
        best_kwh: substation energy of the synchronised timetable [kWh].
        evaluations: network solutions computed.
        result: the synchronised timetable's power result (with feedback).
    """

    offsets_s: dict[str, float]
    baseline_kwh: float
    best_kwh: float
    evaluations: int
    result: PowerResult

    @property
    def saving(self) -> float:
        """Relative saving against the timetable as given [-]."""
        return 1.0 - self.best_kwh / self.baseline_kwh if self.baseline_kwh else 0.0


def _shifted(services: list[TrainService], offsets: dict[str, float]) -> list[TrainService]:
    return [
        dataclasses.replace(s, departures_s=tuple(d + offsets.get(s.id, 0.0) for d in s.departures_s))
        for s in services
    ]


def synchronise(
    network: Network,
    services: list[TrainService],
    windows_s: dict[str, tuple[float, float]],
    *,
    grid_s: float = 10.0,
    rounds: int = 2,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
) -> SyncResult:
    """Shift the departures of the services named in ``windows_s`` by an offset within
    [lo, hi] [s] (grid ``grid_s``) to minimise the substations' energy over [start_s, end_s] (give
    the window explicitly so that every candidate is judged over the same time)."""
    ids = {s.id for s in services}
    for name, (lo, hi) in windows_s.items():
        if name not in ids:
            raise InputError(
                "unknown train service", field="windows_s", value=name, allowed=", ".join(sorted(ids))
            )
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise InputError(
                "invalid window", field=f"windows_s.{name}", value=(lo, hi), allowed="lo <= hi [s]"
            )
    if not grid_s > 0:
        raise InputError("invalid grid", field="grid_s", value=grid_s, allowed="> 0 s")
    if rounds < 1:
        raise InputError("invalid number of rounds", field="rounds", value=rounds, allowed=">= 1")
    off = FeedbackSettings(enabled=False, max_iterations=1)
    cache: dict[tuple, float] = {}

    def energy(offsets: dict[str, float]) -> float:
        key = tuple(sorted(offsets.items()))
        if key not in cache:
            res = run_study(
                network, _shifted(services, offsets), dt_s=dt_s, start_s=start_s, end_s=end_s, feedback=off
            )
            cache[key] = res.summary()["substations_energy_kwh"]
        return cache[key]

    offsets = {name: 0.0 for name in windows_s}
    baseline = energy(offsets)
    best = baseline
    for _ in range(rounds):
        improved = False
        for name, (lo, hi) in windows_s.items():
            for x in np.arange(lo, hi + 1e-9, grid_s):
                trial = {**offsets, name: float(x)}
                e = energy(trial)
                if e < best - 1e-9:
                    best, offsets, improved = e, trial, True
        if not improved:
            break
    result = run_study(network, _shifted(services, offsets), dt_s=dt_s, start_s=start_s, end_s=end_s)
    return SyncResult(offsets, baseline, best, len(cache), result)
