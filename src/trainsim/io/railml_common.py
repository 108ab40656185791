"""Helpers shared by the railML 2 and railML 3 readers and writers.

* XML reading with line numbers (lxml ``sourceline``): every problem found in a railML file is an
  :class:`~trainsim.errors.InputError` naming the element (``<speedChange id='sc3'>``), the
  attribute and the line; the problems of one file are reported together.
* Units of railML value tables (``xValueUnit``, ``yValueUnit``) and of positioning systems, read
  through :mod:`trainsim.io.units`; an unknown unit is an error naming the element and its line.
* Times (``08:01:31``) and durations (``PT1M31S``, xs:duration).
* The network as a graph of edges (railML 2 tracks, railML 3 netElements) joined at ports
  (track ends, switch branches, net relations), and the path of one train through it: the route.
* Line data placed on that path: spans on edges (``[a, b]`` in edge metres) and changes
  (value from a position on) become route positions in metres along the path.
* Effort curves written as railML value tables: exactly when the curve is a linear interpolation
  of a table, else sampled (and said so).
* What a reader used, so that ``trainsim check`` can list what it ignored, with lines.

Nothing here knows a railML version: element names are matched by their local name, whatever the
namespace of the file (railML 2.2 to 2.5 and 3.1 to 3.2 all use different namespaces).
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
import re
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.errors import Problem as ErrorProblem
from trainsim.io.units import UNITS, Unit, format_units
from trainsim.model import EffortCurve, bounds

__all__ = [
    "EXTENSION_NS",
    "Content",
    "Event",
    "Leg",
    "Network",
    "Port",
    "Problems",
    "RoutePath",
    "RouteSpan",
    "Span",
    "Table",
    "Usage",
    "attr_float",
    "child",
    "children",
    "descendants",
    "effort_table",
    "format_clock",
    "format_duration",
    "label",
    "local",
    "num",
    "parse_clock",
    "parse_duration",
    "parse_xml",
    "read_value_table",
]

#: Namespace of trainsim's own attributes in railML files (``ts:curveFormula``...): the data railML
#: has no place for (line-resistance formula choices, power factor...). railML allows attributes of
#: other namespaces on its elements; other tools ignore them.
EXTENSION_NS = "urn:trainsim:railml-extension:1"
EXT = f"{{{EXTENSION_NS}}}"

#: Positions closer than this are the same position [m] (railML writes 6 decimals at most).
POSITION_TOLERANCE_M = 1e-6


# ====================================================================== XML access
def parse_xml(path: str | Path) -> etree._ElementTree:
    """The XML tree of a file; InputError (with the line) for a missing, malformed or hostile file.

    Read by :func:`trainsim.io.documents.read_xml`: no network, no entity expansion, no DTD,
    bounded size and depth.
    """
    from trainsim.io.documents import read_xml

    return read_xml(path)


def local(el: etree._Element) -> str:
    """The element's name without namespace ("" for comments and processing instructions)."""
    tag = el.tag
    if not isinstance(tag, str):
        return ""
    return tag.rsplit("}", 1)[-1]


def children(el: etree._Element | None, name: str) -> list[etree._Element]:
    """Direct children with that local name."""
    if el is None:
        return []
    return [c for c in el if local(c) == name]


def child(el: etree._Element | None, name: str) -> etree._Element | None:
    """The first direct child with that local name, or None."""
    found = children(el, name)
    return found[0] if found else None


def descendants(el: etree._Element | None, name: str) -> list[etree._Element]:
    """Every element below ``el`` (not ``el`` itself) with that local name, in document order."""
    if el is None:
        return []
    return [d for d in el.iter() if d is not el and local(d) == name]


def path(el: etree._Element | None, *names: str) -> etree._Element | None:
    """Follow direct children by local names: ``path(root, "infrastructure", "tracks")``."""
    for name in names:
        el = child(el, name)
        if el is None:
            return None
    return el


def ext(el: etree._Element, name: str) -> str | None:
    """A trainsim extension attribute (``ts:name``)."""
    return el.get(EXT + name)


def traction_share(el: etree._Element, problems: Problems) -> float:
    """The electrification's ``ts:tractionShare`` [-] (``ElectrificationSection.traction_share``, the
    share of its tractive effort an electric train may use there; railML has no element for it), 1
    when absent; a value outside (0, 1] or not a number is recorded in ``problems`` (and read as 1)."""
    text = ext(el, "tractionShare")
    if text is None:
        return 1.0
    value = num(text)
    if value is None or not (math.isfinite(value) and 0.0 < value <= 1.0):
        problems.add(el, "traction share out of range", attribute="ts:tractionShare", value=text,
                     allowed="0 < share <= 1")  # fmt: skip
        return 1.0
    return float(value)


def label(el: etree._Element) -> str:
    """How an element is named in messages: ``<speedChange id='sc3'>``."""
    ident = el.get("id")
    name = el.get("name")
    if ident:
        return f"<{local(el)} id='{ident}'>"
    if name:
        return f"<{local(el)} name='{name}'>"
    return f"<{local(el)}>"


# ====================================================================== problems
@dataclass(frozen=True)
class Problem:
    """One thing wrong in a railML file."""

    message: str
    element: str
    line: int | None
    attribute: str | None = None
    value: Any = None
    allowed: str | None = None

    def text(self) -> str:
        where = f"line {self.line}, " if self.line else ""
        what = self.element + (f" @{self.attribute}" if self.attribute else "")
        out = f"{where}{what}: {self.message}"
        if self.value is not None:
            out += f" (got {self.value!r})"
        if self.allowed:
            out += f", allowed: {self.allowed}"
        return out


class Problems:
    """Collects the problems of one file so that they are reported together."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.items: list[Problem] = []

    def add(
        self,
        el: etree._Element | None,
        message: str,
        *,
        attribute: str | None = None,
        value: Any = None,
        allowed: str | None = None,
    ) -> None:
        self.items.append(
            Problem(
                message,
                label(el) if el is not None else "(file)",
                el.sourceline if el is not None else None,
                attribute,
                value,
                allowed,
            )
        )

    def error(self, el: etree._Element | None, message: str, **kwargs: Any) -> InputError:
        """This problem alone, with the ones collected so far, as one InputError."""
        self.add(el, message, **kwargs)
        return self.as_error()

    def as_error(self) -> InputError:
        """The problems collected as one InputError with one structured problem each."""
        return InputError.from_problems(
            [
                ErrorProblem(
                    p.message,
                    file=self.file,
                    line=p.line,
                    field=p.element + (f" @{p.attribute}" if p.attribute else ""),
                    value=p.value,
                    allowed=p.allowed,
                )
                for p in self.items
            ]
        )

    def raise_if_any(self) -> None:
        if self.items:
            raise self.as_error()


# ====================================================================== attributes
_NUMBER = re.compile(r"^\s*[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?\s*$")


def num(text: str | None) -> float | None:
    """A number written in an attribute, or None if it is not one."""
    if text is None or not _NUMBER.match(text):
        return None
    return float(text)


def attr_float(
    el: etree._Element,
    name: str,
    problems: Problems,
    *,
    required: bool = False,
    what: str = "",
    minimum: float | None = None,
    positive: bool = False,
) -> float | None:
    """A numeric attribute; a missing required one or a bad value is recorded in ``problems``.

    Args:
        what: what the attribute means, for the message (``"position on the track [m]"``).
        minimum: values below are an error; positive: values <= 0 are an error.
    """
    text = el.get(name)
    if text is None:
        if required:
            problems.add(el, f"missing {what or 'required attribute'}", attribute=name)
        return None
    value = num(text)
    if value is None or not math.isfinite(value):
        problems.add(el, "not a number", attribute=name, value=text)
        return None
    if minimum is not None and value < minimum:
        problems.add(el, "out of range", attribute=name, value=text, allowed=f">= {minimum:g}")
        return None
    if positive and value <= 0:
        problems.add(el, "out of range", attribute=name, value=text, allowed="> 0")
        return None
    if abs(value) > _LARGEST:
        problems.add(el, "out of range", attribute=name, value=text, allowed=f"at most {_LARGEST:g} in size")
        return None
    return value


#: Largest magnitude of any number in a railML file (the quantity's own bounds apply later).
_LARGEST = bounds.BOUNDS["coefficient"].high


def attr_int(
    el: etree._Element, name: str, problems: Problems, *, default: int = 0, low: int = 0, high: int = 100_000
) -> int:
    """A whole-number attribute (``sequence``, ``arrivalDay``, ``orderNumber``...) from ``low`` to
    ``high``; ``default`` when it is absent; a bad value is recorded in ``problems``."""
    text = el.get(name)
    if text is None or not text.strip():
        return default
    stripped = text.strip()
    if not re.fullmatch(r"[-+]?[0-9]{1,9}", stripped) or not low <= int(stripped) <= high:
        problems.add(
            el, "not a whole number in range", attribute=name, value=text, allowed=f"{low} to {high}"
        )
        return default
    return int(stripped)


def sort_number(text: str | None) -> int:
    """A whole number written in a ``sequence`` / ``orderNumber`` attribute to sort by (0 if it is
    not one: the order then falls back on the document order)."""
    if text is None or not re.fullmatch(r"\s*[0-9]{1,9}\s*", text):
        return 0
    return int(text)


def powered_propulsion(form: FormationSource) -> etree._Element | None:
    """The propulsion element of the first powered vehicle that has one (its electrical data)."""
    powered = [v for v in form.vehicles if v.powered and v.propulsion is not None]
    return powered[0].propulsion if powered else None


def extension_numbers(el: etree._Element, out: dict[str, Any], pairs: Sequence[tuple[str, str]]) -> None:
    """``out[key]`` = the number of trainsim's extension attribute ``attr`` of ``el``, where given."""
    for key, attr in pairs:
        value = num(ext(el, attr))
        if value is not None:
            out[key] = value


