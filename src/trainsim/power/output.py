"""CSV tables and matplotlib plots of a power simulation (the report layer of the power package)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trainsim.power.simulation import PowerResult

__all__ = ["save_plots", "write_outputs"]


def write_outputs(result: PowerResult, out: Path, *, plots: bool = True) -> list[Path]:
    """Write ``trains.csv`` (long table, one row per train and step on the network),
    ``substations.csv`` (power [kW] and current [A] of each substation per step),
    ``network.csv`` (losses [kW], rail potential extremes [V] per step), ``substation_table.csv``
    (one row per substation: energy, peak power, RMS currents, overloads) and the plots."""
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    written = []
    t = result.time_s
    rows = []
    for k, tid in enumerate(result.train_ids):
        on = np.isfinite(result.train_position_m[:, k])
        rows.append(
            pd.DataFrame(
                {
                    "time_s": t[on],
                    "train": tid,
                    "position_m": result.train_position_m[on, k],
                    "voltage_v": result.train_voltage_v[on, k],
                    "current_a": result.train_current_a[on, k],
                    "power_kw": result.train_power_w[on, k] / 1e3,
                    "traction_demand_kw": result.traction_demand_w[on, k] / 1e3,
                    "traction_delivered_kw": result.traction_delivered_w[on, k] / 1e3,
                    "regen_offered_kw": result.regen_offered_w[on, k] / 1e3,
                    "regen_accepted_kw": result.regen_accepted_w[on, k] / 1e3,
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
    pd.DataFrame(
        {
            "time_s": t,
            "line_loss_kw": result.line_loss_w / 1e3,
            "substation_loss_kw": result.substation_loss_w / 1e3,
            "rail_potential_min_v": result.rail_potential_min_v,
            "rail_potential_max_v": result.rail_potential_max_v,
            "converged": result.converged,
            "iterations": result.iterations,
        }
    ).to_csv(path, index=False, float_format="%.4f")
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


def save_plots(result: PowerResult, out: Path) -> list[Path]:
    """PNG plots: pantograph voltage over time and over position (with the EN 50163 limits),
    substation power over time, energy per substation and the fate of regenerated energy, rail
    potential extremes over time (DC with rail-to-earth conductance)."""
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
        ax.plot(result.time_s, result.train_voltage_v[:, k], lw=0.7)
    limit_lines(ax)
    ax.set(xlabel="time [s]", ylabel="pantograph voltage [V]", title="Pantograph voltage of every train")
    save(fig, "voltage_time.png")

    fig, ax = plt.subplots(figsize=(10, 4.5))
    for k in range(len(result.train_ids)):
        ax.plot(result.train_position_m[:, k] / 1e3, result.train_voltage_v[:, k], ".", ms=1.2)
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
    return written
