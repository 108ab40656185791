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
import re
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


def _zip_member(filename: str, name: str) -> PurePosixPath:
    """A zip entry's path inside the upload, refused (InputError) when absolute or leaving the
    zip's folder: an upload's files never land outside its own temporary folder."""
    path = filename.replace("\\", "/")
    if path.startswith("/") or re.match(r"^[A-Za-z]:", path):
        raise InputError(
            "an absolute path in the zip",
            file=name,
            field=filename[:200],
            allowed="paths relative to the zip",
        )
    parts = PurePosixPath(path).parts
    if ".." in parts:
        raise InputError(
            "a path in the zip leaves its folder ('..')",
            file=name,
            field=filename[:200],
            allowed="paths inside the zip",
        )
    if len(path) > 240 or len(parts) > 8 or any(c < " " for c in path):
        raise InputError(
            "an unusual path in the zip",
            file=name,
            field=filename[:200],
            allowed="at most 8 folders deep, 240 characters, no control characters",
        )
    return PurePosixPath(*(p for p in parts if p != "."))


def _unzip_scenario(
    archive: Path,
    folder: Path,
    limits: WebSettings,
    name: str,
    suffixes: tuple[str, ...] = (".yaml", ".yml", ".json", ".csv"),
    keep_folders: bool = False,
) -> None:
    """Extract a zipped scenario folder: files with ``suffixes`` only, bounded in count and size.
    ``keep_folders``: keep the zip's folders (each path checked by :func:`_zip_member`), for files
    that name each other by relative paths; else flat names (a multi-point scenario folder)."""
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError("not a readable zip file", file=name, allowed="a zip of a scenario folder") from exc
    most = limits.max_upload_files if keep_folders else 16
    with zf:
        entries = [
            i
            for i in zf.infolist()
            if not i.is_dir() and PurePosixPath(i.filename).suffix.lower() in suffixes
        ]
        if len(entries) > most:
            raise InputError(
                "too many files in the zip", file=name, value=len(entries), allowed=f"at most {most}"
            )
        if sum(i.file_size for i in entries) > 4 * limits.max_body_bytes:
            raise InputError(
                "the zip's files are too large",
                file=name,
                allowed=f"at most {4 * limits.max_body_bytes} bytes",
            )
        written: set[PurePosixPath] = set()
        for info in entries:
            if keep_folders:
                if (info.external_attr >> 16) & 0o170000 == 0o120000:
                    raise InputError(
                        "a symbolic link in the zip",
                        file=name,
                        field=info.filename[:200],
                        allowed="plain files",
                    )
                inner = _zip_member(info.filename, name)
                if inner in written:
                    raise InputError("a file twice in the zip", file=name, field=info.filename[:200])
                written.add(inner)
                target = folder / inner
                if not target.resolve().is_relative_to(folder.resolve()):
                    raise InputError(
                        "a path in the zip leaves its folder", file=name, field=info.filename[:200]
                    )
                target.parent.mkdir(parents=True, exist_ok=True)
            else:
                target = folder / _safe_name(PurePosixPath(info.filename).name)
            try:
                with zf.open(info) as src:
                    data = src.read(info.file_size + 1)
            except (zipfile.BadZipFile, OSError, NotImplementedError, RuntimeError, EOFError) as exc:
                raise InputError(
                    f"a file in the zip cannot be read ({type(exc).__name__})",
                    file=name,
                    field=info.filename[:200],
                    allowed="stored or deflated files, not encrypted",
                ) from exc
            if len(data) > info.file_size:
                raise InputError("a file in the zip is larger than it says", file=name, field=target.name)
            target.write_bytes(data)


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


def _in_upload(exc: InputError, folder: Path, name: str, single: str = "scenario.yaml") -> InputError:
    """The error with the temporary folder replaced by the uploaded file's name (``x.zip/train.yaml``);
    ``single`` is the name a plain (not zipped) upload was written under."""
    from trainsim.errors import Problem
    from trainsim.web.errors import problems_of

    prefix = str(folder)
    problems = []
    for p in problems_of(exc):
        file = p.file or name
        if file.startswith(prefix):
            inner = file[len(prefix) :].lstrip("/")
            file = name if inner in ("", single) and not name.endswith(".zip") else f"{name}/{inner}"
        problems.append(
            Problem(p.reason, file=file, line=p.line, field=p.field, value=p.value, allowed=p.allowed)
        )
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