def stations_on_path(
    path: Any,
    entries: Sequence[tuple[Any, float, bool, etree._Element]],
    stops: Sequence[Stop],
    problems: Problems,
) -> list[StationAt]:
    """The stations of a route at their positions along its path, in order: each operational point
    at the first of its locations past the previous one."""
    stations: list[StationAt] = []
    after = -math.inf
    for (_, dwell, stop, el), st in zip(entries, stops, strict=True):
        pos = None
        for edge, x in st.locations:
            s = path.position(edge, x, after)
            if s is not None and (pos is None or s < pos):
                pos = s
        if pos is None:  # pragma: no cover - the path goes through every stop
            problems.add(el, "operational point not on the route's path")
            continue
        after = pos
        stations.append(StationAt(st.name, pos, dwell, stop, el))
    return stations


def formation_by_id(
    formations: dict[str | None, etree._Element], formation_id: str, file: str
) -> etree._Element:
    """The formation of the given id (``--formation-id``), or an InputError naming the ids there are."""
    if formation_id not in formations:
        raise InputError(
            "no formation of that id",
            file=file,
            field="formation_id",
            value=formation_id,
            allowed=", ".join(str(f) for f in formations),
        )
    return formations[formation_id]


def vehicle_order(
    refs: list[etree._Element],
    vehicles: dict[str | None, etree._Element],
    usage: Usage,
    problems: Problems,
    *,
    unknown: str,
    merge_repeats: bool = False,
) -> list[tuple[etree._Element, int, etree._Element]]:
    """``(vehicle, count, reference)`` for the ``vehicleRef`` references of a formation's train order
    (sorted by ``orderNumber``); a reference to an unknown vehicle is a problem (``unknown`` says it).
    With ``merge_repeats``, consecutive references to one vehicle without a count add up (railML 3)."""
    refs = sorted(refs, key=lambda r: sort_number(r.get("orderNumber")))
    order: list[tuple[etree._Element, int, etree._Element]] = []
    for r in refs:
        usage.use(r)
        v = vehicles.get(r.get("vehicleRef"))
        if v is None:
            problems.add(r, unknown, attribute="vehicleRef", value=r.get("vehicleRef"))
            continue
        count = attr_int(r, "vehicleCount", problems, default=1, low=1)
        if merge_repeats and order and order[-1][0] is v and r.get("vehicleCount") is None:
            order[-1] = (v, order[-1][1] + 1, order[-1][2])
        else:
            order.append((v, count, r))
    return order


def index_ids(root: etree._Element, problems: Problems) -> dict[str, etree._Element]:
    """The elements by ``id``; a duplicate id (railML ids are unique in a file) is a problem."""
    ids: dict[str, etree._Element] = {}
    for el in root.iter():
        ident = el.get("id") if isinstance(el.tag, str) else None
        if not ident:
            continue
        if ident in ids:
            first = ids[ident]
            problems.add(
                el,
                f"duplicate id (also {label(first)} on line {first.sourceline})",
                attribute="id",
                value=ident,
                allowed="ids unique in the file",
            )
            continue
        ids[ident] = el
    return ids


def attr_bool(el: etree._Element, name: str) -> bool | None:
    """An xs:boolean attribute (``true``/``false``/``1``/``0``), None if absent or not boolean."""
    text = el.get(name)
    if text is None:
        return None
    return {"true": True, "1": True, "false": False, "0": False}.get(text.strip().lower())


# ====================================================================== times
_DURATION = re.compile(
    r"^\s*(-)?P(?:(\d+(?:\.\d+)?)D)?(?:T(?:(\d+(?:\.\d+)?)H)?(?:(\d+(?:\.\d+)?)M)?(?:(\d+(?:\.\d+)?)S)?)?\s*$"
)
_CLOCK = re.compile(r"^\s*(\d{1,2}):(\d{2}):(\d{2}(?:\.\d+)?)\s*$")


def parse_duration(text: str | None) -> float | None:
    """An xs:duration without years and months (``PT1M31.5S``, ``P1DT2H``) in seconds; None if
    the text is not one."""
    if text is None:
        return None
    m = _DURATION.match(text)
    if m is None or text.strip() in ("P", "PT") or text.strip().endswith("T"):
        return None
    days, hours, minutes, seconds = (float(g) if g else 0.0 for g in m.groups()[1:])
    total = ((days * 24 + hours) * 60 + minutes) * 60 + seconds
    return -total if m.group(1) else total


def format_duration(seconds: float) -> str:
    """Seconds as an xs:duration, e.g. ``PT1M31.25S`` (milliseconds at most)."""
    sign = "-" if seconds < 0 else ""
    ms = round(abs(seconds) * 1000)
    minutes, ms = divmod(ms, 60_000)
    hours, minutes = divmod(minutes, 60)
    out = f"{sign}PT"
    if hours:
        out += f"{hours}H"
    if minutes:
        out += f"{minutes}M"
    if ms or out.endswith("T"):
        sec = f"{ms / 1000:.3f}".rstrip("0").rstrip(".")
        out += f"{sec}S"
    return out


def parse_clock(text: str | None, day: int = 0) -> float | None:
    """An xs:time ``hh:mm:ss[.fff]`` plus ``day`` days, in seconds after midnight of day 0."""
    if text is None:
        return None
    m = _CLOCK.match(text)
    if m is None:
        return None
    h, mi, s = int(m.group(1)), int(m.group(2)), float(m.group(3))
    if h > 23 or mi > 59 or s >= 60:
        return None
    return day * 86400.0 + h * 3600.0 + mi * 60.0 + s


def format_clock(seconds: float) -> tuple[str, int]:
    """Seconds after midnight of day 0 as ``(hh:mm:ss[.f], day offset)``, rounded to 0.1 s."""
    tenths = round(seconds * 10)
    day, tenths = divmod(tenths, 864_000)
    h, rest = divmod(tenths, 36_000)
    m, rest = divmod(rest, 600)
    s = rest / 10
    text = f"{h:02d}:{m:02d}:{int(s):02d}"
    if rest % 10:
        text += f".{rest % 10}"
    return text, int(day)


# ====================================================================== units and value tables
# Spellings seen in railML value tables beside the ones trainsim knows (trainsim.io.units).
_EXTRA_UNITS: dict[str, Unit] = {
    "m/s/s": UNITS["m/s^2"],
    "m/(s*s)": UNITS["m/s^2"],
    "ms-2": UNITS["m/s^2"],
    "km/h/s": Unit("km/h/s", "acceleration", KMH),
    "km/h": UNITS["km/h"],
    "N/t": Unit("N/t", "force per mass", 1e-3),
    "daN": Unit("daN", "force", 10.0),
}


