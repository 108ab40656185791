"""Plots and tables of a study: ``trainsim batch STUDY --report``.

Written to ``OUT/report/``:

* ``report.md``: the study at a glance (runs by status, statistics of the figures, what each plot
  shows, the first failures), with the plots embedded;
* ``statistics.csv``: count, mean, standard deviation, min, 5 / 50 / 95 % quantiles and max of every
  figure over the runs that have figures (``ok`` and ``stalled``);
* ``failures.csv``: every failed run with its parameters and error;
* for each swept parameter: ``energy_net_kwh_by_<param>.csv`` (mean energy per value, one column per
  group) and ``by_<param>.png`` (net energy and running time against the parameter, one line per group:
  the explicit run, or another swept parameter with at most 10 values; means over the other parameters);
  a parameter written as numbers with one unit (``driving.supplement: ["5%", "10%"]``) is plotted
  against the number (``driving.supplement [%]``);
* for each sampled parameter (or a swept one with more than 30 values): ``scatter_<param>.png``;
* with 20 runs or more: ``distributions.png`` (histograms of running time and net energy);
* for a timetable (departure times): ``timetable.png`` (net energy by departure, and the train graph:
  distance against clock time of every run).

Figures are drawn without pyplot (as :mod:`trainsim.plots`), through Agg.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from trainsim.batch.sink import META_FILE, read_results
from trainsim.batch.worker import DRIVING_METRICS, METRICS
from trainsim.errors import InputError

__all__ = ["Report", "write_report"]

#: The figures plotted against parameters.
PLOTTED = (("energy_net_kwh", "net energy [kWh]"), ("running_time_s", "running time [s]"))
#: Most distinct values of a parameter drawn as lines (more: a scatter plot).
MAX_LEVELS = 30
#: Most groups (lines) in one plot.
MAX_GROUPS = 10
#: A number with a unit, as in ``supplement: "10%"`` or ``"30 s"``.
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(%|[A-Za-z]+)\s*$")


@dataclass
class Report:
    """What :func:`write_report` wrote, and the figures it shows."""

    directory: Path
    files: list[Path] = field(default_factory=list)
    status_counts: dict[str, int] = field(default_factory=dict)
    statistics: Any = None  # pandas DataFrame: one row per figure

    @property
    def markdown(self) -> Path:
        return self.directory / "report.md"


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_") or "param"


def _clock(seconds: float) -> str:
    s = round(seconds)
    return f"{s // 3600:02d}:{s % 3600 // 60:02d}:{s % 60:02d}"


def _figure(nrows: int = 1, ncols: int = 2, size: tuple[float, float] = (11.0, 4.2)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes.ravel()


def _is_numeric(series) -> bool:
    import pandas as pd

    return pd.api.types.is_numeric_dtype(series) and not pd.api.types.is_bool_dtype(series)


def _as_numbers(series) -> tuple[Any, str] | None:
    """A text column whose values are all numbers with the same unit (``"5%"``, ``"10%"``) as floats,
    and the unit; None for any other column."""
    values, units = [], set()
    for v in series:
        m = _QUANTITY.match(v) if isinstance(v, str) else None
        if m is None:
            return None
        values.append(float(m.group(1)))
        units.add(m.group(2))
    if len(units) != 1:
        return None
    return np.asarray(values, dtype=float), units.pop()


def _group_column(df, x: str, params: list[str], kinds: dict[str, str]) -> str | None:
    """What the lines of a plot against ``x`` stand for: the explicit run, else another parameter
    with a few values."""
    if "run" in params and x != "run" and df["run"].nunique() > 1:
        return "run"
    for p in params:
        if p in (x, "sample", "departure_s", "run") or kinds.get(p) == "sampled":
            continue
        n = df[p].nunique()
        if 1 < n <= MAX_GROUPS:
            return p
    return None


def _statistics(ok):
    import pandas as pd

    rows = []
    for name in (*METRICS, "arrival_s", *DRIVING_METRICS, "max_draft_force_n", "max_buff_force_n"):
        if name not in ok.columns:
            continue
        v = pd.to_numeric(ok[name], errors="coerce").dropna().to_numpy(dtype=float)
        if not len(v):
            continue
        rows.append(
            {
                "figure": name,
                "count": len(v),
                "mean": v.mean(),
                "std": v.std(ddof=1) if len(v) > 1 else 0.0,
                "min": v.min(),
                "p05": np.quantile(v, 0.05),
                "median": np.median(v),
                "p95": np.quantile(v, 0.95),
                "max": v.max(),
            }
        )
    return pd.DataFrame(rows)


def _markdown_table(df, floatfmt: str = ".4g") -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(str(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for _, row in df.iterrows():
        cells = [format(v, floatfmt) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _plot_by_parameter(ok, x: str, group: str | None, path: Path) -> Any:
    """Net energy and running time against one swept parameter; the mean over the other parameters."""
    fig, axes = _figure()
    groups = [(None, ok)] if group is None else list(ok.groupby(group, sort=True))
    pivot = None
    for ax, (metric, label) in zip(axes, PLOTTED, strict=True):
        for key, sub in groups:
            mean = sub.groupby(x, sort=True)[metric].mean()
            ax.plot(
                mean.index, mean.to_numpy(), marker="o", label=None if key is None else f"{group} = {key}"
            )
        ax.set_xlabel(x)
        ax.set_ylabel(label + (" (mean)" if len(ok) > ok[x].nunique() * max(1, len(groups)) else ""))
        ax.grid(True, alpha=0.3)
        if group is not None:
            ax.legend(fontsize=8)
    fig.suptitle(f"{PLOTTED[0][1]} and {PLOTTED[1][1]} against {x}")
    fig.savefig(path, dpi=110)
    if group is None:
        pivot = ok.groupby(x, sort=True)["energy_net_kwh"].mean().to_frame("energy_net_kwh")
    else:
        pivot = ok.pivot_table(index=x, columns=group, values="energy_net_kwh", aggfunc="mean")
    return pivot


def _plot_scatter(ok, x: str, path: Path) -> None:
    fig, axes = _figure()
    for ax, (metric, label) in zip(axes, PLOTTED, strict=True):
        ax.scatter(ok[x], ok[metric], s=6, alpha=0.5)
        ax.set_xlabel(x)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"runs against {x}")
    fig.savefig(path, dpi=110)


def _plot_distributions(ok, path: Path) -> None:
    fig, axes = _figure()
    for ax, (metric, label) in zip(axes, PLOTTED, strict=True):
        v = ok[metric].dropna().to_numpy(dtype=float)
        ax.hist(v, bins=min(50, max(10, int(np.sqrt(len(v))))), color="tab:blue", alpha=0.8)
        for q, style in ((0.05, ":"), (0.5, "-"), (0.95, ":")):
            ax.axvline(np.quantile(v, q), color="k", linestyle=style, linewidth=1)
        ax.set_xlabel(label)
        ax.set_ylabel("runs")
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"distribution over {len(ok)} runs (lines: 5 %, median, 95 %)")
    fig.savefig(path, dpi=110)


def _busiest_hour(departures: np.ndarray) -> float:
    """Start [s] of the hour-long window with the most departures (starting at a departure)."""
    d = np.sort(departures)
    counts = np.searchsorted(d, d + 3600.0, side="left") - np.arange(len(d))
    return float(d[int(np.argmax(counts))])


def _plot_timetable(ok, path: Path) -> None:
    fig, axes = _figure()
    ax_e, ax_g = axes
    start = _busiest_hour(ok["departure_s"].to_numpy(dtype=float))
    end = start + 3600.0
    names = sorted(ok["run"].unique()) if "run" in ok.columns else [None]
    colours = {n: f"C{k % 10}" for k, n in enumerate(names)}
    for name in names:
        sub = ok if name is None else ok[ok["run"] == name]
        ax_e.plot(
            sub["departure_s"] / 3600.0, sub["energy_net_kwh"], "o", ms=3, color=colours[name], label=name
        )
        window = sub[(sub["arrival_s"] > start) & (sub["departure_s"] < end)]
        for _, row in window.iterrows():
            # train graph: clock time against distance run, station stops as horizontal steps
            t, d, dist = [], [], 0.0
            for sec in row["sections"]:
                t += [sec["departure_s"] / 3600.0, sec["arrival_s"] / 3600.0]
                d += [dist / 1000.0, (dist + sec["distance_m"]) / 1000.0]
                dist += sec["distance_m"]
            ax_g.plot(t, d, color=colours[name], linewidth=0.7)
    ax_e.set_xlabel("departure [h]")
    ax_e.set_ylabel("net energy [kWh]")
    ax_e.grid(True, alpha=0.3)
    if names != [None]:
        ax_e.legend(fontsize=8)
    ax_g.set_xlabel("time [h]")
    ax_g.set_ylabel("distance from the first station [km]")
    ax_g.grid(True, alpha=0.3)
    ax_g.set_xlim(start / 3600.0, end / 3600.0)
    ax_g.set_title(f"train graph of the busiest hour, {_clock(start)} - {_clock(end)}")
    fig.suptitle("timetable")
    fig.savefig(path, dpi=110)


def write_report(out: str | Path, directory: str | Path | None = None) -> Report:
    """Write the report of a study output directory (finished or not) into ``out/report``."""
    import pandas as pd

    out = Path(out)
    meta_path = out / META_FILE
    if not meta_path.exists():
        raise InputError(
            "no study results here", file=str(out), allowed="an output directory of trainsim batch"
        )
    meta = json.loads(meta_path.read_text())
    df = read_results(out)
    rep = Report(Path(directory) if directory is not None else out / "report")
    rep.directory.mkdir(parents=True, exist_ok=True)
    params = [p for p in meta.get("parameters", []) if p in df.columns]
    kinds = meta.get("parameter_kinds", {})
    total = int(meta.get("runs", len(df)))
    counts = df["status"].value_counts().to_dict() if "status" in df.columns else {}
    rep.status_counts = {str(k): int(v) for k, v in counts.items()}
    missing = total - len(df)
    ok = df[df["status"].isin(["ok", "stalled"])] if len(df) else df
    md: list[str] = [f"# {meta.get('study', 'study')}", ""]
    md.append(
        f"{len(df)} of {total} runs written" + (f" ({missing} not computed yet)" if missing else "") + "."
    )
    md.append("")
    md.append(
        _markdown_table(pd.DataFrame({"status": list(rep.status_counts), "runs": list(counts.values())}))
    )
    md.append("")

    rep.statistics = _statistics(ok) if len(ok) else pd.DataFrame()
    stats_path = rep.directory / "statistics.csv"
    rep.statistics.to_csv(stats_path, index=False)
    rep.files.append(stats_path)
    if len(rep.statistics):
        md += ["## Figures over the runs", "", _markdown_table(rep.statistics), ""]

    failed = df[df["status"] == "failed"] if len(df) else df
    fail_path = rep.directory / "failures.csv"
    cols = ["run_index", "run_id", *params, "error_type", "error"]
    (failed[cols] if len(failed) else pd.DataFrame(columns=cols)).to_csv(fail_path, index=False)
    rep.files.append(fail_path)

    figures: list[tuple[Path, str]] = []
    if len(ok):
        for param in params:
            if param in ("sample", "departure_s"):
                continue
            x = param
            if not _is_numeric(ok[param]):
                numbers = _as_numbers(ok[param])
                if numbers is None:
                    continue
                # a supplement sweep ("5%", "10%"...) is plotted against the number
                x = f"{param} [{numbers[1]}]"
                ok = ok.assign(**{x: numbers[0]})
            if ok[x].nunique() < 2:
                continue
            if kinds.get(param) != "sampled" and ok[x].nunique() <= MAX_LEVELS:
                group = _group_column(ok, param, params, kinds)
                png = rep.directory / f"by_{_slug(param)}.png"
                pivot = _plot_by_parameter(ok, x, group, png)
                csv = rep.directory / f"energy_net_kwh_by_{_slug(param)}.csv"
                pivot.to_csv(csv)
                rep.files += [png, csv]
                what = f"net energy and running time against {x}" + (
                    f", one line per {group}" if group else ""
                )
                figures.append((png, what))
            else:
                png = rep.directory / f"scatter_{_slug(param)}.png"
                _plot_scatter(ok, x, png)
                rep.files.append(png)
                figures.append((png, f"every run against its {x}"))
        if len(ok) >= 20:
            png = rep.directory / "distributions.png"
            _plot_distributions(ok, png)
            rep.files.append(png)
            figures.append((png, "distributions of running time and net energy"))
        if "departure_s" in ok.columns and ok["departure_s"].notna().any():
            png = rep.directory / "timetable.png"
            _plot_timetable(ok[ok["departure_s"].notna()], png)
            rep.files.append(png)
            figures.append((png, "net energy by departure and train graph"))
            first, last = ok["departure_s"].min(), ok["arrival_s"].max()
            md += [
                f"Timetable: first departure {_clock(first)}, last arrival {_clock(last)}, "
                f"{ok['energy_net_kwh'].sum():.1f} kWh net energy in all.",
                "",
            ]
    if "run" in params and len(ok):
        by_run = ok.groupby("run", sort=False).agg(
            runs=("run_id", "size"),
            running_time_s=("running_time_s", "mean"),
            total_time_s=("total_time_s", "mean"),
            energy_net_kwh=("energy_net_kwh", "mean"),
            energy_net_kwh_all=("energy_net_kwh", "sum"),
            peak_current_a=("peak_current_a", "max"),
        )
        run_csv = rep.directory / "by_run.csv"
        by_run.to_csv(run_csv)
        rep.files.append(run_csv)
        md += [
            "## By run (means; energy_net_kwh_all: sum over the run's departures)",
            "",
            _markdown_table(by_run.reset_index()),
            "",
        ]
    if figures:
        md += ["## Plots", ""]
        for png, what in figures:
            md += [f"### {what}", "", f"![{what}]({png.name})", ""]
    if len(failed):
        md += [f"## Failed runs ({len(failed)}, all in failures.csv)", ""]
        shown = failed[["run_index", *params, "error"]].head(20)
        md += [_markdown_table(shown), ""]
    rep.markdown.write_text("\n".join(md))
    rep.files.insert(0, rep.markdown)
    return rep
