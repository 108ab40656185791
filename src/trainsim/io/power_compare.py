"""The same power file driven with several strategies, side by side (``trainsim power --compare-driving``).

Energy-efficient driving saves traction energy at the pantographs; at the substations the saving also
depends on how much of the regenerated energy other trains could take (coasting leaves less to
regenerate, so less is burnt when no other train is accelerating nearby). Each strategy's run is the
file's own timetable study (the trains, departures, network and simulation settings as written) with
every train's scenario driven with that strategy; the first strategy is the reference of the savings.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from trainsim.errors import InputError
from trainsim.io.power_file import StudyReader, load_power_file, timetable_result
from trainsim.power.study import TrainService

__all__ = ["STRATEGIES", "compare_driving", "parse_strategies"]

#: The driving strategies of a scenario's ``driving:`` block (docs/OPTIMIZATION.md).
STRATEGIES = ("fastest", "optimal", "lesov", "reference")


def parse_strategies(text: str) -> tuple[str, ...]:
    """``"fastest,optimal"`` as a tuple; InputError (option ``--compare-driving``) unless it names at
    least two distinct known strategies."""
    names = tuple(s.strip() for s in text.split(","))
    allowed = f"two or more of {', '.join(STRATEGIES)}, comma-separated, e.g. fastest,optimal"
    unknown = [s for s in names if s not in STRATEGIES]
    if unknown:
        raise InputError(
            "unknown driving strategy", field="--compare-driving", value=unknown[0], allowed=allowed
        )
    if len(names) < 2 or len(set(names)) != len(names):
        raise InputError(
            "a comparison needs two or more distinct strategies",
            field="--compare-driving",
            value=text,
            allowed=allowed,
        )
    return names


def _driven(services: list[TrainService], strategy: str, timetable: Any, file: str) -> list[TrainService]:
    """The services with every scenario driven with ``strategy``: to ``timetable`` (the option's
    supplement) when given, else to the scenario's own timetable or supplement."""
    out = []
    # services sharing a scenario keep sharing it (each distinct scenario is run once per study)
    driven: dict[int, Any] = {}
    for s in services:
        sc = s.scenario
        if id(sc) not in driven:
            schedule = timetable if timetable is not None else sc.timetable
            if strategy != "fastest" and schedule is None:
                raise InputError(
                    f"driving {strategy} needs a supplement or a timetable: train {s.id}'s scenario "
                    f"'{sc.name}' gives none",
                    file=file,
                    field="--supplement",
                    allowed="--supplement 10% (or 30 s), or driving: {supplement: ...} in the scenario",
                )
            driven[id(sc)] = dataclasses.replace(sc, strategy=strategy, timetable=schedule)
        out.append(dataclasses.replace(s, scenario=driven[id(sc)]))
    return out


def _figures(summary: dict[str, Any], strategy: str) -> dict[str, Any]:
    regen = summary["regen_kwh"]
    return {
        "strategy": strategy,
        "status": summary["status"],
        "statuses": summary.get("statuses", [summary["status"]]),
        "traction_demand_kwh": sum(t["traction_demand_kwh"] for t in summary["trains"]),
        "trains_energy_kwh": summary["trains_energy_kwh"],
        "substations_energy_kwh": summary["substations_energy_kwh"],
        "losses_kwh": summary["losses_kwh"],
        "regen_kwh": {k: regen[k] for k in ("used_by_trains", "returned", "dissipated")},
        "warnings": summary["warnings"],
    }


def _saving(reference: float, value: float) -> dict[str, float | None]:
    saved = reference - value
    return {"kwh": saved, "percent": 100.0 * saved / reference if reference != 0.0 else None}


def compare_driving(
    path: str | Path,
    strategies: tuple[str, ...],
    supplement: str | None = None,
    *,
    synchronise: bool | None = None,
    read_study: StudyReader | None = None,
) -> tuple[dict[str, Any], str]:
    """Run the power file at ``path`` once per strategy; (``driving_comparison`` block, status).

    ``supplement`` ("10%", "30 s": the scenario reader's parser) is the line supplement of every
    strategy but ``fastest``; without it each scenario's own timetable or supplement is used. The
    status is the first run's that is not ``ok`` (``ok`` if all are). Refused (InputError) for an
    operation file (its trains are driven by the operation) and with synchronisation: shifting the
    departures differently per strategy would mix the two savings.
    """
    from trainsim.model.timetable import Timetable
    from trainsim.optimize.timetable import parse_supplement

    file = str(path)
    timetable = None
    if supplement is not None:
        timetable = Timetable(line=parse_supplement(supplement, field="--supplement"))
    if synchronise:
        raise InputError("the driving comparison runs the timetable as given: synchronising each strategy's "
                         "departures would mix the two savings", field="--synchronise", value=True,
                         allowed="--no-synchronise, or no --compare-driving")  # fmt: skip
    spec, network, services = load_power_file(path, read_study=read_study)
    if spec.operation is not None:
        raise InputError("the operation drives an operation file's trains: compare the driving in the operation",
                         file=file, field="--compare-driving", value=",".join(strategies),
                         allowed="a power file with trains: or timetable:")  # fmt: skip
    if spec.synchronisation is not None and synchronise is None:
        raise InputError("the file has a synchronisation: block; the driving comparison runs the timetable as given",
                         file=file, field="--synchronise", allowed="--no-synchronise with --compare-driving")  # fmt: skip
    sim = spec.simulation
    feedback = sim.feedback.settings()
    # every strategy's trains first: a missing supplement is reported before any run is made
    variants = [_driven(services, s, None if s == "fastest" else timetable, file) for s in strategies]
    runs = []
    for strategy, driven in zip(strategies, variants, strict=True):
        try:
            result = timetable_result(network, driven, sim, feedback, (sim.start_s, sim.end_s))
        except InputError as exc:
            raise exc.located(file) from None
        runs.append(_figures(result.summary(), strategy))
    first = runs[0]
    block = {
        "name": spec.name,
        "supplement": supplement,
        "runs": runs,
        "savings": [
            {
                "strategy": r["strategy"],
                "against": first["strategy"],
                "pantographs": _saving(first["trains_energy_kwh"], r["trains_energy_kwh"]),
                "substations": _saving(first["substations_energy_kwh"], r["substations_energy_kwh"]),
            }
            for r in runs[1:]
        ],
    }
    status = next((r["status"] for r in runs if r["status"] != "ok"), "ok")
    block["status"] = status
    return block, status
