"""Sampled disturbances for Monte Carlo studies of a timetable: entry delays, dwell extensions and
running-time extensions, each a distribution given as data, drawn from a seeded generator.

A running-time extension of a stretch between two scheduled stops makes the train drive it slower:
as the fastest run under the speed cap whose running time is the undisturbed one plus the extension
(``RunCache.capped``: a root-find on the cap to 1e-7 s), so that the trajectory, the blocking times
and the energy of the operated train are that one run's and it arrives exactly the extension later.
Where no capped run takes the time (longer than the run at a fifth of the top speed), the slowest one
is driven and the rest stood before leaving, with a warning and the stretch's status
(``TrainOutcome.disturbed``). For delay studies (``simulate(disturbed_energy=False)``, Monte Carlo)
the cheap alternative is the fastest run's path with time stretched by 1 + extension / running
time, labelled ``time-scaled`` (``TrainOutcome.trajectory_note``), its energy not computed.

Draws are taken in a fixed order (per train: entry, then per stop dwell, then per stretch running
time; two draws each), so a seed gives the same disturbances whatever the outcome.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from trainsim.errors import InputError, Problem
from trainsim.operations.simulate import TrainService

#: Distributions and their parameters [s, or - for sigma].
KINDS: dict[str, tuple[str, ...]] = {
    "fixed": ("value_s",),
    "exponential": ("mean_s",),
    "uniform": ("low_s", "high_s"),
    "normal": ("mean_s", "sd_s"),
    "lognormal": ("median_s", "sigma"),
}
#: The largest single disturbance accepted [s] (a day).
MAX_DISTURBANCE_S = 86_400.0


@dataclass(frozen=True)
class Distribution:
    """A non-negative time disturbance: with ``probability`` a draw of ``kind`` with ``params``
    (``KINDS``), else 0 [s]. Normal draws below 0 count as 0."""

    kind: str
    params: tuple[float, ...]
    probability: float = 1.0

    def draw(self, rng: np.random.Generator) -> float:
        """One disturbance [s] (always two draws from ``rng``: whether, and how much)."""
        hit = rng.random() < self.probability
        p = self.params
        if self.kind == "fixed":
            size = p[0] + 0.0 * rng.random()
        elif self.kind == "exponential":
            size = rng.exponential(p[0])
        elif self.kind == "uniform":
            size = rng.uniform(p[0], p[1])
        elif self.kind == "normal":
            size = rng.normal(p[0], p[1])
        else:
            size = p[0] * np.exp(p[1] * rng.standard_normal())
        return float(min(max(size, 0.0), MAX_DISTURBANCE_S)) if hit else 0.0


@dataclass(frozen=True)
class Disturbances:
    """Entry, dwell and running-time disturbances (any may be None) and the seed of the generator."""

    seed: int
    entry: Distribution | None = None
    dwell: Distribution | None = None
    running: Distribution | None = None

    def sample(self, services: list[TrainService], rng: np.random.Generator) -> list[TrainService]:
        """The services with sampled disturbances added: entry delay, extra dwell at every
        intermediate stop (``ScheduledStop.extra_dwell_s``: the planned run does not have it), and
        the running-time extension of every stretch between scheduled stops
        (``TrainService.running_extra_s``, driven as a slower run by the simulation)."""
        out = []
        for svc in services:
            extra_entry = self.entry.draw(rng) if self.entry else 0.0
            stops = list(svc.stops)
            dwell_extra = [self.dwell.draw(rng) if self.dwell else 0.0 for _ in stops]
            # one stretch after the origin and after every stop but the destination
            legs = [s for s in stops if s.station != svc.destination]
            running = [self.running.draw(rng) if self.running else 0.0 for _ in range(len(legs) + 1)]
            new_stops = tuple(
                s if s.station == svc.destination else replace(s, extra_dwell_s=s.extra_dwell_s + dx)
                for s, dx in zip(stops, dwell_extra, strict=True)
            )
            if svc.running_extra_s:
                running = [a + b for a, b in zip(svc.running_extra_s, running, strict=True)]
            out.append(
                replace(
                    svc,
                    entry_delay_s=svc.entry_delay_s + extra_entry,
                    stops=new_stops,
                    running_extra_s=tuple(running) if self.running else svc.running_extra_s,
                )
            )
        return out


def _distribution(data: Any, where: str, file: str | None, problems: list[Problem]) -> Distribution | None:
    if data is None:
        return None
    if not isinstance(data, Mapping):
        problems.append(Problem("a distribution is a mapping", file=file, field=where, value=data))
        return None
    kind = data.get("kind")
    if kind not in KINDS:
        problems.append(
            Problem(
                "unknown distribution", file=file, field=f"{where}.kind", value=kind, allowed=", ".join(KINDS)
            )
        )
        return None
    names = KINDS[kind]
    unknown = sorted(set(data) - {"kind", "probability", *names})
    if unknown:
        problems.append(
            Problem(
                "unknown field",
                file=file,
                field=f"{where}.{unknown[0]}",
                value=unknown,
                allowed=", ".join(names),
            )
        )
    values = []
    for name in names:
        v = data.get(name)
        ok = (
            isinstance(v, int | float)
            and not isinstance(v, bool)
            and np.isfinite(v)
            and 0 <= v <= MAX_DISTURBANCE_S
        )
        if not ok:
            problems.append(
                Problem(
                    "missing or invalid parameter",
                    file=file,
                    field=f"{where}.{name}",
                    value=v,
                    allowed=f"0 .. {MAX_DISTURBANCE_S:g}",
                )
            )
            return None
        values.append(float(v))
    if kind == "uniform" and values[1] < values[0]:
        problems.append(
            Problem("high_s must not be below low_s", file=file, field=f"{where}.high_s", value=values[1])
        )
    if kind == "lognormal" and values[1] > 5:
        problems.append(
            Problem("sigma too large", file=file, field=f"{where}.sigma", value=values[1], allowed="0 .. 5")
        )
    p = data.get("probability", 1.0)
    if not (isinstance(p, int | float) and not isinstance(p, bool) and 0 <= p <= 1):
        problems.append(
            Problem("invalid probability", file=file, field=f"{where}.probability", value=p, allowed="0 .. 1")
        )
        return None
    return Distribution(kind, tuple(values), float(p))


def disturbances_from_dict(data: Any, file: str | None = None, field: str = "disturbances") -> Disturbances:
    """A ``disturbances`` block: ``{seed: int, entry: {...}, dwell: {...}, running: {...}}`` where each
    distribution is ``{kind: exponential, mean_s: 60, probability: 0.2}`` (kinds and parameters:
    ``KINDS``). Every problem is reported at once (``InputError``)."""
    problems: list[Problem] = []
    if not isinstance(data, Mapping):
        raise InputError("the disturbances block is a mapping", file=file, field=field, value=data)
    unknown = sorted(set(data) - {"seed", "entry", "dwell", "running"})
    if unknown:
        problems.append(
            Problem(
                "unknown field",
                file=file,
                field=f"{field}.{unknown[0]}",
                value=unknown,
                allowed="seed, entry, dwell, running",
            )
        )
    seed = data.get("seed")
    if not (isinstance(seed, int) and not isinstance(seed, bool) and 0 <= seed < 2**63):
        problems.append(
            Problem("a non-negative integer seed is required", file=file, field=f"{field}.seed", value=seed)
        )
    parts = {
        k: _distribution(data.get(k), f"{field}.{k}", file, problems) for k in ("entry", "dwell", "running")
    }
    if problems:
        raise InputError.from_problems(problems)
    return Disturbances(int(seed), **parts)


__all__ = ["KINDS", "Distribution", "Disturbances", "disturbances_from_dict"]
