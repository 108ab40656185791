"""Computing runs in a worker: build each run's scenario from the study data, run it, keep its figures.

A worker gets the study's :class:`Payload` once (process-pool initializer, or a Dask future scattered
to every worker) and then chunks of :data:`~trainsim.batch.expand.RunTask`. It builds the train, route
and settings of every entry once and keeps them; a run rebuilds, from its data with the run's values
written in, only the parts its values touch (a load sweep re-reads the train, never the route), so the
per-run overhead stays well below the ~2 ms of a metro fastest run.

A run with a ``driving`` block is computed as :func:`trainsim.run` computes its scenario: the fastest
run (:func:`~trainsim.sim.fastest.run_fastest`) for ``strategy: fastest``, else
:func:`trainsim.optimize.api.optimize` with the strategy and the timetable (a line supplement or a
timetable file, read by the process that started the study). Its row then has the driving columns
(:data:`DRIVING_COLUMNS`): the strategy, the schedule, the deviation from it and the energy saved
against the fastest run (which ``optimize`` computes anyway).

A run with ``model: multi_point`` is computed as :func:`trainsim.run` computes its scenario too: the
scenario built from the run's data as the scenario reader builds it
(:func:`trainsim.batch.study.scenario_from_data`), then
:func:`trainsim.io.multipoint_spec.run_multipoint_scenario`; its row has the coupler-force columns
(:data:`MULTI_POINT_COLUMNS`).

Runs that build the same scenario, as the departures of a timetable entry, are computed once per worker
(:func:`scenario_key`; the last :data:`RUN_CACHE_SIZE` kept): each gets its own row with its own clock
times, bit for bit the row it would have had when computed on its own.

Every run is caught on its own: an exception becomes a failure row (``status: failed``, the error type
and message) and the chunk goes on.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from trainsim.batch.expand import RunTask
from trainsim.batch.paths import parse_path, set_value
from trainsim.errors import InputError

if TYPE_CHECKING:
    from trainsim.batch.study import Study

__all__ = [
    "DRIVING_COLUMNS",
    "DRIVING_METRICS",
    "METRICS",
    "MULTI_POINT_COLUMNS",
    "RUN_CACHE_SIZE",
    "Driving",
    "Payload",
    "WorkerState",
    "driving_figures",
    "multipoint_figures",
    "run_chunk",
    "scenario_key",
    "serve_process",
    "state_for",
]


@dataclass(frozen=True)
class Payload:
    """What every worker needs of a study: its entries' scenario data (train and route inlined) and
    the fingerprint that names the study.

    ``timetables`` holds the driving timetable files the runs may use, read by the process that
    started the study (file name as written -> ``Timetable``, or the reader's error as ``(reason,
    file, field, value, allowed)``); ``driving`` says whether rows get the driving columns.
    ``profiles`` holds the speed-profile files of ``multi_point.profile`` (read alike, name ->
    ``SpeedProfile`` or the error); ``multi_point`` says whether some runs use the multi-point model
    (rows then get :data:`MULTI_POINT_COLUMNS`).
    """

    fingerprint: str
    study_name: str
    entries: tuple[dict[str, Any], ...]
    timetables: tuple[tuple[str, Any], ...] = ()
    driving: bool = False
    profiles: tuple[tuple[str, Any], ...] = ()
    multi_point: bool = False

    @classmethod
    def of(cls, study: Study) -> Payload:
        """The payload of ``study`` (a :class:`~trainsim.batch.study.Study`)."""
        return cls(
            study.fingerprint,
            study.name,
            tuple(e.data for e in study.entries),
            timetables=tuple(study.timetables.items()),
            driving=study.driving,
            profiles=tuple(study.profiles.items()),
            multi_point=study.multi_point,
        )


@dataclass(frozen=True)
class Driving:
    """How a run is driven: ``strategy`` (a name of ``trainsim.optimize.api.STRATEGIES``) to
    ``timetable`` (a ``trainsim.optimize.timetable.Timetable``, None for a fastest run without one)."""

    strategy: str
    timetable: Any = None


#: Metric columns of a result row (see docs/BATCH.md), besides status, error_type, error, warnings.
METRICS = (
    "distance_m",
    "running_time_s",
    "dwell_s",
    "total_time_s",
    "max_speed_kmh",
    "average_speed_kmh",
    "average_running_speed_kmh",
    "peak_current_a",
    "energy_traction_kwh",
    "energy_braking_kwh",
    "energy_regenerated_kwh",
    "energy_auxiliary_kwh",
    "energy_net_kwh",
    "energy_paper_kwh",
)

#: Figures of studies that use ``driving`` (docs/BATCH.md), after the text column ``strategy``.
DRIVING_METRICS = (
    "scheduled_running_time_s",
    "schedule_deviation_s",
    "fastest_running_time_s",
    "fastest_energy_net_kwh",
    "energy_saved_kwh",
    "energy_saved_percent",
)
#: Every driving column, in the order of the results.
DRIVING_COLUMNS = ("strategy", *DRIVING_METRICS)

#: Columns of studies with multi-point runs (docs/BATCH.md; empty in single-point rows): the largest
#: draft (tension, > 0) and buff (compression, < 0) coupler force of the run [N], the coupling (0 =
#: between vehicles 0 and 1), when [s], where the head was and where the coupling was on the route [m]
#: (``MultiPointResult.max_draft`` / ``max_buff``); and how many couplings passed their rated draft or
#: buff capacity (``MultiPointResult.capacity_exceedances``, each also in the warnings).
MULTI_POINT_COLUMNS = (
    *(
        f"max_{kind}_{name}"
        for kind in ("draft", "buff")
        for name in ("force_n", "coupler", "time_s", "head_position_m", "coupler_position_m")
    ),
    "couplings_over_capacity",
)


class _Lru:
    """A small least-recently-used cache (thread-safe: a Dask worker may run chunks in threads)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._d: OrderedDict[str, Any] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: str) -> Any:
        with self._lock:
            value = self._d.get(key)
            if value is not None:
                self._d.move_to_end(key)
            return value

    def put(self, key: str, value: Any) -> None:
        with self._lock:
            self._d[key] = value
            self._d.move_to_end(key)
            while len(self._d) > self.size:
                self._d.popitem(last=False)