def table_unit(
    symbol: str | None, dimensions: Sequence[str], el: etree._Element, attribute: str, problems: Problems
) -> Unit | None:
    """The unit named in a value table attribute, which must measure one of ``dimensions``."""
    allowed = "; ".join(f"{d}: {format_units(d)}" for d in dimensions)
    if symbol is None or not symbol.strip():
        problems.add(el, "the unit is missing", attribute=attribute, allowed=allowed)
        return None
    unit = UNITS.get(symbol.strip()) or _EXTRA_UNITS.get(symbol.strip())
    if unit is None:
        problems.add(el, f"unknown unit '{symbol}'", attribute=attribute, value=symbol, allowed=allowed)
        return None
    if unit.dimension not in dimensions:
        problems.add(
            el,
            f"'{symbol}' is a unit of {unit.dimension}, expected {' or '.join(dimensions)}",
            attribute=attribute,
            value=symbol,
            allowed=allowed,
        )
        return None
    return unit


@dataclass(frozen=True)
class Table:
    """A railML ``valueTable`` read into SI units.

    Attributes:
        x: independent values in SI (speeds [m/s]).
        y: dependent values in SI ([N], [m/s^2] or a ratio).
        y_dimension: what ``y`` measures (``force``, ``acceleration``, ``ratio``).
        element: the ``valueTable`` element.
        curves: how many curves (columns) the table holds; the first one is read.
    """

    x: np.ndarray
    y: np.ndarray
    y_dimension: str
    element: etree._Element
    curves: int = 1


def read_value_table(
    vt: etree._Element, problems: Problems, *, y_dimensions: Sequence[str], usage: Usage | None = None
) -> Table | None:
    """A ``valueTable`` of speeds (``xValueUnit`` km/h or m/s) and values (``yValueUnit``).

    Each ``valueLine`` has ``xValue`` and one ``values`` (railML 2) or ``value`` (railML 3) child per
    curve with ``yValue``; the first curve is read. Speeds must increase strictly.
    """
    if usage is not None:
        usage.use(vt, deep=True)
    x_unit = table_unit(vt.get("xValueUnit"), ("speed",), vt, "xValueUnit", problems)
    y_unit = table_unit(vt.get("yValueUnit"), y_dimensions, vt, "yValueUnit", problems)
    xs: list[float] = []
    ys: list[float] = []
    curves = 1
    for line in children(vt, "valueLine"):
        x = attr_float(line, "xValue", problems, required=True, what="speed value (xValue)")
        cells = [c for c in line if local(c) in ("values", "value")]
        # railML 2 may wrap <value> in <values>; take the innermost elements carrying yValue
        cells = [c for c in cells if c.get("yValue") is not None] or [
            v for c in cells for v in c if local(v) == "value"
        ]
        curves = max(curves, len(cells))
        if not cells:
            problems.add(line, "no value in this line (a 'values' or 'value' child with yValue)")
            continue
        y = attr_float(cells[0], "yValue", problems, required=True)
        if x is not None and y is not None:
            if xs and x <= xs[-1]:
                problems.add(line, "speeds must increase strictly", attribute="xValue", value=x)
                continue
            xs.append(x)
            ys.append(y)
    if not xs and not problems.items:
        problems.add(vt, "the table has no valueLine")
    if x_unit is None or y_unit is None or not xs:
        return None
    if xs[0] < 0:
        problems.add(vt, "speeds must be >= 0", value=xs[0])
        return None
    return Table(np.array(xs) * x_unit.factor, np.array(ys) * y_unit.factor, y_unit.dimension, vt, curves)


def effort_table(
    curve: EffortCurve, max_speed_mps: float, *, step_mps: float = 0.25 * KMH
) -> tuple[np.ndarray, np.ndarray, float, float, bool]:
    """An effort curve as a railML table: ``(speed_mps, force_n, force_cap_n, power_cap_w, exact)``.

    Exact when the curve is a linear interpolation of a table (the form every reader builds):
    the interval starts and forces are written, with the caps as separate figures. A power-limited
    curve (one constant interval with a power cap) is returned with an empty table. Any other
    curve (quadratic or hyperbolic laws) is sampled every ``step_mps`` up to ``max_speed_mps`` and
    at its kinks, and ``exact`` is False.
    """
    starts, coefs, fcap, pcap = curve.as_arrays()
    linear = np.all(coefs[:, 2] == 0.0) and np.all(coefs[:, 3] == 0.0)
    if linear and len(starts) == 1 and coefs[0, 1] == 0.0 and math.isfinite(pcap):
        return np.zeros(0), np.zeros(0), min(coefs[0, 0], fcap), pcap, True
    if linear and not math.isfinite(pcap) and coefs[-1, 1] == 0.0:
        values = coefs[:, 0] + coefs[:, 1] * starts
        ends = np.r_[coefs[:-1, 0] + coefs[:-1, 1] * starts[1:]]
        if np.allclose(ends, values[1:], rtol=1e-12, atol=1e-9):
            return starts.copy(), values.copy(), fcap, pcap, True
    top = max(max_speed_mps, float(starts[-1])) * 1.05
    grid = np.unique(np.r_[np.arange(0.0, top + step_mps, step_mps), starts, _power_kink(fcap, pcap, top)])
    grid = grid[grid <= top + step_mps]
    return grid, np.asarray(curve(grid), dtype=float), math.inf, math.inf, False


def _power_kink(force_cap: float, power_cap: float, top: float) -> list[float]:
    if math.isfinite(force_cap) and math.isfinite(power_cap) and force_cap > 0:
        v = power_cap / force_cap
        if 0 < v < top:
            return [v]
    return []


def sum_tables(tables: Sequence[tuple[np.ndarray, np.ndarray, float]]) -> tuple[np.ndarray, np.ndarray]:
    """The sum of ``count`` x table over several linearly interpolated tables (constant beyond
    their ends), exact on the union of their speeds: ``[(speed, force, count), ...]``."""
    grid = np.unique(np.concatenate([t[0] for t in tables]))
    total = np.zeros_like(grid)
    for x, y, count in tables:
        total += count * np.interp(grid, x, y)
    return grid, total


