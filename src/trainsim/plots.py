"""Figures of a run, of a train's effort curves and of source 001's acceleration analysis.

Every function returns a :class:`matplotlib.figure.Figure` built without ``pyplot``, so that
figures are never registered in pyplot's global figure list (no leaks in long-running processes,
no interactive backend picked up by accident) and rendering always goes through Agg.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from trainsim.constants import KMH, KN, KW, MW, G
from trainsim.physics.line_resistance import gradient_ratio

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    # annotations only: trainsim.analysis.acceleration imports scipy.optimize (0.3-0.5 s, numpy.f2py and
    # scipy.special with it), which `trainsim run --out` writing its plots does not need
    from trainsim.analysis.acceleration import AccelerationAnalysis
    from trainsim.model.route import Route
    from trainsim.model.train import Train
    from trainsim.sim.result import RunResult

__all__ = [
    "PLOT_FILES",
    "plot_acceleration_analysis",
    "plot_effort_resistance",
    "plot_energy_sections",
    "plot_power_current",
    "plot_speed_distance",
    "plot_speed_time",
    "save_all",
]

#: File names written by :func:`save_all`, in order.
PLOT_FILES = (
    "speed_distance.png",
    "speed_time.png",
    "effort_resistance.png",
    "power_current.png",
    "energy_sections.png",
)

_DPI = 120


def _figure(ncols: int = 1, nrows: int = 1, *, width: float = 10.0, height: float = 5.5, **kw) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    # attach an Agg canvas explicitly: savefig then never depends on the configured backend
    FigureCanvasAgg(fig)
    fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig


def _step_xy(
    starts: Sequence[float], ends: Sequence[float], values: Sequence[float], lo: float, hi: float
) -> tuple[np.ndarray, np.ndarray]:
    """x, y of a piecewise constant function (0 where no section covers) for ``ax.plot``."""
    xs: list[float] = []
    ys: list[float] = []
    pos = lo
    for a, b, v in sorted(zip(starts, ends, values, strict=True)):
        a, b = max(a, lo), min(b, hi)
        if b <= a:
            continue
        if a > pos:  # uncovered stretch before this section: level / zero
            xs += [pos, a]
            ys += [0.0, 0.0]
        xs += [a, b]
        ys += [v, v]
        pos = b
    if pos < hi:
        xs += [pos, hi]
        ys += [0.0, 0.0]
    return np.array(xs), np.array(ys)


def _title(result: RunResult, what: str) -> str:
    # names can be long (source descriptions): wrap them so the title stays inside the figure
    import textwrap

    return "\n".join([what, *textwrap.wrap(f"{result.train_name} on {result.route_name}", width=95)])


# ====================================================================== run plots
def plot_speed_distance(
    result: RunResult,
    route: Route,
    train: Train,
    *,
    profile: Literal["gradient", "elevation"] = "gradient",
) -> Figure:
    """Speed [km/h] over distance [km] with the speed ceiling, the line limits, the stations and
    the gradient profile [per mille] (or the elevation derived from it [m]) on a secondary axis."""
    fig = _figure()
    ax: Axes = fig.axes[0]
    tr = result.trace
    km = tr.position_m / 1000.0
    lo, hi = route.start_m, route.end_m

    # the profile goes first, on its own axis behind the speed curves
    ax_p = ax.twinx()
    g_x, g_y = _step_xy(
        [g.start_m for g in route.gradients],
        [g.end_m for g in route.gradients],
        [g.gradient_permille for g in route.gradients],
        lo,
        hi,
    )
    if profile == "elevation":
        # integrate the gradient: elevation relative to the route start [m]
        rise = np.concatenate([[0.0], np.cumsum(np.diff(g_x) * 0.5 * (g_y[:-1] + g_y[1:]) / 1000.0)])
        ax_p.fill_between(g_x / 1000.0, rise, rise.min(), color="tab:brown", alpha=0.15, lw=0)
        ax_p.plot(g_x / 1000.0, rise, color="tab:brown", lw=1.0, label="elevation (from gradients)")
        ax_p.set_ylabel("elevation relative to start [m]")
    else:
        ax_p.fill_between(g_x / 1000.0, g_y, 0.0, color="tab:brown", alpha=0.15, lw=0)
        ax_p.plot(g_x / 1000.0, g_y, color="tab:brown", lw=1.0, label="gradient (+ uphill)")
        ax_p.set_ylabel("gradient [‰]")
        span = max(float(np.abs(g_y).max()) if len(g_y) else 0.0, 1.0)
        # symmetric range so that level track sits in the middle and up/down read at a glance
        ax_p.set_ylim(-3 * span, 3 * span)
    ax.set_zorder(ax_p.get_zorder() + 1)
    ax.patch.set_visible(False)

    l_x, l_y = _step_xy(
        [s.start_m for s in route.speed_limits],
        [s.end_m for s in route.speed_limits],
        [s.limit_mps / KMH for s in route.speed_limits],
        lo,
        hi,
    )
    ax.plot(l_x / 1000.0, l_y, color="tab:red", lw=1.0, ls=":", label="line speed limit")
    # the trace's ceiling at point k holds from point k to k + 1 (evaluated just right of the point)
    ax.step(
        km,
        tr.speed_limit_mps / KMH,
        where="post",
        color="tab:red",
        lw=1.2,
        alpha=0.7,
        label="speed ceiling (train)",
    )
    ax.plot(km, tr.speed_mps / KMH, color="tab:blue", lw=1.6, label="speed")

    top = max(float(np.nanmax(tr.speed_limit_mps)) if len(tr) else 0.0, train.max_speed_mps) / KMH
    for st in route.stations:
        ax.axvline(st.position_m / 1000.0, color="0.3", lw=0.8, ls="-" if st.stop else "--")
        # names beside their line, inside the axes: a station at the route's end gets it on the left
        at_end = st.position_m >= hi - 0.02 * (hi - lo)
        ax.annotate(
            st.name,
            (st.position_m / 1000.0, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(-2 if at_end else 2, -4),
            textcoords="offset points",
            rotation=90,
            ha="right" if at_end else "left",
            va="top",
            fontsize=8,
            color="0.2",
        )
    ax.set_ylim(0, top * 1.15)
    ax.set_xlim(lo / 1000.0, hi / 1000.0)
    ax.set_xlabel("distance [km]")
    ax.set_ylabel("speed [km/h]")
    ax.set_title(_title(result, "Speed over distance"))
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    h2, l2 = ax_p.get_legend_handles_labels()
    fig.legend(handles + h2, labels + l2, loc="outside lower center", fontsize=8, ncols=4)
    return fig


def plot_speed_time(result: RunResult) -> Figure:
    """Speed [km/h] and speed ceiling over time [s]."""
    fig = _figure()
    ax: Axes = fig.axes[0]
    tr = result.trace
    ax.plot(tr.time_s, tr.speed_limit_mps / KMH, color="tab:red", lw=1.0, alpha=0.7, label="speed ceiling")
    ax.plot(tr.time_s, tr.speed_mps / KMH, color="tab:blue", lw=1.6, label="speed")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("speed [km/h]")
    ax.set_ylim(bottom=0)
    ax.set_title(_title(result, "Speed over time"))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower center", fontsize=8)
    return fig


def plot_power_current(result: RunResult) -> Figure:
    """Mechanical, electrical (line) and source 002 paper-convention power [MW] over time, and the
    line current [A] with its paper-convention counterpart, on two stacked axes."""
    fig = _figure(nrows=2, height=7.0, sharex=True)
    ax_p, ax_i = fig.axes
    tr = result.trace
    ax_p.plot(tr.time_s, tr.mechanical_power_w / MW, color="tab:blue", lw=1.2, label="mechanical (wheel)")
    ax_p.plot(tr.time_s, tr.electrical_power_w / MW, color="tab:orange", lw=1.2, label="electrical (line)")
    ax_p.plot(
        tr.time_s,
        tr.paper_power_w / MW,
        color="tab:green",
        lw=1.0,
        ls="--",
        label="source 002: F v η (paper)",
    )
    ax_p.axhline(0.0, color="0.5", lw=0.6)
    ax_p.set_ylabel("power [MW]")
    ax_p.set_title(_title(result, "Power and line current"))
    ax_p.grid(True, alpha=0.3)
    ax_p.legend(fontsize=8, loc="upper right")

    if np.all(np.isnan(tr.line_current_a)):
        # a train without electrical data has no current; say so rather than leave an empty axis
        ax_i.text(
            0.5,
            0.5,
            "no electrical data: no line current",
            ha="center",
            va="center",
            transform=ax_i.transAxes,
        )
    else:
        ax_i.plot(tr.time_s, tr.line_current_a, color="tab:orange", lw=1.2, label="line current")
        ax_i.plot(
            tr.time_s,
            tr.paper_line_current_a,
            color="tab:green",
            lw=1.0,
            ls="--",
            label="source 002 convention (F v η / U cos φ)",
        )
        ax_i.axhline(0.0, color="0.5", lw=0.6)
        ax_i.legend(fontsize=8, loc="upper right")
    ax_i.set_xlabel("time [s]")
    ax_i.set_ylabel("line current [A]")
    ax_i.grid(True, alpha=0.3)
    return fig


def plot_energy_sections(result: RunResult) -> Figure:
    """Bar chart of traction work, regenerated energy and net line energy [kWh] per section."""
    fig = _figure(width=max(6.0, 2.0 + 1.4 * len(result.sections)))
    ax: Axes = fig.axes[0]
    names = [f"{s.from_station} → {s.to_station}" for s in result.sections]
    x = np.arange(len(names))
    width = 0.27
    series = (
        ("traction (wheel)", [s.energy_kwh.traction for s in result.sections], "tab:blue"),
        ("regenerated (to line)", [s.energy_kwh.regenerated for s in result.sections], "tab:green"),
        ("net (from line)", [s.energy_kwh.net for s in result.sections], "tab:orange"),
    )
    for k, (label, values, color) in enumerate(series):
        bars = ax.bar(x + (k - 1) * width, values, width, label=label, color=color)
        ax.bar_label(bars, fmt="%.1f", fontsize=7, padding=2)
    ax.set_xticks(x, names, rotation=30 if len(names) > 4 else 0, ha="right" if len(names) > 4 else "center")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("section")
    ax.set_ylabel("energy [kWh]")
    ax.set_title(_title(result, "Energy per section"))
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


# ====================================================================== train plots
def plot_effort_resistance(train: Train, *, gradients_permille: Sequence[float] = (10.0,)) -> Figure:
    """Maximum traction, service braking (and regenerative braking) and running resistance [kN]
    over speed [km/h]. The running resistance is the resistance on level track (0 per mille); the
    dashed lines add the gradient resistance of each of ``gradients_permille`` uphill."""
    fig = _figure()
    ax: Axes = fig.axes[0]
    v = np.linspace(0.0, train.max_speed_mps, 400)
    kmh = v / KMH
    ax.plot(kmh, np.asarray(train.traction(v)) / KN, color="tab:blue", lw=1.6, label="maximum traction")
    braking = train.braking
    if braking.service_force is not None:
        ax.plot(
            kmh, np.asarray(braking.service_force(v)) / KN, color="tab:red", lw=1.6, label="service braking"
        )
    else:
        # constant-deceleration braking has no force law; show the force it takes on level track
        equiv = np.full_like(v, train.inertial_mass_kg * float(braking.deceleration_mps2 or 0.0))
        ax.plot(
            kmh,
            equiv / KN,
            color="tab:red",
            lw=1.6,
            ls="-.",
            label=f"service braking ({braking.deceleration_mps2:g} m/s², ρ m a)",
        )
    if braking.regenerative is not None:
        ax.plot(
            kmh,
            np.asarray(braking.regenerative(v)) / KN,
            color="tab:green",
            lw=1.3,
            label="regenerative braking",
        )
    running = np.asarray(train.running_resistance_n(v), dtype=float)
    ax.plot(kmh, running / KN, color="black", lw=1.4, label="running resistance (level, 0 ‰)")
    for i in gradients_permille:
        # same gradient law as the run's default (small angle: i per mille = i N/kN)
        extra = gradient_ratio(i, "small_angle") * train.mass_kg * G
        ax.plot(kmh, (running + extra) / KN, color="black", lw=1.0, ls="--", label=f"resistance on {i:g} ‰")
    ax.set_xlim(0, train.max_speed_mps / KMH)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("speed [km/h]")
    ax.set_ylabel("force [kN]")
    ax.set_title(f"Effort and resistance\n{train.name}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return fig


def plot_energy_time_curve(table, title: str = "") -> Figure:
    """Energy drawn from the line against running time, from ``energy_time_curve``'s table."""
    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(table["running_time_s"], table["energy_kwh"], "o-", label="optimal strategy (net, from the line)")
    for _, row in table.iterrows():
        ax.annotate(f"{row['supplement_percent']:.0f} %", (row["running_time_s"], row["energy_kwh"]),
                    textcoords="offset points", xytext=(4, 4), fontsize=8)  # fmt: skip
    ax.set_xlabel("running time [s]")
    ax.set_ylabel("energy [kWh]")
    import textwrap

    ax.set_title("\n".join(["Energy against running time", *textwrap.wrap(title, width=80)]))
    ax.grid(True, alpha=0.3)
    ax.legend()
    return fig


