"""Trains and tracks as spreadsheet tables (Excel workbooks or folders of CSV files).

The tables are laid out like source 002's (Cui et al.) parameter tables: a parameter table of
two columns (name with its unit in brackets, value), and tables with one column per quantity,
**units in the column headers** (``Velocity (km/h) | Traction force (kN)``). A workbook holds one
sheet per table; a CSV folder one file per table, named after the sheet (``traction.csv``).

Train tables
    * ``train`` (parameters, first column the name, second the value): ``name``,
      ``rotating mass factor`` or ``rotary mass coefficient`` (gamma = factor - 1, source 002),
      ``max speed (km/h)``, ``davis A (kN)``, ``davis B (kN/(km/h))``, ``davis C (kN/(km/h)^2)``
      (also ``basic resistance parameter 1/2/3``; any force per speed unit), ``traction motors``
      (the traction table is per motor), ``traction power (kW)`` and ``max traction force (kN)``
      (power-limited traction at the wheel, without a traction table), ``braking table is``
      (service/full), ``service braking fraction``, ``braking deceleration (m/s^2)`` (instead of a
      braking table), ``regenerative fraction`` (regenerative force = fraction x traction),
      ``line voltage (V)``, ``traction efficiency``, ``regenerative efficiency``, ``power factor``,
      ``auxiliary power (kW)``, ``receptivity``; for a train without vehicle table ``mass (t)``,
      ``load (t)``, ``length (m)``.
    * ``vehicles``: ``name``, ``count``, ``mass (t)``, ``load (t)``, ``length (m)``, ``axles``,
      ``powered`` (yes/no), ``rotating mass factor``, ``max speed (km/h)``.
    * ``traction``, ``braking``, ``regenerative``: ``speed (km/h)``, ``force (kN)`` (braking forces
      may be negative, as source 002 prints them).

Track tables
    * ``route`` (parameters): ``name``, ``curve formula``, ``tunnel formula``, ``gradient formula``,
      ``apply over``, ``start (m)``, ``end (m)`` (default: the end of the last section).
    * ``stations``: ``name``, ``position (m)``, ``dwell (s)``, ``stop`` (yes/no, default yes).
    * ``sections`` (source 002 table 1: accumulated journey, track speed, gradient, curve length
      and central angle, tunnel length): ``from (m)``, ``length (m)`` (or ``to (m)``),
      ``speed limit (km/h)``, ``gradient (‰)``, ``curve radius (m)`` or ``curve central angle
      (deg)`` with ``curve length (m)`` (default: the section's length, from its start),
      ``tunnel length (m)`` (a tunnel from the section's start; touching tunnels are one tunnel),
      ``limiting gradient`` (yes/no), ``voltage (V)``, ``traction share (%)`` (or ‰: the share of
      tractive effort an electric train may use, 0 < share <= 100 %, default 100 %; needs a voltage).

Signalling tables of a line in operation (``line.spreadsheet`` of an operation file, read with the
track tables above by :func:`read_spreadsheet_signalling`; positions are route positions, the
coordinate of the ``stations`` table)
    * ``signals``: ``name``, ``position (m)``, ``direction`` (``up``: governs trains running towards
      increasing positions, ``down``: the other way), ``kind`` (``main``, ``block`` or ``distant``;
      default ``main``). Block signals of a double-track line give its blocks (``block_signals_m``);
      main signals give the stations' entry signal distances and exit signal offsets.
    * ``station tracks`` (or ``station_tracks``): ``station`` (a name of the ``stations`` table),
      ``tracks`` (platform tracks, 1 .. 50; a station not listed has 1).
    * ``detection points`` (or ``detection_points``): ``name``, ``position (m)``, ``kind``
      (``axle_counter``, ``track_circuit_border`` or ``detector``; default ``detector``), ``track``
      (``up``, default, or ``down``: the track of the down direction of a double-track line).
    * ``switches``: ``name``, ``position (m)`` (the blade tip), ``clearance (m)`` (optional: its
      clearance point, towards its station; default the nearest detection point on that side),
      ``track`` (``up``, default, or ``down``), ``diverging speed (km/h)`` (optional: the highest
      speed over its diverging branch; empty: line speed).

Header names are matched without case, spaces or underscores mattering; units are any trainsim
knows (km/h or m/s, t or kg, kN or N, ‰ or %...). A column that needs a unit and has none, an
unknown unit, an unknown column or a cell that is not a number are errors naming the file, the
sheet and the cell.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from trainsim.constants import KMH
from trainsim.errors import InputError, shown_value
from trainsim.io import documents
from trainsim.io import railml_common as rc
from trainsim.io.units import UNITS, Unit, format_units
from trainsim.model import Route, Train, bounds

__all__ = ["is_spreadsheet", "read_spreadsheet", "read_spreadsheet_signalling", "write_spreadsheet"]

TRAIN_SHEETS = ("train", "vehicles", "traction", "braking", "regenerative")
ROUTE_SHEETS = ("route", "stations", "sections")
#: Signalling tables of a line in operation, each under any of its names.
SIGNAL_SHEETS = {
    "signals": ("signals",),
    "station tracks": ("station tracks", "station_tracks"),
    "detection points": ("detection points", "detection_points"),
    "switches": ("switches",),
}
#: Most platform tracks at one station.
MAX_STATION_TRACKS = 50
EXCEL_SUFFIXES = (".xlsx", ".xlsm")

_EXTRA = {"‰": UNITS["‰"], "permil": UNITS["‰"], "o/oo": UNITS["‰"], "m/s/s": UNITS["m/s^2"]}


# ====================================================================== reading cells
@dataclass
class Sheet:
    """One table: its name, where it comes from, its header and rows of raw cell texts."""

    name: str
    source: str  # "file.xlsx, sheet 'traction'" or "dir/traction.csv"
    file: str
    header: list[str]
    rows: list[list[str]]

    def cell(self, row: int, col: int) -> str:
        """Spreadsheet name of a cell, e.g. ``C4`` (row 0 is the first row below the header)."""
        letters = ""
        n = col + 1
        while n:
            n, r = divmod(n - 1, 26)
            letters = chr(65 + r) + letters
        return f"{letters}{row + 2}"

    def error(
        self,
        message: str,
        *,
        row: int | None = None,
        col: int | None = None,
        value: Any = None,
        allowed: str | None = None,
    ) -> InputError:
        if row is None and col is not None:
            where = f"{self.name}!{self.cell(-1, col)} ('{self.header[col]}')"
            line = 1
        elif row is not None and col is not None:
            where = f"{self.name}!{self.cell(row, col)}"
            line = row + 2
        else:
            where, line = self.name, None
        return InputError(message, file=self.source, field=where, value=value, allowed=allowed, line=line)


def _text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        return (
            repr(value) if not value.is_integer() else str(int(value)) if abs(value) < 1e15 else repr(value)
        )
    return str(value).strip()


def _trim(rows: list[list[str]]) -> list[list[str]]:
    rows = [r for r in rows if any(c for c in r)]
    width = max((max((i + 1 for i, c in enumerate(r) if c), default=0) for r in rows), default=0)
    return [[*r[:width], *[""] * (width - len(r))] for r in rows]


def read_sheets(path: str | Path) -> dict[str, Sheet]:
    """The tables of a workbook or of a folder of CSV files, by lower-case sheet name."""
    p = Path(path)
    file = str(path)
    if not p.exists():
        raise InputError("file not found", file=file)
    out: dict[str, Sheet] = {}
    if p.is_dir():
        files = sorted(p.glob("*.csv"))
        if not files:
            raise InputError(
                "no CSV file in this folder", file=file, allowed=", ".join(TRAIN_SHEETS + ROUTE_SHEETS)
            )
        for f in files:
            text = documents.read_text(f)  # bounded size, UTF-8 (an optional BOM dropped)
            try:
                dialect = csv.Sniffer().sniff(text[:4096], delimiters=",;\t")
            except csv.Error:
                dialect = csv.excel
            reader = csv.reader(io.StringIO(text, newline=""), dialect)
            rows = []
            try:
                for r in reader:
                    rows.append([c.strip() for c in r[: MAX_TABLE_COLUMNS + 1]])
                    _check_table_size(len(rows), len(r), str(f), reader.line_num)
            except csv.Error as exc:
                raise InputError(
                    f"not a readable CSV table ({exc})", file=str(f), line=reader.line_num
                ) from exc
            rows = _trim(rows)
            if rows:
                out[f.stem.lower()] = Sheet(f.stem.lower(), str(f), str(f), rows[0], rows[1:])
        return out
    if p.suffix.lower() not in EXCEL_SUFFIXES:
        raise InputError(
            "not a spreadsheet", file=file, allowed="an Excel workbook (.xlsx) or a folder of CSV files"
        )
    try:
        import openpyxl
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise InputError("reading Excel files needs the openpyxl package", file=file) from exc
    _check_workbook_size(p, file)
    try:
        book = openpyxl.load_workbook(p, read_only=True, data_only=True)
    except Exception as exc:  # openpyxl raises many kinds for a damaged file
        raise InputError(f"cannot read the workbook ({shown_value(str(exc))[1:-1]})", file=file) from exc
    for ws in book.worksheets:
        read: list[list[str]] = []
        try:
            for row in ws.iter_rows(max_col=MAX_TABLE_COLUMNS, values_only=True):
                read.append([_text(c) for c in row])
                _check_table_size(len(read), len(row), f"{file}, sheet '{ws.title}'", len(read))
        except InputError:
            book.close()
            raise
        except Exception as exc:  # a damaged sheet
            book.close()
            raise InputError(f"cannot read the sheet ({shown_value(str(exc))[1:-1]})", file=file) from exc
        rows = _trim(read)
        if rows:
            name = ws.title.strip().lower()
            out[name] = Sheet(name, f"{file}, sheet '{ws.title}'", file, rows[0], rows[1:])
    book.close()
    return out


#: Largest table read [rows, columns]: route tables of a long line have some thousands of rows.
MAX_TABLE_ROWS = 1_000_000
MAX_TABLE_COLUMNS = 200
#: Largest uncompressed content of a workbook [bytes] (a workbook is a zip archive: a small file can
#: unpack to gigabytes).
MAX_WORKBOOK_UNPACKED_BYTES = 256 * 1024 * 1024


def _check_table_size(rows: int, columns: int, where: str, line: int) -> None:
    if rows > MAX_TABLE_ROWS:
        raise InputError("table too long", file=where, line=line, allowed=f"at most {MAX_TABLE_ROWS} rows")
    if columns > MAX_TABLE_COLUMNS:
        raise InputError(
            "table too wide",
            file=where,
            line=line,
            value=columns,
            allowed=f"at most {MAX_TABLE_COLUMNS} columns",
        )


def _check_workbook_size(p: Path, file: str) -> None:
    """Refuse a workbook too large, or unpacking to too much (a zip bomb), before openpyxl reads it."""
    import zipfile

    documents.read_bytes(p)  # the size limit of every file
    try:
        with zipfile.ZipFile(p) as archive:
            unpacked = sum(info.file_size for info in archive.infolist())
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise InputError(
            "not an Excel workbook (not a zip archive)", file=file, allowed=".xlsx files"
        ) from exc
    if unpacked > MAX_WORKBOOK_UNPACKED_BYTES:
        raise InputError(
            "the workbook unpacks to too much data",
            file=file,
            value=f"{unpacked} bytes",
            allowed=f"at most {MAX_WORKBOOK_UNPACKED_BYTES} bytes",
        )


def is_spreadsheet(path: str | Path) -> bool:
    """Whether a path is a workbook or a folder of CSV tables trainsim can read."""
    p = Path(path)
    if p.is_dir():
        return any(p.glob("*.csv"))
    return p.suffix.lower() in EXCEL_SUFFIXES or p.suffix.lower() == ".csv"


# ====================================================================== headers and units
_HEADER = re.compile(r"^(.*?)\s*[\(\[]\s*(.+?)\s*[\)\]]\s*$")


def _norm(name: str) -> str:
    return re.sub(r"[\s_]+", " ", name.strip().lower())


def split_header(text: str) -> tuple[str, str | None]:
    """``"Traction force (kN)"`` -> ``("traction force", "kN")``; no unit -> None. A unit with
    brackets of its own (``kN/(km/h)``) is taken whole."""
    t = text.strip()
    m = re.match(r"^(.*?)\s*\((.*)\)\s*$", t) or _HEADER.match(t)
    if not m:
        return _norm(t), None
    return _norm(m.group(1)), m.group(2).strip()


_FORCE_PER_SPEED = re.compile(r"^(k?N)\s*/\s*\(?\s*(km/h|m/s)\s*\)?\s*(\^?2|²)?$")


def compound_factor(unit: str) -> tuple[float, int] | None:
    """``"kN/(km/h)^2"`` -> (SI factor, power of speed): force per speed^k units of Davis factors."""
    m = _FORCE_PER_SPEED.match(unit.strip())
    if not m:
        u = UNITS.get(unit.strip())
        if u is not None and u.dimension == "force":
            return u.factor, 0
        return None
    force = 1000.0 if m.group(1) == "kN" else 1.0
    speed = KMH if m.group(2) == "km/h" else 1.0
    k = 2 if m.group(3) else 1
    return force / speed**k, k


def _unit(sheet: Sheet, col: int, unit: str | None, dimension: str) -> Unit:
    allowed = format_units(dimension)
    if unit is None:
        raise sheet.error(
            f"this column needs its unit in the header, e.g. '{sheet.header[col]} ({allowed.split(',')[0]})'",
            col=col,
            allowed=allowed,
        )
    u = UNITS.get(unit) or _EXTRA.get(unit)
    if u is None:
        raise sheet.error(f"unknown unit '{unit}'", col=col, value=unit, allowed=allowed)
    if u.dimension != dimension:
        raise sheet.error(
            f"'{unit}' is a unit of {u.dimension}, this column is a {dimension}",
            col=col,
            value=unit,
            allowed=allowed,
        )
    return u


@dataclass(frozen=True)
class Column:
    """A known column: its aliases and what it measures (None: a name, a count or a flag)."""

    key: str
    aliases: tuple[str, ...]
    dimension: str | None = None
    kind: str = "number"  # number, text, bool, int


def _columns(sheet: Sheet, known: Sequence[Column], required: Sequence[str]) -> dict[str, tuple[int, float]]:
    """key -> (column index, SI factor) for each header; unknown headers are errors."""
    out: dict[str, tuple[int, float]] = {}
    for col, header in enumerate(sheet.header):
        if not header:
            continue
        name, unit = split_header(header)
        match = next((c for c in known if name in c.aliases), None)
        if match is None:
            raise sheet.error(
                "unknown column", col=col, value=header, allowed=", ".join(c.aliases[0] for c in known)
            )
        if match.key in out:
            raise sheet.error("this column is given twice", col=col, value=header)
        factor = 1.0
        if match.dimension is not None:
            factor = _unit(sheet, col, unit, match.dimension).factor
        elif unit is not None:
            raise sheet.error("this column takes no unit", col=col, value=unit)
        out[match.key] = (col, factor)
    for key in required:
        if key not in out:
            alias = next(c.aliases[0] for c in known if c.key == key)
            raise sheet.error(f"missing column '{alias}'", allowed=", ".join(c.aliases[0] for c in known))
    return out


#: "1,500" or "-12,000": one comma before exactly three digits, no dot: 1500 or 1.5?
_AMBIGUOUS_SEPARATOR = re.compile(r"[-+]?[0-9]{1,3},[0-9]{3}")
_TRUE = {"yes", "y", "true", "1", "x", "ja", "oui"}
_FALSE = {"no", "n", "false", "0", "", "-", "nein", "non"}


def _value(sheet: Sheet, row: int, col: int, kind: str, factor: float = 1.0) -> Any:
    text = sheet.rows[row][col] if col < len(sheet.rows[row]) else ""
    if kind == "text":
        return text
    if kind == "bool":
        low = text.strip().lower()
        if low in _TRUE:
            return True
        if low in _FALSE:
            return False
        raise sheet.error("expected yes or no", row=row, col=col, value=text, allowed="yes, no")
    if text == "":
        return None
    if _AMBIGUOUS_SEPARATOR.fullmatch(text):
        raise sheet.error(
            "ambiguous number: the comma may separate thousands or decimals",
            row=row,
            col=col,
            value=text,
            allowed=f"{text.replace(',', '')} or {text.replace(',', '.')} written without the comma",
        )
    value = rc.num(text.replace(",", ".") if text.count(",") == 1 and "." not in text else text)
    if value is None:
        raise sheet.error("not a number", row=row, col=col, value=text)
    if kind == "int":
        try:
            return bounds.check_count(value)
        except InputError as exc:
            raise sheet.error(exc.reason, row=row, col=col, value=text, allowed=exc.allowed) from exc
    si = value * factor
    if not (math.isfinite(si) and abs(si) <= bounds.BOUNDS["coefficient"].high):
        raise sheet.error(
            "out of range", row=row, col=col, value=text, allowed=bounds.BOUNDS["coefficient"].allowed()
        )
    return si


def _table(sheet: Sheet, y_aliases: tuple[str, ...]) -> tuple[list[float], list[float]]:
    """A speed / force table: (speeds [m/s], forces [N])."""
    cols = _columns(
        sheet,
        [Column("speed", ("speed", "velocity", "v"), "speed"), Column("force", y_aliases, "force")],
        ["speed", "force"],
    )
    speeds, forces = [], []
    for r in range(len(sheet.rows)):
        v = _value(sheet, r, cols["speed"][0], "number", cols["speed"][1])
        f = _value(sheet, r, cols["force"][0], "number", cols["force"][1])
        if v is None or f is None:
            raise sheet.error(
                "every row needs a speed and a force",
                row=r,
                col=cols["speed"][0] if v is None else cols["force"][0],
            )
        speeds.append(v)
        forces.append(f)
    if not speeds:
        raise sheet.error("the table has no rows")
    return speeds, forces


# ====================================================================== parameters
@dataclass(frozen=True)
class Param:
    key: str
    aliases: tuple[str, ...]
    dimension: str | None = None  # None: text; "ratio-free": a plain number
    kind: str = "number"


_TRAIN_PARAMS = (
    Param("name", ("name", "train name", "train"), kind="text"),
    Param("rho", ("rotating mass factor", "rotation mass factor", "rho")),
    Param("gamma", ("rotary mass coefficient", "rotating mass coefficient", "gamma")),
    Param("max_speed", ("max speed", "designed max speed", "maximum speed"), "speed"),
    Param("mass", ("mass", "train mass"), "mass"),
    Param("load", ("load", "train load"), "mass"),
    Param("length", ("length", "train length"), "length"),
    Param("davis_a", ("davis a", "resistance a", "basic resistance parameter 1"), "force-per-speed0"),
    Param("davis_b", ("davis b", "resistance b", "basic resistance parameter 2"), "force-per-speed1"),
    Param("davis_c", ("davis c", "resistance c", "basic resistance parameter 3"), "force-per-speed2"),
    Param("motors", ("traction motors", "motors", "motor cars", "bullet train quantity"), kind="int"),
    Param("power", ("traction power", "power"), "power"),
    Param("max_force", ("max traction force", "max tractive effort", "starting tractive effort"), "force"),
    Param("table_is", ("braking table is", "braking table"), kind="text"),
    Param("service_fraction", ("service braking fraction",)),
    Param("deceleration", ("braking deceleration", "service deceleration", "deceleration"), "acceleration"),
    Param("regen_fraction", ("regenerative fraction", "regenerative braking fraction")),
    Param("voltage", ("line voltage", "working voltage", "voltage"), "voltage"),
    Param("eta", ("traction efficiency", "energy conversion efficiency", "efficiency")),
    Param("eta_regen", ("regenerative efficiency",)),
    Param("power_factor", ("power factor", "cos phi")),
    Param("aux", ("auxiliary power",), "power"),
    Param("receptivity", ("receptivity",)),
)
_ROUTE_PARAMS = (
    Param("name", ("name", "route name", "line", "route"), kind="text"),
    Param("curve_formula", ("curve formula", "curve resistance formula"), kind="text"),
    Param("tunnel_formula", ("tunnel formula", "tunnel resistance formula"), kind="text"),
    Param("gradient_formula", ("gradient formula",), kind="text"),
    Param("apply_over", ("apply over", "line resistance applied over"), kind="text"),
    Param("start", ("start", "route start"), "length"),
    Param("end", ("end", "route end", "total journey"), "length"),
)


def _params(sheet: Sheet, known: Sequence[Param]) -> tuple[dict[str, Any], dict[str, int]]:
    """Parameter table: first column the name (unit in brackets), second the value."""
    out: dict[str, Any] = {}
    rows: dict[str, int] = {}
    all_rows = [sheet.header, *sheet.rows]
    # the header row may be a title ("Parameter name | Variable") or already a parameter
    start = (
        0
        if split_header(sheet.header[0])[0] not in ("parameter", "parameter name", "name of parameter")
        else 1
    )
    for i in range(start, len(all_rows)):
        row = all_rows[i]
        r = i - 1  # row index for messages (the header row is -1)
        if not row or not row[0]:
            continue
        name, unit = split_header(row[0])
        value_text = row[1] if len(row) > 1 else ""
        match = next((p for p in known if name in p.aliases), None)
        if match is None:
            raise sheet.error(
                "unknown parameter",
                row=r,
                col=0,
                value=row[0],
                allowed=", ".join(p.aliases[0] for p in known),
            )
        if match.key in out:
            raise sheet.error("parameter given twice", row=r, col=0, value=row[0])
        if match.kind == "text":
            out[match.key] = value_text
        else:
            factor = 1.0
            if match.dimension and match.dimension.startswith("force-per-speed"):
                found = compound_factor(unit) if unit else None
                power = int(match.dimension[-1])
                if found is None or found[1] != power:
                    want = ("kN", "kN/(km/h)", "kN/(km/h)^2")[power]
                    raise sheet.error(
                        f"this parameter needs its unit, e.g. '{name} ({want})'", row=r, col=0, value=unit
                    )
                factor = found[0]
            elif match.dimension:
                if unit is None:
                    raise sheet.error(
                        f"this parameter needs its unit ({format_units(match.dimension)})", row=r, col=0
                    )
                u = UNITS.get(unit) or _EXTRA.get(unit)
                if u is None or u.dimension != match.dimension:
                    raise sheet.error(
                        f"unknown unit '{unit}'"
                        if u is None
                        else f"'{unit}' is not a unit of {match.dimension}",
                        row=r,
                        col=0,
                        value=unit,
                        allowed=format_units(match.dimension),
                    )
                factor = u.factor
            tmp = Sheet(sheet.name, sheet.source, sheet.file, sheet.header, [row])
            value = _value(tmp, 0, 1, "int" if match.kind == "int" else "number", factor)
            if value is None:
                raise sheet.error("missing value", row=r, col=1)
            out[match.key] = value
        rows[match.key] = r
    return out, rows


# ====================================================================== train
def _train(sheets: dict[str, Sheet], content: rc.Content) -> dict[str, Any]:
    params_sheet = sheets.get("train")
    params, prow = _params(params_sheet, _TRAIN_PARAMS) if params_sheet else ({}, {})
    src = params_sheet.source if params_sheet else content.file
    for key, r in prow.items():
        if params_sheet is not None:
            content.origins[f"param:{key}"] = f"{params_sheet.name}!A{r + 2}"
    train: dict[str, Any] = {
        "schema": "trainsim/train",
        "version": 1,
        "name": params.get("name") or Path(content.file).stem,
    }
    vs = sheets.get("vehicles")
    if vs is not None:
        cols = _columns(
            vs,
            [
                Column("name", ("name", "vehicle", "type"), kind="text"),
                Column("count", ("count", "quantity", "number"), kind="int"),
                Column("mass", ("mass", "empty mass", "tare mass", "tare weight"), "mass"),
                Column("load", ("load", "payload"), "mass"),
                Column("length", ("length",), "length"),
                Column("axles", ("axles",), kind="int"),
                Column("powered", ("powered", "motor", "motor car"), kind="bool"),
                Column("rho", ("rotating mass factor", "rotation mass factor"), kind="number"),
                Column("max_speed", ("max speed", "maximum speed"), "speed"),
            ],
            ["name", "mass", "length"],
        )
        kinds = {"name": "text", "count": "int", "axles": "int", "powered": "bool"}
        formation = []
        for r in range(len(vs.rows)):
            v = {k: _value(vs, r, c, kinds.get(k, "number"), f) for k, (c, f) in cols.items()}
            entry: dict[str, Any] = {
                "name": v["name"],
                "mass_t": (v["mass"] or 0) / 1000.0,
                "length_m": v["length"],
            }
            if v.get("count") is not None:
                entry["count"] = v["count"]
            if v.get("load") is not None:
                entry["load_t"] = v["load"] / 1000.0
            for key, field in (("axles", "axles"), ("rho", "rotating_mass_factor")):
                if v.get(key) is not None:
                    entry[field] = v[key]
            if v.get("powered"):
                entry["powered"] = True
            if v.get("max_speed") is not None:
                entry["max_speed_kmh"] = v["max_speed"] / KMH
            content.origins[f"formation[{len(formation)}]"] = f"{vs.source}, row {r + 2}"
            formation.append(entry)
        train["formation"] = formation
    else:
        for key, field, factor in (
            ("mass", "mass_t", 1e-3),
            ("load", "load_t", 1e-3),
            ("length", "length_m", 1.0),
        ):
            if key in params:
                train[field] = params[key] * factor
    if "rho" in params:
        train["rotating_mass_factor"] = params["rho"]
    if "gamma" in params:
        train["gamma"] = params["gamma"]
    if "max_speed" in params:
        train["max_speed_kmh"] = params["max_speed"] / KMH
    ts = sheets.get("traction")
    if ts is not None:
        speeds, forces = _table(ts, ("force", "traction force", "tractive effort", "tractive force"))
        traction: dict[str, Any] = {
            "model": "table",
            "speed_kmh": [x / KMH for x in speeds],
            "force_n": forces,
        }
        if "motors" in params:
            traction.update(per_motor=True, motors=params["motors"])
        if "max_force" in params:
            traction["max_force_kn"] = params["max_force"] / 1000.0
        if "power" in params:
            traction["max_power_kw"] = params["power"] / 1000.0
        content.origins["traction"] = ts.source
    elif "power" in params and "max_force" in params:
        traction = {
            "model": "power_limited",
            "power_kw": params["power"] / 1000.0,
            "efficiency": 1.0,
            "max_force_kn": params["max_force"] / 1000.0,
        }
        content.notes.append("no traction table: power-limited traction with the power at the wheel")
    else:
        raise InputError(
            "no traction data: a 'traction' table, or 'traction power (kW)' and 'max traction force (kN)'",
            file=src,
        )
    train["traction"] = traction
    bs = sheets.get("braking")
    if bs is not None:
        speeds, forces = _table(bs, ("force", "braking force", "brake force"))
        kind = (params.get("table_is") or "").strip().lower()
        if kind not in ("service", "full"):
            raise InputError(
                "say what the braking table is: parameter 'braking table is' = service or full",
                file=src,
                field="braking table is",
                value=params.get("table_is"),
                allowed="service, full",
            )
        braking: dict[str, Any] = {
            "model": "table",
            "table_is": kind,
            "speed_kmh": [x / KMH for x in speeds],
            "force_n": forces,
        }
        if "service_fraction" in params:
            braking["service_fraction"] = params["service_fraction"]
        content.origins["braking"] = bs.source
    elif "deceleration" in params:
        braking = {"model": "deceleration", "deceleration_mps2": params["deceleration"]}
    else:
        raise InputError("no braking data: a 'braking' table or 'braking deceleration (m/s^2)'", file=src)
    rs = sheets.get("regenerative")
    if rs is not None:
        speeds, forces = _table(rs, ("force", "regenerative force", "braking force"))
        braking["regenerative"] = {
            "model": "table",
            "speed_kmh": [x / KMH for x in speeds],
            "force_n": forces,
        }
    elif "regen_fraction" in params:
        braking["regenerative"] = {"model": "fraction_of_traction", "fraction": params["regen_fraction"]}
    else:
        braking["regenerative"] = "none"
    train["braking"] = braking
    if not {"davis_a", "davis_b", "davis_c"} & set(params):
        raise InputError(
            "no running resistance: parameters 'davis A (kN)', 'davis B (kN/(km/h))', "
            "'davis C (kN/(km/h)^2)'",
            file=src,
        )
    train["resistance"] = [
        {
            "family": "davis",
            "applies_to": "train",
            "a_n": params.get("davis_a", 0.0),
            "b_n_s_per_m": params.get("davis_b", 0.0),
            "c_n_s2_per_m2": params.get("davis_c", 0.0),
        }
    ]
    if "voltage" in params:
        elec: dict[str, Any] = {"line_voltage_v": params["voltage"]}
        for key, field in (
            ("eta", "traction_efficiency"),
            ("eta_regen", "regenerative_efficiency"),
            ("power_factor", "power_factor"),
            ("receptivity", "receptivity"),
        ):
            if key in params:
                elec[field] = params[key]
        if "aux" in params:
            elec["auxiliary_power_kw"] = params["aux"] / 1000.0
        train["electrical"] = elec
    for key, field in (
        ("rho", "rotating_mass_factor"),
        ("gamma", "gamma"),
        ("max_speed", "max_speed_kmh"),
        ("voltage", "electrical"),
        ("eta", "electrical.traction_efficiency"),
    ):
        if key in prow and params_sheet is not None:
            content.origins[field] = f"{params_sheet.source}, row {prow[key] + 2}"
    return train


# ====================================================================== route
def _route(
    sheets: dict[str, Sheet], content: rc.Content, line_resistance: dict[str, str] | None
) -> dict[str, Any]:
    ps = sheets.get("route")
    params, _ = _params(ps, _ROUTE_PARAMS) if ps else ({}, {})
    ss = sheets.get("stations")
    if ss is None:
        raise InputError("no 'stations' table", file=content.file)
    cols = _columns(
        ss,
        [
            Column("name", ("name", "station"), kind="text"),
            Column("position", ("position", "accumulated journey", "distance", "km"), "length"),
            Column("dwell", ("dwell", "dwell time", "stop time"), "time"),
            Column("stop", ("stop",), kind="bool"),
        ],
        ["name", "position"],
    )
    stations = []
    for r in range(len(ss.rows)):
        name = _value(ss, r, cols["name"][0], "text")
        pos = _value(ss, r, cols["position"][0], "number", cols["position"][1])
        if not name or pos is None:
            raise ss.error(
                "every station needs a name and a position",
                row=r,
                col=cols["name"][0] if not name else cols["position"][0],
            )
        st: dict[str, Any] = {"name": name, "position_m": pos}
        if "dwell" in cols:
            d = _value(ss, r, cols["dwell"][0], "number", cols["dwell"][1])
            if d is not None:
                st["dwell_s"] = d
        if "stop" in cols and ss.rows[r][cols["stop"][0]].strip():
            st["stop"] = _value(ss, r, cols["stop"][0], "bool")
        content.origins[f"stations[{len(stations)}]"] = f"{ss.source}, row {r + 2}"
        stations.append(st)
    sec = sheets.get("sections")
    if sec is None:
        raise InputError("no 'sections' table (speed limits, gradients, curves, tunnels)", file=content.file)
    cols = _columns(
        sec,
        [
            Column("section", ("section", "no", "serial number"), kind="text"),
            Column("from", ("from", "start", "accumulated journey"), "length"),
            Column("length", ("length", "section length", "slope length"), "length"),
            Column("to", ("to", "end"), "length"),
            Column("speed", ("speed limit", "track speed", "v limit", "limit"), "speed"),
            Column("gradient", ("gradient", "vertical section gradient", "slope"), "ratio"),
            Column("radius", ("curve radius", "radius"), "length"),
            Column("angle", ("curve central angle", "central angle"), "angle"),
            Column("curve_length", ("curve length",), "length"),
            Column("tunnel", ("tunnel length",), "length"),
            Column("limiting", ("limiting gradient",), kind="bool"),
            Column("voltage", ("voltage", "line voltage"), "voltage"),
            Column("traction_share", ("traction share",), "ratio"),
        ],
        ["from", "speed"],
    )
    if "length" not in cols and "to" not in cols:
        raise sec.error("missing column 'length' (or 'to')")
    rows = []
    for r in range(len(sec.rows)):

        def val(key: str, kind: str = "number", r: int = r) -> Any:
            if key not in cols:
                return None
            c, f = cols[key]
            return _value(sec, r, c, kind, f)

        a = val("from")
        b = (
            val("to")
            if "to" in cols
            else (a + val("length") if a is not None and val("length") is not None else None)
        )
        if a is None or b is None or not b > a:
            raise sec.error(
                "a section needs its start and a length > 0 (or an end after the start)",
                row=r,
                col=cols["from"][0],
            )
        rows.append((r, a, b, val))
    rows.sort(key=lambda x: x[1])
    limits, grads, curves, tunnels, elec = [], [], [], [], []
    for r, a, b, val in rows:
        speed = val("speed")
        if speed is None:
            raise sec.error("missing speed limit", row=r, col=cols["speed"][0])
        where = f"{sec.source}, row {r + 2}"
        if not limits or limits[-1]["limit_kmh"] != speed / KMH or abs(limits[-1]["to_m"] - a) > 1e-9:
            content.origins[f"speed_limits[{len(limits)}]"] = where
            limits.append({"from_m": a, "to_m": b, "limit_kmh": speed / KMH})
        else:
            limits[-1]["to_m"] = b
        g = val("gradient")
        if g is not None:
            permille = g * 1000.0  # the ratio in SI -> per mille
            if not grads or grads[-1]["gradient_permille"] != permille or abs(grads[-1]["to_m"] - a) > 1e-9:
                content.origins[f"gradients[{len(grads)}]"] = where
                grads.append({"from_m": a, "to_m": b, "gradient_permille": permille})
            else:
                grads[-1]["to_m"] = b
        radius, angle = val("radius"), val("angle")
        if radius and angle:
            raise sec.error(
                "give the curve's radius or its central angle, not both", row=r, col=cols["angle"][0]
            )
        if radius or angle:
            length = val("curve_length") or (b - a)
            curve: dict[str, Any] = {"from_m": a, "length_m": length}
            if radius:
                curve["radius_m"] = radius
            else:
                curve["central_angle_deg"] = math.degrees(angle)
            content.origins[f"curves[{len(curves)}]"] = where
            curves.append(curve)
        t = val("tunnel")
        if t:
            limiting = bool(val("limiting", "bool")) if "limiting" in cols else False
            if (
                tunnels
                and abs(tunnels[-1]["to_m"] - a) < 1e-9
                and tunnels[-1]["limiting_gradient"] == limiting
            ):
                tunnels[-1]["to_m"] = a + t
            else:
                content.origins[f"tunnels[{len(tunnels)}]"] = where
                tunnels.append({"from_m": a, "to_m": a + t, "limiting_gradient": limiting})
        u, share = val("voltage"), val("traction_share")
        if share is not None:
            if u is None:
                raise sec.error(
                    "a traction share needs the section's voltage", row=r, col=cols["traction_share"][0]
                )
            if not 0.0 < share <= 1.0:
                col = cols["traction_share"][0]
                raise sec.error(
                    "traction share out of range", row=r, col=col, value=sec.rows[r][col],
                    allowed="0 < share <= 1 (0 % < share <= 100 %)",
                )  # fmt: skip
        share = 1.0 if share is None else share
        if u is not None and (
            not elec
            or elec[-1]["voltage_v"] != u
            or elec[-1].get("traction_share", 1.0) != share
            or abs(elec[-1]["to_m"] - a) > 1e-9
        ):
            content.origins[f"electrification[{len(elec)}]"] = where
            elec.append({"from_m": a, "to_m": b, "voltage_v": u})
            if share != 1.0:
                elec[-1]["traction_share"] = share
        elif u is not None:
            elec[-1]["to_m"] = b
    start = params.get("start", rows[0][1])
    end = params.get("end", rows[-1][2])
    lr = {
        k: params[k]
        for k in ("curve_formula", "tunnel_formula", "gradient_formula", "apply_over")
        if params.get(k)
    }
    lr.update({k: v for k, v in (line_resistance or {}).items() if v})
    if "curve_formula" not in lr or "tunnel_formula" not in lr:
        raise InputError(
            "say which curve and tunnel resistance formulas apply: parameters 'curve formula' and "
            "'tunnel formula' "
            "in the 'route' table (or give them to convert)",
            file=ps.source if ps else content.file,
            field="curve formula" if "curve_formula" not in lr else "tunnel formula",
            allowed="curve: roeckl, wang, tbt1407, french800, none; tunnel: wang, tbt1407, none",
        )
    route: dict[str, Any] = {
        "schema": "trainsim/route",
        "version": 1,
        "name": params.get("name") or Path(content.file).stem,
        "start_m": start,
        "end_m": end,
        "stations": stations,
        "speed_limits": limits,
        "line_resistance": lr,
    }
    for key, items in (
        ("gradients", grads),
        ("curves", curves),
        ("tunnels", tunnels),
        ("electrification", elec),
    ):
        if items:
            route[key] = items
    return route


def read_spreadsheet(path: str | Path, *, line_resistance: dict[str, str] | None = None) -> rc.Content:
    """Read a workbook (``.xlsx``) or a folder of CSV tables: its train and/or route as trainsim
    YAML mappings (see the module docstring for the tables)."""
    sheets = read_sheets(path)
    kind = "xlsx" if Path(path).is_file() else "CSV folder"
    content = rc.Content(format=f"spreadsheet ({kind})", file=str(path))
    signal_names = {n for names in SIGNAL_SHEETS.values() for n in names}
    unknown = [n for n in sheets if n not in TRAIN_SHEETS + ROUTE_SHEETS and n not in signal_names]
    if unknown:
        content.ignored = [f"table '{n}' ({sheets[n].source})" for n in unknown]
    if {"traction", "vehicles", "train"} & set(sheets):
        content.train = _train(sheets, content)
    if {"stations", "sections"} & set(sheets):
        content.route = _route(sheets, content, line_resistance)
    if content.train is None and content.route is None:
        raise InputError(
            "no train or track tables",
            file=str(path),
            allowed="train: " + ", ".join(TRAIN_SHEETS) + "; track: " + ", ".join(ROUTE_SHEETS),
        )
    content.figures["tables"] = ", ".join(sorted(sheets))
    content.train = rc.plain(content.train) if content.train is not None else None
    content.route = rc.plain(content.route) if content.route is not None else None
    return content


# ====================================================================== signalling
def _signal_sheet(sheets: dict[str, Sheet], key: str) -> Sheet | None:
    found = [sheets[n] for n in SIGNAL_SHEETS[key] if n in sheets]
    if len(found) > 1:
        raise InputError(
            f"the '{key}' table is given twice", file=found[1].source, allowed=" or ".join(SIGNAL_SHEETS[key])
        )
    return found[0] if found else None


def _choice(sheet: Sheet, row: int, col: int, allowed: Sequence[str], default: str | None = None) -> str:
    text = _value(sheet, row, col, "text").strip()
    if not text and default is not None:
        return default
    if text.lower() not in allowed:
        raise sheet.error(
            "not one of the allowed values", row=row, col=col, value=text, allowed=", ".join(allowed)
        )
    return text.lower()


def _placed_rows(sheet: Sheet, start_m: float, end_m: float, extra: Sequence[Column]):
    """Rows of a table of named items at route positions: (row, name, position [m], column map)."""
    cols = _columns(
        sheet,
        [
            Column("name", ("name", "id"), kind="text"),
            Column("position", ("position", "pos", "km"), "length"),
            *extra,
        ],
        ["name", "position"],
    )
    for r in range(len(sheet.rows)):
        name = _value(sheet, r, cols["name"][0], "text")
        pos = _value(sheet, r, cols["position"][0], "number", cols["position"][1])
        if not name or pos is None:
            raise sheet.error(
                "every row needs a name and a position",
                row=r,
                col=cols["name"][0] if not name else cols["position"][0],
            )
        if not start_m - 1e-9 <= pos <= end_m + 1e-9:
            raise sheet.error(
                "position off the route",
                row=r,
                col=cols["position"][0],
                value=sheet.rows[r][cols["position"][0]],
                allowed=f"{start_m:g} .. {end_m:g} m (the route of the track tables)",
            )
        yield r, name, pos, cols


def read_spreadsheet_signalling(path: str | Path, route: Route | None = None):  # -> LineSignalling
    """The signals, station tracks and train detection points of a line from a workbook or CSV folder
    (the module docstring gives the tables), along ``route`` (default: the route of the file's own
    track tables), in the form the railML reader gives (:class:`~trainsim.io.railml_signalling.
    LineSignalling`), so that an operation file takes its line from either.

    Raises:
        InputError naming the file, the sheet, the cell, the value and what is allowed.
    """
    from trainsim.io.railml_signalling import (
        DetectionPoint,
        LineSignalling,
        SignalAt,
        StationTracks,
        SwitchAt,
    )

    sheets = read_sheets(path)
    if route is None:
        route = rc.build_route(read_spreadsheet(path))
    found = {key: _signal_sheet(sheets, key) for key in SIGNAL_SHEETS}
    if found["signals"] is None:
        raise InputError(
            "no 'signals' table",
            file=str(path),
            allowed="tables: signals (name, position, direction, kind), station tracks, detection points, "
            "switches",
        )
    start_m, end_m = float(route.start_m), float(route.end_m)
    tracks: dict[str, int] = {}
    st = found["station tracks"]
    if st is not None:
        cols = _columns(
            st,
            [
                Column("station", ("station", "name"), kind="text"),
                Column("tracks", ("tracks", "platform tracks"), kind="int"),
            ],
            ["station", "tracks"],
        )
        names = [x.name for x in route.stations]
        for r in range(len(st.rows)):
            name = _value(st, r, cols["station"][0], "text")
            if name not in names:
                raise st.error(
                    "unknown station", row=r, col=cols["station"][0], value=name, allowed=", ".join(names)
                )
            if name in tracks:
                raise st.error("station given twice", row=r, col=cols["station"][0], value=name)
            n = _value(st, r, cols["tracks"][0], "int")
            if n is None or not 1 <= n <= MAX_STATION_TRACKS:
                raise st.error(
                    "invalid number of tracks",
                    row=r,
                    col=cols["tracks"][0],
                    value=st.rows[r][cols["tracks"][0]],
                    allowed=f"1 .. {MAX_STATION_TRACKS}",
                )
            tracks[name] = n
    out = LineSignalling(
        name=route.name,
        start_m=start_m,
        end_m=end_m,
        stations=[StationTracks(x.name, x.position_m, tracks.get(x.name, 1)) for x in route.stations],
    )
    sig = found["signals"]
    extra = [
        Column("direction", ("direction", "dir"), kind="text"),
        Column("kind", ("kind", "type"), kind="text"),
    ]
    for r, name, pos, cols in _placed_rows(sig, start_m, end_m, extra):
        if "direction" not in cols:
            raise sig.error("missing column 'direction'", allowed="direction (up or down)")
        direction = _choice(sig, r, cols["direction"][0], ("up", "down"))
        kind = (
            _choice(sig, r, cols["kind"][0], ("main", "block", "distant"), "main")
            if "kind" in cols
            else "main"
        )
        where = f"{sig.source}, row {r + 2}"
        out.signals.append(SignalAt(name, pos, direction, kind, where))  # type: ignore[arg-type]
    det = found["detection points"]
    track_col = Column("track", ("track",), kind="text")
    if det is not None:
        kinds = ("axle_counter", "track_circuit_border", "detector")
        for r, name, pos, cols in _placed_rows(
            det, start_m, end_m, [Column("kind", ("kind", "type"), kind="text"), track_col]
        ):
            kind = _choice(det, r, cols["kind"][0], kinds, "detector") if "kind" in cols else "detector"
            track = _choice(det, r, cols["track"][0], ("up", "down"), "up") if "track" in cols else "up"
            out.detection_points.append(
                DetectionPoint(name, pos, kind, f"{det.source}, row {r + 2}", track)  # type: ignore[arg-type]
            )
    sw = found["switches"]
    if sw is not None:
        clear_col = Column("clearance", ("clearance", "clearance point"), "length")
        speed_col = Column("diverging_speed", ("diverging speed", "diverging", "branch speed"), "speed")
        for r, name, pos, cols in _placed_rows(sw, start_m, end_m, [clear_col, track_col, speed_col]):
            clearance = (
                _value(sw, r, cols["clearance"][0], "number", cols["clearance"][1])
                if "clearance" in cols
                else None
            )
            speed = (
                _value(sw, r, cols["diverging_speed"][0], "number", cols["diverging_speed"][1])
                if "diverging_speed" in cols
                else None
            )
            if speed is not None and not 0 < speed <= 150:
                raise sw.error(
                    "invalid diverging speed",
                    row=r,
                    col=cols["diverging_speed"][0],
                    value=sw.rows[r][cols["diverging_speed"][0]],
                    allowed="0 < v <= 540 km/h, or an empty cell for line speed",
                )
            if clearance is not None and not start_m - 1e-9 <= clearance <= end_m + 1e-9:
                raise sw.error(
                    "clearance point off the route",
                    row=r,
                    col=cols["clearance"][0],
                    value=sw.rows[r][cols["clearance"][0]],
                    allowed=f"{start_m:g} .. {end_m:g} m (the route of the track tables)",
                )
            track = _choice(sw, r, cols["track"][0], ("up", "down"), "up") if "track" in cols else "up"
            out.switches.append(
                SwitchAt(name, pos, f"{sw.source}, row {r + 2}", track, clearance, speed)  # type: ignore[arg-type]
            )
    out.signals.sort(key=lambda x: (x.direction != "up", x.position_m))
    out.detection_points.sort(key=lambda d: (d.path != "up", d.position_m))
    out.switches.sort(key=lambda d: (d.path != "up", d.position_m))
    return out


# ====================================================================== writing
def _rows_train(train: Train) -> dict[str, list[list[Any]]]:
    tables: dict[str, list[list[Any]]] = {}
    params: list[list[Any]] = [["parameter", "value"], ["name", train.name]]
    params.append(["rotating mass factor", train.rotating_mass_factor])
    params.append(["max speed (km/h)", train.max_speed_mps / KMH])
    law = train.resistance_law
    params += [
        ["davis A (N)", law.c0],
        ["davis B (N/(km/h))", law.c1 * KMH],
        ["davis C (N/(km/h)^2)", law.c2 * KMH**2],
    ]
    if train.vehicles:
        rows: list[list[Any]] = [["name", "count", "mass (t)", "load (t)", "length (m)", "axles", "powered"]]
        for v, n in rc.vehicle_groups(train):
            rows.append(
                [
                    v.name,
                    n,
                    v.mass_kg / 1000.0,
                    v.load_kg / 1000.0,
                    v.length_m,
                    v.axles or "",
                    "yes" if v.powered else "no",
                ]
            )
        tables["vehicles"] = rows
    else:
        params += [["mass (t)", train.mass_kg / 1000.0], ["length (m)", train.length_m]]
    speeds, forces, fcap, pcap, _ = rc.effort_table(train.traction, train.max_speed_mps)
    if len(speeds) == 0:
        params += [["traction power (kW)", pcap / 1000.0], ["max traction force (kN)", fcap / 1000.0]]
    else:
        tables["traction"] = [
            ["speed (km/h)", "force (kN)"],
            *([x / KMH, f / 1000.0] for x, f in zip(speeds, forces, strict=True)),
        ]
        if math.isfinite(fcap):
            params.append(["max traction force (kN)", fcap / 1000.0])
    b = train.braking
    if b.deceleration_mps2 is not None:
        params.append(["braking deceleration (m/s^2)", b.deceleration_mps2])
    else:
        assert b.service_force is not None
        speeds, forces, _, _, ok = rc.effort_table(b.service_force, train.max_speed_mps)
        if not ok or len(speeds) == 0:
            speeds = np.arange(0.0, train.max_speed_mps * 1.05 + 0.25 * KMH, 0.25 * KMH)
            forces = np.asarray(b.service_force(speeds), dtype=float)
        params.append(["braking table is", "service"])
        tables["braking"] = [
            ["speed (km/h)", "force (kN)"],
            *([x / KMH, f / 1000.0] for x, f in zip(speeds, forces, strict=True)),
        ]
    if b.regenerative is not None:
        speeds, forces, _, _, ok = rc.effort_table(b.regenerative, train.max_speed_mps)
        if not ok or len(speeds) == 0:
            speeds = np.arange(0.0, train.max_speed_mps * 1.05 + 0.25 * KMH, 0.25 * KMH)
            forces = np.asarray(b.regenerative(speeds), dtype=float)
        tables["regenerative"] = [
            ["speed (km/h)", "force (kN)"],
            *([x / KMH, f / 1000.0] for x, f in zip(speeds, forces, strict=True)),
        ]
    e = train.electrical
    if e is not None:
        params += [
            ["line voltage (V)", e.line_voltage_v],
            ["traction efficiency", e.traction_efficiency],
            ["regenerative efficiency", e.regenerative_efficiency],
            ["power factor", e.power_factor],
            ["auxiliary power (kW)", e.auxiliary_power_w / 1000.0],
            ["receptivity", e.receptivity],
        ]
    tables = {"train": params, **tables}
    return tables


def _rows_route(route: Route) -> dict[str, list[list[Any]]]:
    lr = route.line_resistance
    params = [
        ["parameter", "value"],
        ["name", route.name],
        ["curve formula", lr.curve_formula],
        ["tunnel formula", lr.tunnel_formula],
        ["gradient formula", lr.gradient_formula],
        ["apply over", lr.apply_over],
        ["start (m)", route.start_m],
        ["end (m)", route.end_m],
    ]
    stations = [["name", "position (m)", "dwell (s)", "stop"]]
    stations += [[s.name, s.position_m, s.dwell_s, "yes" if s.stop else "no"] for s in route.stations]
    cuts = {route.start_m, route.end_m}
    for items in (route.speed_limits, route.gradients, route.curves, route.tunnels, route.electrification):
        for x in items:
            cuts |= {x.start_m, x.end_m}
    cuts = sorted(c for c in cuts if route.start_m <= c <= route.end_m)
    header = [
        "from (m)",
        "length (m)",
        "speed limit (km/h)",
        "gradient (‰)",
        "curve radius (m)",
        "curve length (m)",
        "tunnel length (m)",
        "limiting gradient",
    ]
    shares = any(e.traction_share != 1.0 for e in route.electrification)
    if route.electrification:
        header.append("voltage (V)")
    if shares:
        # percent: the column's unit must be in its header, and a share is a ratio (‰ or %)
        header.append("traction share (%)")
    rows = [header]

    def at(items: Sequence[Any], a: float) -> Any:
        return next((x for x in items if x.start_m <= a < x.end_m), None)

    for a, b in itertools.pairwise(cuts):
        lim = at(route.speed_limits, a)
        g = at(route.gradients, a)
        c = at(route.curves, a)
        t = next((x for x in route.tunnels if abs(x.start_m - a) < 1e-9), None)
        row = [
            a,
            b - a,
            lim.limit_mps / KMH if lim else "",
            g.gradient_permille if g else 0.0,
            c.radius_m if c else "",
            (min(c.end_m, b) - a) if c else "",
            (t.end_m - t.start_m) if t else "",
            ("yes" if t.limiting_gradient else "no") if t else "",
        ]
        if route.electrification:
            e = at(route.electrification, a)
            row.append(e.voltage_v if e else "")
        if shares:
            row.append(e.traction_share * 100.0 if e else "")
        rows.append(row)
    return {"route": params, "stations": stations, "sections": rows}


def write_spreadsheet(path: str | Path, *, train: Train | None = None, route: Route | None = None) -> Path:
    """Write a train and/or a route as tables: an Excel workbook for a ``.xlsx`` path, else a
    folder of CSV files (one per table)."""
    tables: dict[str, list[list[Any]]] = {}
    if train is not None:
        tables.update(_rows_train(train))
    if route is not None:
        tables.update(_rows_route(route))
    out = Path(path)
    if out.suffix.lower() in EXCEL_SUFFIXES:
        import openpyxl

        book = openpyxl.Workbook()
        book.remove(book.active)
        for name, rows in tables.items():
            ws = book.create_sheet(name)
            for row in rows:
                ws.append([float(x) if isinstance(x, np.floating) else x for x in row])
        out.parent.mkdir(parents=True, exist_ok=True)
        book.save(out)
        return out
    import csv

    out.mkdir(parents=True, exist_ok=True)
    for name, rows in tables.items():
        with (out / f"{name}.csv").open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            for row in rows:
                writer.writerow([repr(float(x)) if isinstance(x, float | np.floating) else x for x in row])
    return out