def _located(exc: InputError, source: str, part: str) -> InputError:
    """The error with the run as its file and the scenario part before its field."""
    field = f"{part}.{exc.field}" if exc.field else part
    out = InputError(exc.reason, file=source, field=field, value=exc.value, allowed=exc.allowed)
    return out


class WorkerState:
    """A worker's view of one study: entries built once, caches of rebuilt trains and routes."""

    def __init__(self, payload: Payload) -> None:
        self.payload = payload
        # per entry: (train, route with the entry's stops, settings, route as in its file, driving)
        self._entries: list[tuple[Any, Any, Any, Any, Driving | None] | None] = [None] * len(payload.entries)
        self._timetables = dict(payload.timetables)
        self._profiles = dict(payload.profiles)
        self._trains = _Lru(32)
        self._routes = _Lru(32)
        # (RunResult without trace, driving figures, optimiser warnings) of the scenarios computed
        self._runs = _Lru(RUN_CACHE_SIZE)
        self._lock = threading.Lock()

    # -------------------------------------------------------------- building
    def _train(self, data: Any, source: str):
        from trainsim.io import loader
        from trainsim.io import trainsim_yaml as tsy

        key = data if isinstance(data, str) else json.dumps(data, sort_keys=True, default=str)
        train = self._trains.get(key)
        if train is None:
            try:
                train = (
                    loader.load_train(data) if isinstance(data, str) else tsy.train_from_dict(data, source)
                )
            except InputError as exc:
                raise _located(exc, source, "train") from None
            self._trains.put(key, train)
        return train

    def _route(self, data: Any, source: str):
        from trainsim.io import loader
        from trainsim.io import trainsim_yaml as tsy

        key = data if isinstance(data, str) else json.dumps(data, sort_keys=True, default=str)
        route = self._routes.get(key)
        if route is None:
            try:
                route = (
                    loader.load_route(data) if isinstance(data, str) else tsy.route_from_dict(data, source)
                )
            except InputError as exc:
                raise _located(exc, source, "route") from None
            self._routes.put(key, route)
        return route

    @staticmethod
    def _settings(data: Any, source: str):
        from trainsim.io import trainsim_yaml as tsy

        return tsy.settings_from_dict(data or {}, source)

    @staticmethod
    def _stops(route, data: dict[str, Any], source: str):
        from trainsim.io import trainsim_yaml as tsy

        stops, dwell = data.get("stops"), data.get("dwell_s")
        if stops is not None and not (isinstance(stops, list) and all(isinstance(s, str) for s in stops)):
            raise InputError("must be a list of station names", file=source, field="stops", value=stops)
        if dwell is not None and not isinstance(dwell, dict):
            raise InputError(
                "must be a mapping of station name to dwell time", file=source, field="dwell_s", value=dwell
            )
        for name, value in (dwell or {}).items():
            if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
                raise InputError(
                    "invalid dwell time", file=source, field=f"dwell_s.{name}", value=value, allowed=">= 0 s"
                )
        return tsy.apply_stops(route, stops, dwell, file=source)

    def _timetable(self, name: str, source: str):
        """The timetable file ``name`` (as written), read by the process that started the study."""
        from trainsim.io.timetable_file import read_timetable_yaml

        return _shared_file(self._timetables, name, source, read_timetable_yaml, "driving.timetable")

    def _driving(self, data: Any, source: str) -> Driving | None:
        """How a run with the scenario's ``driving`` block ``data`` is driven (None: no block).

        The block is read as ``ScenarioSpec.to_scenario`` reads it (the same functions of
        trainsim/io/trainsim_yaml.py), its timetable file as read by the process that started the study.
        """
        if data is None:
            return None
        from trainsim.io import trainsim_yaml as tsy

        spec = tsy.driving_spec_from_dict(data, source)
        strategy, timetable = tsy.driving_from_spec(spec, source, lambda name: self._timetable(name, source))
        return Driving(strategy, timetable)

    def entry(self, e: int) -> tuple[Any, Any, Any]:
        """(train, route with the entry's stops, settings) of entry ``e``, built once."""
        return self._entry(e)[:3]

    def _entry(self, e: int) -> tuple[Any, Any, Any, Any, Driving | None]:
        built = self._entries[e]
        if built is None:
            data = self.payload.entries[e]
            source = f"{self.payload.study_name}: entry {e}"
            train = self._train(data["train"], source)
            plain = self._route(data["route"], source)
            route = self._stops(plain, data, source)
            settings = self._settings(data.get("settings"), source)
            built = (train, route, settings, plain, self._driving(data.get("driving"), source))
            self._entries[e] = built
        return built

    def scenario(self, task: RunTask) -> tuple[Any, Any, Any, Driving | None]:
        """(train, route, settings, driving) of one run: the entry's, rebuilt where the run's values
        touch it (a supplement sweep rebuilds only the driving, never the train or the route)."""
        index, e, _, overrides = task
        train, route, settings, plain, driving = self._entry(e)
        if not overrides:
            return train, route, settings, driving
        source = f"run {index}"
        data, touched = self.run_data(task)
        if "train" in touched:
            train = self._train(data["train"], source)
        if "route" in touched:
            route = self._stops(self._route(data["route"], source), data, source)
        elif touched & {"stops", "dwell_s"}:
            route = self._stops(plain, data, source)
        if "settings" in touched:
            settings = self._settings(data.get("settings"), source)
        if "driving" in touched:
            driving = self._driving(data.get("driving"), source)
        return train, route, settings, driving

    def run_data(self, task: RunTask) -> tuple[dict[str, Any], set[str]]:
        """The scenario data of one run (the entry's with the run's values written in; parts not
        touched are shared, never to be written into) and the parts its values touch."""
        index, e, _, overrides = task
        source = f"run {index}"
        base = self.payload.entries[e]
        touched = {parse_path(path).root for path, _, _ in overrides}
        data = {k: (copy.deepcopy(v) if k in touched else v) for k, v in base.items()}
        for path, value, relative in overrides:
            try:
                set_value(data, path, value, scale=relative)
            except InputError as exc:
                raise InputError(
                    exc.reason, file=source, field=path, value=exc.value, allowed=exc.allowed
                ) from None
        if "model" in touched:
            from trainsim.batch.study import drop_unused_block

            drop_unused_block(data)
        return data, touched

    def _is_multipoint(self, task: RunTask) -> bool:
        for path, value, _ in task[3]:
            if path == "model":
                return value != "single_point"  # an unknown model fails in the reader
        return self.payload.entries[task[1]].get("model", "single_point") != "single_point"

    def _profile(self, name: str, source: str):
        """The speed-profile file ``name`` (as written), read by the process that started the study."""
        from trainsim.io.multipoint_spec import read_profile

        return _shared_file(
            self._profiles, name, source, lambda n: read_profile(Path(n), n), "multi_point.profile"
        )

    def run_multipoint(self, task: RunTask):
        """The ``MultiPointResult`` of a run with ``model: multi_point``, as :func:`trainsim.run`
        computes its scenario (``run_multipoint_scenario(scenario, scenario.multi_point)``); the block's
        profile file as read by the process that started the study."""
        from trainsim.batch.study import scenario_from_data
        from trainsim.io.multipoint_spec import run_multipoint_scenario

        source = f"run {task[0]}"
        data, _ = self.run_data(task)
        if data.get("driving") is not None:  # refused when the study is read; kept for direct callers
            raise InputError(
                "the multi-point model is not driven by a 'driving' block (trainsim.run ignores it)",
                file=source,
                field="driving",
            )
        scenario = scenario_from_data(data, source)
        spec = scenario.multi_point
        profile = self._profile(spec.profile, source) if spec.profile else None
        return run_multipoint_scenario(scenario, spec, profile=profile)

    # -------------------------------------------------------------- running
    def run(self, task: RunTask) -> dict[str, Any]:
        """The result row of one run (metrics, or the failure).

        Runs that build the same scenario (:func:`scenario_key`: a timetable entry's departures) are
        computed once per worker; each gets its own row, with its own clock times."""
        key = scenario_key(task)
        computed = self._runs.get(key)
        if computed is None:
            try:
                computed = self._compute(task)
            except Exception as exc:  # a failed run must never stop the study
                return {"status": "failed", "error_type": type(exc).__name__, "error": str(exc) or repr(exc)}
            self._runs.put(key, computed)
        result, extra, warnings = computed
        row = metrics_row(result, task[2])
        if extra is not None:
            row.update(extra)
        if warnings:
            # as OptimizationResult.summary(): the optimiser's warnings first
            row["warnings"] = "; ".join([*warnings, *result.warnings])
        return row

    def _compute(self, task: RunTask) -> tuple[Any, dict[str, Any] | None, list[str]]:
        """(RunResult without its trace, the row's extra columns or None, the optimiser's warnings)
        of one run: what its row needs besides its clock times."""
        if self.payload.multi_point and self._is_multipoint(task):
            mp = self.run_multipoint(task)
            return _summary_only(mp.run), multipoint_figures(mp), []
        train, route, settings, driving = self.scenario(task)
        result, figures, warnings = drive(train, route, settings, driving, source=f"run {task[0]}")
        if not self.payload.driving:
            return _summary_only(result), None, []
        return _summary_only(result), figures, warnings


