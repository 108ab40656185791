"""Trains and routes for the editor: files of any format trainsim reads, as editable trainsim specs.

The editor works on ``trainsim/train`` and ``trainsim/route`` mappings (the YAML formats of
docs/FORMAT.md as JSON). Files in trainsim's formats are read as they are. Files in other formats
(railtoolkit / TrainRuns.jl) are read by the core into its model objects and written back as the
equivalent trainsim mapping: every effort curve and resistance law of the model has an exact
trainsim form (a table for piecewise-linear curves, a piecewise law otherwise; Davis terms in SI
for the summed running resistance), so the converted train runs exactly as the file does.
"""

from __future__ import annotations

import itertools
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from trainsim.constants import KMH, KN, KW, TONNE
from trainsim.errors import InputError
from trainsim.io import loader
from trainsim.io import trainsim_yaml as tsy
from trainsim.model import EffortCurve, Route, Train
from trainsim.web.sessions import Loaded

__all__ = [
    "load_route_upload",
    "load_train_upload",
    "loaded_route",
    "loaded_train",
    "route_to_dict",
    "spec_dict",
    "train_to_dict",
]


def spec_dict(spec: Any) -> dict[str, Any]:
    """A validated spec as the JSON mapping the editor shows (same content as its YAML dump)."""
    return yaml.safe_load(tsy.dump_yaml(spec))


def _clean(x: float, digits: int = 12) -> float:
    """A float without conversion noise (1.0000000000000002 -> 1.0)."""
    return float(f"{x:.{digits}g}")


# ====================================================================== trains
def _table_points(curve: EffortCurve) -> tuple[list[float], list[float]] | None:
    """(speeds [m/s], forces [N]) of a curve that is a linearly interpolated table, else None."""
    starts, coefs, _, _ = curve.as_arrays()
    if np.any(coefs[:, 2] != 0) or np.any(coefs[:, 3] != 0) or coefs[-1, 1] != 0:
        return None
    values = coefs[:, 0] + coefs[:, 1] * starts
    ends = coefs[:-1, 0] + coefs[:-1, 1] * starts[1:]
    if not np.allclose(ends, values[1:], rtol=1e-9, atol=1e-6):
        return None  # a jump between intervals: not a table
    return starts.tolist(), values.tolist()


def _curve_dict(curve: EffortCurve) -> dict[str, Any]:
    """A traction spec for any effort curve: a table if it is one, else an exact piecewise law."""
    starts, coefs, force_cap, power_cap = curve.as_arrays()
    table = _table_points(curve)
    if table is not None:
        out: dict[str, Any] = {
            "model": "table",
            "speed_kmh": [_clean(v / KMH) for v in table[0]],
            "force_kn": [_clean(f / KN) for f in table[1]],
        }
    else:
        out = {
            "model": "piecewise",
            "intervals": [
                {
                    "from_kmh": _clean(s / KMH),
                    "c0_kn": _clean(c0 / KN),
                    "c1_kn_per_kmh": _clean(c1 * KMH / KN),
                    "c2_kn_per_kmh2": _clean(c2 * KMH**2 / KN),
                    "ch_kw": _clean(ch / KW),
                }
                for s, (c0, c1, c2, ch) in zip(starts, coefs, strict=True)
            ],
        }
    if math.isfinite(force_cap):
        out["max_force_kn"] = _clean(force_cap / KN)
    if math.isfinite(power_cap):
        out["max_power_kw"] = _clean(power_cap / KW)
    return out


def _fraction_of(curve: EffortCurve, base: EffortCurve) -> float | None:
    """k if ``curve`` is ``base`` scaled by k (regenerative braking as a share of traction), else None."""
    s1, c1, f1, p1 = curve.as_arrays()
    s0, c0, f0, p0 = base.as_arrays()
    if s1.shape != s0.shape or not np.allclose(s1, s0) or not np.any(c0):
        return None
    k = float(c1.flat[np.flatnonzero(c0)[0]] / c0.flat[np.flatnonzero(c0)[0]])
    same = np.allclose(c1, k * c0, rtol=1e-12, atol=1e-9)
    caps = all(
        (math.isinf(a) and math.isinf(b)) or math.isclose(a, k * b, rel_tol=1e-12)
        for a, b in ((f1, f0), (p1, p0))
    )
    return k if same and caps and 0 < k <= 1 else None


