"""JSON bodies of the API: a train's curves and figures, a route's profile, a run's plot data."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from trainsim.constants import KMH, KN, KW, KWH, TONNE, G
from trainsim.model.route import Route
from trainsim.model.train import Train
from trainsim.sim.result import RunResult
from trainsim.web.sessions import Loaded, StoredRun


def floats(values: Any, digits: int = 4) -> list[float | None]:
    """A numeric array as a JSON list, rounded to ``digits`` decimals, NaN and inf as null."""
    rounded = np.round(np.asarray(values, dtype=float), digits)
    if np.isfinite(rounded).all():
        return rounded.tolist()
    return [float(x) if math.isfinite(x) else None for x in rounded.tolist()]


def _num(x: float | None) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


# ====================================================================== train
def train_figures(train: Train) -> dict[str, Any]:
    """Key figures of a train in engineering units."""
    v_max = train.max_speed_mps
    braking = train.braking
    return {
        "mass_t": train.mass_kg / TONNE,
        "inertial_mass_t": train.inertial_mass_kg / TONNE,
        "rotating_mass_factor": train.rotating_mass_factor,
        "length_m": train.length_m,
        "vehicles": len(train.vehicles),
        "max_speed_kmh": v_max / KMH,
        "traction_at_0_kn": float(train.traction(0.0)) / KN,
        "traction_at_max_speed_kn": float(train.traction(v_max)) / KN,
        "max_traction_power_kw": float(
            np.max(np.asarray(train.traction(np.linspace(0, v_max, 200))) * np.linspace(0, v_max, 200))
        )
        / KW,
        "resistance_at_max_speed_kn": float(train.running_resistance_n(v_max)) / KN,
        "braking": (
            f"constant deceleration {braking.deceleration_mps2:g} m/s²"
            if braking.deceleration_mps2 is not None
            else f"service force {float(train.max_braking_n(0.0)) / KN:.1f} kN at 0 km/h"
        ),
        "regenerative_braking": braking.regenerative is not None,
        "line_voltage_v": train.electrical.line_voltage_v if train.electrical else None,
    }


def train_curves(train: Train, points: int = 161) -> dict[str, Any]:
    """Effort and resistance over speed [kN over km/h] for the page's plot."""
    v = np.linspace(0.0, train.max_speed_mps, points)
    braking = train.braking
    if braking.service_force is not None:
        brake = np.asarray(braking.service_force(v))
        brake_label = "service braking"
    else:
        # constant-deceleration braking has no force law: the force it takes on level track
        brake = np.full_like(v, train.inertial_mass_kg * float(braking.deceleration_mps2 or 0.0))
        brake_label = f"service braking ({braking.deceleration_mps2:g} m/s², ρ m a)"
    running = np.asarray(train.running_resistance_n(v), dtype=float)
    return {
        "speed_kmh": floats(v / KMH, 3),
        "traction_kn": floats(np.asarray(train.traction(v)) / KN),
        "braking_kn": floats(brake / KN),
        "braking_label": brake_label,
        "regenerative_kn": floats(np.asarray(braking.regenerative(v)) / KN) if braking.regenerative else None,
        "resistance_kn": floats(running / KN),
        # the same resistance on a 10 per mille climb (small-angle gradient law: i N/kN)
        "resistance_10_permille_kn": floats((running + 0.010 * train.mass_kg * G) / KN),
    }


def train_payload(spec: dict[str, Any], loaded: Loaded) -> dict[str, Any]:
    """What the train endpoints answer."""
    train: Train = loaded.model
    return {
        "spec": spec,
        "source": loaded.source,
        "name": train.name,
        "notes": loaded.notes,
        "warnings": loaded.warnings,
        "figures": train_figures(train),
        "curves": train_curves(train),
    }