#: operation files shipped with the web application (example_files/operations, copies of the repository's
#: examples/operations; the trains those name from tests/data/trainruns are in example_files/trainruns)
OPERATION_EXAMPLES: dict[str, tuple[str, str]] = {
    "metro_fixed_block": ("metro_fixed_block.yaml", "metro line B, 14 trains, 3-aspect fixed block"),
    "metro_cbtc": ("metro_cbtc.yaml", "metro line B, 12 trains, CBTC moving block"),
    "metro_disturbed": ("metro_disturbed.yaml", "metro line B, 14 trains, seeded disturbances (one day)"),
    "single_track": ("single_track.yaml", "single-track branch, 5 trains crossing at loops (conflicts)"),
    "single_track_tracks": ("single_track_tracks.yaml", "single-track branch with its tracks drawn in"),
    "main_line_mixed": ("main_line_mixed.yaml", "double-track main line, 7 mixed trains overtaking"),
    "main_line_etcs": ("main_line_etcs.yaml", "double-track main line, 3 trains, ETCS Level 2"),
    "branch_line_railml": ("branch_line_railml.yaml", "single-track branch read from railML, 3 trains"),
    "metro_eco": ("metro_eco.yaml", "metro line B, 2 trains driven energy-efficiently (a conflict)"),
    "sheets_double_track": (
        "sheets_double_track/operation.yaml",
        "double-track line from spreadsheet tables, 5 trains",
    ),
}

#: files an operation upload may hold: the operation, trains, routes, railML and spreadsheet lines
_OPERATION_FILES = (".yaml", ".yml", ".json", ".csv", ".xml", ".railml", ".xlsx", ".xlsm")


def _operation_run(
    path: Path, name: str, max_points: int, root: tuple[Path, str], limits: WebSettings | None = None
) -> bytes:
    """Read an operation file with the command line's reader and run it as ``trainsim operate`` does:
    the train graph, delays and headways (:func:`trainsim.web.operation_payload.operation_body`). The
    readers' warnings (defaults they assumed) are the answer's warnings too, with the folder
    ``root[0]`` shown as ``root[1]``; ``limits``: also bound the line's length (an upload)."""
    import warnings

    from trainsim.io.operation_file import read_operation
    from trainsim.io.operation_run import run_operation
    from trainsim.web.operation_payload import operation_body

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        op = read_operation(path)
    if limits is not None and op.line.length_m > limits.max_route_length_m:
        raise InputError(
            "line too long for the web application",
            file=str(path),
            field="line",
            value=op.line.length_m,
            allowed=f"at most {limits.max_route_length_m:g} m",
        )
    body = operation_body(name, op.name, op.line, run_operation(op), max_points)
    read = [str(w.message).replace(str(root[0]), root[1]) for w in caught]
    body["warnings"] = [*dict.fromkeys(read), *body["warnings"]]
    return _dumps(body, "operation run")


def operation_example(name: str, max_points: int = 400) -> bytes:
    """A shipped operation run as ``trainsim operate`` runs it, as the answer body."""
    from trainsim.web.examples import EXAMPLES_DIR

    if name not in OPERATION_EXAMPLES:
        raise InputError(
            "no such operation example", field="name", value=name, allowed=", ".join(OPERATION_EXAMPLES)
        )
    path = EXAMPLES_DIR / "operations" / OPERATION_EXAMPLES[name][0]
    return _operation_run(path, name, max_points, (EXAMPLES_DIR, "examples"))


def _operation_file(folder: Path, name: str, limits: WebSettings) -> tuple[Path, Any]:
    """The one ``trainsim/operation`` document of an upload (every YAML/JSON file bounded by the
    guard first), with its data."""
    found = []
    for document in sorted(folder.rglob("*")):
        if document.is_file() and document.suffix.lower() in (".yaml", ".yml", ".json"):
            data = tsy.read_yaml(document)
            guard.check_document(data, limits, file=str(document))
            if isinstance(data, dict) and data.get("schema") == "trainsim/operation":
                found.append((document, data))
    if len(found) != 1:
        raise InputError(
            "the upload must hold exactly one operation file",
            file=name,
            field="schema",
            value=[str(p.relative_to(folder)) for p, _ in found],
            allowed="one YAML file with 'schema: trainsim/operation', with the train and route files it names",
        )
    return found[0]