def _force_table(curve: EffortCurve, what: str) -> dict[str, Any]:
    """Speed/force table of a braking curve; curves that are not tables are sampled finely."""
    table = _table_points(curve)
    if table is None:
        v = np.linspace(0.0, 100.0, 201)  # up to 360 km/h, 1.8 km/h apart
        table = (v.tolist(), np.asarray(curve(v)).tolist())
    return {
        "speed_kmh": [_clean(v / KMH) for v in table[0]],
        "force_kn": [_clean(f / KN) for f in table[1]],
    }


def train_to_dict(train: Train) -> tuple[dict[str, Any], list[str]]:
    """The ``trainsim/train`` mapping of a model train, and notes on what the conversion did."""
    notes: list[str] = []
    out: dict[str, Any] = {"schema": "trainsim/train", "version": 1, "name": train.name}
    groups = [(v, len(list(g))) for v, g in itertools.groupby(train.vehicles)]
    vehicle_mass = sum(v.total_mass_kg * n for v, n in groups)
    if groups and math.isclose(vehicle_mass, train.mass_kg, rel_tol=1e-9):
        names: dict[str, int] = {}
        formation = []
        for v, n in groups:
            # vehicle names must be unique in a formation: number repeated types
            names[v.name] = names.get(v.name, 0) + 1
            name = v.name if names[v.name] == 1 else f"{v.name} ({names[v.name]})"
            entry: dict[str, Any] = {
                "name": name if name != "train" else "train vehicle",
                "count": n,
                "mass_t": _clean(v.mass_kg / TONNE),
                "load_t": _clean(v.load_kg / TONNE),
                "length_m": _clean(v.length_m),
            }
            if v.axles is not None:
                entry["axles"] = v.axles
            if v.powered:
                entry["powered"] = True
            formation.append(entry)
        out["formation"] = formation
    else:
        out["mass_t"] = _clean(train.mass_kg / TONNE)
        out["length_m"] = _clean(train.length_m)
    if train.adhesion_mass_kg is not None:
        out["adhesion_mass_t"] = _clean(train.adhesion_mass_kg / TONNE)
    out["rotating_mass_factor"] = _clean(train.rotating_mass_factor)
    out["max_speed_kmh"] = _clean(train.max_speed_mps / KMH)
    out["traction"] = _curve_dict(train.traction)
    braking = train.braking
    if braking.deceleration_mps2 is not None:
        brake: dict[str, Any] = {"model": "deceleration", "deceleration_mps2": braking.deceleration_mps2}
    else:
        assert braking.service_force is not None
        brake = {"model": "table", "table_is": "service", **_force_table(braking.service_force, "braking")}
    if braking.regenerative is None:
        brake["regenerative"] = "none"
    else:
        fraction = _fraction_of(braking.regenerative, train.traction)
        if fraction is not None:
            brake["regenerative"] = {"model": "fraction_of_traction", "fraction": _clean(fraction)}
        else:
            brake["regenerative"] = {"model": "table", **_force_table(braking.regenerative, "regenerative")}
            if _table_points(braking.regenerative) is None:
                notes.append("regenerative braking curve sampled every 1.8 km/h into a table")
    if braking.service_force is not None and _table_points(braking.service_force) is None:
        notes.append("service braking curve sampled every 1.8 km/h into a table")
    out["braking"] = brake
    law = train.resistance_law
    out["resistance"] = [
        {
            "family": "davis",
            "applies_to": "train",
            "a_n": _clean(law.c0),
            "b_n_s_per_m": _clean(law.c1),
            "c_n_s2_per_m2": _clean(law.c2),
        }
    ]
    notes.append(
        "converted to trainsim's format: running resistance as one Davis law in SI units (the sum of "
        + ", ".join(t.label for t in train.resistance)
        + f"), traction as a {out['traction']['model']} law"
    )
    if train.electrical is not None:
        e = train.electrical
        out["electrical"] = {
            "line_voltage_v": e.line_voltage_v,
            "traction_efficiency": e.traction_efficiency,
            "regenerative_efficiency": e.regenerative_efficiency,
            "power_factor": e.power_factor,
            "auxiliary_power_kw": _clean(e.auxiliary_power_w / KW),
            "receptivity": e.receptivity,
        }
    return out, notes


