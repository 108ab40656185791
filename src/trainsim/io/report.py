"""What ``trainsim check`` shows: the report of a file and the key figures of trains and routes."""

from __future__ import annotations

from dataclasses import dataclass, field

from trainsim.constants import KMH, KN, TONNE
from trainsim.model import Route, Train

__all__ = ["CheckReport", "route_figures", "train_figures"]


@dataclass
class CheckReport:
    """What ``trainsim check FILE`` shows.

    Attributes:
        path: the file.
        kind: ``train``, ``route``, ``scenario`` or ``settings``.
        format: format name and version, e.g. ``trainsim/train v1``.
        name: name of the train / route / scenario.
        figures: key figures, already formatted with units.
        notes: defaults applied, readings made and fields ignored.
        warnings: things that look wrong but are not errors.
    """

    path: str
    kind: str
    format: str
    name: str
    figures: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def to_text(self) -> str:
        """The report as plain text, one item per line."""
        lines = [f"{self.path}: {self.kind} '{self.name}' ({self.format})"]
        width = max((len(k) for k in self.figures), default=0)
        lines += [f"  {k.ljust(width)}  {v}" for k, v in self.figures.items()]
        lines += [f"  note: {n}" for n in self.notes]
        lines += [f"  WARNING: {w}" for w in self.warnings]
        return "\n".join(lines)


def train_figures(train: Train) -> dict[str, str]:
    """Key figures of a train, formatted with units."""
    v_max = train.max_speed_mps
    figures = {
        "mass": f"{train.mass_kg / TONNE:.1f} t",
        "length": f"{train.length_m:.2f} m",
        "max speed": f"{v_max / KMH:.1f} km/h",
        "rotating mass factor": f"{train.rotating_mass_factor:.4f}",
        "vehicles": str(len(train.vehicles)) if train.vehicles else "(given as a whole)",
        "traction at 0 km/h": f"{float(train.traction(0.0)) / KN:.1f} kN",
        "traction at max speed": f"{float(train.traction(v_max)) / KN:.1f} kN",
        "resistance at max speed": f"{float(train.running_resistance_n(v_max)) / KN:.2f} kN "
        f"({len(train.resistance)} term(s))",
    }
    if train.braking.deceleration_mps2 is not None:
        figures["braking"] = f"constant deceleration {train.braking.deceleration_mps2:g} m/s^2"
    else:
        figures["braking"] = f"service force {float(train.max_braking_n(0.0)) / KN:.1f} kN at 0 km/h"
    figures["regenerative braking"] = "yes" if train.braking.regenerative is not None else "none"
    if train.electrical is not None:
        figures["line voltage"] = f"{train.electrical.line_voltage_v:g} V"
    return figures


def route_figures(route: Route) -> dict[str, str]:
    """Key figures of a route, formatted with units."""
    stations = ", ".join(
        f"{s.name} @ {s.position_m:g} m" + ("" if s.stop else " (no stop)") for s in route.stations
    )
    limits = [x.limit_mps / KMH for x in route.speed_limits]
    grades = [g.gradient_permille for g in route.gradients] or [0.0]
    lr = route.line_resistance
    return {
        "length": f"{route.length_m:.2f} m ({route.start_m:g} .. {route.end_m:g} m)",
        "stations": f"{len(route.stations)}: {stations}",
        "speed limits": f"{len(route.speed_limits)} section(s), {min(limits):g} .. {max(limits):g} km/h",
        "gradients": f"{len(route.gradients)} section(s), {min(grades):g} .. {max(grades):g} per mille",
        "curves": str(len(route.curves)),
        "tunnels": str(len(route.tunnels)),
        "line resistance": f"curves {lr.curve_formula}, tunnels {lr.tunnel_formula}, "
        f"gradients {lr.gradient_formula}, applied over {lr.apply_over}",
    }
