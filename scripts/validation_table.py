"""Convergence and energy-balance table of every example and strategy, written into docs/VALIDATION.md.

For each example scenario (``examples/*/scenario*.yaml``) and each strategy (``fastest``; ``optimal``
and ``lesov`` through ``trainsim.optimize.api.optimize``, to the scenario's timetable or a 10 % line
supplement), the run at the scenario's step h and at h / 2: running time, net and traction energy,
the relative change of each on halving the step, and the energy-balance residual of both runs.

    python scripts/validation_table.py            # rewrite the table in docs/VALIDATION.md
    python scripts/validation_table.py --print    # print it only
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "VALIDATION.md"
START = "<!-- validation-table:start -->"
END = "<!-- validation-table:end -->"
STRATEGIES = ("fastest", "optimal", "lesov")
#: Supplement used for the optimize strategies when a scenario has no timetable of its own.
DEFAULT_SUPPLEMENT = "10%"


def _run(scenario, strategy: str, step_m: float):
    import trainsim
    from trainsim.optimize.api import optimize
    from trainsim.optimize.timetable import line_supplement

    settings = dataclasses.replace(scenario.settings, max_step_m=step_m)
    if strategy == "fastest":
        return trainsim.run_fastest(scenario.train, scenario.route, settings)
    timetable = scenario.timetable if scenario.timetable is not None else line_supplement(DEFAULT_SUPPLEMENT)
    return optimize(scenario.train, scenario.route, timetable, strategy, settings).run


def _change(a: float, b: float) -> str:
    if b == 0.0 and a == 0.0:
        return "0"
    return f"{abs(a - b) / max(abs(b), 1e-12):.1e}"


def rows() -> list[str]:
    """The table's markdown rows (header included)."""
    import trainsim

    out = [
        "| example | strategy | step h [m] | running time [s] | change h->h/2 | net energy [kWh] | change "
        "| traction [kWh] | change | balance residual (h, h/2) | status |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for path in sorted((ROOT / "examples").glob("*/scenario*.yaml")):
        name = f"{path.parent.name}/{path.name}"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                scenario = trainsim.load_scenario(path)
        except trainsim.InputError as err:
            out.append(f"| {name} | - | - | not read: {str(err).splitlines()[0]} | | | | | | | |")
            continue
        h = scenario.settings.max_step_m
        for strategy in STRATEGIES:
            try:
                a, b = _run(scenario, strategy, h), _run(scenario, strategy, h / 2)
            except trainsim.InputError as err:
                out.append(f"| {name} | {strategy} | {h:g} | not run: {err} | | | | | | | |")
                continue
            ea, eb = a.energy_kwh, b.energy_kwh
            out.append(
                f"| {name} | {strategy} | {h:g} | {a.running_time_s:.3f} | {_change(a.running_time_s, b.running_time_s)} "
                f"| {ea.net:.4f} | {_change(ea.net, eb.net)} | {ea.traction:.4f} | {_change(ea.traction, eb.traction)} "
                f"| {a.energy_balance['relative_error']:.1e}, {b.energy_balance['relative_error']:.1e} "
                f"| {a.status} |"
            )
            print(out[-1], file=sys.stderr, flush=True)
    return out


def write(table: list[str]) -> None:
    """Replace the table between the markers of docs/VALIDATION.md."""
    text = DOC.read_text(encoding="utf-8")
    if START not in text or END not in text:
        raise SystemExit(f"{DOC} has no {START} ... {END} markers")
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    DOC.write_text(head + START + "\n" + "\n".join(table) + "\n" + END + tail, encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--print", action="store_true", help="print the table instead of writing the doc")
    args = parser.parse_args()
    table = rows()
    if args.print:
        print("\n".join(table))
    else:
        write(table)
        print(f"wrote {DOC}")


if __name__ == "__main__":
    main()
