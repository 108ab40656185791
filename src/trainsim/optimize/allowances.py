"""Running-time allowances as planners write them, turned into a per-section timetable.

A planner adds to the fastest (technical) running time allowances on ranges of the line (UIC leaflet
451-1 and the practice of European infrastructure managers; OSRD's "standard" and "engineering"
allowances):

* ``percent``: a percentage of the fastest running time over the range (e.g. 5 %);
* ``min_per_100km``: minutes per 100 km of the range's length (e.g. 1.5 min/100 km);
* ``seconds``: a fixed time on the range (e.g. 30 s), such as a construction margin for works.

Each range's allowance is shared between the sections (between stops) it covers:

* ``time``: in proportion to each section's fastest running time inside the range (the same
  percentage everywhere: a uniform allowance);
* ``distance``: in proportion to the length of each section inside the range (the same minutes per
  kilometre everywhere);
* ``optimal``: with one price of time for the sections of the range (equal marginal energy per
  second, Albrecht et al. 2016; the split of ``trainsim.optimize.api``), for ranges made of whole
  sections.

Allowances on overlapping ranges add up (a construction margin comes on top of the standard
allowance). ``allowance_spread`` checks that the allowance stays within a band (2 percentage
points by default) between any two consecutive timing points of a run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.timetable import SectionSchedule, Timetable
from trainsim.model.train import Train

KINDS = ("percent", "min_per_100km", "seconds")
DISTRIBUTIONS = ("time", "distance", "optimal")


@dataclass(frozen=True)
class Allowance:
    """A running-time allowance on a range of the line.

    Attributes:
        kind: "percent" (of the fastest running time over the range), "min_per_100km" (of the range's
            length) or "seconds" (a fixed time, e.g. a construction margin).
        value: the amount in the kind's unit [%, min/100 km, s].
        start_m: start of the range [m]; None: the start of the line.
        end_m: end of the range [m]; None: the end of the line.
        distribution: how it is shared between the sections of the range: "time", "distance" or
            "optimal" (module doc).
        label: a name for messages (e.g. "construction margin Wil").
    """

    kind: str
    value: float
    start_m: float | None = None
    end_m: float | None = None
    distribution: str = "time"
    label: str = ""

    def __post_init__(self) -> None:
        where = self.label or "allowance"
        if self.kind not in KINDS:
            raise InputError(
                "unknown kind of allowance", field=f"{where}.kind", value=self.kind, allowed=", ".join(KINDS)
            )
        if self.distribution not in DISTRIBUTIONS:
            raise InputError(
                "unknown distribution",
                field=f"{where}.distribution",
                value=self.distribution,
                allowed=", ".join(DISTRIBUTIONS),
            )
        if not (isinstance(self.value, int | float) and np.isfinite(self.value) and self.value >= 0.0):
            raise InputError(
                "must be a finite number >= 0", field=f"{where}.value", value=self.value, allowed=">= 0"
            )
        if self.kind == "percent" and self.value > 300.0:
            raise InputError("too large", field=f"{where}.value", value=self.value, allowed="0 .. 300 %")
        for name, x in (("start_m", self.start_m), ("end_m", self.end_m)):
            if x is not None and not (isinstance(x, int | float) and np.isfinite(x)):
                raise InputError("must be a finite position", field=f"{where}.{name}", value=x, allowed="[m]")
        if self.start_m is not None and self.end_m is not None and not self.end_m > self.start_m:
            raise InputError(
                "the range must end after it starts",
                field=f"{where}.end_m",
                value=self.end_m,
                allowed=f"> {self.start_m}",
            )


#: The units a written allowance may end with, and its kind.
_UNITS = (("min/100km", "min_per_100km"), ("%", "percent"), ("s", "seconds"))


def parse_allowance(text: str, field: str = "--allowance") -> Allowance:
    """An allowance as a planner writes it on the command line: ``AMOUNT[@START-END][:DISTRIBUTION]``.

    AMOUNT is ``5%`` (of the fastest running time over the range), ``1.5min/100km`` or ``30s``;
    START-END the range in metres (default: the whole line); DISTRIBUTION ``time`` (default),
    ``distance`` or ``optimal``. Examples: ``5%``, ``1.5min/100km:distance``,
    ``30s@1200-3400`` (a construction margin on 1200-3400 m).

    Raises:
        InputError: the text does not follow that form (naming ``field``, the value and the form).
    """
    allowed = "AMOUNT[@START-END][:DISTRIBUTION], AMOUNT 5% | 1.5min/100km | 30s, DISTRIBUTION " + ", ".join(
        DISTRIBUTIONS
    )
    raw = text.strip().replace(" ", "")
    body, _, distribution = raw.partition(":")
    amount, _, span = body.partition("@")
    kind = next((k for unit, k in _UNITS if amount.endswith(unit)), None)
    try:
        if kind is None:
            raise ValueError
        unit = next(unit for unit, k in _UNITS if k == kind)
        value = float(amount[: -len(unit)])
        start = end = None
        if span:
            a, sep, b = span.partition("-")
            if not sep:
                raise ValueError
            start, end = float(a), float(b)
    except ValueError:
        raise InputError("not an allowance", field=field, value=text, allowed=allowed) from None
    return Allowance(
        kind, value, start, end, distribution=distribution or "time", label=f"{field} {text.strip()}"
    )


def allowance_s(kind: str, value: float, fastest_time_s: float, length_m: float) -> float:
    """The allowance [s] of a range whose fastest running time is ``fastest_time_s`` [s] and whose
    length is ``length_m`` [m]: value % of the time, value min per 100 km, or value seconds."""
    if kind == "percent":
        return 0.01 * value * fastest_time_s
    if kind == "min_per_100km":
        return 60.0 * value * length_m / 100_000.0
    return float(value)


def _time_at(solver, x: float) -> float:
    """The fastest run's time from its section's departure at position x [m] (clipped to the section)."""
    s, _, t, _ = solver.fastest
    return float(np.interp(min(max(x, solver.s0), solver.s1), s, t))


def allowance_timetable(
    train: Train,
    route: Route,
    allowances: Sequence[Allowance],
    settings: RunSettings | None = None,
) -> tuple[Timetable, list[dict]]:
    """The per-section timetable that the allowances give (module doc).

    Returns the timetable (one running time per section between stops) and one row per allowance:
    label, range [m], allowance [s], and the seconds it gives each section.

    Raises:
        InputError: a range outside the line, or an "optimal" range that cuts a section.
    """
    from trainsim.optimize.api import _optimal_plans, _solvers

    solvers = _solvers(train, route, settings or RunSettings())
    fastest = np.array([sv.fastest_time_s for sv in solvers])
    extra = np.zeros(len(solvers))
    rows = []
    for k, a in enumerate(allowances):
        where = a.label or f"allowances[{k}]"
        lo = route.stops[0].position_m if a.start_m is None else a.start_m
        hi = route.stops[-1].position_m if a.end_m is None else a.end_m
        if lo < route.stops[0].position_m - 1e-6 or hi > route.stops[-1].position_m + 1e-6:
            raise InputError(
                "the range lies outside the line",
                field=f"{where}.start_m/end_m",
                value=(lo, hi),
                allowed=f"{route.stops[0].position_m:g} .. {route.stops[-1].position_m:g} m",
            )
        overlap_m = np.array([max(0.0, min(hi, sv.s1) - max(lo, sv.s0)) for sv in solvers])
        overlap_s = np.array(
            [max(0.0, _time_at(sv, min(hi, sv.s1)) - _time_at(sv, max(lo, sv.s0))) if m > 0 else 0.0
             for sv, m in zip(solvers, overlap_m, strict=True)]
        )  # fmt: skip
        total = allowance_s(a.kind, a.value, float(overlap_s.sum()), float(overlap_m.sum()))
        inside = overlap_m > 0.0
        if not inside.any():
            raise InputError("the range covers no section", field=where, value=(lo, hi))
        if a.distribution == "optimal":
            whole = np.isclose(
                overlap_m[inside], [sv.s1 - sv.s0 for sv, i in zip(solvers, inside, strict=True) if i]
            )
            if not whole.all():
                raise InputError(
                    "an energy-optimal split needs a range made of whole sections",
                    field=f"{where}.start_m/end_m",
                    value=(lo, hi),
                    allowed="positions of stops",
                )
            subset = [sv for sv, i in zip(solvers, inside, strict=True) if i]
            plans, _ = _optimal_plans(subset, Timetable(line=SectionSchedule(supplement_s=total)))
            shares = np.zeros(len(solvers))
            shares[inside] = [
                p.running_time_s - sv.fastest_time_s for p, sv in zip(plans, subset, strict=True)
            ]
            # the split keeps the total to within the holding-speed search's tolerance: exact sum
            if shares.sum() > 0:
                shares *= total / shares.sum()
        else:
            weight = overlap_s if a.distribution == "time" else overlap_m
            shares = total * weight / weight.sum()
        extra += shares
        rows.append(
            {"label": a.label, "start_m": lo, "end_m": hi, "kind": a.kind, "value": a.value,
             "distribution": a.distribution, "allowance_s": total, "per_section_s": shares.tolist()}
        )  # fmt: skip
    sections = tuple(
        SectionSchedule(running_time_s=float(f + e)) for f, e in zip(fastest, extra, strict=True)
    )
    return Timetable(sections=sections, source="allowances"), rows


def allowance_spread(
    positions_m: Sequence[float],
    run_time_at,
    fastest_time_at,
    band: float = 0.02,
) -> list[str]:
    """Where the allowance between two consecutive points leaves a band around the overall one.

    Args:
        positions_m: the timing points and stops, in order [m].
        run_time_at, fastest_time_at: callables giving the run's and the fastest run's time at a
            position [s] (running time only, without dwell).
        band: the largest allowed difference from the overall allowance, as a fraction (0.02: 2
            percentage points).

    Returns:
        One message per pair of consecutive points outside the band (empty when all are inside).
    """
    pts = list(positions_m)
    total_fast = fastest_time_at(pts[-1]) - fastest_time_at(pts[0])
    total_run = run_time_at(pts[-1]) - run_time_at(pts[0])
    overall = total_run / total_fast - 1.0
    out = []
    for a, b in pairwise(pts):
        fast = fastest_time_at(b) - fastest_time_at(a)
        if fast <= 0.0:
            continue
        share = (run_time_at(b) - run_time_at(a)) / fast - 1.0
        if abs(share - overall) > band + 1e-9:
            out.append(
                f"{a:.0f}-{b:.0f} m: allowance {100 * share:.1f} % against {100 * overall:.1f} % overall "
                f"(more than {100 * band:.0f} percentage points apart)"
            )
    return out