# ====================================================================== route
def route_profile(route: Route) -> dict[str, Any]:
    """A route's line data for the profile plots (positions in m, limits in km/h)."""
    lo, hi = route.start_m, route.end_m
    # elevation relative to the start, integrated from the gradients (m per km = per mille)
    xs, zs, z, pos = [lo], [0.0], 0.0, lo
    for g in sorted(route.gradients, key=lambda g: g.start_m):
        if g.start_m > pos:
            xs.append(g.start_m)
            zs.append(z)
        z += (g.end_m - g.start_m) * g.gradient_permille / 1000.0
        xs.append(g.end_m)
        zs.append(z)
        pos = g.end_m
    if pos < hi:
        xs.append(hi)
        zs.append(z)
    return {
        "name": route.name,
        "start_m": lo,
        "end_m": hi,
        "stations": [
            {"name": s.name, "position_m": s.position_m, "dwell_s": s.dwell_s, "stop": s.stop}
            for s in route.stations
        ],
        "speed_limits": [[x.start_m, x.end_m, x.limit_mps / KMH] for x in route.speed_limits],
        "gradients": [[g.start_m, g.end_m, g.gradient_permille] for g in route.gradients],
        "curves": [[c.start_m, c.end_m, c.radius_m] for c in route.curves],
        "tunnels": [[t.start_m, t.end_m] for t in route.tunnels],
        "electrification": [[e.start_m, e.end_m, e.voltage_v] for e in route.electrification],
        "elevation": {"position_m": floats(xs, 2), "elevation_m": floats(zs, 3)},
    }


def route_payload(spec: dict[str, Any], loaded: Loaded) -> dict[str, Any]:
    """What the route endpoints answer."""
    route: Route = loaded.model
    return {
        "spec": spec,
        "source": loaded.source,
        "name": route.name,
        "notes": loaded.notes,
        "warnings": loaded.warnings,
        "figures": {
            "length_m": route.length_m,
            "stations": len(route.stations),
            "stops": len(route.stops),
            "speed_limit_sections": len(route.speed_limits),
            "gradient_sections": len(route.gradients),
            "curves": len(route.curves),
            "tunnels": len(route.tunnels),
        },
        "profile": route_profile(route),
    }


# ====================================================================== runs
def _sample(n: int, max_points: int) -> np.ndarray:
    if n <= max_points:
        return np.arange(n)
    idx = np.unique(np.linspace(0, n - 1, max_points).round().astype(int))
    return idx


def run_plot(result: RunResult, max_points: int) -> dict[str, Any]:
    """A run's trace for plotting, at most ``max_points`` points."""
    tr = result.trace
    i = _sample(len(tr), max_points)
    names = tr.regime_names
    return {
        "points": len(tr),
        "shown_points": len(i),
        "time_s": floats(tr.time_s[i], 3),
        "position_m": floats(tr.position_m[i], 3),
        "speed_kmh": floats(tr.speed_mps[i] / KMH, 3),
        "speed_limit_kmh": floats(tr.speed_limit_mps[i] / KMH, 3),
        "acceleration_mps2": floats(tr.acceleration_mps2[i], 4),
        "traction_force_kn": floats(tr.traction_force_n[i] / KN, 3),
        "braking_force_kn": floats(tr.braking_force_n[i] / KN, 3),
        "mechanical_power_kw": floats(tr.mechanical_power_w[i] / KW, 2),
        "electrical_power_kw": floats(tr.electrical_power_w[i] / KW, 2),
        "line_current_a": floats(tr.line_current_a[i], 1),
        "electrical_energy_kwh": floats(tr.electrical_energy_j[i] / KWH, 4),
        "regime": [names[k] for k in i.tolist()],
    }


def run_brief(run: StoredRun) -> dict[str, Any]:
    """A run in the runs list."""
    r = run.result
    return {
        "id": run.id,
        "label": run.label,
        "strategy": run.strategy,
        "kind": r.kind,
        "status": r.status,
        "created": run.created,
        "train": r.train_name,
        "route": r.route_name,
        "running_time_s": _num(r.running_time_s),
        "total_time_s": _num(r.total_time_s),
        "energy_net_kwh": _num(r.energy_kwh.net),
    }


def run_body(result: RunResult, route: Route, max_points: int) -> dict[str, Any]:
    """The heavy part of a run's answer: summary, plot data and line profile."""
    return {
        "summary": result.summary(),
        "plot": run_plot(result, max_points),
        "profile": route_profile(route),
    }


def run_payload(run: StoredRun, max_points: int) -> dict[str, Any]:
    """A run with its summary and plot data."""
    return {**run_brief(run), "params": run.params, **run_body(run.result, run.route, max_points)}