def fit_quadratic(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares ``c0 + c1 x + c2 x^2`` through the points, and the largest deviation
    relative to the largest |y| (0 for a table sampled from a quadratic)."""
    if len(x) >= 3:
        c2, c1, c0 = np.polyfit(x, y, 2)
    elif len(x) == 2:
        c2 = 0.0
        c1, c0 = np.polyfit(x, y, 1)
    else:
        c0, c1, c2 = float(y[0]), 0.0, 0.0
    fitted = c0 + c1 * x + c2 * x * x
    scale = max(float(np.max(np.abs(y))), 1e-12)
    return float(c0), float(c1), float(c2), float(np.max(np.abs(fitted - y)) / scale)


def fmt(value: float) -> str:
    """A number for an XML attribute: 12 significant digits, no exponent for usual magnitudes."""
    if value == 0:
        return "0"
    text = f"{value:.12g}"
    if "e" in text:
        text = np.format_float_positional(value, precision=12, unique=True, trim="-")
    return text


# ====================================================================== usage (what was read)
class Usage:
    """Which elements a reader used, to report the others as ignored (with their lines)."""

    def __init__(self) -> None:
        self._used: set[etree._Element] = set()
        self._deep: set[etree._Element] = set()
        self.reasons: list[tuple[etree._Element, str]] = []

    def use(self, el: etree._Element | None, *, deep: bool = False) -> None:
        """Mark an element (and with ``deep`` everything below it) as read."""
        if el is None:
            return
        self._used.add(el)
        if deep:
            self._deep.add(el)

    def skip(self, el: etree._Element, reason: str) -> None:
        """Record that an element was deliberately not used, and why."""
        self.reasons.append((el, reason))
        self._used.add(el)  # reported with its reason, not again as unread
        self._deep.add(el)

    def ignored(self, root: etree._Element, *, limit: int = 40) -> list[str]:
        """The topmost elements nothing was read from, with their line, and the skipped ones."""
        used_ancestors: set[etree._Element] = set()
        for el in self._used:
            p = el.getparent()
            while p is not None and p not in used_ancestors:
                used_ancestors.add(p)
                p = p.getparent()
        out: list[str] = []

        def covered(el: etree._Element) -> bool:
            p = el
            while p is not None:
                if p in self._deep:
                    return True
                p = p.getparent()
            return False

        def walk(el: etree._Element) -> None:
            for c in el:
                if not local(c):
                    continue
                if c in self._used or c in used_ancestors:
                    if c not in self._deep:
                        walk(c)
                    continue
                if covered(c):
                    continue
                n = sum(1 for d in c.iter() if local(d)) - 1
                more = f", {n} element(s) inside" if n else ""
                out.append(f"{label(c)} at line {c.sourceline}{more}")

        walk(root)
        out += [f"{label(el)} at line {el.sourceline}: {why}" for el, why in self.reasons]
        if len(out) > limit:
            out = [*out[:limit], f"... and {len(out) - limit} more"]
        return out


# ====================================================================== network and path
@dataclass(frozen=True)
class Port:
    """Where a train can leave an edge for another one.

    Attributes:
        key: unique name (the connection's id).
        edge: the edge the port is on; pos: where on it [m, edge coordinates].
        leave: directions (+1 towards increasing positions, -1 towards decreasing) in which a
            train passes through the port onto the partner.
        arrive: directions a train coming from the partner moves in on this edge.
        partner: key of the port on the other edge.
        element: the XML element, for messages.
    """

    key: str
    edge: str
    pos: float
    leave: tuple[int, ...]
    arrive: tuple[int, ...]
    partner: str | None
    element: etree._Element | None = None


@dataclass(frozen=True)
class Leg:
    """A train's run along one edge from ``start`` to ``end`` [m, edge coordinates]."""

    edge: str
    start: float
    end: float

    @property
    def direction(self) -> int:
        return 1 if self.end >= self.start else -1

    @property
    def length(self) -> float:
        return abs(self.end - self.start)

    def covers(self, pos: float) -> bool:
        lo, hi = sorted((self.start, self.end))
        return lo - POSITION_TOLERANCE_M <= pos <= hi + POSITION_TOLERANCE_M


@dataclass
class Network:
    """Edges (tracks, netElements) with their extent, and the ports joining them."""

    extent: dict[str, tuple[float, float]] = field(default_factory=dict)
    elements: dict[str, etree._Element] = field(default_factory=dict)
    ports: dict[str, Port] = field(default_factory=dict)
    by_edge: dict[str, list[Port]] = field(default_factory=lambda: defaultdict(list))

    def add_edge(self, edge: str, begin: float, end: float, element: etree._Element) -> None:
        self.extent[edge] = (begin, end)
        self.elements[edge] = element

    def add_port(self, port: Port) -> None:
        self.ports[port.key] = port
        self.by_edge[port.edge].append(port)

    def shortest(
        self, a: tuple[str, float], b: tuple[str, float], directions: Sequence[int]
    ) -> tuple[float, list[Leg], int] | None:
        """The shortest way from location ``a`` to ``b`` leaving ``a`` in one of ``directions``,
        without reversing, as ``(length, legs, direction at b)``; None if there is none.
        Locations are ``(edge, position)``. Dijkstra over states (edge, position, direction)."""
        State = tuple[str, float, int]
        heap: list[tuple[float, int, State, bool]] = []
        dist: dict[State, float] = {}
        prev: dict[State, tuple[State | None, Leg | None]] = {}
        counter = 0
        for d in directions:
            state = (a[0], round(a[1], 6), d)
            dist[state] = 0.0
            prev[state] = (None, None)
            heapq.heappush(heap, (0.0, counter, state, False))
            counter += 1
        while heap:
            cost, _, state, is_goal = heapq.heappop(heap)
            if is_goal:
                return cost, self._legs(prev, state, b), state[2]
            if cost > dist.get(state, math.inf):
                continue
            edge, pos, d = state
            if edge == b[0] and (b[1] - pos) * d >= -POSITION_TOLERANCE_M:
                heapq.heappush(heap, (cost + abs(b[1] - pos), counter, state, True))
                counter += 1
            for port in self.by_edge.get(edge, []):
                if d not in port.leave or (port.pos - pos) * d < -POSITION_TOLERANCE_M:
                    continue
                other = self.ports.get(port.partner or "")
                if other is None:
                    continue
                new_cost = cost + abs(port.pos - pos)
                for d2 in other.arrive:
                    nxt = (other.edge, round(other.pos, 6), d2)
                    if new_cost < dist.get(nxt, math.inf):
                        dist[nxt] = new_cost
                        prev[nxt] = (state, Leg(edge, pos, port.pos))
                        heapq.heappush(heap, (new_cost, counter, nxt, False))
                        counter += 1
        return None

    @staticmethod
    def _legs(
        prev: dict[tuple[str, float, int], tuple[tuple[str, float, int] | None, Leg | None]],
        state: tuple[str, float, int],
        b: tuple[str, float],
    ) -> list[Leg]:
        legs = [Leg(state[0], state[1], b[1])]
        cur: tuple[str, float, int] | None = state
        while cur is not None:
            before, leg = prev[cur]
            if leg is not None:
                legs.append(leg)
            cur = before
        legs.reverse()
        return [leg for leg in legs if leg.length > POSITION_TOLERANCE_M] or [legs[-1]]


def merge_legs(legs: Iterable[Leg]) -> list[Leg]:
    """Consecutive legs on the same edge in the same direction as one."""
    out: list[Leg] = []
    for leg in legs:
        if leg.length <= POSITION_TOLERANCE_M and out:
            continue
        if (
            out
            and out[-1].edge == leg.edge
            and out[-1].direction == leg.direction
            and abs(out[-1].end - leg.start) <= POSITION_TOLERANCE_M
        ):
            out[-1] = Leg(leg.edge, out[-1].start, leg.end)
        else:
            out.append(leg)
    return out


# ====================================================================== line data on the path
@dataclass(frozen=True)
class Span:
    """A value on ``[a, b]`` of an edge [m, edge coordinates], e.g. a gradient or a curve.

    ``directions`` says for which travel directions it applies (+1, -1); ``down`` maps the value
    for trains running towards decreasing positions (a gradient changes sign)."""

    edge: str
    a: float
    b: float
    value: Any
    element: etree._Element
    directions: tuple[int, ...] = (1, -1)


@dataclass(frozen=True)
class RouteSpan:
    """A value on ``[start_m, end_m)`` of the route [m]."""

    start_m: float
    end_m: float
    value: Any
    element: etree._Element


@dataclass(frozen=True)
class Event:
    """A value that applies from ``position_m`` of the route on [m]."""

    position_m: float
    value: Any
    element: etree._Element


class RoutePath:
    """The legs of a route with their route positions: the first leg starts at ``origin_m``."""

    def __init__(self, legs: Sequence[Leg], origin_m: float = 0.0) -> None:
        self.legs = list(legs)
        self.offsets: list[float] = []
        s = origin_m
        for leg in self.legs:
            self.offsets.append(s)
            s += leg.length
        self.start_m = origin_m
        self.end_m = s

    def position(self, edge: str, pos: float, after_m: float = -math.inf) -> float | None:
        """Route position of an edge position, the first one at or after ``after_m``."""
        for leg, s0 in zip(self.legs, self.offsets, strict=True):
            if leg.edge == edge and leg.covers(pos):
                s = s0 + abs(pos - leg.start)
                if s >= after_m - POSITION_TOLERANCE_M:
                    return s
        return None

    def spans(self, spans: Iterable[Span], down: Callable[[Any], Any] | None = None) -> list[RouteSpan]:
        """Spans on edges as route spans, in route order; values of spans run in the decreasing
        direction are mapped by ``down``."""
        out: list[RouteSpan] = []
        for sp in spans:
            lo, hi = sorted((sp.a, sp.b))
            for leg, s0 in zip(self.legs, self.offsets, strict=True):
                if leg.edge != sp.edge or leg.direction not in sp.directions:
                    continue
                l_lo, l_hi = sorted((leg.start, leg.end))
                a, b = max(lo, l_lo), min(hi, l_hi)
                if b - a <= POSITION_TOLERANCE_M:
                    continue
                ra, rb = sorted((s0 + abs(a - leg.start), s0 + abs(b - leg.start)))
                value = sp.value if leg.direction > 0 or down is None else down(sp.value)
                out.append(RouteSpan(ra, rb, value, sp.element))
        out.sort(key=lambda r: (r.start_m, r.end_m))
        return out

    def changes(self, changes: Iterable[tuple[str, float, int, Any, etree._Element]]) -> list[Event]:
        """Direction-bound changes ``(edge, pos, direction, value, element)`` (a railML 2
        ``speedChange`` applies from its position on for trains running in its direction) as
        route events, in route order."""
        out: list[Event] = []
        for edge, pos, d, value, el in changes:
            for leg, s0 in zip(self.legs, self.offsets, strict=True):
                if leg.edge == edge and leg.direction == d and leg.covers(pos):
                    out.append(Event(s0 + abs(pos - leg.start), value, el))
        out.sort(key=lambda e: e.position_m)
        return out


def check_overlaps(spans: Sequence[RouteSpan], what: str, problems: Problems) -> None:
    """Overlapping route spans of one kind are an error naming both elements."""
    for p, q in itertools.pairwise(spans):
        if q.start_m < p.end_m - POSITION_TOLERANCE_M:
            problems.add(
                q.element,
                f"this {what} overlaps {label(p.element)} (line {p.element.sourceline}) between "
                f"{q.start_m:g} m and {min(p.end_m, q.end_m):g} m of the route",
            )


def events_from_spans(spans: Sequence[RouteSpan]) -> list[Event]:
    """Each span as an event at its start (a gap keeps the value before it)."""
    return [Event(s.start_m, s.value, s.element) for s in spans]


def merge_spans(spans: Sequence[RouteSpan]) -> list[RouteSpan]:
    """Touching spans of equal value as one (a curve or tunnel over two edges)."""
    out: list[RouteSpan] = []
    for s in spans:
        if out and out[-1].value == s.value and abs(out[-1].end_m - s.start_m) <= POSITION_TOLERANCE_M:
            out[-1] = RouteSpan(out[-1].start_m, s.end_m, s.value, out[-1].element)
        else:
            out.append(s)
    return out


def regions(changes: Sequence[tuple[float, Any, etree._Element]], edge: str, end: float) -> Iterator[Span]:
    """railML 2 changes on a track (value from ``pos`` to the next change, the last one to the
    track end) as spans; positions before the first change are left out (they keep the value of
    the route before them)."""
    for (pos, value, el), nxt in zip(changes, [*changes[1:], None], strict=False):
        b = nxt[0] if nxt is not None else end
        if b - pos > POSITION_TOLERANCE_M:
            yield Span(edge, pos, b, value, el)


# ====================================================================== read result
@dataclass
class Content:
    """What a railML or spreadsheet reader found, as trainsim YAML mappings.

    Attributes:
        format: ``railML 2.4``, ``railML 3.2``, ``spreadsheet (xlsx)``...
        train: a ``trainsim/train`` mapping, or None.
        route: a ``trainsim/route`` mapping, or None.
        notes: readings made and defaults applied.
        ignored: elements not read, with their lines.
        origins: dict field prefix (``speed_limits[2]``) -> where it came from (``<speedChange
            id='sc3'> at line 40``), to point errors found later at the source.
        figures: what was read, for ``trainsim check``.
        station_elements: the element each route station comes from (railML ``ocpTT``,
            ``baseItineraryPoint``), for writing running times back.
    """

    format: str
    file: str
    train: dict[str, Any] | None = None
    route: dict[str, Any] | None = None
    notes: list[str] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)
    origins: dict[str, str] = field(default_factory=dict)
    origin_lines: dict[str, int | None] = field(default_factory=dict)
    figures: dict[str, str] = field(default_factory=dict)
    train_error: InputError | None = None
    route_error: InputError | None = None
    station_elements: list[etree._Element] = field(default_factory=list)

    def located(self, exc: InputError) -> InputError:
        """An error of the trainsim validation pointed at the element each field came from."""

        def locate(p: ErrorProblem) -> ErrorProblem:
            best = ""
            if p.field:
                for prefix in self.origins:
                    if p.field.startswith(prefix) and len(prefix) > len(best):
                        best = prefix
            where = self.origins.get(best) if best else None
            return dataclasses.replace(
                p,
                reason=p.reason + (f" (read from {where})" if where else ""),
                file=self.file,
                line=self.origin_lines.get(best) if best else None,
            )

        return InputError.from_problems([locate(p) for p in exc.problems])

    def origin(self, key: str, el: etree._Element) -> None:
        self.origins[key] = f"{label(el)} at line {el.sourceline}"
        self.origin_lines[key] = el.sourceline


# ====================================================================== route and train mappings
END_OF_RESTRICTION = "end"  #: value of a speed event that ends a temporary restriction


@dataclass(frozen=True)
class StationAt:
    """A station on the route: from an operational point and the train's timetable."""

    name: str
    position_m: float
    dwell_s: float
    stop: bool
    element: etree._Element


def _dedupe(events: Sequence[Event], what: str, problems: Problems) -> list[Event]:
    out: list[Event] = []
    for ev in events:
        if out and abs(out[-1].position_m - ev.position_m) <= POSITION_TOLERANCE_M:
            if out[-1].value != ev.value:
                problems.add(
                    ev.element,
                    f"two {what} at the same position ({ev.position_m:g} m of the route) with different "
                    f"values; the other is {label(out[-1].element)} at line {out[-1].element.sourceline}",
                )
            continue
        out.append(ev)
    return out


def _r(x: float) -> float:
    # route positions are sums of track positions: drop the last-bit noise of the additions
    return round(x, 9)


def route_mapping(
    content: Content,
    problems: Problems,
    *,
    name: str,
    path: RoutePath,
    stations: Sequence[StationAt],
    speed: Sequence[Event],
    gradients: Sequence[Event],
    electrification: Sequence[Event],
    curves: Sequence[RouteSpan],
    tunnels: Sequence[RouteSpan],
    line_resistance: dict[str, str],
    anchor: etree._Element | None = None,
) -> dict[str, Any]:
    """The ``trainsim/route`` mapping of a path with its line data; problems are recorded
    (``anchor``: the element to name when the problem is the route as a whole)."""
    start, end = path.start_m, path.end_m
    inside = [e for e in speed if e.position_m < end - POSITION_TOLERANCE_M]
    # speed: values carried over gaps, 'end' of a temporary restriction restores the value before it
    limits: list[tuple[float, float, etree._Element]] = []
    in_force: list[float] = []
    for ev in _dedupe(inside, "speed changes", problems):
        if ev.value == END_OF_RESTRICTION:
            if len(in_force) < 2:
                problems.add(ev.element, "end of a speed restriction ('end') with no restriction before it")
                continue
            in_force.pop()
        else:
            in_force.append(float(ev.value))
        limits.append((ev.position_m, in_force[-1], ev.element))
    first_stop = stations[0].position_m if stations else start
    if not limits:
        problems.add(anchor, "no speed limit on the route (no speed change or speed section on its path)")
    elif limits[0][0] > start + POSITION_TOLERANCE_M:
        if limits[0][0] > first_stop + POSITION_TOLERANCE_M:
            problems.add(
                limits[0][2],
                f"no speed limit at the start station '{stations[0].name}' ({first_stop:g} m): the first "
                f"one on the path starts at {limits[0][0]:g} m",
            )
        else:
            content.notes.append(
                f"no speed limit between {start:g} m and {limits[0][0]:g} m (behind the first station): "
                f"the first limit, {limits[0][1]:g} km/h, is used there"
            )
            limits[0] = (start, limits[0][1], limits[0][2])
    speed_limits: list[dict[str, Any]] = []
    for pos, value, el in limits:
        if speed_limits and speed_limits[-1]["limit_kmh"] == value:
            continue
        content.origin(f"speed_limits[{len(speed_limits)}]", el)
        speed_limits.append({"from_m": _r(pos), "limit_kmh": value})

    grads: list[dict[str, Any]] = []
    for ev in _dedupe(
        [e for e in gradients if e.position_m < end - POSITION_TOLERANCE_M], "gradients", problems
    ):
        if grads and grads[-1]["gradient_permille"] == ev.value:
            continue
        content.origin(f"gradients[{len(grads)}]", ev.element)
        grads.append({"from_m": _r(ev.position_m), "gradient_permille": float(ev.value)})
    if grads and grads[0]["from_m"] > start + POSITION_TOLERANCE_M:
        content.notes.append(f"no gradient given before {grads[0]['from_m']:g} m of the route: level there")
    if not grads:
        content.notes.append("no gradient on the route's path: level line")

    elec: list[dict[str, Any]] = []
    for ev in _dedupe(
        [e for e in electrification if e.position_m < end - POSITION_TOLERANCE_M],
        "electrification changes",
        problems,
    ):
        # a value is the voltage [V], or (voltage [V], traction share [-]) where the file gives a share
        voltage, share = ev.value if isinstance(ev.value, tuple) else (ev.value, 1.0)
        if elec and elec[-1]["voltage_v"] == voltage and elec[-1].get("traction_share", 1.0) == share:
            continue
        content.origin(f"electrification[{len(elec)}]", ev.element)
        elec.append({"from_m": _r(ev.position_m), "voltage_v": float(voltage)})
        if share != 1.0:
            elec[-1]["traction_share"] = float(share)
    if elec and elec[0]["from_m"] > start + POSITION_TOLERANCE_M:
        content.notes.append(
            f"no electrification given before {elec[0]['from_m']:g} m of the route: the first value "
            f"({elec[0]['voltage_v']:g} V) is used from the route start"
        )
        elec[0]["from_m"] = _r(start)
    if not electrification:
        content.notes.append("no electrification data on the path: electrified everywhere (trainsim's rule)")

    curve_spans = merge_spans([c for c in curves if c.value])
    check_overlaps(curve_spans, "curve", problems)
    curve_list = []
    for c in curve_spans:
        content.origin(f"curves[{len(curve_list)}]", c.element)
        curve_list.append({"from_m": _r(c.start_m), "to_m": _r(c.end_m), "radius_m": abs(float(c.value))})
    tunnel_spans = merge_spans(list(tunnels))
    check_overlaps(tunnel_spans, "tunnel", problems)
    tunnel_list = []
    for t in tunnel_spans:
        content.origin(f"tunnels[{len(tunnel_list)}]", t.element)
        tunnel_list.append({"from_m": _r(t.start_m), "to_m": _r(t.end_m), "limiting_gradient": bool(t.value)})

    station_list = []
    seen: dict[str, int] = {}
    for st in stations:
        nm = st.name
        if nm in seen:
            nm = f"{st.name} ({st.element.get('id')})"
        seen[nm] = len(station_list)
        content.origin(f"stations[{len(station_list)}]", st.element)
        station_list.append(
            {"name": nm, "position_m": _r(st.position_m), "dwell_s": st.dwell_s, "stop": st.stop}
        )
    route: dict[str, Any] = {
        "schema": "trainsim/route",
        "version": 1,
        "name": name,
        "start_m": _r(start),
        "end_m": _r(end),
        "stations": station_list,
        "speed_limits": speed_limits,
    }
    if grads:
        route["gradients"] = grads
    if curve_list:
        route["curves"] = curve_list
    if tunnel_list:
        route["tunnels"] = tunnel_list
    if elec:
        route["electrification"] = elec
    route["line_resistance"] = dict(line_resistance)
    return plain(route)


LINE_RESISTANCE_KEYS = {
    "curve_formula": "curveFormula",
    "tunnel_formula": "tunnelFormula",
    "gradient_formula": "gradientFormula",
    "apply_over": "applyOver",
}


def line_resistance_choice(
    el: etree._Element | None,
    given: dict[str, str] | None,
    content: Content,
    *,
    required: bool,
) -> dict[str, str]:
    """The route's line-resistance formulas: given by the caller, else the file's trainsim
    attributes (``ts:curveFormula``...), else an error: railML has no place for them, and they
    change the result."""
    from_file = {k: ext(el, a) for k, a in LINE_RESISTANCE_KEYS.items()} if el is not None else {}
    chosen = {k: v for k, v in from_file.items() if v}
    if given:
        for k, v in given.items():
            if v is None:
                continue
            if k in chosen and chosen[k] != v:
                content.notes.append(f"line_resistance.{k}: '{v}' given, the file says '{chosen[k]}'")
            chosen[k] = v
    missing = [k for k in ("curve_formula", "tunnel_formula") if k not in chosen]
    if missing:
        if required:
            raise InputError(
                "railML does not say which curve and tunnel resistance formulas apply, and they change the "
                "result: give them (trainsim convert IN OUT --curve-formula ... --tunnel-formula ...; in "
                "Python line_resistance={'curve_formula': ..., 'tunnel_formula': ...})",
                file=content.file,
                field="line_resistance." + missing[0],
                allowed="curve: roeckl, wang, tbt1407, french800, none; tunnel: wang, tbt1407, none",
            )
        content.notes.append(
            "no line-resistance formulas in the file (curves, tunnels): they must be given to convert or "
            "run it"
        )
        chosen.update({k: "none" for k in missing})
    return chosen


def build_train(content: Content) -> Any:
    """The :class:`~trainsim.model.Train` of a read file (errors pointed at the source element)."""
    from trainsim.io.trainsim_yaml import train_spec_from_dict

    if content.train is None:
        raise content.train_error or InputError("the file holds no train", file=content.file)
    try:
        return train_spec_from_dict(content.train, content.file).to_train(content.file)
    except InputError as exc:
        raise content.located(exc) from None


def build_route(content: Content) -> Any:
    """The :class:`~trainsim.model.Route` of a read file (errors pointed at the source element)."""
    from trainsim.io.trainsim_yaml import route_spec_from_dict

    if content.route is None:
        raise content.route_error or InputError("the file holds no route", file=content.file)
    try:
        return route_spec_from_dict(content.route, content.file).to_route(content.file)
    except InputError as exc:
        raise content.located(exc) from None


def rho_of(formation: Sequence[dict[str, Any]], train_rho: float | None) -> float:
    """Rotating mass factor of a formation mapping (the rule of trainsim/train: the vehicles'
    rotating parts add (xi - 1) x empty mass)."""
    if train_rho is not None:
        return train_rho
    total = sum(v.get("count", 1) * (v["mass_t"] + v.get("load_t", 0.0)) for v in formation)
    extra = sum(
        v.get("count", 1) * ((v.get("rotating_mass_factor") or 1.0) - 1.0) * v["mass_t"] for v in formation
    )
    return 1.0 + extra / total


def vehicle_factors_for(rho: float, vehicles: Sequence[tuple[float, float, int]]) -> float:
    """The rotating mass factor to give every vehicle so that the train's factor, combined from the
    vehicles' empty masses, is ``rho``: ``xi = 1 + (rho - 1) m_total / m_empty``.
    ``vehicles``: ``(empty mass, load, count)``."""
    total = sum(n * (m + load) for m, load, n in vehicles)
    empty = sum(n * m for m, _, n in vehicles)
    return 1.0 + (rho - 1.0) * total / empty


@dataclass(frozen=True)
class Stop:
    """A point the route passes: where it may lie on the network, and the element naming it."""

    name: str
    locations: tuple[tuple[str, float], ...]
    element: etree._Element


def route_path(
    network: Network,
    stops: Sequence[Stop],
    problems: Problems,
    origin_of: Callable[[str], float | None] = lambda edge: None,
) -> RoutePath | None:
    """The path of a train through the network visiting ``stops`` in order without reversing,
    each leg the shortest one. The path is extended behind the first stop and beyond the last
    one to the ends of their edges (line data there matters for a long train). Route positions
    start at the mileage of the first edge's begin (``origin_of``) when the path runs in its
    direction, else at 0."""
    if len(stops) < 2:
        problems.add(stops[0].element if stops else None, "a route needs at least two points (stations)")
        return None
    choices: list[tuple[tuple[str, float], tuple[int, ...]]] = [(loc, (1, -1)) for loc in stops[0].locations]
    legs: list[Leg] = []
    for prev, stop in itertools.pairwise(stops):
        best: tuple[float, list[Leg], int, tuple[str, float]] | None = None
        for loc, dirs in choices:
            for cand in stop.locations:
                found = network.shortest(loc, cand, dirs)
                if found is not None and (best is None or found[0] < best[0]):
                    best = (found[0], found[1], found[2], cand)
        if best is None:
            problems.add(
                stop.element,
                f"no way from '{prev.name}' to '{stop.name}' through the network without reversing "
                "(are the tracks connected?)",
            )
            return None
        legs += best[1]
        choices = [(best[3], (best[2],))]
    legs = merge_legs(legs)
    first, last = legs[0], legs[-1]
    b0, e0 = network.extent[first.edge]
    legs[0] = Leg(first.edge, b0 if first.direction > 0 else e0, first.end)
    if len(legs) == 1:
        last = legs[0]
    b1, e1 = network.extent[last.edge]
    legs[-1] = Leg(last.edge, last.start, e1 if last.direction > 0 else b1)
    origin = origin_of(legs[0].edge) if legs[0].direction > 0 else None
    return RoutePath(legs, origin if origin is not None else 0.0)


# ====================================================================== train mapping
@dataclass
class VehicleSource:
    """One vehicle type of a formation as read from a file (railML 2 or 3), SI units inside the
    tables, railML units (t, m, km/h, N, W) in the figures."""

    name: str
    count: int
    mass_t: float
    load_t: float
    length_m: float
    element: etree._Element
    axles: int | None = None
    max_speed_kmh: float | None = None
    rotating_mass_factor: float | None = None
    powered: bool = False
    traction: Table | None = None  #: tractive effort of ONE vehicle [N over m/s]
    max_effort_n: float | None = None
    power_w: float | None = None
    regenerative: Table | None = None
    max_brake_power_w: float | None = None
    deceleration: Table | None = None  #: the vehicle's braking deceleration table
    auxiliary_w: float = 0.0
    propulsion: etree._Element | None = None


@dataclass
class FormationSource:
    """A formation as read from a file: its vehicles and the train-level data."""

    name: str
    element: etree._Element
    vehicles: list[VehicleSource]
    max_speed_kmh: float | None = None
    rotating_mass_factor: float | None = None
    mean_deceleration: tuple[float, etree._Element] | None = None
    deceleration_table: tuple[Table, str, float | None] | None = None  # table, table_is, service fraction
    davis: tuple[float, float, float, bool, etree._Element] | None = None  # A [N], B [N/(km/h)], C, per tonne
    strahl: tuple[float, etree._Element] | None = None
    resistance_table: Table | None = None
    electrical: dict[str, Any] | None = None
    notes: list[str] = field(default_factory=list)


def train_mapping(src: FormationSource, content: Content, problems: Problems) -> dict[str, Any]:
    """The ``trainsim/train`` mapping of a formation read from railML (the rules are in the
    docstrings of :mod:`trainsim.io.railml2` and :mod:`trainsim.io.railml3`)."""
    c = content
    entries: list[dict[str, Any]] = []
    for i, v in enumerate(src.vehicles):
        entry: dict[str, Any] = {
            "name": v.name,
            "count": v.count,
            "mass_t": v.mass_t,
            "load_t": v.load_t,
            "length_m": v.length_m,
        }
        if v.axles:
            entry["axles"] = v.axles
        if v.rotating_mass_factor is not None:
            entry["rotating_mass_factor"] = v.rotating_mass_factor
        if v.powered:
            entry["powered"] = True
        if v.max_speed_kmh is not None:
            entry["max_speed_kmh"] = v.max_speed_kmh
        c.origin(f"formation[{i}]", v.element)
        entries.append(entry)
    train: dict[str, Any] = {"schema": "trainsim/train", "version": 1, "name": src.name, "formation": entries}
    missing = [e["name"] for e in entries if "rotating_mass_factor" not in e]
    if src.rotating_mass_factor is not None:
        train["rotating_mass_factor"] = src.rotating_mass_factor
    elif missing:
        problems.add(
            src.element,
            "the rotating mass factor is missing for vehicle(s) " + ", ".join(missing) + " (the vehicles' "
            "rotation mass factors); or give the train's (--rotating-mass-factor)",
        )
    if src.max_speed_kmh is not None:
        train["max_speed_kmh"] = src.max_speed_kmh
    elif any("max_speed_kmh" not in e for e in entries):
        problems.add(src.element, "missing maximum speed (the formation's or every vehicle's speed) [km/h]")
    problems.raise_if_any()
    rho = rho_of(entries, train.get("rotating_mass_factor"))
    mass_kg = sum(e["count"] * (e["mass_t"] + e["load_t"]) for e in entries) * 1000.0
    train["traction"] = _traction(src, content, problems)
    braking = _braking(src, rho * mass_kg, content, problems)
    braking["regenerative"] = _regenerative(src)
    train["braking"] = braking
    train["resistance"] = _resistance(src, mass_kg, content, problems)
    if src.electrical is not None:
        aux = sum(v.count * v.auxiliary_w for v in src.vehicles)
        electrical = dict(src.electrical)
        if aux and "auxiliary_power_kw" not in electrical:
            electrical["auxiliary_power_kw"] = aux / 1000.0
        train["electrical"] = electrical
    else:
        c.notes.append("no electrical data (line voltage and traction efficiency): energy at the wheel only")
    c.notes += src.notes
    for key in ("traction", "braking", "resistance", "electrical", "rotating_mass_factor", "max_speed_kmh"):
        c.origin(key, src.element)
    c.figures["vehicles"] = ", ".join(f"{e['count']} x {e['name']}" for e in entries)
    return plain(train)


def plain(obj: Any) -> Any:
    """A mapping with numpy numbers turned into Python ones (for YAML and JSON)."""
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [plain(v) for v in obj]
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _traction(src: FormationSource, content: Content, problems: Problems) -> dict[str, Any]:
    powered = [v for v in src.vehicles if v.powered]
    if not powered:
        raise problems.error(src.element, "no powered vehicle in the formation (a vehicle with an engine)")
    with_table = [v for v in powered if v.traction is not None]
    if with_table:
        if len(with_table) != len(powered):
            raise problems.error(
                powered[0].element, "some powered vehicles have a tractive effort table and others not"
            )
        for v in with_table:
            if v.traction is not None and v.traction.curves > 1:
                content.notes.append(
                    f"{label(v.traction.element)} (line {v.traction.element.sourceline}): "
                    f"{v.traction.curves} curves, the first is read"
                )
        speed, force = sum_tables(
            [(v.traction.x, v.traction.y, float(v.count)) for v in with_table if v.traction]
        )
        out: dict[str, Any] = {
            "model": "table",
            "speed_kmh": [x / KMH for x in speed],
            "force_n": [float(f) for f in force],
        }
        caps = [v.max_effort_n for v in powered]
        if all(cap is not None for cap in caps):
            total = sum(v.count * (v.max_effort_n or 0.0) for v in powered)
            if total < float(np.max(force)) - 1e-6:
                out["max_force_kn"] = total / 1000.0
        return out
    lacking = [v for v in powered if v.max_effort_n is None or v.power_w is None]
    if lacking:
        raise problems.error(
            lacking[0].propulsion if lacking[0].propulsion is not None else lacking[0].element,
            "no traction data: a tractive effort table, or the maximum tractive effort [N] and the power [W]",
        )
    content.notes.append(
        "no tractive effort table: power-limited traction, the engine power read as the power at the wheel"
    )
    return {
        "model": "power_limited",
        "power_kw": sum(v.count * (v.power_w or 0.0) for v in powered) / 1000.0,
        "efficiency": 1.0,
        "max_force_kn": sum(v.count * (v.max_effort_n or 0.0) for v in powered) / 1000.0,
    }


def _regenerative(src: FormationSource) -> Any:
    tables = [
        (v.regenerative.x, np.abs(v.regenerative.y), float(v.count)) for v in src.vehicles if v.regenerative
    ]
    if not tables:
        return "none"
    speed, force = sum_tables(tables)
    out: dict[str, Any] = {
        "model": "table",
        "speed_kmh": [x / KMH for x in speed],
        "force_n": [float(f) for f in force],
    }
    power = sum(v.count * (v.max_brake_power_w or 0.0) for v in src.vehicles if v.regenerative)
    if power > 0:
        out["max_power_kw"] = power / 1000.0
    return out


def _braking(
    src: FormationSource, inertial_kg: float, content: Content, problems: Problems
) -> dict[str, Any]:
    if src.deceleration_table is not None:
        table, kind, fraction = src.deceleration_table
        force = table.y * inertial_kg if table.y_dimension == "acceleration" else table.y
        out: dict[str, Any] = {
            "model": "table",
            "table_is": kind,
            "speed_kmh": [x / KMH for x in table.x],
            "force_n": [float(f) for f in np.abs(force)],
        }
        if fraction is not None:
            out["service_fraction"] = fraction
        return out
    if src.mean_deceleration is not None:
        value, el = src.mean_deceleration
        content.notes.append(
            f"{label(el)} (line {el.sourceline}): meanDeceleration {value:g} m/s^2 read as a constant "
            "service deceleration (TrainRuns.jl's braking model)"
        )
        return {"model": "deceleration", "deceleration_mps2": value}
    tables = [(v.deceleration, v) for v in src.vehicles if v.deceleration is not None]
    if tables:
        weights = [v.count * (v.mass_t + v.load_t) for _, v in tables]
        total = sum(weights)
        speed, decel = sum_tables(
            [(t.x, np.abs(t.y), w / total) for (t, _), w in zip(tables, weights, strict=True)]
        )
        content.notes.append(
            "vehicle deceleration tables: the train's is their mass-weighted mean; braking force = "
            "deceleration x inertial mass (service braking)"
        )
        return {
            "model": "table",
            "table_is": "service",
            "speed_kmh": [x / KMH for x in speed],
            "force_n": [float(f) for f in decel * inertial_kg],
        }
    raise problems.error(
        src.element,
        "no braking data: a mean deceleration (trainBrakes@meanDeceleration) or a deceleration table",
    )


def _resistance(
    src: FormationSource, mass_kg: float, content: Content, problems: Problems
) -> list[dict[str, Any]]:
    from trainsim.constants import STANDARD_GRAVITY as G  # railML states no g: the standard one

    if src.davis is not None:
        a, b, c, per_tonne, el = src.davis
        k = mass_kg / 1000.0 if per_tonne else 1.0
        content.notes.append(
            f"{label(el)}: Davis factors read as A [N], B [N/(km/h)], C [N/(km/h)^2]"
            + (" per tonne of train mass" if per_tonne else " for the whole formation")
        )
        # V [km/h] = v [m/s] / KMH: the linear factor scales by 1/KMH, the quadratic one by 1/KMH^2
        return [
            {
                "family": "davis",
                "applies_to": "train",
                "a_n": a * k,
                "b_n_s_per_m": b * k / KMH,
                "c_n_s2_per_m2": c * k / KMH**2,
            }
        ]
    if src.strahl is not None:
        k, el = src.strahl
        # Strahl: w = 2.5 + k (V/10)^2 per mille = 2.5 + 100 k (V/100)^2: trainsim's strahl family
        content.notes.append(
            f"{label(el)}: strahlFactor k read as Strahl's law w = 2.5 + k (V/10)^2 per mille (ASSUMPTION)"
        )
        return [{"family": "strahl", "applies_to": "train", "f0_permille": 2.5, "f2_permille": 100.0 * k}]
    if src.resistance_table is not None:
        t = src.resistance_table
        force = t.y if t.y_dimension == "force" else t.y * mass_kg * G
        c0, c1, c2, dev = fit_quadratic(t.x, force)
        content.notes.append(
            f"{label(t.element)} (line {t.element.sourceline}): resistance table fitted with A + B v + C v^2 "
            f"(largest deviation {100 * dev:.3g} % of the largest value)"
        )
        return [
            {
                "family": "davis",
                "applies_to": "train",
                "a_n": max(c0, 0.0),
                "b_n_s_per_m": c1,
                "c_n_s2_per_m2": max(c2, 0.0),
            }
        ]
    raise problems.error(
        src.element, "no running resistance: Davis factors, a Strahl factor or a resistance table"
    )


def vehicle_mass(
    tare: float | None,
    brutto: float | None,
    netto: float | None,
    el: etree._Element,
    content: Content,
    problems: Problems,
) -> tuple[float, float] | None:
    """Empty mass and load [t] from railML's tare (empty), brutto (with the load the train runs
    with) and netto (load) weights."""
    if tare is not None:
        load = brutto - tare if brutto is not None else (netto or 0.0)
        if load < -1e-9:
            problems.add(
                el, "the gross weight is below the tare weight", attribute="bruttoWeight", value=brutto
            )
        return tare, max(load, 0.0)
    if brutto is not None:
        if netto is not None:
            return brutto - netto, netto
        content.notes.append(f"{label(el)}: no tareWeight, the bruttoWeight {brutto:g} t is the running mass")
        return brutto, 0.0
    problems.add(el, "missing vehicle mass (tareWeight, bruttoWeight) [t]", attribute="tareWeight")
    return None


class ElementWriter:
    """Shared part of the railML writers: namespaced elements with trainsim extension attributes
    (keyword ``ts_name`` writes ``ts:name``) and speed value tables."""

    #: railML family for messages ("railML 2", "railML 3") and the tag of one value in a value line
    family = ""
    value_tag = ""

    def __init__(self, version: str, namespaces: dict[str, str]) -> None:
        if version not in namespaces:
            raise InputError(
                f"unsupported {self.family} version to write", value=version, allowed=", ".join(namespaces)
            )
        self.ns = namespaces[version]
        self.version = version
        self.notes: list[str] = []

    def el(self, parent: etree._Element | None, tag_name: str, /, **attrs: Any) -> etree._Element:
        tag = f"{{{self.ns}}}{tag_name}"
        e = (
            etree.SubElement(parent, tag)
            if parent is not None
            else etree.Element(tag, nsmap={None: self.ns, "ts": EXTENSION_NS})
        )
        for k, v in attrs.items():
            if v is None:
                continue
            key = EXT + k[3:] if k.startswith("ts_") else k
            if isinstance(v, bool):
                e.set(key, str(v).lower())
            elif isinstance(v, float | int):
                e.set(key, fmt(v))
            else:
                e.set(key, str(v))
        return e

    def value_table(
        self, parent: etree._Element, y_name: str, y_unit: str, speeds_mps: np.ndarray, values: np.ndarray
    ) -> None:
        vt = self.el(
            parent, "valueTable", xValueName="speed", xValueUnit="km/h", yValueName=y_name, yValueUnit=y_unit
        )
        for x, y in zip(speeds_mps, values, strict=True):
            line = self.el(vt, "valueLine", xValue=float(x / KMH))
            self.el(line, self.value_tag, yValue=float(y))


# ====================================================================== writing trains
def sampled(curve: Any, max_speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """An effort curve sampled every 0.25 km/h up to 5 % above the maximum speed: (speeds [m/s],
    forces [N])."""
    speeds = np.arange(0.0, max_speed_mps * 1.05 + 0.25 * KMH, 0.25 * KMH)
    return speeds, np.asarray(curve(speeds), dtype=float)


def vehicle_groups(train: Any) -> list[tuple[Any, int]]:
    """The formation as (vehicle, count) groups of consecutive equal vehicles; a train given by
    its mass alone as one vehicle."""
    from trainsim.model import Vehicle

    if not train.vehicles:
        return [(Vehicle("train", train.mass_kg, train.length_m, powered=True), 1)]
    groups: list[tuple[Any, int]] = []
    for v in train.vehicles:
        if groups and groups[-1][0] == v:
            groups[-1] = (v, groups[-1][1] + 1)
        else:
            groups.append((v, 1))
    return groups


@dataclass(frozen=True)
class WrittenTables:
    """What the railML writers write of a train's curves (tables, exact or sampled).

    Attributes:
        xi: rotating mass factor per vehicle group (they combine back to the train's).
        speeds, forces, force_cap_n, power_cap_w: the traction table and its caps.
        regen_speeds, regen_forces: the regenerative braking table (empty without one).
    """

    xi: Any
    speeds: np.ndarray
    forces: np.ndarray
    force_cap_n: float
    power_cap_w: float
    regen_speeds: np.ndarray
    regen_forces: np.ndarray


def written_tables(train: Any, groups: list[tuple[Any, int]], notes: list[str]) -> WrittenTables:
    """The traction and regenerative tables a railML writer writes (``notes`` says when sampled)."""
    xi = vehicle_factors_for(train.rotating_mass_factor, [(v.mass_kg, v.load_kg, n) for v, n in groups])
    speeds, forces, fcap, pcap, exact = effort_table(train.traction, train.max_speed_mps)
    if not exact:
        notes.append(f"traction: the curve is not a table; written sampled at {len(speeds)} speeds")
    r_speeds, r_forces = np.zeros(0), np.zeros(0)
    regen = train.braking.regenerative
    if regen is not None:
        r_speeds, r_forces, _, _, r_exact = effort_table(regen, train.max_speed_mps)
        if not r_exact or len(r_speeds) == 0:
            r_speeds, r_forces = sampled(regen, train.max_speed_mps)
            notes.append("regenerative braking: the curve is not a table; written sampled")
    return WrittenTables(xi, speeds, forces, fcap, pcap, r_speeds, r_forces)
