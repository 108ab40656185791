"""Figures of a multi-point run: coupler forces as a heat map over time and coupling, the force of one
coupling over time, and the speeds of the vehicles.

Like :mod:`trainsim.plots`, every function returns a :class:`matplotlib.figure.Figure` built without
``pyplot`` (an Agg canvas is attached explicitly).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from trainsim.constants import KMH
from trainsim.multipoint.result import MultiPointResult

__all__ = [
    "MULTIPOINT_PLOT_FILES",
    "plot_coupler_force",
    "plot_coupler_heatmap",
    "plot_vehicle_speeds",
    "save_multipoint_plots",
]

#: File names written by :func:`save_multipoint_plots`.
MULTIPOINT_PLOT_FILES = ("coupler_heatmap.png", "coupler_force.png", "vehicle_speeds.png")

_DPI = 120


def _figure(width: float = 10.0, height: float = 5.5) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def plot_coupler_heatmap(result: MultiPointResult, *, against: str = "time") -> Figure:
    """Coupler force by coupling (vertical, head at the top) and time or head position (horizontal):
    draft red, buff blue, in kN; the largest draft and buff forces are marked."""
    fig = _figure()
    ax = fig.add_subplot()
    forces = result.coupler_force_n.T / 1e3
    x = result.time_s if against == "time" else result.head_position_m / 1e3
    lim = max(float(np.max(np.abs(forces), initial=0.0)), 1.0)
    norm = TwoSlopeNorm(vcenter=0.0, vmin=-lim, vmax=lim)
    n_c = forces.shape[0]
    mesh = ax.pcolormesh(
        x, np.arange(n_c), forces, cmap="RdBu_r", norm=norm, shading="nearest", rasterized=True
    )
    fig.colorbar(mesh, ax=ax, label="coupler force [kN] (draft > 0, buff < 0)")
    for ext, marker, label in ((result.max_draft, "v", "max draft"), (result.max_buff, "^", "max buff")):
        if np.isfinite(ext.head_position_m):
            pos = ext.time_s if against == "time" else ext.head_position_m / 1e3
            ax.plot(
                pos, ext.coupler, marker, color="k", markersize=9, label=f"{label} {ext.force_n / 1e3:.0f} kN"
            )
    for loco in result.mptrain.locomotive_indices:
        ax.axhline(loco - 0.5, color="0.3", lw=0.6, ls=":")
    ax.set_ylim(n_c - 0.5, -0.5)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("coupling (0 = behind the head vehicle; dotted: in front of a locomotive)")
    ax.set_xlabel("time [s]" if against == "time" else "head position [km]")
    ax.set_title(f"In-train forces: {result.run.train_name}")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def plot_coupler_force(result: MultiPointResult, couplers: int | list[int] | None = None) -> Figure:
    """Force of chosen couplings over time [kN] (default: those with the largest draft and buff force),
    with the train's mean speed on a second axis."""
    if couplers is None:
        couplers = sorted({result.max_draft.coupler, result.max_buff.coupler})
    elif isinstance(couplers, int):
        couplers = [couplers]
    n_c = result.coupler_force_n.shape[1]
    for c in couplers:
        if not 0 <= c < n_c:
            raise ValueError(f"no coupling {c}: the train has couplings 0 .. {n_c - 1}")
    fig = _figure()
    ax = fig.add_subplot()
    for c in couplers:
        ax.plot(result.time_s, result.coupler_force_n[:, c] / 1e3, lw=0.9, label=f"coupling {c}")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("coupler force [kN] (draft > 0)")
    ax2 = ax.twinx()
    ax2.plot(result.time_s, result.mean_speed_mps / KMH, color="0.6", lw=0.8, ls="--", label="mean speed")
    ax2.set_ylabel("speed [km/h]")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], loc="upper right", fontsize=8)
    ax.set_title("Coupler force over time")
    return fig


def plot_vehicle_speeds(result: MultiPointResult, vehicles: list[int] | None = None) -> Figure:
    """Speed of some vehicles over time [km/h] (default: head, locomotives, rear)."""
    n = result.mptrain.n_vehicles
    if vehicles is None:
        vehicles = sorted({0, *result.mptrain.locomotive_indices.tolist(), n - 1})
    fig = _figure()
    ax = fig.add_subplot()
    names = result.vehicle_names
    for i in vehicles:
        ax.plot(result.time_s, result.speed_mps[:, i] / KMH, lw=0.8, label=f"{i}: {names[i]}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("speed [km/h]")
    ax.legend(fontsize=8)
    ax.set_title("Vehicle speeds")
    return fig


def save_multipoint_plots(result: MultiPointResult, out_dir: str | Path) -> list[Path]:
    """Write the three figures as PNG files into ``out_dir``; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in zip(
        MULTIPOINT_PLOT_FILES,
        (plot_coupler_heatmap(result), plot_coupler_force(result), plot_vehicle_speeds(result)),
        strict=True,
    ):
        path = out / name
        fig.savefig(path, dpi=_DPI)
        paths.append(path)
    return paths