def _summary_only(result):
    """The run without its trace: a kept run's row needs none (an optimised or multi-point run's trace
    would hold megabytes in the cache of a worker)."""
    return dataclasses.replace(result, trace=None) if result.trace is not None else result


#: Runs whose results a worker keeps, by :func:`scenario_key`: the runs of a timetable entry differ
#: only in their departures, which move the clock columns but not the run. Kept without trace (about
#: 1.5 kB for a metro run).
RUN_CACHE_SIZE = 64


def scenario_key(task: RunTask) -> str:
    """What a run's result depends on: its entry and the values the run writes into the
    entry's data, not its index or departure (which only shift the clock times of its row).

    Canonical JSON with values written exactly (``repr`` of floats): two runs share a key only when
    they build the same scenario; a value JSON cannot tell apart (a tuple and a list) builds the
    same scenario either way."""
    _, entry, _, overrides = task
    return json.dumps([entry, overrides], sort_keys=True, default=repr)


def _shared_file(contents: dict[str, Any], name: str, source: str, read: Any, field: str):
    """What the study read from the file ``name`` (as written) that a run's ``field`` names; the
    reader's error, kept as ``(reason, file, field, value, allowed)``, is raised for this run."""
    content = contents.get(name)
    if content is None:  # not expected (the study reads every name it can see); read it here
        try:
            content = read(name)
        except InputError as exc:
            content = (exc.reason, exc.file, exc.field, exc.value, exc.allowed)
    if isinstance(content, tuple):
        reason, file, inner_field, value, allowed = content
        inner = ", ".join(x for x in (file, f"field '{inner_field}'" if inner_field else None) if x)
        kind = field.rsplit(".", 1)[-1]
        raise InputError(
            f"{kind} {name}: {reason}" + (f" ({inner})" if inner else ""),
            file=source,
            field=field,
            value=value,
            allowed=allowed,
        )
    return content


