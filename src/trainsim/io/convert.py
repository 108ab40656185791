"""Any readable input to trainsim's YAML, and format detection for railML and spreadsheets.

* :func:`detect_interchange` says whether a path is railML 2, railML 3 or a spreadsheet (by its
  content: the XML root element and its version; a workbook or a folder of CSV tables).
* :func:`read_content` reads such a file into trainsim YAML mappings (:class:`Content`), with
  notes on the readings made and the elements not read (with their lines).
* :func:`detect_and_load` is the hook of :mod:`trainsim.io.loader`: a Train, Route or Scenario
  from an interchange file, or None if the file is of another format.
* :func:`convert` writes any readable input (railML, spreadsheets, trainsim and railtoolkit YAML)
  as trainsim YAML: a train, a route, or a scenario holding both.
* :func:`check_file` is ``trainsim check`` for interchange files.

Reader options (all formats that need them; see :func:`trainsim.io.railml2.read_railml2`):
``train_id``, ``formation_id``, ``ocps``, ``line_resistance`` (``curve_formula``,
``tunnel_formula``, ``gradient_formula``, ``apply_over``), ``rotating_mass_factor``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from trainsim.errors import InputError

# The readers behind the loaders live in trainsim.io.interchange; they are re-exported here, where
# they were first (convert sits above the loaders: it reads any format to write another).
from trainsim.io.interchange import (
    Format,
    Kind,
    check_file,
    detect_and_load,
    detect_interchange,
    rc,
    read_content,
)

__all__ = [
    "Format",
    "Kind",
    "check_file",
    "convert",
    "detect_and_load",
    "detect_interchange",
    "dump_yaml",
    "read_content",
    "read_documents",
]


def read_documents(
    path: str | Path, kind: Kind | None = None, **options: Any
) -> tuple[dict[str, dict[str, Any]], list[str], str]:
    """Any readable input as validated trainsim YAML mappings: ``({"train": ..., "route": ...},
    notes, format)``. trainsim YAML files are passed through; railtoolkit files are converted
    from the model objects (their fields have no YAML twin)."""
    fmt = detect_interchange(path)
    if fmt is not None:
        if kind == "train" and fmt != "spreadsheet":
            options.setdefault("require_line_resistance", False)
        content = read_content(path, fmt, **options)
        docs: dict[str, dict[str, Any]] = {}
        # building the objects validates the mappings, with errors pointed at the source elements
        if content.train is not None:
            rc.build_train(content)
            docs["train"] = content.train
        if content.route is not None and kind != "train":
            rc.build_route(content)
            docs["route"] = content.route
        notes = list(content.notes) + [f"not read: {x}" for x in content.ignored]
        return docs, notes, content.format
    from trainsim.io import loader
    from trainsim.io import trainsim_yaml as tsy

    if options and any(v is not None for v in options.values()):
        used = [k for k, v in options.items() if v is not None]
        raise InputError(
            "these options apply to railML and spreadsheet inputs", file=str(path), field=used[0]
        )
    detected = loader.detect_format(path)
    if detected.format.startswith("trainsim/"):
        data = tsy.read_yaml(path)
        if detected.kind == "scenario":
            scenario = loader.load_scenario(path)
            train_data = data.get("train")
            notes = ["route written from the scenario's route with its stops and dwell times"]
            if isinstance(train_data, str):
                train_path = Path(path).parent / train_data
                if loader.detect_format(train_path).format == "trainsim/train":
                    train_doc = tsy.read_yaml(train_path)
                else:
                    train_doc = train_document(scenario.train)
                    notes.append("train written from its model object")
            else:
                train_doc = {"schema": "trainsim/train", "version": 1, **train_data}
            return {"train": train_doc, "route": route_document(scenario.route)}, notes, detected.format
        return {detected.kind: data}, [], detected.format
    if detected.kind == "train":
        return (
            {"train": train_document(loader.load_train(path))},
            ["written from the model objects"],
            detected.format,
        )
    if detected.kind == "route":
        return (
            {"route": route_document(loader.load_route(path))},
            ["written from the model objects"],
            detected.format,
        )
    raise InputError("nothing to convert in this file", file=str(path), value=detected.format)


def train_document(train: Any) -> dict[str, Any]:
    """A :class:`~trainsim.model.Train` as a ``trainsim/train`` mapping (through a spreadsheet-
    free, exact route: the railML writer's tables)."""
    import tempfile

    from trainsim.io import railml2

    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "train.xml"
        railml2.write_railml2(f, train=train)
        content = railml2.read_railml2(f)
    assert content.train is not None
    return content.train


def route_document(route: Any) -> dict[str, Any]:
    """A :class:`~trainsim.model.Route` as a ``trainsim/route`` mapping."""
    doc: dict[str, Any] = {
        "schema": "trainsim/route",
        "version": 1,
        "name": route.name,
        "start_m": route.start_m,
        "end_m": route.end_m,
        "stations": [
            {"name": s.name, "position_m": s.position_m, "dwell_s": s.dwell_s, "stop": s.stop}
            for s in route.stations
        ],
        "speed_limits": [
            {"from_m": x.start_m, "to_m": x.end_m, "limit_kmh": x.limit_mps * 3.6} for x in route.speed_limits
        ],
    }
    if route.gradients:
        doc["gradients"] = [
            {"from_m": g.start_m, "to_m": g.end_m, "gradient_permille": g.gradient_permille}
            for g in route.gradients
        ]
    if route.curves:
        doc["curves"] = [{"from_m": c.start_m, "to_m": c.end_m, "radius_m": c.radius_m} for c in route.curves]
    if route.tunnels:
        doc["tunnels"] = [
            {"from_m": t.start_m, "to_m": t.end_m, "limiting_gradient": t.limiting_gradient}
            for t in route.tunnels
        ]
    if route.electrification:
        doc["electrification"] = [
            {"from_m": e.start_m, "to_m": e.end_m, "voltage_v": e.voltage_v}
            # written only where it is not the default, so routes without it read back unchanged
            | ({"traction_share": e.traction_share} if e.traction_share != 1.0 else {})
            for e in route.electrification
        ]
    lr = route.line_resistance
    doc["line_resistance"] = {
        "curve_formula": lr.curve_formula,
        "tunnel_formula": lr.tunnel_formula,
        "gradient_formula": lr.gradient_formula,
        "apply_over": lr.apply_over,
    }
    return doc


class _Dumper(yaml.SafeDumper):
    """Lists of numbers on one line (tables read better so)."""


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = all(isinstance(x, int | float | str | bool) for x in data) and len(data) > 0
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


def _represent_dict(dumper: yaml.SafeDumper, data: dict[str, Any]) -> yaml.Node:
    # short mappings of scalars (stations, sections) on one line
    flow = len(data) <= 6 and all(isinstance(v, int | float | str | bool) for v in data.values())
    return dumper.represent_mapping("tag:yaml.org,2002:map", data, flow_style=flow and "schema" not in data)


_Dumper.add_representer(list, _represent_list)
_Dumper.add_representer(dict, _represent_dict)


def dump_yaml(doc: dict[str, Any], header: Sequence[str] = ()) -> str:
    """A mapping as YAML text, with ``header`` lines as comments at the top."""
    text = yaml.dump(rc.plain(doc), Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=110)
    comments = "".join(f"# {line}\n" for line in header)
    return comments + text


def convert(
    inp: str | Path, out: str | Path, *, kind: Kind | None = None, **options: Any
) -> tuple[Path, list[str]]:
    """Convert any readable input to trainsim YAML.

    Args:
        inp: railML 2 or 3, a workbook or CSV folder, a trainsim or railtoolkit YAML file.
        out: the YAML file to write.
        kind: ``train``, ``route`` or ``scenario`` (default: scenario when the input holds a train
            and a route, else the one it holds). A scenario holds the train and the route inline.
        options: reader options (module docstring).

    Returns:
        The path written and the notes of the conversion (also written as comments at the top).
    """
    docs, notes, fmt = read_documents(inp, kind, **options)
    if kind is None:
        kind = "scenario" if {"train", "route"} <= set(docs) else next(iter(docs))  # type: ignore[assignment]
    if kind == "scenario":
        missing = [k for k in ("train", "route") if k not in docs]
        if missing:
            raise InputError(
                f"a scenario needs a train and a route; the file has no {missing[0]}",
                file=str(inp),
                allowed=", ".join(docs),
            )
        train, route = docs["train"], docs["route"]
        doc: dict[str, Any] = {
            "schema": "trainsim/scenario",
            "version": 1,
            "name": f"{train['name']} on {route['name']}",
            "train": train,
            "route": route,
        }
    elif kind in docs:
        doc = docs[kind]
    else:
        raise InputError(f"the file holds no {kind}", file=str(inp), allowed=", ".join(docs) or "nothing")
    header = [f"converted by trainsim from {Path(inp).name} ({fmt})", *notes]
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dump_yaml(doc, header), encoding="utf-8")
    return path, notes
