"""The optimal strategy and source 004's method against the reference optimum (CasADi/IPOPT) on
every TTOBench track, with NL_Intercity_VIRM6 and CN_Beijing_Subway, at 5, 10, 20 and 30 %
supplements, section by section.

Run: python benchmarks/bench_optimize.py [--out table.csv] [--tracks NAME ...]
Prints one line per case and a summary; energies are net electrical energy without auxiliaries;
gaps are (optimal - reference) / |reference| (net-regenerating descents have negative energies).
Targets (issue 3): optimal within 1 % of the reference everywhere (0.1 % on flat tracks); under
50 ms per section of up to 10 km; the reference under 10 s with at least 1000 intervals.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from itertools import pairwise
from pathlib import Path

from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.model.route import Station
from trainsim.model.scenario import RunSettings
from trainsim.optimize.lesov import lesov_train
from trainsim.optimize.optimal import SectionSolver
from trainsim.optimize.reference import solve_reference
from trainsim.sim.profile import line_resistance_profile, speed_ceiling
from trainsim.sim.result import build_result

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "ttobench"
TRAINS = ["NL_Intercity_VIRM6", "CN_Beijing_Subway"]
SUPPLEMENTS = [0.05, 0.10, 0.20, 0.30]


def energy_j(train, route, s0, s1, plan) -> float:
    section = dataclasses.replace(route, stations=(Station("a", s0), Station("b", s1)))
    res = build_result(
        train=train, route=section, settings=RunSettings(), profile=line_resistance_profile(section, train),
        ceiling=speed_ceiling(section, train), s=plan.s, v=plan.v, t=plan.t, regime=plan.regime, status="ok",
    )  # fmt: skip
    return res.energy_kwh.net * 3.6e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=None, help="write the table as CSV")
    parser.add_argument("--tracks", nargs="*", default=None)
    parser.add_argument("--no-lesov", action="store_true")
    args = parser.parse_args()
    rows = []
    header = (f"{'track':28s} {'train':8s} {'section m':>15s} {'sup':>4s} {'ref kWh':>9s} {'opt kWh':>9s} "
              f"{'gap %':>7s} {'opt ms':>7s} {'ref s':>6s} {'N':>5s} {'004 kWh':>9s} {'004 gap %':>9s} {'004 dT s':>8s}")  # fmt: skip
    print(header)
    for track_file in sorted(DATA.glob("tracks/*.json")):
        if args.tracks and track_file.stem not in args.tracks:
            continue
        for train_name in TRAINS:
            tt = read_ttobench_train(DATA / "trains" / f"{train_name}.json")
            train = tt.train
            route = read_ttobench_track(track_file, tt)
            stops = [s.position_m for s in route.stations]
            lt = lesov_train(train)
            for s0, s1 in pairwise(stops):
                solver = SectionSolver(train, route, s0, s1)
                solver.solve(solver.fastest_time_s * 1.1)  # warm-up (numba compilation, caches)
                lesov_solver = not args.no_lesov
                for sup in SUPPLEMENTS:
                    T = solver.fastest_time_s * (1 + sup)
                    t0 = time.perf_counter()
                    plan = solver.solve(T)
                    t_opt = time.perf_counter() - t0
                    e_opt = energy_j(train, route, s0, s1, plan)
                    intervals = max(1000, int((s1 - s0) / 20))
                    ref = solve_reference(train, route, s0, s1, T, intervals=intervals)
                    # relative to |reference|: on net-regenerating descents the energies are negative
                    gap = (
                        (e_opt - ref.energy_j) / abs(ref.energy_j) * 100
                        if ref.status == "ok"
                        else float("nan")
                    )
                    e_les = les_dev = float("nan")
                    if lesov_solver:
                        from trainsim.optimize.lesov import lesov_plans

                        lp = lesov_plans(train, route, [solver], [T], RunSettings())[0][0]
                        e_les = energy_j(lt, route, s0, s1, lp)
                        les_dev = lp.running_time_s - T
                    gap_les = (
                        (e_les - ref.energy_j) / abs(ref.energy_j) * 100
                        if ref.status == "ok"
                        else float("nan")
                    )
                    row = dict(track=track_file.stem, train=train_name, s0=s0, s1=s1, supplement=sup,
                               time_s=T, ref_kwh=ref.energy_j / 3.6e6, opt_kwh=e_opt / 3.6e6, gap_percent=gap,
                               gap_kwh=(e_opt - ref.energy_j) / 3.6e6,
                               opt_ms=t_opt * 1e3, ref_s=ref.solve_time_s, intervals=ref.intervals,
                               ref_status=ref.status, lesov_kwh=e_les / 3.6e6, lesov_gap_percent=gap_les,
                               opt_time_error_s=plan.running_time_s - T, lesov_time_error_s=les_dev)  # fmt: skip
                    rows.append(row)
                    print(f"{track_file.stem[:28]:28s} {train_name[:8]:8s} {s0:7.0f}-{s1:7.0f} {sup:4.2f} "
                          f"{row['ref_kwh']:9.3f} {row['opt_kwh']:9.3f} {gap:7.3f} {row['opt_ms']:7.0f} "
                          f"{ref.solve_time_s:6.2f} {ref.intervals:5d} {row['lesov_kwh']:9.3f} {gap_les:9.2f} "
                          f"{les_dev:+7.1f}"
                          + ("" if ref.status == "ok" else f"  ({ref.status})"), flush=True)  # fmt: skip
    ok = [r for r in rows if r["ref_status"] == "ok"]
    if ok:
        gaps = [r["gap_percent"] for r in ok]
        print(f"\ncases {len(rows)}, reference converged {len(ok)}")
        print(f"optimal vs reference: median gap {statistics.median(gaps):.3f} %, max {max(gaps):.3f} %, "
              f"within 1 %: {sum(g <= 1.0 for g in gaps)}/{len(gaps)}")  # fmt: skip
        short = [r["opt_ms"] for r in rows if r["s1"] - r["s0"] <= 10_000]
        if short:
            print(
                f"optimal wall time per section <= 10 km: median {statistics.median(short):.0f} ms, "
                f"max {max(short):.0f} ms"
            )
        print(
            f"reference solve time: median {statistics.median(r['ref_s'] for r in ok):.2f} s, "
            f"max {max(r['ref_s'] for r in ok):.2f} s"
        )
        if not args.no_lesov:
            lg = [r["lesov_gap_percent"] for r in ok]
            print(f"source 004 vs reference: median gap {statistics.median(lg):.2f} %, max {max(lg):.2f} %")
    if args.out:
        import pandas as pd

        pd.DataFrame(rows).to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