def drive(train, route, settings, driving: Driving | None, *, source: str = "<run>"):
    """The run of a scenario as :func:`trainsim.run` computes it, with its driving figures.

    Returns (RunResult, :func:`driving_figures`, the optimiser's warnings). ``driving`` None or
    ``strategy: fastest``: the fastest run (``trainsim.run`` calls ``run_scenario``, that is
    ``run_fastest``), without its trace (``trace`` is None; every summary figure is the same); else ``trainsim.optimize.api.optimize`` (``trainsim.run`` returns its ``.run``).
    """
    from trainsim.sim.fastest import run_fastest

    strategy = driving.strategy if driving is not None else "fastest"
    timetable = driving.timetable if driving is not None else None
    if timetable is not None and timetable.sections:
        # as read_timetable_yaml(path, n_sections) does when the scenario is read
        n = len(route.stops) - 1
        if len(timetable.sections) != n:
            raise InputError(
                "one schedule per section is needed",
                file=source,
                field="driving.timetable",
                value=len(timetable.sections),
                allowed=f"{n} (the route's sections between stops)",
            )
    if strategy == "fastest":
        # a study keeps only summary figures: no trace arrays (the same figures, tested in tests/sim)
        result = run_fastest(train, route, settings, trace=False)
        return result, driving_figures(strategy, timetable, result, None), []
    from trainsim.optimize.api import optimize

    opt = optimize(train, route, timetable, strategy, settings)
    return opt.run, driving_figures(strategy, timetable, opt.run, opt), list(opt.warnings)


