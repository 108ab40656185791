"""``trainsim power FILE``: many trains on a DC or AC traction power network (docs/POWER.md)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import exit_for_status, require_file, user_errors

__all__ = ["power"]


def _print_summary(summary: dict) -> None:
    typer.echo(
        f"{summary['name']}: {summary['system'].upper()}, {len(summary['trains'])} trains, "
        f"{summary['duration_s']:.0f} s in steps of {summary['step_s']:g} s"
    )
    typer.echo(
        f"{'substation':<14}{'energy kWh':>12}{'peak kW':>10}{'RMS A':>9}{'RMS 15 min A':>14}{'overloads':>11}"
    )
    for s in summary["substations"]:
        rms15 = s["rms_current_max_a"]["900s"]
        typer.echo(
            f"{s['id']:<14}{s['energy_kwh']:>12.1f}{s['peak_power_kw']:>10.0f}{s['rms_current_a']:>9.0f}"
            f"{'-' if rms15 is None else f'{rms15:.0f}':>14}{len(s['overload_events']):>11}"
        )
    vmin = min(
        (t["min_voltage_v"] for t in summary["trains"] if t["min_voltage_v"] is not None), default=None
    )
    lost = max((t.get("time_lost_s", 0.0) for t in summary["trains"]), default=0.0)
    r = summary["regen_kwh"]
    typer.echo(
        f"trains {summary['trains_energy_kwh']:.1f} kWh at the pantographs, losses {summary['losses_kwh']:.1f} kWh, "
        f"lowest pantograph voltage {vmin:.0f} V, most time lost {lost:.1f} s"
    )
    typer.echo(
        f"regenerated {r['offered']:.1f} kWh: used by trains {r['used_by_trains']:.1f}, returned {r['returned']:.1f}, "
        f"dissipated {r['dissipated']:.1f}"
        + (f", stored on board {r['stored_onboard']:.1f}" if "stored_onboard" in r else "")
        + f"; energy balance {summary['energy_balance_error']:.1e}"
    )
    stray = summary.get("stray_current_a") or {}
    if stray.get("max") is not None:
        typer.echo(f"stray current {stray['mean']:.1f} A mean, {stray['max']:.1f} A at most")
    for w in summary["warnings"]:
        typer.echo(f"warning: {w}", err=True)
    late = [t for t in summary["trains"] if t.get("status", "ok") != "ok"]
    for t in late:
        typer.echo(
            f"train {t['id']}: {t['status']}, {t['time_lost_s']:.1f} s lost to voltage-limited traction"
        )
    sync = summary.get("synchronisation")
    if sync is not None:
        _print_synchronisation(sync)
    traces = summary.get("traces")
    if traces is not None:
        typer.echo(
            f"traces kept while each train runs: {traces['train_steps']} train-steps, {traces['memory_mb']:.1f} MB"
            + (f"; {traces['outputs']}" if "outputs" in traces else "")
        )
    if summary["status"] != "ok":
        # every condition, most severe first: one does not hide another
        others = [s for s in summary.get("statuses", []) if s != summary["status"]]
        typer.echo(f"status: {summary['status']}" + (f" (also {', '.join(others)})" if others else ""))


def _print_synchronisation(sync: dict) -> None:
    typer.echo(
        f"synchronisation ({sync['per']}, {sync['evaluations']} network solutions, {sync['evaluation']}): "
        f"substations {sync['baseline_kwh']:.2f} kWh as given -> {sync['synchronised_kwh']:.2f} kWh, "
        f"saving {sync['saving_kwh']:.2f} kWh ({sync['saving_percent']:.2f} %), status {sync['status']}"
    )
    if sync["message"]:
        typer.echo(f"  {sync['message']}")
    typer.echo(f"  {'departure':<14}{'timetabled s':>14}{'offset s':>10}{'synchronised s':>16}")
    for d in sync["departures"]:
        typer.echo(
            f"  {d['id']:<14}{d['departure_s']:>14.1f}{d['offset_s']:>+10.1f}{d['synchronised_departure_s']:>16.1f}"
        )


def power(
    file: Annotated[Path, typer.Argument(help="Power-supply file (schema: trainsim/power).")],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Directory for summary.json, CSV tables and plots.")
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json/--no-json", help="Print only the summary as JSON.")
    ] = False,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Write PNG plots with --out.")] = True,
    synchronise: Annotated[
        bool | None,
        typer.Option(
            "--synchronise/--no-synchronise",
            help="Shift the departures to minimise the substations' energy (the file's synchronisation: block, "
            "or its defaults); --no-synchronise ignores the block.",
        ),
    ] = None,
) -> None:
    """Solve a traction power network with many trains over time (substations, voltages, regeneration).

    Status (table, JSON 'status' and 'statuses', exit code 3 when not ok): not_converged,
    voltage_out_of_limits (a pantograph voltage left Umin2 .. Umax2), feedback_not_converged,
    substation_overloaded (above its overload power), traction_limited (the voltage limited traction
    and it was not fed back into the runs), time_lost (a train ran more than 0.5 s slower because of
    the voltage), headway_not_met (synchronisation: no timetable within the windows keeps the minimum
    headway; nothing shifted). Informational, in the warnings only: power above a substation's rated power but
    within its overload power, regenerated energy the line could not take (burnt on board or by the
    friction brakes: the train still brakes as asked). See docs/POWER.md, "Status".
    """
    with user_errors():
        require_file(file, "power-supply file")
        # the batch layer's wrapper: it reads the batch studies of a timetable: block (the file layer
        # may not import the batch layer)
        from trainsim.batch.power_timetable import run_power_file

        summary, status = run_power_file(file, out, plots=plots, synchronise=synchronise)
        if as_json:
            typer.echo(json.dumps(summary, indent=2, allow_nan=False))
        else:
            _print_summary(summary)
            if out is not None:
                typer.echo(f"wrote {out}/")
    exit_for_status(status)
