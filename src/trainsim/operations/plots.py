"""Plots of an operation (matplotlib, written as PNG): the train graph with blocking-time stairs and
conflicts, the delay per station, and the minimum headway over the line."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trainsim.operations.line import Line
from trainsim.operations.simulate import OperationResult


def _figure(width: float = 11.0, height: float = 6.5):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt, *plt.subplots(figsize=(width, height))


def train_graph(line: Line, result: OperationResult, path: Path, max_trains: int = 200) -> Path:
    """Time-distance graph: operated runs (solid), planned runs (dashed), the operated blocking-time
    stairs (shaded boxes from blocking start to end over each route's extent) and the planned
    conflicts (red boxes)."""
    from matplotlib.patches import Rectangle

    plt, fig, ax = _figure()
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    trains = result.trains[:max_trains]
    shown = {t.id for t in trains}
    colour = {t.id: colours[i % len(colours)] for i, t in enumerate(trains)}
    for b in result.blocking:
        if b.train not in shown:
            continue
        lo, hi = sorted((b.from_m, b.to_m))
        ax.add_patch(
            Rectangle(
                (b.start_s / 60, lo / 1000),
                (b.end_s - b.start_s) / 60,
                (hi - lo) / 1000,
                color=colour[b.train],
                alpha=0.12,
                lw=0,
            )
        )
    planned = {(b.train, b.resource): b for b in result.planned_blocking}
    for c in result.conflicts:
        b = planned.get((c.second, c.resource))
        if b is None:
            continue
        lo, hi = sorted((b.from_m, b.to_m))
        ax.add_patch(
            Rectangle(
                (c.time_s / 60, lo / 1000), c.overlap_s / 60, (hi - lo) / 1000, fill=False, ec="red", lw=1.5
            )
        )
    for t in trains:
        for tr, style in ((t.planned_trajectory, "--"), (t.trajectory, "-")):
            if tr is None:
                continue
            pos = np.asarray(line.line_position(t.direction, tr.position_m), dtype=float)
            ax.plot(tr.time_s / 60, pos / 1000, style, color=colour[t.id], lw=1.0 if style == "-" else 0.7)
        if t.trajectory is not None:
            x0 = t.trajectory.time_s[0] / 60
            y0 = float(line.line_position(t.direction, t.trajectory.position_m[0])) / 1000
            ax.annotate(t.id, (x0, y0), fontsize=7, color=colour[t.id])
    for s in line.stations:
        ax.axhline(s.position_m / 1000, color="0.8", lw=0.6)
        ax.text(ax.get_xlim()[0], s.position_m / 1000, f" {s.name}", va="bottom", fontsize=8, color="0.4")
    ax.set_xlabel("time [min after midnight]")
    ax.set_ylabel("line position [km]")
    ax.set_title(
        f"{line.name} ({line.signalling.system})\nsolid: operated, dashed: planned, "
        "shaded: blocking times, red: conflicts of the plan",
        fontsize=10,
    )
    ax.autoscale_view()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def delay_plot(line: Line, result: OperationResult, path: Path) -> Path:
    """Delay of each train at each station (departure, arrival at the destination) [s]."""
    from matplotlib.lines import Line2D

    plt, fig, ax = _figure(10, 5)
    order = {s.name: i for i, s in enumerate(line.stations)}
    shown = result.trains[:200]
    named = 0
    for t in shown:
        xs = [order[s.station] for s in t.stops if s.delay_s is not None]
        ys = [s.delay_s for s in t.stops if s.delay_s is not None]
        if xs:
            # the first 12 trains by name in the legend, the others summed up in one entry
            ax.plot(xs, ys, "o-", ms=3, lw=0.8, label=t.id if named < 12 else None)
            named += 1
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xticks(range(len(line.stations)), [s.name for s in line.stations])
    ax.set_xlabel("station (in line order)")
    ax.set_ylabel("delay [s]")
    ax.set_title("delay per station (departure; arrival at the destination)")
    handles, labels = ax.get_legend_handles_labels()
    if named > 12:
        handles.append(Line2D([], [], color="0.5", marker="o", ms=3, lw=0.8))
        labels.append(f"... {named - 12} more trains")
    if not handles:
        handles, labels = [Line2D([], [], color="0.5", lw=0.8)], ["no train delays known"]
    ax.legend(handles, labels, fontsize=7, title="train", title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def headway_plot(line: Line, result: OperationResult, path: Path) -> Path:
    """For each pair of consecutive planned trains: the headway each route needs over the line
    (leader's blocking end minus follower's blocking start, plus their planned headway) [s]; the
    highest point is the pair's minimum headway."""
    plt, fig, ax = _figure(10, 5)
    by: dict[str, dict[str, tuple[float, float, float]]] = {}
    for b in result.planned_blocking:
        by.setdefault(b.train, {})[b.resource] = (b.start_s, b.end_s, 0.5 * (b.from_m + b.to_m))
    refs = {t.id: t.planned_trajectory.time_s[0] for t in result.trains}
    for h in result.headways[:50]:
        lead, foll = by.get(h.leader, {}), by.get(h.follower, {})
        pts = sorted(
            (foll[r][2] / 1000, lead[r][1] - foll[r][0] + (refs[h.follower] - refs[h.leader]))
            for r in foll
            if r in lead
        )
        if pts:
            x, y = zip(*pts, strict=True)
            ax.plot(
                x,
                y,
                ".-",
                lw=0.8,
                ms=3,
                label=f"{h.leader} -> {h.follower}" if len(result.headways) <= 12 else None,
            )
    ax.set_xlabel("line position [km]")
    ax.set_ylabel("headway needed [s]")
    ax.set_title("minimum headway over the line (consecutive planned trains)")
    if 0 < len(result.headways) <= 12:
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_plots(line: Line, result: OperationResult, out: Path) -> list[Path]:
    """The three plots into ``out``."""
    return [
        train_graph(line, result, out / "train_graph.png"),
        delay_plot(line, result, out / "delays.png"),
        headway_plot(line, result, out / "headways.png"),
    ]
