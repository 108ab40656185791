"""Our fastest run of source 002's type B metro beside the paper's published figures (section 4).

Run: python examples/metro_b/compare_with_paper.py
"""

from __future__ import annotations

from pathlib import Path

import trainsim

#: Source 002, section 4, first group of data (fastest strategy).
PAPER = {
    "running time S1-S2 [s]": 91.0,
    "running time S2-S3 [s]": 87.5,
    "running time S3-S4 [s]": 82.5,
    "dwell S2 [s]": 51.0,
    "dwell S3 [s]": 49.0,
    "running time [s]": 261.0,
    "total time [s]": 361.0,
    "average speed [km/h]": 44.78,
    "average running speed [km/h]": 61.9,
    "peak current [A]": 4863.0,
    "energy [kWh]": 38.24,
}


def ours(result: trainsim.RunResult) -> dict[str, float]:
    s = result.sections
    return {
        "running time S1-S2 [s]": s[0].running_time_s,
        "running time S2-S3 [s]": s[1].running_time_s,
        "running time S3-S4 [s]": s[2].running_time_s,
        "dwell S2 [s]": s[0].dwell_s,
        "dwell S3 [s]": s[1].dwell_s,
        "running time [s]": result.running_time_s,
        "total time [s]": result.total_time_s,
        "average speed [km/h]": result.average_speed_kmh,
        "average running speed [km/h]": result.average_running_speed_kmh,
        "peak current [A]": result.peak_paper_current_a,
        "energy [kWh]": result.energy_kwh.paper,
    }


def main() -> None:
    scenario = trainsim.load_scenario(Path(__file__).with_name("scenario.yaml"))
    result = trainsim.run(scenario)
    mine = ours(result)
    print(f"{'quantity':32s} {'paper':>10s} {'trainsim':>10s} {'difference':>11s}")
    for key, paper in PAPER.items():
        diff = (mine[key] - paper) / paper * 100
        print(f"{key:32s} {paper:10.2f} {mine[key]:10.2f} {diff:10.1f}%")
    print(
        "\nPeak current and energy in the paper's convention (P = F v eta, I = P / (U cos phi)); "
        f"physically the line supplies F v / eta: peak {result.peak_current_a:.0f} A, "
        f"net energy {result.energy_kwh.net:.2f} kWh."
    )
    # the paper's second run: running time +12.8 % (294.4 s against 261 s), 22.4 kWh against 38.24
    from trainsim.optimize.api import optimize
    from trainsim.optimize.timetable import line_supplement

    eco = optimize(scenario.train, scenario.route, line_supplement("12.8%"))
    saved = 100.0 * (1.0 - eco.run.energy_kwh.paper / result.energy_kwh.paper)
    print("\nEnergy-efficient run at the paper's running-time increase (+12.8 %):")
    print(f"{'':32s} {'paper':>10s} {'trainsim':>10s}")
    print(f"{'running time, fastest [s]':32s} {261.0:10.1f} {result.running_time_s:10.1f}")
    print(f"{'running time, efficient [s]':32s} {294.4:10.1f} {eco.run.running_time_s:10.1f}")
    print(f"{'energy, fastest [kWh]':32s} {38.24:10.2f} {result.energy_kwh.paper:10.2f}")
    print(f"{'energy, efficient [kWh]':32s} {22.4:10.2f} {eco.run.energy_kwh.paper:10.2f}")
    print(f"{'saving [%]':32s} {100 * (1 - 22.4 / 38.24):10.1f} {saved:10.1f}")
    print(f"{'peak current, efficient [A]':32s} {4206.0:10.0f} {eco.run.peak_paper_current_a:10.0f}")


if __name__ == "__main__":
    main()