def driving_figures(strategy: str, timetable, result, optimization=None) -> dict[str, Any]:
    """The driving columns of a run (:data:`DRIVING_COLUMNS`).

    Args:
        strategy: the strategy that drove the run.
        timetable: its ``Timetable`` (None: a fastest run without a schedule; the schedule columns are
            then empty).
        result: the run (``RunResult``).
        optimization: the ``OptimizationResult`` of an energy-efficient run (its schedule, deviations
            and fastest run); None for a fastest run, whose schedule is the timetable's, a line
            supplement shared in proportion to the sections' fastest times (as ``optimize`` does for
            the fastest strategy), and which is its own fastest run.
    """
    if optimization is not None:
        targets = list(optimization.scheduled_running_time_s)
        deviations = list(optimization.schedule_deviation_s)
        fastest = optimization.fastest
    else:
        fastest = result
        targets = deviations = None
        if timetable is not None and result.status == "ok":
            # the optimiser's own rule for the fastest strategy (one definition of it)
            from trainsim.optimize.api import proportional_targets

            times = [sec.running_time_s for sec in result.sections]
            targets = proportional_targets(timetable, times)
            deviations = [t - target for t, target in zip(times, targets, strict=True)]
    fastest_net = fastest.energy_kwh.net
    saved = fastest_net - result.energy_kwh.net
    return {
        "strategy": strategy,
        "scheduled_running_time_s": _num(sum(targets)) if targets else None,
        # the largest deviation of a section's running time from its schedule, early or late [s]
        "schedule_deviation_s": _num(max(abs(d) for d in deviations)) if deviations else None,
        "fastest_running_time_s": _num(fastest.running_time_s),
        "fastest_energy_net_kwh": _num(fastest_net),
        "energy_saved_kwh": _num(saved),
        "energy_saved_percent": _num(100.0 * saved / fastest_net) if fastest_net > 0 else None,
    }