def _check_operation_upload(path: Path, data: dict[str, Any], folder: Path, limits: WebSettings) -> None:
    """Bounds of an uploaded operation before it is read: every file it names lies inside the
    upload, and it has at most ``max_operation_trains`` trains (``repeat`` counts summed)."""
    from trainsim.errors import Problem
    from trainsim.io.operation_file import _line_of

    text = path.read_text(encoding="utf-8", errors="replace")
    line = data.get("line") if isinstance(data.get("line"), dict) else {}
    trains = data.get("trains") if isinstance(data.get("trains"), list) else []
    named: list[tuple[str, list[Any], Any]] = [("line.route", ["line", "route"], line.get("route"))]
    for key in ("railml", "spreadsheet"):
        if isinstance(line.get(key), dict):
            named.append((f"line.{key}.file", ["line", key, "file"], line[key].get("file")))
    named += [
        (f"trains[{i}].train", ["trains", i, "train"], t.get("train"))
        for i, t in enumerate(trains)
        if isinstance(t, dict)
    ]
    problems = []
    inside = folder.resolve()

    def outside(ref: str) -> bool:
        try:
            target = (path.parent / ref).resolve()
            target.exists()  # a name the system refuses (too long) is no file of the upload either
            return not target.is_relative_to(inside)
        except (ValueError, OSError):  # a NUL character, a name too long
            return True

    for field, loc, ref in named:
        if isinstance(ref, str) and outside(ref):
            problems.append(
                Problem(
                    "a file named outside the upload (or a path no file can have)",
                    file=str(path),
                    line=_line_of(text, loc),
                    field=field,
                    value=ref[:200],
                    allowed="a path relative to the operation file, to a file inside the upload "
                    "(upload a zip holding the operation file and the train and route files it names)",
                )
            )
    if problems:
        raise InputError.from_problems(problems)
    count = 0
    for t in trains:
        repeat = t.get("repeat") if isinstance(t, dict) else None
        times = repeat.get("count") if isinstance(repeat, dict) else 1
        count += times if isinstance(times, int) and times > 0 else 1
    if count > limits.max_operation_trains:
        raise InputError(
            "too many trains for the web application",
            file=str(path),
            field="trains",
            value=count,
            allowed=f"at most {limits.max_operation_trains} trains (repeat counts summed); "
            "run larger days with trainsim operate",
        )


def operation_upload(content: bytes, name: str, limits: WebSettings, max_points: int = 400) -> bytes:
    """An uploaded operation (``schema: trainsim/operation``), read as ``trainsim operate`` reads it and
    run: a YAML file, or a zip holding it with the files it names (folders kept, so that relative
    paths such as ``../metro_b/train.yaml`` work inside the zip). The answer body is that of
    :func:`operation_example`; messages name the file inside the upload (``x.zip/op.yaml``)."""
    with tempfile.TemporaryDirectory(prefix="trainsim-web-") as tmp:
        folder = Path(tmp)
        single = "operation.yaml"
        try:
            safe = _safe_name(name)
            if safe.lower().endswith(".zip"):
                archive = folder / "upload.zip"
                archive.write_bytes(content)
                folder = folder / "files"
                folder.mkdir()
                _unzip_scenario(archive, folder, limits, name, _OPERATION_FILES, keep_folders=True)
            else:
                if PurePosixPath(safe).suffix.lower() not in (".yaml", ".yml", ".json"):
                    raise InputError(
                        "not an operation file",
                        file=name,
                        value=PurePosixPath(safe).suffix or "(no ending)",
                        allowed="an operation .yaml, or a .zip holding it with the train and route files it names",
                    )
                folder = folder / "files"
                folder.mkdir()
                (folder / single).write_bytes(content)
            path, data = _operation_file(folder, name, limits)
            _check_operation_upload(path, data, folder, limits)
            return _operation_run(path, "upload", max_points, (folder, name), limits)
        except InputError as exc:
            raise _in_upload(exc, folder, name, single) from exc