def plot_acceleration_analysis(analysis: AccelerationAnalysis) -> Figure:
    """Source 001's two plots side by side: available power P_available(v) [kW] and the speed gained
    in one time step dv(v) [m/s], both over speed [km/h], with the balancing speed marked."""
    fig = _figure(ncols=2, width=12.0, height=5.0)
    ax_p, ax_v = fig.axes
    kmh = analysis.speed_mps / KMH
    ax_p.plot(
        kmh, analysis.available_power_w / KW, color="tab:blue", lw=1.6, label="P_available = η P_nom − R(v) v"
    )
    ax_p.set_ylabel("available power [kW]")
    ax_p.set_title(
        f"Available power (P_nom = {analysis.nominal_power_w / KW:g} kW, η = {analysis.efficiency:g})"
    )
    ax_v.plot(kmh, analysis.delta_v_mps, color="tab:orange", lw=1.6, label=f"Δv in {analysis.dt_s:g} s")
    ax_v.set_ylabel(f"speed gained in {analysis.dt_s:g} s [m/s]")
    ax_v.set_title(f"Speed increment per step (k = {analysis.mass_factor:g})")
    for ax in (ax_p, ax_v):
        ax.axhline(0.0, color="0.5", lw=0.6)
        if analysis.balancing_speed_mps is not None:
            vb = analysis.balancing_speed_mps / KMH
            if vb <= 1.05 * kmh.max():
                ax.axvline(vb, color="tab:red", lw=1.0, ls="--", label=f"balancing speed {vb:.1f} km/h")
            else:
                # a line far right of the curves would squash them: name it in the legend only
                ax.plot([], [], " ", label=f"balancing speed {vb:.1f} km/h (beyond the range shown)")
        ax.set_xlabel("speed [km/h]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    return fig


# ====================================================================== files
def save_all(result: RunResult, route: Route, train: Train, out_dir: str | Path) -> list[Path]:
    """Write the run's plots as PNG files (see :data:`PLOT_FILES`) into ``out_dir``; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = (
        plot_speed_distance(result, route, train),
        plot_speed_time(result),
        plot_effort_resistance(train),
        plot_power_current(result),
        plot_energy_sections(result),
    )
    paths = []
    for name, fig in zip(PLOT_FILES, figures, strict=True):
        path = out / name
        fig.savefig(path, dpi=_DPI)
        paths.append(path)
    return paths
