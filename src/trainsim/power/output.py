"""CSV tables and matplotlib plots of a power simulation (the report layer of the power package)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trainsim.power.simulation import PowerResult

__all__ = ["moving_rms_a", "save_plots", "substation_current_figure", "write_outputs"]


def write_outputs(result: PowerResult, out: Path, *, plots: bool = True) -> list[Path]:
    """Write ``trains.csv`` (long table, one row per train and step on the network),
    ``substations.csv`` (power [kW] and current [A] of each substation per step),
    ``network.csv`` (losses [kW]: line, contact line, return, substations; rail potential extremes
    [V] per step), ``substation_table.csv``
    (one row per substation: energy, peak power, RMS currents, overloads) and the plots."""
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    written = []
    t = result.time_s
    rows = []
    for k, tid in enumerate(result.train_ids):
        # train_series / train_time_s: a train's own steps, for full and compact (whole-day) results alike
        on = np.isfinite(result.train_series(result.train_position_m, k))
        tk = result.train_time_s(k)
        rows.append(
            pd.DataFrame(
                {
                    "time_s": tk[on],
                    "train": tid,
                    "position_m": result.train_series(result.train_position_m, k)[on],
                    "voltage_v": result.train_series(result.train_voltage_v, k)[on],
                    "current_a": result.train_series(result.train_current_a, k)[on],
                    "power_kw": result.train_series(result.train_power_w, k)[on] / 1e3,
                    "traction_demand_kw": result.train_series(result.traction_demand_w, k)[on] / 1e3,
                    "traction_delivered_kw": result.train_series(result.traction_delivered_w, k)[on] / 1e3,
                    "regen_offered_kw": result.train_series(result.regen_offered_w, k)[on] / 1e3,
                    "regen_accepted_kw": result.train_series(result.regen_accepted_w, k)[on] / 1e3,
                }
            )
        )
    path = out / "trains.csv"
    pd.concat(rows).sort_values(["time_s", "train"]).to_csv(path, index=False, float_format="%.4f")
    written.append(path)
    subs = {"time_s": t}
    for i, s in enumerate(result.network.substations):
        subs[f"{s.id}_power_kw"] = result.substation_power_w[:, i] / 1e3
        subs[f"{s.id}_current_a"] = result.substation_current_a[:, i]
    path = out / "substations.csv"
    pd.DataFrame(subs).to_csv(path, index=False, float_format="%.4f")
    written.append(path)
    path = out / "network.csv"
    columns = {"time_s": t, "line_loss_kw": result.line_loss_w / 1e3}
    split = _loss_split_w(result)
    if split is not None:
        columns["contact_loss_kw"], columns["return_loss_kw"] = split[0] / 1e3, split[1] / 1e3
    columns.update(
        {
            "substation_loss_kw": result.substation_loss_w / 1e3,
            "rail_potential_min_v": result.rail_potential_min_v,
            "rail_potential_max_v": result.rail_potential_max_v,
            "converged": result.converged,
            "iterations": result.iterations,
        }
    )
    pd.DataFrame(columns).to_csv(path, index=False, float_format="%.4f")
    written.append(path)
    table = []
    for s in result.summary()["substations"]:
        row = {k: v for k, v in s.items() if k not in ("rms_current_max_a", "overload_events")}
        row.update({f"rms_{k}_a": v for k, v in s["rms_current_max_a"].items()})
        row["overload_events"] = len(s["overload_events"])
        table.append(row)
    path = out / "substation_table.csv"
    pd.DataFrame(table).to_csv(path, index=False, float_format="%.4f")
    written.append(path)
    if plots:
        written += save_plots(result, out)
    return written


def _loss_split_w(result: PowerResult) -> tuple[np.ndarray, np.ndarray] | None:
    """(contact line, return) losses per step [W], or None for a result that does not record the
    split (``line_loss_w`` is then their sum, shown as one)."""
    contact, ret = getattr(result, "contact_loss_w", None), getattr(result, "return_loss_w", None)
    return None if contact is None or ret is None else (contact, ret)


def save_plots(result: PowerResult, out: Path) -> list[Path]:
    """PNG plots: pantograph voltage over time and over position (with the EN 50163 limits),
    substation power over time, energy per substation and the fate of regenerated energy, rail
    potential extremes over time (DC with rail-to-earth conductance), train current over time,
    substation current with its moving RMS over 1 min / 15 min / 1 h and the overload events,
    network losses over time, stray current over time (where defined) and time lost per train."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lim = result.network.limits
    written = []

    def save(fig, name: str) -> None:
        path = out / name
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    def limit_lines(ax) -> None:
        for value, label in (
            (lim.min2_v, "Umin2"),
            (lim.min1_v, "Umin1"),
            (lim.nominal_v, "Un"),
            (lim.max1_v, "Umax1"),
            (lim.max2_v, "Umax2"),
        ):
            ax.axhline(value, color="0.6", lw=0.8, ls="--")
            ax.text(
                0.995,
                value,
                f" {label}",
                color="0.4",
                fontsize=7,
                ha="right",
                va="bottom",
                transform=ax.get_yaxis_transform(),
            )

    fig, ax = plt.subplots(figsize=(10, 4.5))
    for k in range(len(result.train_ids)):
        ax.plot(result.train_time_s(k), result.train_series(result.train_voltage_v, k), lw=0.7)
    limit_lines(ax)
    ax.set(xlabel="time [s]", ylabel="pantograph voltage [V]", title="Pantograph voltage of every train")
    save(fig, "voltage_time.png")

    fig, ax = plt.subplots(figsize=(10, 4.5))
    for k in range(len(result.train_ids)):
        ax.plot(
            result.train_series(result.train_position_m, k) / 1e3,
            result.train_series(result.train_voltage_v, k),
            ".",
            ms=1.2,
        )
    limit_lines(ax)
    for s in result.network.substations:
        ax.axvline(s.position_m / 1e3, color="tab:red", lw=0.6, alpha=0.5)
    ax.set(
        xlabel="position [km] (red: substations)",
        ylabel="pantograph voltage [V]",
        title="Pantograph voltage over position",
    )
    save(fig, "voltage_position.png")

    fig, ax = plt.subplots(figsize=(10, 4.5))
    for i, s in enumerate(result.network.substations):
        ax.plot(result.time_s, result.substation_power_w[:, i] / 1e3, lw=0.7, label=s.id)
        if s.rated_power_w:
            ax.axhline(s.rated_power_w / 1e3, color="0.6", lw=0.6, ls=":")
    ax.axhline(0, color="k", lw=0.5)
    ax.set(xlabel="time [s]", ylabel="power [kW] (negative: returned)", title="Substation power")
    ax.legend(fontsize=7, ncol=4)
    save(fig, "substation_power.png")

    s = result.summary()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4.2))
    ids = [x["id"] for x in s["substations"]]
    a1.bar(ids, [x["energy_delivered_kwh"] for x in s["substations"]], label="delivered")
    a1.bar(ids, [-x["energy_returned_kwh"] for x in s["substations"]], label="returned")
    a1.set(ylabel="energy [kWh]", title="Energy per substation")
    a1.legend(fontsize=8)
    r = s["regen_kwh"]
    a2.bar(
        ["used by trains", "returned", "dissipated"],
        [r["used_by_trains"], r["returned"], r["dissipated"]],
        color=["tab:green", "tab:blue", "tab:red"],
    )
    a2.set(ylabel="energy [kWh]", title=f"Regenerated energy ({r['offered']:.1f} kWh offered)")
    save(fig, "energy.png")

    if np.any(np.isfinite(result.rail_potential_max_v)):
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.plot(result.time_s, result.rail_potential_max_v, lw=0.7, label="highest")
        ax.plot(result.time_s, result.rail_potential_min_v, lw=0.7, label="lowest")
        ax.set(xlabel="time [s]", ylabel="rail-to-earth potential [V]", title="Rail potential extremes")
        ax.legend(fontsize=8)
        save(fig, "rail_potential.png")

    fig, ax = plt.subplots(figsize=(10, 4.5))
    for k, tid in enumerate(result.train_ids):
        ax.plot(result.train_time_s(k), result.train_series(result.train_current_a, k), lw=0.7, label=tid)
    ax.axhline(0, color="k", lw=0.5)
    ax.set(xlabel="time [s]", ylabel="train current [A] (negative: regenerating)", title="Train current")
    if len(result.train_ids) <= 24:
        ax.legend(fontsize=7, ncol=6)
    save(fig, "train_current.png")

    save(substation_current_figure(result, plt), "substation_current.png")

    fig, ax = plt.subplots(figsize=(10, 4))
    split = _loss_split_w(result)
    if split is None:
        ax.plot(result.time_s, result.line_loss_w / 1e3, lw=0.7, label="line")
    else:
        ax.plot(result.time_s, split[0] / 1e3, lw=0.7, label="contact line")
        if np.any(split[1] != 0.0):
            ax.plot(result.time_s, split[1] / 1e3, lw=0.7, label="return (rails)")
    ax.plot(result.time_s, result.substation_loss_w / 1e3, lw=0.7, label="substations (internal)")
    ax.plot(result.time_s, (result.line_loss_w + result.substation_loss_w) / 1e3, lw=0.7, label="total")
    ax.set(
        xlabel="time [s]",
        ylabel="losses [kW]",
        title=f"Network losses ({s['losses_kwh']:.1f} kWh in total)",
    )
    ax.legend(fontsize=8)
    save(fig, "losses.png")

    stray = result.stray_current_a
    if stray is not None and np.any(np.isfinite(stray)):
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.plot(result.time_s, stray, lw=0.7, label="stray current")
        ax.axhline(float(np.nanmean(stray)), color="0.5", lw=0.8, ls="--", label="mean")
        ax.set(
            xlabel="time [s]",
            ylabel="stray current [A]",
            title=f"Stray current ({s['stray_current_a']['charge_ah']:.2f} Ah leaked)",
        )
        ax.legend(fontsize=8)
        save(fig, "stray_current.png")

    lost = [(t["id"], t.get("time_lost_s")) for t in s["trains"]]
    if any(v is not None for _, v in lost):
        from trainsim.power.study import TIME_LOST_TOLERANCE_S

        fig, ax = plt.subplots(figsize=(10, 4))
        ids = [tid for tid, _ in lost]
        ax.bar(ids, [np.nan if v is None else v for _, v in lost], label="time lost")
        ax.axhline(0, color="k", lw=0.5)
        ax.axhline(TIME_LOST_TOLERANCE_S, color="tab:red", lw=0.8, ls="--", label="tolerance")
        ax.set(xlabel="train", ylabel="time lost [s]", title="Running time lost to limited traction")
        ax.tick_params(axis="x", labelrotation=90 if len(ids) > 12 else 0, labelsize=7)
        ax.legend(fontsize=8)
        save(fig, "time_lost.png")
    return written


