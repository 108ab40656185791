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


def _compare_driving(
    file: Path,
    strategies: str | None,
    supplement: str | None,
    out: Path | None,
    as_json: bool,
    synchronise: bool | None,
) -> str:
    """``--compare-driving``: print (and with ``out`` write) the ``driving_comparison`` block; its status."""
    from trainsim.batch.power_timetable import read_study_trains
    from trainsim.errors import InputError
    from trainsim.io.power_compare import compare_driving, parse_strategies

    if strategies is None:
        raise InputError("--supplement is the supplement of a driving comparison", field="--supplement",
                         value=supplement, allowed="with --compare-driving, e.g. fastest,optimal")  # fmt: skip
    names = parse_strategies(strategies)
    require_file(file, "power-supply file")
    block, status = compare_driving(
        file, names, supplement, synchronise=synchronise, read_study=read_study_trains
    )
    document = {"driving_comparison": block}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "driving_comparison.json").write_text(json.dumps(document, indent=2, allow_nan=False))
    if as_json:
        typer.echo(json.dumps(document, indent=2, allow_nan=False))
        return status
    _print_comparison(block)
    if out is not None:
        typer.echo(f"wrote {out}/driving_comparison.json")
    return status


def _print_comparison(block: dict) -> None:
    given = f", supplement {block['supplement']}" if block["supplement"] is not None else ""
    typer.echo(f"{block['name']}: driving compared{given} (kWh)")
    typer.echo(
        f"{'driving':<11}{'status':<24}{'traction asked':>15}{'pantographs':>13}{'substations':>13}"
        f"{'losses':>9}{'regen used':>12}{'returned':>10}{'dissipated':>12}"
    )
    for r in block["runs"]:
        g = r["regen_kwh"]
        typer.echo(
            f"{r['strategy']:<11}{r['status']:<24}{r['traction_demand_kwh']:>15.1f}{r['trains_energy_kwh']:>13.1f}"
            f"{r['substations_energy_kwh']:>13.1f}{r['losses_kwh']:>9.1f}{g['used_by_trains']:>12.1f}"
            f"{g['returned']:>10.1f}{g['dissipated']:>12.1f}"
        )

    def pct(s: dict) -> str:
        return "-" if s["percent"] is None else f"{s['percent']:.1f} %"

    for s in block["savings"]:
        p, u = s["pantographs"], s["substations"]
        typer.echo(
            f"{s['strategy']} against {s['against']}: saves {p['kwh']:.1f} kWh ({pct(p)}) at the pantographs, "
            f"{u['kwh']:.1f} kWh ({pct(u)}) at the substations"
        )
    for r in block["runs"]:
        for w in r["warnings"]:
            typer.echo(f"warning ({r['strategy']}): {w}", err=True)
        if r["status"] != "ok":
            others = [x for x in r["statuses"] if x != r["status"]]
            typer.echo(
                f"status ({r['strategy']}): {r['status']}"
                + (f" (also {', '.join(others)})" if others else "")
            )
    if block["status"] != "ok":
        typer.echo(f"status: {block['status']}")


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
    compare_driving: Annotated[
        str | None,
        typer.Option(
            "--compare-driving",
            help="Run the file once per driving strategy (comma-separated, e.g. fastest,optimal; every "
            "train's scenario driven so) and print them side by side with the savings against the first, "
            "at the pantographs and at the substations.",
        ),
    ] = None,
    supplement: Annotated[
        str | None,
        typer.Option(
            "--supplement",
            help="With --compare-driving: the running-time supplement of the energy-efficient strategies "
            "('10%', '30 s'); without it each scenario's own driving: supplement or timetable.",
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

    --compare-driving fastest,optimal [--supplement 10%]: the file run once per strategy, side by side
    (JSON: driving_comparison); exit code 3 when any run is not ok.
    """
    with user_errors():
        if compare_driving is not None or supplement is not None:
            status = _compare_driving(file, compare_driving, supplement, out, as_json, synchronise)
            exit_for_status(status)
            return
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
