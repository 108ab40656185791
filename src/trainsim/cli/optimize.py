"""``trainsim optimize``: energy-efficient runs to a timetable (a thin layer over trainsim.optimize)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import (
    console,
    echo_warnings,
    exit_for_status,
    load_scenario,
    require_file,
    user_errors,
)
from trainsim.errors import InputError


def optimize(
    scenario: Annotated[
        Path | None,
        typer.Argument(
            help="Scenario: trainsim YAML, railML, a workbook or a folder of CSV tables; or give --train "
            "and --route."
        ),
    ] = None,
    train: Annotated[Path | None, typer.Option("--train", "-t", help="Train file (format detected).")] = None,
    route: Annotated[Path | None, typer.Option("--route", "-r", help="Route file (format detected).")] = None,
    supplement: Annotated[
        str | None, typer.Option("--supplement", help="Line running-time supplement, e.g. 10% or 30s.")
    ] = None,
    timetable: Annotated[
        Path | None, typer.Option("--timetable", help="trainsim timetable YAML or TTOBench journey JSON.")
    ] = None,
    strategy: Annotated[
        str, typer.Option("--strategy", help="optimal, lesov (source 004), reference (CasADi), fastest.")
    ] = "optimal",
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Directory for trace, summary and plots.")
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json/--no-json", help="Print only the summary JSON on stdout.")
    ] = False,
    curve: Annotated[
        bool,
        typer.Option(
            "--curve/--no-curve", help="Also compute the energy-versus-running-time curve (with --out)."
        ),
    ] = False,
    allowance: Annotated[
        list[str] | None,
        typer.Option(
            "--allowance",
            help="Running-time allowance AMOUNT[@START-END][:DISTRIBUTION], repeatable, adding up: AMOUNT "
            "5% (of the fastest time), 1.5min/100km or 30s; START-END a range in m (default the line); "
            "DISTRIBUTION time (default), distance or optimal. E.g. --allowance 5% "
            "--allowance 30s@1200-3400 (a construction margin).",
        ),
    ] = None,
    max_acceleration: Annotated[
        float | None, typer.Option("--max-acceleration", help="Comfort limit on acceleration [m/s^2].")
    ] = None,
    max_deceleration: Annotated[
        float | None, typer.Option("--max-deceleration", help="Comfort limit on deceleration [m/s^2].")
    ] = None,
    max_jerk: Annotated[
        float | None, typer.Option("--max-jerk", help="Jerk limit [m/s^3] (--strategy reference only).")
    ] = None,
    speed_margin: Annotated[
        float, typer.Option("--speed-margin", help="Stay this far below every speed limit [km/h].")
    ] = 0.0,
    min_regime_time: Annotated[
        float,
        typer.Option(
            "--min-regime-time", help="Shortest regime arc [s] (optimal; limits and stops excepted)."
        ),
    ] = 0.0,
    coast_min_speed: Annotated[
        float, typer.Option("--coast-min-speed", help="Coast only above this speed, hold it below [km/h].")
    ] = 0.0,
) -> None:
    """Drive a scenario to a timetable with least energy: switching points, savings, deviations.

    The schedule is one of --supplement, --timetable, --allowance (repeatable) or the scenario's
    'driving' block. Constraints (--max-acceleration, --max-deceleration, --max-jerk, --speed-margin)
    apply to every strategy; the driving rules --min-regime-time and --coast-min-speed to the optimal
    and reference strategies only, and asking another strategy for them is an error (exit 2)
    (docs/OPTIMIZATION.md, "Driving constraints").

    Exit code 3 when the result's status is not ok (e.g. an infeasible schedule or a missed timing
    window: the best feasible run is printed and the summary says by how much it is missed).
    """
    with user_errors():
        scn = load_scenario(scenario, train, route, None)
        from trainsim.io.timetable_file import read_timetable_yaml
        from trainsim.optimize.api import STRATEGIES, energy_time_curve
        from trainsim.optimize.api import optimize as run_optimize
        from trainsim.optimize.timetable import line_supplement

        if strategy not in STRATEGIES:
            raise InputError(
                "unknown strategy", field="--strategy", value=strategy, allowed=", ".join(STRATEGIES)
            )
        given = [name for name, x in (("--supplement", supplement), ("--timetable", timetable),
                                      ("--allowance", allowance)) if x]  # fmt: skip
        if len(given) > 1:
            raise InputError(
                "give exactly one of --supplement, --timetable and --allowance",
                field=" and ".join(given),
                allowed="one of them",
            )
        if not given:
            if scn.timetable is None:
                raise InputError(
                    "give exactly one of --supplement, --timetable and --allowance (or a 'driving' block in "
                    "the scenario)"
                )
            if strategy == "optimal" and scn.strategy != "fastest":
                strategy = scn.strategy
        _check_driving_rules(strategy, min_regime_time, coast_min_speed)
        constraints = _constraints(
            max_acceleration, max_deceleration, max_jerk, speed_margin, min_regime_time, coast_min_speed
        )
        route_used = scn.route
        if allowance:
            from trainsim.optimize.allowances import allowance_timetable, parse_allowance
            from trainsim.optimize.constraints import constrained_route, constrained_train

            # shared on the fastest run the constraints allow, as the strategies then drive it
            c_train, c_route = scn.train, scn.route
            if constraints is not None:
                c_train, c_route = (
                    constrained_train(c_train, constraints),
                    constrained_route(c_route, constraints),
                )
            tt, _ = allowance_timetable(
                c_train, c_route, [parse_allowance(a) for a in allowance], scn.settings
            )
        elif supplement is not None:
            tt = line_supplement(supplement)
        elif timetable is None:
            tt = scn.timetable
        else:
            require_file(timetable, "timetable file")
            from trainsim.io.loader import detect_format

            fmt = detect_format(timetable).format
            if fmt == "ttobench/journey":
                from trainsim.io.ttobench import read_ttobench_journey
                from trainsim.optimize.timetable import timetable_from_journey

                # its passing points become the timetable's timing points: the result reports them
                route_used, tt = timetable_from_journey(read_ttobench_journey(timetable), scn.route)
            elif fmt == "trainsim/timetable":
                tt = read_timetable_yaml(timetable, n_sections=len(scn.route.stops) - 1)
            else:
                raise InputError(
                    "not a timetable", file=str(timetable), allowed="trainsim/timetable, TTOBench journey"
                )
        result = run_optimize(
            scn.train, route_used, tt, strategy=strategy, settings=scn.settings, constraints=constraints
        )
        summary = result.summary()
        written: list[Path] = []
        if out is not None:
            from trainsim.io.export import write_trace_csv
            from trainsim.plots import save_all

            out.mkdir(parents=True, exist_ok=True)
            written.append(write_trace_csv(result.run, out / "trace.csv"))
            (out / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
            written.append(out / "summary.json")
            written += save_all(result.run, route_used, scn.train, out)
            if curve:
                table = energy_time_curve(scn.train, route_used, settings=scn.settings)
                table.to_csv(out / "energy_time_curve.csv", index=False)
                written.append(out / "energy_time_curve.csv")
                from trainsim.plots import plot_energy_time_curve

                fig = plot_energy_time_curve(table, title=f"{scn.train.name} on {route_used.name}")
                fig.savefig(out / "energy_time_curve.png", dpi=110)
                written.append(out / "energy_time_curve.png")
    if as_json:
        typer.echo(json.dumps(summary, indent=2, allow_nan=False))
        exit_for_status(str(summary["status"]))
        return
    from trainsim.io.export import summary_table

    out_console = console()
    out_console.print(summary_table(result.run, status=str(summary["status"])))
    out_console.print(
        f"strategy {strategy}: running {result.run.running_time_s:.1f} s (fastest {result.fastest.running_time_s:.1f} s), "
        f"net energy {result.run.energy_kwh.net:.2f} kWh (fastest {result.fastest.energy_kwh.net:.2f} kWh, "
        f"saved {summary['energy_saved_percent'] or 0:.1f} %)",
        markup=False,
    )
    for dev, sched in zip(result.schedule_deviation_s, result.scheduled_running_time_s, strict=True):
        out_console.print(f"schedule {sched:.1f} s, deviation {dev:+.2f} s", markup=False)
    if summary["status"] != "ok":
        out_console.print(f"status: {summary['status']}", markup=False, highlight=False)
    echo_warnings(list(summary["warnings"]))
    for p in written:
        out_console.print(f"wrote {p}", markup=False, highlight=False)
    exit_for_status(str(summary["status"]))


#: The strategies that keep each driving rule, and how. lesov and fastest drive by their own rule (a
#: coasting speed, full effort): asked for these rules they used to run without them and add a warning
#: that turned the status into "infeasible schedule" (exit 3), blaming a timetable that can be met.
_DRIVING_RULES = {
    "--min-regime-time": (("optimal", "reference"), "the reference reports the arcs shorter than it"),
    "--coast-min-speed": (("optimal", "reference"), ""),
}


def _check_driving_rules(strategy: str, min_regime_time_s: float, coast_min_kmh: float) -> None:
    """An InputError when a driving rule is asked of a strategy that does not apply it."""
    for option, value in (("--min-regime-time", min_regime_time_s), ("--coast-min-speed", coast_min_kmh)):
        strategies, how = _DRIVING_RULES[option]
        if value and strategy not in strategies:
            raise InputError(
                f"{option} applies to the {' and '.join(strategies)} strategies"
                + (f" ({how})" if how else "")
                + f"; strategy {strategy} does not apply it",
                field="--strategy",
                value=strategy,
                allowed=f"{', '.join(strategies)} with {option}, or leave {option} out",
            )


def _constraints(
    max_acceleration: float | None,
    max_deceleration: float | None,
    max_jerk: float | None,
    margin_kmh: float,
    min_regime_time_s: float = 0.0,
    coast_min_kmh: float = 0.0,
):
    """The driving constraints the options ask for (None when none), the speeds converted to m/s."""
    if (
        max_acceleration is None
        and max_deceleration is None
        and max_jerk is None
        and not margin_kmh
        and not min_regime_time_s
        and not coast_min_kmh
    ):
        return None
    from trainsim.constants import KMH
    from trainsim.optimize.constraints import DrivingConstraints

    limits = (
        ("--max-acceleration", max_acceleration),
        ("--max-deceleration", max_deceleration),
        ("--max-jerk", max_jerk),
    )
    for name, x in limits:
        if x is not None and not (0.0 < x < float("inf")):
            raise InputError("must be a finite number > 0", field=name, value=x, allowed="> 0")
    if not 0.0 <= margin_kmh < float("inf"):
        raise InputError(
            "must be a finite number >= 0", field="--speed-margin", value=margin_kmh, allowed=">= 0 km/h"
        )
    for name, x, unit in (
        ("--min-regime-time", min_regime_time_s, "s"),
        ("--coast-min-speed", coast_min_kmh, "km/h"),
    ):
        if not 0.0 <= x < float("inf"):
            raise InputError("must be a finite number >= 0", field=name, value=x, allowed=f">= 0 {unit}")
    return DrivingConstraints(
        max_acceleration_mps2=max_acceleration,
        max_deceleration_mps2=max_deceleration,
        max_jerk_mps3=max_jerk,
        speed_margin_mps=margin_kmh * KMH,
        min_regime_time_s=min_regime_time_s,
        coast_min_speed_mps=coast_min_kmh * KMH,
    )