def moving_rms_a(result: PowerResult, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Moving RMS current of every substation over ``window_s`` [A], [step, substation], with the
    time at the end of each window [s]; empty when the run is shorter than the window. Its maximum
    is ``PowerResult.rms_current_a(window_s)``."""
    n = round(window_s / result.dt_s)
    i2 = result.substation_current_a**2
    if n < 1 or n > len(result.time_s):
        return np.empty(0), np.empty((0, i2.shape[1]))
    c = np.vstack([np.zeros((1, i2.shape[1])), np.cumsum(i2, axis=0)])
    return result.time_s[n - 1 :], np.sqrt((c[n:] - c[:-n]) / n)


def substation_current_figure(result: PowerResult, plt):
    """Substation current over time with the overload events shaded (top) and its moving RMS over
    the windows of ``RMS_WINDOWS_S`` (bottom); each RMS line has the gid ``rms_<window>s_<id>``."""
    from trainsim.power.simulation import RMS_WINDOWS_S

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    shaded = False
    for si, sub in enumerate(result.network.substations):
        color = colors[si % len(colors)]
        a1.plot(result.time_s, result.substation_current_a[:, si], lw=0.7, color=color, label=sub.id)
        for ev in result.overload_events(si):
            a1.axvspan(
                ev["start_s"],
                ev["start_s"] + ev["duration_s"],
                color="tab:red",
                alpha=0.5 if ev["beyond_overload"] else 0.2,
                lw=0,
                label=None if shaded else "overload (above rated power)",
            )
            shaded = True
        for window, ls in zip(RMS_WINDOWS_S, ("-", "--", ":"), strict=False):
            t, rms = moving_rms_a(result, window)
            if len(t):
                a2.plot(
                    t,
                    rms[:, si],
                    lw=0.9,
                    ls=ls,
                    color=color,
                    gid=f"rms_{int(window)}s_{sub.id}",
                    label=f"{sub.id} {_window_label(window)}",
                )
    a1.axhline(0, color="k", lw=0.5)
    a1.set(ylabel="current [A]", title="Substation current (red: overload events)")
    a1.legend(fontsize=7, ncol=5)
    a2.set(
        xlabel="time [s] (end of the window)",
        ylabel="moving RMS current [A]",
        title="Moving RMS substation current (solid 1 min, dashed 15 min, dotted 1 h)",
    )
    if a2.lines:
        a2.legend(fontsize=6, ncol=6)
    return fig


def _window_label(window_s: float) -> str:
    if window_s >= 3600 and window_s % 3600 == 0:
        return f"{int(window_s // 3600)} h"
    if window_s >= 60 and window_s % 60 == 0:
        return f"{int(window_s // 60)} min"
    return f"{window_s:g} s"