def multipoint_figures(result) -> dict[str, Any]:
    """The :data:`MULTI_POINT_COLUMNS` of a ``MultiPointResult``: its largest draft and buff forces."""
    row: dict[str, Any] = {}
    for kind, ext in (("draft", result.max_draft), ("buff", result.max_buff)):
        row[f"max_{kind}_force_n"] = _num(ext.force_n)
        row[f"max_{kind}_coupler"] = int(ext.coupler)
        row[f"max_{kind}_time_s"] = _num(ext.time_s)
        row[f"max_{kind}_head_position_m"] = _num(ext.head_position_m)
        row[f"max_{kind}_coupler_position_m"] = _num(ext.coupler_position_m)
    row["couplings_over_capacity"] = len({e.coupler for e in result.capacity_exceedances})
    return row


def _num(x: float) -> float | None:
    x = float(x)
    return x if x == x and x not in (float("inf"), float("-inf")) else None


def metrics_row(result, departure_s: float | None) -> dict[str, Any]:
    """The summary figures of a run, with section times as clock times when it has a departure."""
    e = result.energy_kwh
    row: dict[str, Any] = {
        "status": result.status,
        "error_type": None,
        "error": None,
        "warnings": "; ".join(result.warnings) or None,
        "train": result.train_name,
        "route": result.route_name,
        "distance_m": _num(result.distance_m),
        "running_time_s": _num(result.running_time_s),
        "dwell_s": _num(result.dwell_s),
        "total_time_s": _num(result.total_time_s),
        "max_speed_kmh": _num(result.max_speed_kmh),
        "average_speed_kmh": _num(result.average_speed_kmh),
        "average_running_speed_kmh": _num(result.average_running_speed_kmh),
        "peak_current_a": _num(result.peak_current_a),
        "energy_traction_kwh": _num(e.traction),
        "energy_braking_kwh": _num(e.braking),
        "energy_regenerated_kwh": _num(e.regenerated),
        "energy_auxiliary_kwh": _num(e.auxiliary),
        "energy_net_kwh": _num(e.net),
        "energy_paper_kwh": _num(e.paper),
    }
    t = departure_s or 0.0
    sections = []
    for sec in result.sections:
        arrive = t + sec.running_time_s
        sections.append(
            {
                "from": sec.from_station,
                "to": sec.to_station,
                "distance_m": _num(sec.distance_m),
                "departure_s": _num(t),
                "arrival_s": _num(arrive),
                "running_time_s": _num(sec.running_time_s),
                "dwell_s": _num(sec.dwell_s),
                "energy_net_kwh": _num(sec.energy_kwh.net),
            }
        )
        t = arrive + sec.dwell_s
    row["sections"] = sections
    if departure_s is not None:
        row["arrival_s"] = _num(departure_s + result.total_time_s)
    return row


# one state per study and process; a Dask worker may hold several studies
_STATES: dict[str, WorkerState] = {}
_STATES_LOCK = threading.Lock()


def state_for(payload: Payload) -> WorkerState:
    """This process's state for a study, made on first use."""
    with _STATES_LOCK:
        state = _STATES.get(payload.fingerprint)
        if state is None:
            if len(_STATES) >= 4:
                _STATES.pop(next(iter(_STATES)))
            state = _STATES[payload.fingerprint] = WorkerState(payload)
        return state


