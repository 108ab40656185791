"""The web application's heavy work, as plain functions a worker process runs (:mod:`trainsim.web.workers`).

Every function takes and returns picklable values, validates everything it accepts and computes
the answer's JSON body before returning, so that the server process only stores results that are
known to be valid and serializable (nothing invalid is ever stored).

* :func:`train_from_mapping`, :func:`route_from_mapping`: an edited train or route;
* :func:`upload`: an uploaded file of any format trainsim reads (parsed once);
* :func:`run`: a run with a registered strategy, with its answer body.
"""

from __future__ import annotations

import json
import tempfile
import zipfile
from pathlib import Path, PurePosixPath
from typing import Any

from trainsim.errors import InputError
from trainsim.io import trainsim_yaml as tsy
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim.result import RunResult
from trainsim.web import guard, strategies
from trainsim.web.cache import identity
from trainsim.web.config import WebSettings
from trainsim.web.convert import loaded_route, loaded_train, route_to_dict, spec_dict, train_to_dict
from trainsim.web.payloads import route_payload, run_body, train_payload
from trainsim.web.sessions import Loaded

__all__ = ["UPLOAD_SUFFIXES", "route_from_mapping", "run", "train_from_mapping", "upload", "warm"]

#: file name endings an upload may have, and what reads them
UPLOAD_SUFFIXES: dict[str, str] = {
    ".yaml": "trainsim / railtoolkit YAML",
    ".yml": "trainsim / railtoolkit YAML",
    ".json": "TTOBench JSON",
    ".xml": "railML 2 or 3",
    ".railml": "railML 2 or 3",
    ".xlsx": "spreadsheet (Excel)",
    ".xlsm": "spreadsheet (Excel)",
    ".zip": "spreadsheet as a folder of CSV tables, zipped",
}


def _dumps(payload: Any, what: str) -> bytes:
    try:
        return json.dumps(payload, allow_nan=False, separators=(",", ":")).encode()
    except ValueError as exc:
        raise InputError(
            f"the {what} gives figures that are not finite numbers",
            allowed="values within the physical bounds of the format (docs/FORMAT.md)",
        ) from exc


def _check_route(loaded: Loaded, limits: WebSettings, file: str | None = None) -> None:
    length = loaded.model.length_m
    if length > limits.max_route_length_m:
        raise InputError(
            "route too long for the web application",
            file=file,
            field="length_m",
            value=length,
            allowed=f"<= {limits.max_route_length_m:g} m",
        )


def train_from_mapping(
    data: Any, source: str, limits: WebSettings, shown_source: str | None = None
) -> tuple[Loaded, bytes]:
    """An edited ``trainsim/train`` mapping: bounded, validated, built; with the answer body.
    ``source`` names it in messages, ``shown_source`` (default: the same) in the page."""
    guard.check_document(data, limits)
    loaded = loaded_train(data, source)
    loaded.source = shown_source or source
    identity(loaded)
    return loaded, _dumps(train_payload(spec_dict(loaded.spec), loaded), "train")


def route_from_mapping(
    data: Any, source: str, limits: WebSettings, shown_source: str | None = None
) -> tuple[Loaded, bytes]:
    """An edited ``trainsim/route`` mapping: bounded, validated, built; with the answer body.
    ``source`` names it in messages, ``shown_source`` (default: the same) in the page."""
    guard.check_document(data, limits)
    loaded = loaded_route(data, source)
    loaded.source = shown_source or source
    _check_route(loaded, limits)
    identity(loaded)
    return loaded, _dumps(route_payload(spec_dict(loaded.spec), loaded), "route")


# ====================================================================== uploads
def _safe_name(name: str) -> str:
    """The file's base name, with only plain characters (never ``.`` or ``..``)."""
    base = PurePosixPath(name.replace("\\", "/")).name
    safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in base)[:100].lstrip(".")
    return safe or "upload"