# ====================================================================== routes
def _changes(
    sections: list[tuple[float, float, float]], key: str, start: float, end: float, fill: float | None
) -> list[dict[str, Any]]:
    """A list of changes (``from_m`` + value, each to the next) from sections; gaps get ``fill``."""
    out: list[dict[str, Any]] = []
    pos = start
    for a, b, value in sorted(sections):
        if a > pos + 1e-9 and fill is not None:
            out.append({"from_m": _clean(pos), key: fill})
        out.append({"from_m": _clean(a), key: _clean(value)})
        pos = b
    if pos < end - 1e-9 and fill is not None and out:
        out.append({"from_m": _clean(pos), key: fill})
    return out


def route_to_dict(route: Route) -> dict[str, Any]:
    """The ``trainsim/route`` mapping of a model route."""
    lr = route.line_resistance
    out: dict[str, Any] = {
        "schema": "trainsim/route",
        "version": 1,
        "name": route.name,
        "start_m": _clean(route.start_m),
        "end_m": _clean(route.end_m),
        "stations": [
            {"name": s.name, "position_m": _clean(s.position_m), "dwell_s": s.dwell_s, "stop": s.stop}
            for s in route.stations
        ],
        "speed_limits": _changes(
            [(x.start_m, x.end_m, x.limit_mps / KMH) for x in route.speed_limits],
            "limit_kmh",
            route.start_m,
            route.end_m,
            None,
        ),
        "gradients": _changes(
            [(g.start_m, g.end_m, g.gradient_permille) for g in route.gradients],
            "gradient_permille",
            route.start_m,
            route.end_m,
            0.0,
        ),
        "curves": [
            {"from_m": _clean(c.start_m), "to_m": _clean(c.end_m), "radius_m": _clean(c.radius_m)}
            for c in route.curves
        ],
        "tunnels": [
            {"from_m": _clean(t.start_m), "to_m": _clean(t.end_m), "limiting_gradient": t.limiting_gradient}
            for t in route.tunnels
        ],
        "electrification": _changes(
            [(x.start_m, x.end_m, x.voltage_v) for x in route.electrification],
            "voltage_v",
            route.start_m,
            route.end_m,
            0.0,
        ),
        "line_resistance": {
            "curve_formula": lr.curve_formula,
            "tunnel_formula": lr.tunnel_formula,
            "gradient_formula": lr.gradient_formula,
            "apply_over": lr.apply_over,
        },
    }
    return out


# ====================================================================== loading
def loaded_train(data: Any, source: str, extra_notes: list[str] | None = None) -> Loaded:
    """Validate a ``trainsim/train`` mapping and build the train; InputError naming ``source``."""
    spec = tsy.train_spec_from_dict(data, source)
    train = spec.to_train(source)
    return Loaded(spec, train, source, [*(extra_notes or []), *spec.notes()], spec.warnings())


def loaded_route(data: Any, source: str, extra_notes: list[str] | None = None) -> Loaded:
    """Validate a ``trainsim/route`` mapping and build the route; InputError naming ``source``."""
    spec = tsy.route_spec_from_dict(data, source)
    route = spec.to_route(source)
    return Loaded(spec, route, source, [*(extra_notes or []), *spec.notes()])


def _write_temp(directory: str, text: str, name: str) -> Path:
    # the readers take paths; the file keeps its own name so that messages can name it
    safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in Path(name).name)[:100] or "upload.yaml"
    path = Path(directory) / safe
    path.write_text(text, encoding="utf-8")
    return path


