"""The trains of a batch study's timetable on a power network (``timetable:`` of a power file).

A power file's ``timetable:`` entries name batch studies (``schema: trainsim/study``, docs/BATCH.md).
This module reads such a study with the batch layer's own reader and expansion
(:func:`~trainsim.batch.study.load_study`, :meth:`~trainsim.batch.study.Study.expand`) and builds each
run's scenario as a batch worker does (:class:`~trainsim.batch.worker.WorkerState`): the runs that differ
only by their departure make one train service with all their departures, so each distinct scenario
(train, route with its stops and dwells, load, driving) is run once. It lives in the batch layer because
the file layer (trainsim.io) sits below it and may not import it; the file layer takes the reader as an
argument (:data:`~trainsim.io.power_file.StudyReader`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from trainsim.batch.study import load_study
from trainsim.batch.worker import Payload, WorkerState
from trainsim.errors import InputError
from trainsim.io import power_file
from trainsim.io.power_file import PowerFile, StudyTrains
from trainsim.model.scenario import Scenario
from trainsim.power.network import Network
from trainsim.power.study import TrainService

__all__ = ["load_power_file", "read_study_trains", "run_power_file"]


def read_study_trains(path: Path) -> list[StudyTrains]:
    """The distinct scenarios of the batch study at ``path``, each with its runs' departures [s since
    midnight], in the study's run order. InputError (naming the study file and the entry) if a run has
    no departure: a power study places every train in time."""
    study = load_study(path)
    expansion = study.expand()
    payload = Payload.of(study)
    state = WorkerState(payload)
    groups: dict[str, tuple[int, Any, list[float]]] = {}
    for i in range(len(expansion)):
        _, e, departure_s, overrides = expansion.task(i)
        if departure_s is None:
            entry = study.entries[e].name
            raise InputError(
                "a run of the study has no departure: the power simulation needs every train's time",
                file=study.file,
                field=f"runs[{e}].departures" if entry is not None else "departures",
                value=entry,
                allowed="departures: on every run entry (docs/BATCH.md)",
            )
        # runs differing only by their departure are one service; values may be lists (unhashable)
        key = json.dumps([e, overrides], sort_keys=True, default=str)
        groups.setdefault(key, (e, overrides, []))[2].append(float(departure_s))
    entry_groups: dict[int, int] = {}
    out = []
    for e, overrides, departures in groups.values():
        entry = study.entries[e]
        label = entry.name if entry.name is not None else study.name
        k = entry_groups[e] = entry_groups.get(e, 0) + 1
        where = f"runs[{e}] '{label}'" if entry.name is not None else "(the study's base)"
        if state._is_multipoint((0, e, None, overrides)):
            out.append(StudyTrains(label, where, Scenario(label, None, None, model="multi_point"), ()))
            continue
        train, route, settings, driving = state.scenario((0, e, None, overrides))
        scenario = Scenario(label, train, route, settings)
        if driving is not None:
            scenario = Scenario(
                label, train, route, settings, strategy=driving.strategy, timetable=driving.timetable
            )
        # an entry with swept values makes several services: numbered after the first
        name = label if k == 1 else f"{label} #{k}"
        out.append(StudyTrains(name, where, scenario, tuple(departures)))
    return out


def load_power_file(path: str | Path) -> tuple[PowerFile, Network, list[TrainService]]:
    """:func:`trainsim.io.power_file.load_power_file` with the ``timetable:`` studies read."""
    return power_file.load_power_file(path, read_study=read_study_trains)


def run_power_file(
    path: str | Path,
    out_dir: str | Path | None = None,
    *,
    plots: bool = True,
    synchronise: bool | None = None,
) -> tuple[dict[str, Any], str]:
    """:func:`trainsim.io.power_file.run_power_file` with the ``timetable:`` studies read."""
    return power_file.run_power_file(
        path, out_dir, plots=plots, synchronise=synchronise, read_study=read_study_trains
    )