def _unzip_tables(archive: Path, folder: Path, limits: WebSettings, name: str) -> None:
    """Extract the CSV tables of a zipped folder (flat names only, bounded in count and size)."""
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError("not a readable zip file", file=name, allowed="a zip of CSV tables") from exc
    with zf:
        entries = [i for i in zf.infolist() if not i.is_dir()]
        if len(entries) > 32:
            raise InputError(
                "too many files in the zip", file=name, value=len(entries), allowed="at most 32 CSV tables"
            )
        total = 0
        for info in entries:
            base = PurePosixPath(info.filename).name
            if not base.lower().endswith(".csv") or base.startswith("."):
                continue
            total += info.file_size
            if total > 4 * limits.max_body_bytes:
                raise InputError(
                    "the zip's tables are too large",
                    file=name,
                    allowed=f"at most {4 * limits.max_body_bytes} bytes unpacked",
                )
            with zf.open(info) as src:
                data = src.read(info.file_size + 1)
            if len(data) > info.file_size:
                raise InputError("a table in the zip is larger than it says", file=name, field=base)
            (folder / _safe_name(base)).write_bytes(data)


def _yaml_document(data: Any, kind: str, name: str, path: Path) -> tuple[dict[str, Any], list[str]]:
    """The editable mapping of a YAML/JSON upload read once as ``data``."""
    from trainsim.io import loader

    schema = data.get("schema") if isinstance(data, dict) else None
    if schema == f"trainsim/{kind}":
        return data, []
    if schema == "trainsim/scenario":
        inline = data.get(kind)
        if not isinstance(inline, dict):
            raise InputError(
                f"this scenario names its {kind} file; open the {kind} file itself",
                file=name,
                field=kind,
                value=inline,
            )
        return {"schema": f"trainsim/{kind}", "version": 1, **inline}, []
    detected = loader.detect_format(path)
    if detected.kind != kind:
        raise InputError(
            f"this is a {detected.kind} file ({detected.format}), expected a {kind} file",
            file=name,
            field="schema",
            allowed=f"a {kind} file: trainsim/{kind}, trainsim/scenario with an inline {kind}, "
            + (
                "railtoolkit/rolling-stock, ttobench/train"
                if kind == "train"
                else "railtoolkit/running-path, ttobench/track"
            ),
        )
    if kind == "train":
        train = loader.load_train(path)
        mapping, notes = train_to_dict(train)
        return mapping, [f"read as {detected.format}", *notes]
    route = loader.load_route(path)
    return route_to_dict(route), [f"read as {detected.format}"]


def _read_upload(
    kind: str, content: bytes, name: str, limits: WebSettings, folder: Path
) -> tuple[Any, list[str]]:
    suffix = PurePosixPath(_safe_name(name)).suffix.lower()
    if suffix not in UPLOAD_SUFFIXES and suffix != ".csv":
        raise InputError(
            "unknown kind of file",
            file=name,
            value=suffix or "(no ending)",
            allowed=", ".join(f"{k} ({v})" for k, v in UPLOAD_SUFFIXES.items()),
        )
    if suffix == ".csv":
        raise InputError(
            "a CSV file holds one table",
            file=name,
            allowed="a zip of the folder holding the tables (train.csv, vehicles.csv, traction.csv, braking.csv; "
            "route.csv, stations.csv, sections.csv)",
        )
    path = folder / f"upload{suffix}"
    path.write_bytes(content)
    if suffix in (".yaml", ".yml", ".json"):
        try:
            content.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError("not a text file in UTF-8", file=name) from exc
        data = tsy.read_yaml(path)
        guard.check_document(data, limits, file=name)
        return _yaml_document(data, kind, name, path)
    from trainsim.io import convert as interchange

    source: Path = path
    if suffix in (".xml", ".railml") and interchange.detect_interchange(path) is None:
        raise InputError(
            "not a railML file",
            file=name,
            allowed="an XML file whose root element is <railml> (railML 2.x) or <railML> (railML 3.x)",
        )
    if suffix == ".zip":
        source = folder / "tables"
        source.mkdir()
        _unzip_tables(path, source, limits, name)
    docs, notes, fmt = interchange.read_documents(source, kind)  # type: ignore[arg-type]
    if kind not in docs:
        raise InputError(f"no {kind} in this file", file=name, value=fmt, allowed=f"a file with a {kind}")
    return docs[kind], [f"read as {fmt}", *notes]


def _renamed(exc: InputError, folder: Path, name: str) -> InputError:
    """The error with the temporary file's path replaced by the uploaded file's name."""
    from trainsim.errors import Problem
    from trainsim.web.errors import problems_of

    prefix = str(folder)
    problems = []
    for p in problems_of(exc):
        file = p.file
        if file and file.startswith(prefix):
            file = name
        problems.append(
            Problem(p.reason, file=file or name, line=p.line, field=p.field, value=p.value, allowed=p.allowed)
        )
    return InputError.from_problems(problems)