def run_chunk(payload: Payload, tasks: list[RunTask]) -> list[tuple[int, dict[str, Any]]]:
    """Compute a chunk of runs: (run_index, row) for each, failures included."""
    state = state_for(payload)
    return [(task[0], state.run(task)) for task in tasks]


# ---------------------------------------------------------------- process-pool workers
_PAYLOAD: Payload | None = None


def _die_with_parent() -> None:
    """Have the kernel kill this worker when its parent process ends (Linux): a study killed with
    SIGKILL must not leave workers behind, waiting for chunks that will never come."""
    import multiprocessing
    import signal
    import sys

    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    parent = multiprocessing.parent_process()
    if parent is not None and not parent.is_alive():  # the parent died before prctl
        os._exit(1)


def init_process(payload: Payload) -> None:
    """Process-pool initializer: keep the payload, build the entries and load the compiled kernel,
    so that the first chunk is as fast as the others."""
    import signal

    global _PAYLOAD
    _die_with_parent()
    # Ctrl-C goes to the whole process group: the parent stops the study, the workers just end
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _PAYLOAD = payload
    state = state_for(payload)
    try:
        from trainsim.sim.fastest import run_fastest

        run_fastest(*state.entry(0))  # warm-up: the first run imports what every run of the chunk uses
    except Exception:  # a bad entry fails its runs, with their own error rows
        pass


def run_chunk_in_process(tasks: list[RunTask]) -> list[tuple[int, dict[str, Any]]]:
    """The task function of the process pool (the payload came with the initializer)."""
    assert _PAYLOAD is not None, "process not initialised with a study payload"
    return run_chunk(_PAYLOAD, tasks)


#: Longest time a worker process keeps computed rows before sending them [s]. Rows go back in small
#: batches, not one by one: for millisecond runs a message per run costs the study's process a wake-up,
#: a receive and an unpickling per run (about 40 us of its CPU, taken from the workers on a 2-core
#: machine), while a killed worker still loses at most the run it was computing and this much work.
#: Each wake-up of the study's process costs it about 0.1 ms of CPU on a loaded machine: at 0.05 s,
#: 0.27 ms per metro run (half of it these wake-ups, measured at load 12); at 0.2 s, see docs/BATCH.md.
SEND_INTERVAL_S = 0.2

#: Threads of the numerical libraries in a worker process: one (the pool runs one process per core).
THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


def single_threaded_env() -> dict[str, str]:
    """:data:`THREAD_ENV` less the variables the user set (an explicit setting is kept)."""
    return {k: v for k, v in THREAD_ENV.items() if k not in os.environ}


def serve_process(payload: Payload, conn: Any) -> None:
    """Main function of a worker process of the ``processes`` executor: receive chunks of runs on the
    pipe ``conn`` (None: stop) and send back lists of ``(run_index, row, cpu_s)`` as runs are
    computed: at the end of each chunk and whenever :data:`SEND_INTERVAL_S` has passed since the last
    list, so that a worker killed in the middle of a chunk loses only the run it was computing and the
    runs of the last fraction of a second (the runs it sent are kept, the rest of the chunk goes to
    another worker). ``cpu_s`` is the run's CPU time in this process [s], which the chunk sizing uses as
    the measured cost of the run."""
    import gc
    import time

    init_process(payload)
    # what the set-up built lives as long as the process: out of the collector's way, so that a full
    # collection does not walk (and write to, un-sharing the forked pages) every module and entry again
    gc.freeze()
    state = state_for(payload)
    while True:
        try:
            tasks = conn.recv()
        except (EOFError, OSError):  # the study's process is gone
            return
        if tasks is None:
            return
        batch: list[tuple[int, dict[str, Any], float]] = []
        sent = time.perf_counter()
        for task in tasks:
            c0 = time.process_time()
            row = state.run(task)
            batch.append((task[0], row, time.process_time() - c0))
            now = time.perf_counter()
            if now - sent >= SEND_INTERVAL_S:
                conn.send(batch)
                batch, sent = [], now
        if batch:
            conn.send(batch)
