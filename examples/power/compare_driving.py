"""Energy-efficient driving judged at the substations: the same 3-minute timetable on the 750 V
line with diode rectifiers, driven fastest and optimally (+10 % running time), side by side.

At the pantograph the optimal strategy saves traction energy; at the substations the saving also
depends on how much regenerated energy other trains could take: coasting instead of braking leaves
less to regenerate, so less is burnt in the resistors when no other train is accelerating nearby.

Run from the repository root: python examples/power/compare_driving.py
"""

from __future__ import annotations

from pathlib import Path

from trainsim.io.power_file import run_power_file

HERE = Path(__file__).resolve().parent


def main() -> None:
    rows = []
    for label, name in (("fastest", "metro_750v_diode.yaml"), ("optimal +10 %", "metro_750v_diode_eco.yaml")):
        summary, status = run_power_file(HERE / name)
        trains = summary["trains"]
        rows.append(
            (
                label,
                status,
                sum(t["traction_demand_kwh"] for t in trains),
                summary["trains_energy_kwh"],
                summary["substations_energy_kwh"],
                summary["losses_kwh"],
                summary["regen_kwh"]["dissipated"],
            )
        )
    print(
        f"{'driving':<15}{'status':<8}{'traction asked':>16}{'pantographs':>13}{'substations':>13}"
        f"{'losses':>9}{'regen burnt':>13}  (kWh)"
    )
    for label, status, asked, panto, subs, losses, burnt in rows:
        print(f"{label:<15}{status:<8}{asked:>16.1f}{panto:>13.1f}{subs:>13.1f}{losses:>9.1f}{burnt:>13.1f}")
    f, o = rows
    print(
        f"saving at the pantographs {100 * (1 - o[3] / f[3]):.1f} %, "
        f"at the substations {100 * (1 - o[4] / f[4]):.1f} %"
    )


if __name__ == "__main__":
    main()