def upload(kind: str, content: bytes, name: str, limits: WebSettings) -> tuple[Loaded, bytes]:
    """An uploaded train or route file (``kind``) of any format trainsim reads, read once, with
    the answer body. Messages name the file as uploaded."""
    with tempfile.TemporaryDirectory(prefix="trainsim-web-") as tmp:
        folder = Path(tmp)
        try:
            mapping, notes = _read_upload(kind, content, name, limits, folder)
            guard.check_document(mapping, limits, file=name)
            if kind == "train":
                loaded = loaded_train(mapping, name, notes)
                return loaded, _dumps(train_payload(spec_dict(loaded.spec), loaded), "train")
            loaded = loaded_route(mapping, name, notes)
            _check_route(loaded, limits, name)
            return loaded, _dumps(route_payload(spec_dict(loaded.spec), loaded), "route")
        except InputError as exc:
            raise _renamed(exc, folder, name) from exc


# ====================================================================== runs
def run(
    strategy_name: str | strategies.Strategy,
    params: dict[str, Any],
    train: Train,
    route: Route,
    settings: RunSettings,
    max_plot_points: int,
) -> tuple[RunResult, bytes]:
    """A run, and its answer body without the run's id and label (:func:`payloads.run_body`).

    ``strategy_name`` is a name registered when trainsim is imported (the worker processes know
    those), or the :class:`~trainsim.web.strategies.Strategy` itself (strategies registered later
    run in the server process)."""
    if isinstance(strategy_name, strategies.Strategy):
        strategy: strategies.Strategy | None = strategy_name
    else:
        strategy = strategies.get(strategy_name)
    if strategy is None:
        raise InputError("unknown strategy", field="strategy", value=strategy_name)
    result = strategy.run(train, route, settings, strategy.params.model_validate(params))
    return result, _dumps(run_body(result, route, max_plot_points), "run")


def warm() -> None:
    """Compile the kernels once (the fork server does it, so every worker starts warm)."""
    from trainsim.sim.fastest import run_fastest
    from trainsim.web.examples import route_spec, train_spec

    try:
        train = train_spec("metro_b").to_train("warm-up")
        route = route_spec("metro_b").to_route("warm-up")
        run_fastest(train, route, RunSettings(max_step_m=50.0))
    except Exception:  # warming up is an optimisation only
        pass


def energy_time(train: Train, route: Route, settings: RunSettings, supplements_percent: list[float]) -> bytes:
    """The optimal strategy's net energy against running time for line supplements [%], as the
    answer body ``{"points": [{supplement_percent, running_time_s, energy_kwh, energy_traction_kwh}]}``."""
    try:
        from trainsim.optimize.api import energy_time_curve
    except ImportError as exc:
        raise InputError(
            "the optimizer is not installed", allowed="pip install 'trainsim[optimize]'"
        ) from exc
    frame = energy_time_curve(train, route, [x / 100.0 for x in supplements_percent], settings)
    return _dumps({"points": frame.to_dict(orient="records")}, "energy-time curve")


#: multi-point scenarios shipped with the web application (example_files/heavy_haul)
MULTIPOINT_EXAMPLES: dict[str, str] = {
    "heavy_haul_dp": "scenario_dp.yaml",
    "heavy_haul_head": "scenario_head.yaml",
}


def multipoint_example(name: str, max_columns: int = 400) -> bytes:
    """A shipped multi-point scenario run (per-vehicle masses and forces, couplers with slack):
    the coupler-force heat map (at most ``max_columns`` instants), the extreme couplers, and the
    run's figures, as the answer body."""
    import trainsim
    from trainsim.web.examples import EXAMPLES_DIR

    if name not in MULTIPOINT_EXAMPLES:
        raise InputError(
            "no such multi-point example", field="name", value=name, allowed=", ".join(MULTIPOINT_EXAMPLES)
        )
    result = trainsim.run(trainsim.load_scenario(EXAMPLES_DIR / "heavy_haul" / MULTIPOINT_EXAMPLES[name]))
    return _multipoint_body(result, name, MULTIPOINT_EXAMPLES[name], max_columns)