def _renamed(exc: InputError, path: Path, name: str) -> InputError:
    if exc.file and str(path) in exc.file:
        renamed = InputError(
            exc.reason, file=name, field=exc.field, value=exc.value, allowed=exc.allowed, line=exc.line
        )
        if hasattr(exc, "problems"):
            renamed.problems = exc.problems  # type: ignore[attr-defined]
        return renamed
    return exc


def _decode(content: bytes, name: str) -> str:
    try:
        return content.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError("not a text file in UTF-8", file=name) from exc


def _inline_part(data: dict[str, Any], kind: str, name: str) -> dict[str, Any]:
    """The train or route (``kind``) written inline in an uploaded scenario, as its own file's mapping."""
    inline = data.get(kind)
    if not isinstance(inline, dict):
        raise InputError(
            f"this scenario names its {kind} file; open the {kind} file itself",
            file=name,
            field=kind,
            value=inline,
        )
    return {"schema": f"trainsim/{kind}", "version": 1, **inline}


def load_train_upload(content: bytes, name: str) -> tuple[dict[str, Any], Loaded]:
    """An uploaded train file of any format trainsim reads, as (editable mapping, loaded train).

    trainsim train files, scenario files with an inline train and railtoolkit rolling-stock files
    are accepted.
    """
    text = _decode(content, name)
    with tempfile.TemporaryDirectory(prefix="trainsim-web-") as directory:
        path = _write_temp(directory, text, name)
        try:
            data = tsy.read_yaml(path)
            detected = loader.detect_format(path)
            if detected.format == "trainsim/train":
                loaded = loaded_train(data, name)
                return spec_dict(loaded.spec), loaded
            if detected.format == "trainsim/scenario":
                loaded = loaded_train(_inline_part(data, "train", name), name)
                return spec_dict(loaded.spec), loaded
            if detected.format == "railtoolkit/rolling-stock":
                from trainsim.io import railtoolkit as rtk

                read = rtk.read_railtoolkit_train(path)
                mapping, notes = train_to_dict(read.train)
                notes = [f"read as railtoolkit rolling stock (train '{read.train_id}')", *read.notes, *notes]
                loaded = loaded_train(mapping, name, notes)
                return spec_dict(loaded.spec), loaded
        except InputError as exc:
            raise _renamed(exc, path, name) from exc
    raise InputError(
        f"this is a {detected.kind} file ({detected.format}), expected a train file",
        file=name,
        field="schema",
        allowed="trainsim/train, trainsim/scenario with an inline train, railtoolkit/rolling-stock",
    )


def load_route_upload(content: bytes, name: str) -> tuple[dict[str, Any], Loaded]:
    """An uploaded route file of any format trainsim reads, as (editable mapping, loaded route)."""
    text = _decode(content, name)
    with tempfile.TemporaryDirectory(prefix="trainsim-web-") as directory:
        path = _write_temp(directory, text, name)
        try:
            data = tsy.read_yaml(path)
            detected = loader.detect_format(path)
            if detected.format == "trainsim/route":
                loaded = loaded_route(data, name)
                return spec_dict(loaded.spec), loaded
            if detected.format == "trainsim/scenario":
                loaded = loaded_route(_inline_part(data, "route", name), name)
                return spec_dict(loaded.spec), loaded
            if detected.format == "railtoolkit/running-path":
                from trainsim.io import railtoolkit as rtk

                read = rtk.read_railtoolkit_path(path)
                mapping = route_to_dict(read.route)
                notes = [f"read as railtoolkit running path (path '{read.path_id}')", *read.notes]
                loaded = loaded_route(mapping, name, notes)
                return spec_dict(loaded.spec), loaded
        except InputError as exc:
            raise _renamed(exc, path, name) from exc
    raise InputError(
        f"this is a {detected.kind} file ({detected.format}), expected a route file",
        file=name,
        field="schema",
        allowed="trainsim/route, trainsim/scenario with an inline route, railtoolkit/running-path",
    )
