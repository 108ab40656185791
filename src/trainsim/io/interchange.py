"""railML and spreadsheet files behind the loaders: what a file is, reading it, ``trainsim check``.

The readers of railML 2 (:mod:`trainsim.io.railml2`), railML 3 (:mod:`trainsim.io.railml3`) and
spreadsheets (:mod:`trainsim.io.spreadsheet`) give a :class:`~trainsim.io.railml_common.Content` (trainsim
train / route mappings with notes); this module detects the format from the content, reads it and
builds the model objects (:func:`detect_and_load`, the loaders' hook) or the check report
(:func:`check_file`). Converting between formats is :mod:`trainsim.io.convert`, above the loaders.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from trainsim.errors import InputError
from trainsim.io.railtoolkit_names import MASS_MODELS
from trainsim.io.report import CheckReport, route_figures, train_figures

if TYPE_CHECKING:
    from trainsim.io.railml_common import Content


class _RailmlCommon:
    """``trainsim.io.railml_common``, imported on first use: it needs lxml (the ``interchange`` extra),
    which a light install reading only YAML and JSON files does not have."""

    def __getattr__(self, name: str) -> Any:
        from trainsim.io import railml_common

        return getattr(railml_common, name)


rc = _RailmlCommon()

__all__ = [
    "Format",
    "Kind",
    "check_file",
    "detect_and_load",
    "detect_interchange",
    "read_content",
]

Kind = Literal["train", "route", "scenario"]
Format = Literal["railml2", "railml3", "spreadsheet"]

#: mass models of railtoolkit / TrainRuns.jl -> where line resistance applies
_MASS_MODELS = MASS_MODELS


def detect_interchange(path: str | Path) -> Format | None:
    """``railml2``, ``railml3`` or ``spreadsheet`` from the content, or None for other files."""
    p = Path(path)
    try:
        p.is_dir()
    except (OSError, ValueError) as exc:  # a name too long, a NUL byte in it...
        raise InputError("not a usable file name", file=str(path)[:200], allowed="a path to a file") from exc
    if p.is_dir():
        # the spreadsheet reader (and lxml behind it) is imported only for what may be a spreadsheet:
        # a light install without the interchange extra reads YAML and JSON files
        from trainsim.io import spreadsheet

        return "spreadsheet" if spreadsheet.is_spreadsheet(p) else None
    if not p.is_file():
        return None
    if p.suffix.lower() in (".xlsx", ".xlsm"):  # spreadsheet.EXCEL_SUFFIXES
        return "spreadsheet"
    try:
        with p.open("rb") as fh:
            head = fh.read(2048)
    except OSError:
        return None
    if p.suffix.lower() == ".csv":
        return "spreadsheet"
    text = head.lstrip(b"\xef\xbb\xbf").lstrip()
    if not text.startswith(b"<"):
        return None
    from trainsim.io.documents import read_xml

    root = read_xml(p).getroot()  # an XML file that is malformed or hostile: its error, not YAML's
    tag = rc.local(root)
    version = root.get("version") or ""
    if tag == "railml":
        return "railml2"
    if tag == "railML":
        return "railml3" if not version.startswith("2") else "railml2"
    return None


def _options(options: dict[str, Any]) -> dict[str, Any]:
    """Reader options, with ``mass_model`` and the formula keys folded into ``line_resistance``."""
    opts = {k: v for k, v in options.items() if v is not None}
    lr = dict(opts.pop("line_resistance", None) or {})
    for key in ("curve_formula", "tunnel_formula", "gradient_formula", "apply_over"):
        if key in opts:
            lr[key] = opts.pop(key)
    mass_model = opts.pop("mass_model", None)
    if mass_model is not None:
        if mass_model not in _MASS_MODELS:
            raise InputError(
                "unknown mass model", field="mass_model", value=mass_model, allowed=", ".join(_MASS_MODELS)
            )
        lr["apply_over"] = _MASS_MODELS[mass_model]
    if isinstance(opts.get("ocps"), str):
        opts["ocps"] = [x.strip() for x in opts["ocps"].split(",") if x.strip()]
    if lr:
        opts["line_resistance"] = lr
    return opts


def read_content(path: str | Path, fmt: Format | None = None, **options: Any) -> Content:
    """Read a railML or spreadsheet file into trainsim YAML mappings (see the module docstring
    for the options)."""
    from trainsim.io import railml2, railml3, spreadsheet

    fmt = fmt or detect_interchange(path)
    opts = _options(options)
    if fmt == "railml2":
        return railml2.read_railml2(path, **opts)
    if fmt == "railml3":
        return railml3.read_railml3(path, **opts)
    if fmt == "spreadsheet":
        p = Path(path)
        if p.is_file() and p.suffix.lower() == ".csv":
            raise InputError(
                "a CSV file holds one table; give the folder holding the tables (train.csv, vehicles.csv, "
                "traction.csv, braking.csv; route.csv, stations.csv, sections.csv)",
                file=str(path),
            )
        unknown = set(opts) - {"line_resistance"}
        if unknown:
            raise InputError(
                "option not used by spreadsheets",
                file=str(path),
                field=sorted(unknown)[0],
                allowed="line_resistance",
            )
        return spreadsheet.read_spreadsheet(path, line_resistance=opts.get("line_resistance"))
    raise InputError("not a railML or spreadsheet file", file=str(path))


def detect_and_load(path: str | Path, kind: str, **options: Any) -> Any:
    """The loader's hook: a Train (``kind="train"``), Route (``"route"``) or Scenario
    (``"scenario"``, train and route from the same file) read from a railML or spreadsheet file,
    or None when the file is not one of these formats (the loader then reads it as YAML)."""
    fmt = detect_interchange(path)
    if fmt is None:
        return None
    if kind == "train" and fmt != "spreadsheet":
        options.setdefault("require_line_resistance", False)  # the route is not wanted
    content = read_content(path, fmt, **options)
    if kind == "train":
        return rc.build_train(content)
    if kind == "route":
        return rc.build_route(content)
    if kind == "scenario":
        from trainsim.model.scenario import Scenario

        train, route = rc.build_train(content), rc.build_route(content)
        return Scenario(name=f"{train.name} on {route.name}", train=train, route=route)
    raise InputError(
        f"this is a {fmt} file; expected a {kind} file", file=str(path), allowed="train, route, scenario"
    )


def check_file(path: str | Path, **options: Any) -> Any:
    """``trainsim check`` for railML and spreadsheet files: a :class:`~trainsim.io.report.CheckReport`
    (what was read, readings, what was not read with its line), or None for other formats.
    Line-resistance formulas are not required here (the report says when they are missing)."""
    fmt = detect_interchange(path)
    if fmt is None:
        return None
    opts = _options(options)
    if fmt != "spreadsheet":
        opts.setdefault("require_line_resistance", False)
    content = read_content(path, fmt, **opts)
    figures = dict(content.figures)
    kinds = []
    name = Path(path).stem
    if content.train is not None:
        train = rc.build_train(content)
        figures.update({f"train {k}": v for k, v in train_figures(train).items()})
        kinds.append("train")
        name = train.name
    if content.route is not None:
        route = rc.build_route(content)
        figures.update({f"route {k}": v for k, v in route_figures(route).items()})
        kinds.append("route")
        name = route.name if not kinds[:-1] else f"{name} on {route.name}"
    notes = list(content.notes) + [f"not read: {x}" for x in content.ignored]
    kind = " and ".join(kinds) or "nothing usable"
    return CheckReport(str(path), kind, content.format, name, figures, notes)