def _multipoint_body(result: Any, name: str, scenario: str, max_columns: int) -> bytes:
    """The answer body of a multi-point run: figures, extreme couplers, the heat map."""
    import numpy as np

    forces = np.asarray(result.coupler_force_n)  # (instants, couplers) [N]
    step = max(1, len(forces) // max_columns)
    rows = slice(None, None, step)

    def extreme(ext: Any) -> dict[str, Any]:
        return {
            "force_kn": ext.force_n / 1e3,
            "coupler": int(ext.coupler),
            "behind_vehicle": ext.behind_vehicle,
            "time_s": ext.time_s,
            "head_position_m": ext.head_position_m,
        }

    run = result.run
    body = {
        "name": name,
        "scenario": scenario,
        "train": run.train_name,
        "route": run.route_name,
        "status": result.status,
        "warnings": list(result.warnings),
        "vehicles": int(forces.shape[1] + 1),
        "locomotives": [int(i) for i in result.mptrain.locomotive_indices],
        "running_time_s": run.running_time_s,
        "energy_net_kwh": run.energy_kwh.net,
        "max_draft": extreme(result.max_draft),
        "max_buff": extreme(result.max_buff),
        "heatmap": {
            "time_s": np.round(np.asarray(result.time_s)[rows], 2).tolist(),
            "head_position_m": np.round(np.asarray(result.head_position_m)[rows], 1).tolist(),
            "force_kn": np.round(forces[rows].T / 1e3, 1).tolist(),  # (couplers, instants)
        },
    }
    return _dumps(body, "multi-point run")


#: files a multi-point upload may hold (the scenario, its train and route, a speed profile)
_MULTIPOINT_FILES = (".yaml", ".yml", ".json", ".csv")


def _unzip_scenario(archive: Path, folder: Path, limits: WebSettings, name: str) -> None:
    """Extract a zipped scenario folder (flat names, YAML/JSON/CSV only, bounded in count and size)."""
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError("not a readable zip file", file=name, allowed="a zip of a scenario folder") from exc
    with zf:
        entries = [
            i
            for i in zf.infolist()
            if not i.is_dir() and PurePosixPath(i.filename).suffix.lower() in _MULTIPOINT_FILES
        ]
        if len(entries) > 16:
            raise InputError("too many files in the zip", file=name, value=len(entries), allowed="at most 16")
        if sum(i.file_size for i in entries) > 4 * limits.max_body_bytes:
            raise InputError(
                "the zip's files are too large", file=name, allowed=f"at most {4 * limits.max_body_bytes} bytes"
            )
        for info in entries:
            base = _safe_name(PurePosixPath(info.filename).name)
            with zf.open(info) as src:
                data = src.read(info.file_size + 1)
            if len(data) > info.file_size:
                raise InputError("a file in the zip is larger than it says", file=name, field=base)
            (folder / base).write_bytes(data)


def _scenario_file(folder: Path, name: str) -> Path:
    candidates = sorted(
        p for p in folder.iterdir() if p.suffix.lower() in (".yaml", ".yml") and p.name.startswith("scenario")
    )
    if len(candidates) != 1:
        raise InputError(
            "the zip must hold exactly one scenario file",
            file=name,
            value=[p.name for p in candidates],
            allowed="one file named scenario*.yaml, with the train, route and profile files it names",
        )
    return candidates[0]


def _in_upload(exc: InputError, folder: Path, name: str) -> InputError:
    """The error with the temporary folder replaced by the uploaded file's name (``x.zip/train.yaml``)."""
    from trainsim.errors import Problem
    from trainsim.web.errors import problems_of

    prefix = str(folder)
    problems = []
    for p in problems_of(exc):
        file = p.file or name
        if file.startswith(prefix):
            inner = file[len(prefix) :].lstrip("/")
            file = name if inner in ("", "scenario.yaml") and not name.endswith(".zip") else f"{name}/{inner}"
        problems.append(Problem(p.reason, file=file, line=p.line, field=p.field, value=p.value, allowed=p.allowed))
    return InputError.from_problems(problems)


def multipoint_upload(content: bytes, name: str, limits: WebSettings, max_columns: int = 400) -> bytes:
    """An uploaded multi-point scenario, read as ``trainsim run`` reads it and run: a scenario YAML
    with ``model: multi_point`` and its train and route inline, or a zip of a scenario folder
    (``scenario*.yaml`` with the train, route and profile files it names). The answer body is that
    of :func:`multipoint_example`; messages name the uploaded file (``x.zip/train.yaml``)."""
    from trainsim.io.multipoint_spec import load_multipoint_scenario, run_multipoint_scenario
    from trainsim.io.trainsim_yaml import read_yaml

    with tempfile.TemporaryDirectory(prefix="trainsim-web-") as tmp:
        folder = Path(tmp)
        try:
            safe = _safe_name(name)
            if safe.lower().endswith(".zip"):
                archive = folder / "upload.zip"
                archive.write_bytes(content)
                source = folder / "scenario"
                source.mkdir()
                _unzip_scenario(archive, source, limits, name)
                path = _scenario_file(source, name)
                folder = source
            else:
                if PurePosixPath(safe).suffix.lower() not in (".yaml", ".yml", ".json"):
                    raise InputError(
                        "not a scenario file",
                        file=name,
                        allowed="a scenario .yaml (train and route inline) or a .zip of a scenario folder",
                    )
                path = folder / "scenario.yaml"
                path.write_bytes(content)
            for document in sorted(folder.iterdir()):
                if document.suffix.lower() in (".yaml", ".yml", ".json"):
                    guard.check_document(read_yaml(document), limits, file=str(document))
            scenario, spec = load_multipoint_scenario(path)
            if spec is None:
                raise InputError(
                    "this scenario does not choose the multi-point model",
                    file=str(path),
                    field="model",
                    allowed="model: multi_point",
                )
            route = scenario.route
            if route.end_m - route.start_m > limits.max_route_length_m:
                raise InputError(
                    "route too long for the web application",
                    file=str(path),
                    field="route",
                    value=route.end_m - route.start_m,
                    allowed=f"at most {limits.max_route_length_m:g} m",
                )
            result = run_multipoint_scenario(scenario, spec, base_dir=folder)
            return _multipoint_body(result, "upload", name, max_columns)
        except InputError as exc:
            raise _in_upload(exc, folder, name) from exc


#: operation files shipped with the web application (example_files/operations)
OPERATION_EXAMPLES: dict[str, str] = {"metro_fixed_block": "metro_fixed_block.yaml"}


def operation_example(name: str, max_points: int = 400) -> bytes:
    """A shipped operation run as ``trainsim operate`` runs it: the train graph (every train's line
    position over time, at most ``max_points`` per train) with the operated blocking times (one
    rectangle per resource and train: from_m..to_m over start_s..end_s), the stations, conflicts
    and the status, as the answer body."""
    import numpy as np

    from trainsim.io.operation_file import read_operation
    from trainsim.io.operation_run import run_operation
    from trainsim.web.examples import EXAMPLES_DIR

    if name not in OPERATION_EXAMPLES:
        raise InputError(
            "no such operation example", field="name", value=name, allowed=", ".join(OPERATION_EXAMPLES)
        )
    op = read_operation(EXAMPLES_DIR / "operations" / OPERATION_EXAMPLES[name])
    result = run_operation(op)
    trains = []
    for t in result.trains:
        tr = t.trajectory if t.trajectory is not None else t.planned_trajectory
        keep = np.unique(np.linspace(0, len(tr.time_s) - 1, min(max_points, len(tr.time_s))).round().astype(int))
        position = np.asarray(op.line.line_position(t.direction, tr.position_m[keep]), dtype=float)
        trains.append(
            {
                "id": t.id,
                "direction": str(t.direction),
                "status": t.status,
                "delay_s": t.delay_s,
                "time_s": np.round(tr.time_s[keep], 1).tolist(),
                "position_m": np.round(position, 1).tolist(),
            }
        )
    body = {
        "name": name,
        "title": op.name,
        "status": result.status,
        "warnings": list(result.warnings),
        "signalling": op.line.signalling.system,
        "line_length_m": op.line.length_m,
        "stations": [{"name": s.name, "position_m": s.position_m} for s in op.line.stations],
        "trains": trains,
        "blocking": [
            {"train": b.train, "start_s": b.start_s, "end_s": b.end_s, "from_m": b.from_m, "to_m": b.to_m}
            for b in result.blocking
        ],
        "conflicts": len(result.conflicts),
    }
    return _dumps(body, "operation run")
