"""Timetable synchronisation on the 750 V line with diode rectifiers (metro_750v_diode.yaml).

The up trains leave every 3 minutes from S1, the down trains every 3 minutes from S4, 90 s later. A
braking train's regenerated energy is used when a train on the other track accelerates nearby at
the same time, and burnt otherwise. Two searches over the same span, each candidate solved on the
network with the trains' real runs (one run per service, shifted in time):

* per service: one offset for all of a service's departures (up, down), within +-60 s;
* per departure: each departure its own offset within +-20 s, 150 s at least between consecutive
  departures on a track (the file examples/power/metro_750v_diode_sync.yaml does the same from
  ``trainsim power``).

Run from the repository root: python examples/power/synchronise_timetable.py
"""

from __future__ import annotations

from pathlib import Path

from trainsim.io.power_file import load_power_file
from trainsim.power.day import departure_loads
from trainsim.power.synchronise import SyncSettings, synchronise_departures

HERE = Path(__file__).resolve().parent


def main() -> None:
    spec, network, services = load_power_file(HERE / "metro_750v_diode.yaml")
    loads, _ = departure_loads(services)
    owner = [s for s in services for _ in s.departures_s]
    groups = [(s.track, s.direction) for s in owner]
    names = [s.id for s in owner]
    searches = {
        "per service": SyncSettings(window_s=60.0, step_s=15.0, rounds=2, refinements=1, min_headway_s=150.0,
                                    per="service"),
        "per departure": SyncSettings(window_s=20.0, step_s=10.0, rounds=2, refinements=1, min_headway_s=150.0),
    }  # fmt: skip
    for label, settings in searches.items():
        out = synchronise_departures(
            network, loads, groups, settings, services=names, dt_s=spec.simulation.step_s
        )
        offsets = ", ".join(f"{ld.id} {x:+.1f}" for ld, x in zip(loads, out.offsets_s, strict=True) if x)
        print(
            f"{label}: substations {out.baseline_kwh:.1f} kWh as given -> {out.synchronised_kwh:.1f} kWh, saving "
            f"{out.saving_kwh:.1f} kWh ({out.saving_percent:.1f} %), {out.evaluations} network solutions "
            f"({out.evaluation}), status {out.status}"
        )
        print(f"  offsets [s]: {offsets or 'none'}")


if __name__ == "__main__":
    main()
