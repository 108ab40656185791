"""The optimal strategy and source 004's method against the certified reference optimum
(CasADi/IPOPT with mesh refinement and a convex lower bound) on every TTOBench track with all four
TTOBench trains, and on the heavy-haul example and the source 002 metro with and without
regeneration, at 5, 10, 20 and 30 % supplements, section by section.

Run: python benchmarks/bench_optimize.py [--out table.csv] [--tracks NAME ...] [--trains NAME ...]
     [--extra-only] [--no-extra] [--extra-first] [--extras metro metro_regen heavy_haul] [--skip-done]
     [--no-lesov] [--no-bound]
``--tracks`` are measured in the order given (two processes can work a list from both ends).
     python benchmarks/bench_optimize.py --journeys [--out journeys.csv] [--trains NAME ...]
``--journeys``: every TTOBench journey with passing windows, with every train: the optimal strategy
with the windows enforced (``optimize.windows``, as ``optimize(..., strategy="optimal")`` drives it)
against the certified reference with the same windows, one row per window (``journeys``).
     python benchmarks/bench_optimize.py --speed [--max-km 35] [--tracks ...] [--trains ...]
``--speed`` times the optimal strategy alone at +10 % (no reference): a fresh solver per section,
one solve beforehand, wall and CPU time against the RK4 baseline of ``_timing`` timed around
each solve, and the kernel runs per solve (final-phase runs, ``_pmp_c.final_phase_modes``, and
holding speeds tried, ``SectionSolver.plan``: deterministic, unlike the times), summarised per length
class (docs/OPTIMIZATION.md, Speed).
Prints one line per case and a summary; energies are net electrical energy without auxiliaries;
gaps are (x - reference) / |reference|, with the difference in kWh beside them, and the judged gap
(x - reference) / max(|reference|, 10 % of the reference's traction energy) (``optimize_report.
judged_denominator_kwh``: net-regenerating descents have net energies near zero or negative), and
the certified gap (optimal - lower bound) / |lower bound|. The reference's limits are CPU time
(``reference.py``): its CPU seconds are recorded beside the wall seconds. Every CSV row records the
commit measured (``+dirty`` when src/ or benchmarks/ differ from it).
Targets (issue 16): every case within 0.5 % of the certified reference, 95 % within 0.1 %; optimal
strategy: sections <= 10 km within 50 ms (median <= 20 ms), <= 35 km within 500 ms; the reference
within 30 s; energy decreasing with running time on every section.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import subprocess
import time
from itertools import pairwise
from pathlib import Path

import numpy as np
from _timing import machine, rk4_line
from optimize_report import judged_denominator_kwh, reachable_window_s

from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.model.route import Station
from trainsim.model.scenario import RunSettings
from trainsim.optimize.lesov import lesov_plans, lesov_train
from trainsim.optimize.optimal import SectionSolver
from trainsim.optimize.reference import certified_reference
from trainsim.sim.profile import line_resistance_profile, speed_ceiling
from trainsim.sim.result import build_result

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "ttobench"
TRAINS = ["NL_Intercity_VIRM6", "CN_Beijing_Subway", "CH_Stadler_FLIRT_TPF", "CH_Stadler_KISS_SBB"]
SUPPLEMENTS = [0.05, 0.10, 0.20, 0.30]


def energies_j(train, route, s0, s1, plan) -> tuple[float, float]:
    """(net electrical energy without auxiliaries, traction energy drawn = traction work / efficiency)
    of a plan [J], as trainsim's simulator accounts them."""
    section = dataclasses.replace(route, stations=(Station("a", s0), Station("b", s1)))
    res = build_result(
        train=train, route=section, settings=RunSettings(), profile=line_resistance_profile(section, train),
        ceiling=speed_ceiling(section, train), s=plan.s, v=plan.v, t=plan.t, regime=plan.regime, status="ok",
    )  # fmt: skip
    e = res.energy_kwh
    return (e.net - e.auxiliary) * 3.6e6, (e.net - e.auxiliary + e.regenerated) * 3.6e6


def energy_j(train, route, s0, s1, plan) -> float:
    """Net electrical energy of a plan without auxiliaries [J], as trainsim's simulator accounts it."""
    return energies_j(train, route, s0, s1, plan)[0]


def reference_flows_j(train, ref) -> tuple[float, float]:
    """(traction energy drawn, regenerated energy returned) of a reference solution [J]: the two
    flows whose difference is its net energy (reference.py's objective)."""
    h = np.diff(ref.s)
    elec, regen = train.electrical, train.braking.regenerative
    eta_t = elec.traction_efficiency if elec else 1.0
    eta_r = elec.regenerative_efficiency * elec.receptivity if (elec and regen is not None) else 0.0
    return float(np.sum(h * ref.traction_n)) / eta_t, eta_r * float(np.sum(h * ref.regenerative_n))


def measured_commit() -> str:
    """The commit of the checkout measured, ``+dirty`` when src/ or benchmarks/ differ from it."""
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short=12", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no", "--", "src", "benchmarks"],
            capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def cases(args):
    """(case name, train name, train, route, sections) for every line and train to measure."""
    extras = getattr(args, "extras", None) or list(EXTRAS)
    if getattr(args, "extra_first", False) and not args.no_extra:
        yield from extra_cases(extras)
    if not args.extra_only:
        tracks = sorted(DATA.glob("tracks/*.json"))
        if args.tracks:
            unknown = set(args.tracks) - {f.stem for f in tracks}
            if unknown:
                raise SystemExit(f"--tracks: no TTOBench track {sorted(unknown)} in {DATA / 'tracks'}")
            tracks = [DATA / "tracks" / f"{name}.json" for name in args.tracks]
        for track_file in tracks:
            for train_name in args.trains or TRAINS:
                tt = read_ttobench_train(DATA / "trains" / f"{train_name}.json")
                route = read_ttobench_track(track_file, tt)
                stops = [s.position_m for s in route.stations]
                yield track_file.stem, train_name, tt.train, route, list(pairwise(stops))
    if not args.no_extra and not getattr(args, "extra_first", False):
        yield from extra_cases(extras)


#: The cases beside TTOBench, in their default order (``--extras`` chooses and orders them).
EXTRAS = ("metro", "metro_regen", "heavy_haul")


def extra_cases(which=EXTRAS):
    """The source 002 metro without (``metro``) and with regeneration (``metro_regen``) and the
    heavy-haul example (``heavy_haul``), in the order of ``which``."""
    import trainsim

    for name in which:
        if name in ("metro", "metro_regen"):
            metro = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")
            stops = list(pairwise(s.position_m for s in metro.route.stations))
            if name == "metro":
                yield "metro_b", "source 002 metro", metro.train, metro.route, stops
            else:
                t = metro.train
                regen = dataclasses.replace(
                    t, braking=dataclasses.replace(t.braking, regenerative=t.traction.scaled(0.8))
                )
                yield "metro_b", "source 002 metro + regen 0.8", regen, metro.route, stops
        elif name == "heavy_haul":
            heavy = trainsim.load_scenario(ROOT / "examples" / "heavy_haul" / "scenario_head.yaml")
            stops = list(pairwise(s.position_m for s in heavy.route.stations))
            yield "heavy_haul", "heavy haul (head power)", heavy.train, heavy.route, stops
        else:
            raise SystemExit(f"--extras: no case {name!r} (allowed: {', '.join(EXTRAS)})")


def done_cases(path: Path | None) -> set[tuple[str, str, float, float, float]]:
    """(track, train, s0, s1, supplement) of the rows already in a CSV (``--skip-done``)."""
    if path is None or not path.exists():
        return set()
    import pandas as pd

    df = pd.read_csv(path)
    return {
        (r.track, r.train, round(float(r.s0), 2), round(float(r.s1), 2), round(float(r.supplement), 2))
        for r in df.itertuples()
    }


#: A window no run can meet is given to the reference moved this far inside what the fastest run
#: reaches [s], at least (the transcription's fastest run is not the integrator's to the second).
RELAXED_WINDOW_SLACK_S = 1.0
#: ... or this fraction of the section's running time, whichever is larger [-].
RELAXED_WINDOW_SLACK_FRACTION = 0.005


def journey_cases(args):
    """(journey name, train name, TTOBench train, route with the journey's stops, timetable) for every
    journey with a passing window and every train."""
    from trainsim.io.ttobench import read_ttobench_journey
    from trainsim.optimize.timetable import timetable_from_journey

    for path in sorted(DATA.glob("journeys/*.json")):
        journey = read_ttobench_journey(path)
        if not any(p.earliest_s is not None or p.latest_s is not None for p in journey.passing_points):
            continue
        for train_name in args.trains or TRAINS:
            tt = read_ttobench_train(DATA / "trains" / f"{train_name}.json")
            route = read_ttobench_track(DATA / "tracks" / f"{journey.track_id}.json", tt)
            section_route, timetable = timetable_from_journey(journey, route)
            yield path.stem, train_name, tt, section_route, timetable


def journeys(args) -> None:
    """The optimal strategy with windows against the certified reference with the same windows."""
    from trainsim.optimize.api import optimize
    from trainsim.optimize.windows import enforce_windows, passing_time_s, window_miss_s

    commit = measured_commit()
    print(f"commit {commit}; {machine()}", flush=True)
    for name, train_name, tt, route, timetable in journey_cases(args):
        train = tt.train
        result = optimize(train, route, timetable, strategy="optimal")
        summary = result.summary()
        stops = [s.position_m for s in route.stations]
        for (s0, s1), sched in zip(pairwise(stops), timetable.sections, strict=True):
            windows = [w for w in timetable.timing_points if s0 < w.position_m < s1]
            if not windows:
                continue
            T = float(sched.running_time_s)
            solver = SectionSolver(train, route, s0, s1)
            t0, c0 = time.perf_counter(), time.process_time()
            outcome = enforce_windows(solver, T, timetable.timing_points, solver.solve(T))
            t_opt, c_opt = time.perf_counter() - t0, time.process_time() - c0
            plan = outcome.plan
            e_opt, _ = energies_j(train, route, s0, s1, plan)
            # a window no run can meet goes to the reference as the nearest reachable one (slack
            # inside), so that both are compared on the runs that come as close to it as possible
            slack = max(RELAXED_WINDOW_SLACK_S, RELAXED_WINDOW_SLACK_FRACTION * T)
            ref_windows, reach = [], {}
            for w in windows:
                lo, hi = reachable_window_s(solver.fastest[0], solver.fastest[2], w.position_m, T)
                reach[w.position_m] = (lo, hi)
                e, lt = w.earliest_s, w.latest_s
                if lt is not None and lt < lo:
                    lt = min(lo + slack, hi)
                if e is not None and e > hi:
                    e = max(hi - slack, lo)
                ref_windows.append(dataclasses.replace(w, earliest_s=e, latest_s=lt))
            t0, c0 = time.perf_counter(), time.process_time()
            ref = certified_reference(
                train, route, s0, s1, T, intervals=max(1000, int((s1 - s0) / 20)),
                warm_start=(plan.s, plan.v), timing_points=ref_windows,
            )  # fmt: skip
            t_ref, c_ref = time.perf_counter() - t0, time.process_time() - c0
            usable = ref.status == "ok" or ref.status.startswith("mesh not converged")
            ref_traction, _ = reference_flows_j(train, ref)
            judged = judged_denominator_kwh(ref.energy_j / 3.6e6, ref_traction / 3.6e6) * 3.6e6
            for w, rw in zip(windows, ref_windows, strict=True):
                lo, hi = reach[w.position_m]
                t_o = passing_time_s(plan, w.position_m)
                v_o = float(np.interp(w.position_m, plan.s, plan.v))
                t_r = float(np.interp(w.position_m, ref.s, ref.time_s))
                late = 0.0 if w.latest_s is None else lo - w.latest_s
                early = 0.0 if w.earliest_s is None else w.earliest_s - hi
                unreachable = max(late, early, 0.0)
                miss_o = window_miss_s(t_o, w)
                row = dict(
                    journey=name, train=train_name, s0=s0, s1=s1, time_s=T, window=w.label,
                    position_m=w.position_m, earliest_s=w.earliest_s, latest_s=w.latest_s,
                    min_speed_kmh=None if w.min_speed_mps is None else w.min_speed_mps * 3.6,
                    reachable_from_s=lo, reachable_to_s=hi, no_run_meets_by_s=unreachable,
                    opt_pass_s=t_o, opt_pass_kmh=v_o * 3.6, opt_miss_s=miss_o,
                    opt_speed_ok=w.min_speed_mps is None or v_o >= w.min_speed_mps - 1e-6,
                    ref_pass_s=t_r, ref_earliest_s=rw.earliest_s, ref_latest_s=rw.latest_s,
                    opt_kwh=e_opt / 3.6e6, ref_kwh=ref.energy_j / 3.6e6, gap_kwh=(e_opt - ref.energy_j) / 3.6e6,
                    judged_gap_percent=(e_opt - ref.energy_j) / judged * 100 if usable else float("nan"),
                    lower_bound_kwh=(ref.lower_bound_j or float("nan")) / 3.6e6, ref_status=ref.status,
                    bound_status=ref.bound_status, ref_cpu_s=c_ref, ref_s=t_ref, opt_ms=t_opt * 1e3,
                    opt_cpu_ms=c_opt * 1e3, opt_running_time_s=plan.running_time_s,
                    result_status=summary["status"],
                    result_warning="; ".join(x for x in summary.get("warnings", []) if f"{w.position_m:.0f} m" in x),
                    notes="; ".join(outcome.notes), commit=commit,
                )  # fmt: skip
                print(f"{name} {train_name:22s} {w.label:>12s} window {w.earliest_s}-{w.latest_s} s, reachable "
                      f"{lo:.1f}-{hi:.1f} s, optimal passes {t_o:.1f} s ({miss_o:+.1f}), reference {t_r:.1f} s; "
                      f"opt {e_opt / 3.6e6:.3f} ref {ref.energy_j / 3.6e6:.3f} kWh ({row['judged_gap_percent']:.3f} %), "
                      f"ref {ref.status[:40]}, CPU {c_ref:.1f} s; result {summary['status']}", flush=True)  # fmt: skip
                if args.out:
                    import pandas as pd

                    pd.DataFrame([row]).to_csv(args.out, mode="a", header=not args.out.exists(), index=False)


#: Length classes of the speed targets (issue 16): (label, longest section [m], target max [ms]).
SPEED_CLASSES = (("<= 10 km", 10_000.0, 50.0), ("10-35 km", 35_000.0, 500.0))


def _timed(fn) -> tuple[float, float]:
    """(wall, CPU) seconds of one call."""
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def _counted() -> dict[str, int]:
    """Counts final-phase runs and holding speeds tried (the work of a solve, whatever the load)."""
    from trainsim.optimize import _pmp_c

    count = {"runs": 0, "plans": 0}
    final_phase, plan = _pmp_c.final_phase_modes, SectionSolver.plan

    def counted_final_phase(*a):
        count["runs"] += 1
        return final_phase(*a)

    def counted_plan(self, holding_speed_mps):
        count["plans"] += 1
        return plan(self, holding_speed_mps)

    _pmp_c.final_phase_modes = counted_final_phase  # (optimal.py calls it through the module)
    SectionSolver.plan = counted_plan
    return count


def speed(args) -> None:
    """Per-section times of the optimal strategy at +10 % with the baseline around each solve."""
    print(machine(), flush=True)
    rows = []
    count = _counted()
    warm = True
    for track, train_name, train, route, sections in cases(args):
        for s0, s1 in sections:
            if s1 - s0 > args.max_km * 1e3:
                continue
            if warm:  # first-call costs (imports, caches) are not what is timed
                solver = SectionSolver(train, route, s0, s1)
                solver.solve(solver.fastest_time_s * 1.1)
                rk4_line()
                warm = False
            base0 = _timed(rk4_line)

            def run(s0=s0, s1=s1, train=train, route=route):
                solver = SectionSolver(train, route, s0, s1)
                solver.solve(solver.fastest_time_s * 1.1)

            count["runs"] = count["plans"] = 0
            wall, cpu = _timed(run)
            base1 = _timed(rk4_line)
            base_wall, base_cpu = min(base0[0], base1[0]), max(min(base0[1], base1[1]), 1e-6)
            rows.append((s1 - s0, wall, cpu, cpu / base_cpu, count["runs"], count["plans"]))
            print(f"{track[:26]:26s} {train_name[:12]:12s} {s0:7.0f}-{s1:7.0f} wall {wall * 1e3:8.1f} ms "
                  f"cpu {cpu * 1e3:8.1f} ms  baseline {base_wall * 1e3:5.2f} ms  cpu ratio {cpu / base_cpu:7.0f}  "
                  f"final-phase runs {count['runs']:5d}, holding speeds {count['plans']:3d}", flush=True)  # fmt: skip
    lower = 0.0
    for label, upper, target_ms in SPEED_CLASSES:
        g = [r for r in rows if lower < r[0] <= upper]
        lower = upper
        if not g:
            continue
        wall = [r[1] * 1e3 for r in g]
        print(f"{label}: {len(g)} sections, wall median {statistics.median(wall):.0f} ms, max {max(wall):.0f} ms "
              f"({sum(w <= target_ms for w in wall)}/{len(g)} within {target_ms:.0f} ms); CPU median "
              f"{statistics.median(r[2] * 1e3 for r in g):.0f} ms; CPU / baseline median "
              f"{statistics.median(r[3] for r in g):.0f}, max {max(r[3] for r in g):.0f}; final-phase runs median "
              f"{statistics.median(r[4] for r in g):.0f}, holding speeds median {statistics.median(r[5] for r in g):.0f}")  # fmt: skip
    print(machine())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=None, help="write the table as CSV (appended row by row)")
    parser.add_argument("--tracks", nargs="*", default=None)
    parser.add_argument("--trains", nargs="*", default=None)
    parser.add_argument("--extra-only", action="store_true", help="only the metro and heavy-haul cases")
    parser.add_argument("--no-extra", action="store_true", help="only the TTOBench cases")
    parser.add_argument("--extra-first", action="store_true", help="the metro and heavy-haul cases first")
    parser.add_argument(
        "--extras", nargs="*", default=None, help=f"which of {', '.join(EXTRAS)}, in this order"
    )
    parser.add_argument("--skip-done", action="store_true", help="skip the cases already in --out")
    parser.add_argument("--no-lesov", action="store_true")
    parser.add_argument("--no-bound", action="store_true", help="skip the lower bound")
    parser.add_argument("--speed", action="store_true", help="time the optimal strategy only, at +10 %%")
    parser.add_argument("--max-km", type=float, default=35.0, help="with --speed: longest section [km]")
    parser.add_argument("--journeys", action="store_true", help="the TTOBench journeys with windows")
    args = parser.parse_args()
    if args.speed:
        speed(args)
        return
    if args.journeys:
        journeys(args)
        return
    rows = []
    commit = measured_commit()
    print(f"commit {commit}; {machine()}", flush=True)
    header = (f"{'track':26s} {'train':10s} {'section m':>15s} {'sup':>4s} {'ref kWh':>9s} {'opt kWh':>9s} "
              f"{'d kWh':>8s} {'gap %':>7s} {'judged %':>8s} {'cert %':>7s} {'opt ms':>7s} {'ref cpu s':>9s} "
              f"{'N':>6s} {'004 gap %':>9s}")  # fmt: skip
    print(header, flush=True)
    done = done_cases(args.out) if args.skip_done else set()
    for track, train_name, train, route, sections in cases(args):
        for s0, s1 in sections:
            todo = [
                sup
                for sup in SUPPLEMENTS
                if (track, train_name, round(s0, 2), round(s1, 2), round(sup, 2)) not in done
            ]
            if not todo:
                continue
            solver = SectionSolver(train, route, s0, s1)
            solver.solve(solver.fastest_time_s * 1.1)  # warm-up (numba compilation, caches)
            for sup in todo:
                T = solver.fastest_time_s * (1 + sup)
                t0 = time.perf_counter()
                plan = solver.solve(T)
                t_opt = time.perf_counter() - t0
                e_opt, e_opt_traction = energies_j(train, route, s0, s1, plan)
                t0, c0 = time.perf_counter(), time.process_time()
                ref = certified_reference(
                    train, route, s0, s1, T, intervals=max(1000, int((s1 - s0) / 20)),
                    warm_start=(plan.s, plan.v), bound=not args.no_bound,
                )  # fmt: skip
                t_ref, cpu_ref = time.perf_counter() - t0, time.process_time() - c0
                usable = ref.status == "ok" or ref.status.startswith("mesh not converged")
                ref_traction, ref_regen = reference_flows_j(train, ref)
                scale = max(abs(ref.energy_j), 3.6e3)
                judged = judged_denominator_kwh(ref.energy_j / 3.6e6, ref_traction / 3.6e6) * 3.6e6
                gap = (e_opt - ref.energy_j) / scale * 100 if usable else float("nan")
                judged_gap = (e_opt - ref.energy_j) / judged * 100 if usable else float("nan")
                cert = ref.certified_gap(e_opt)
                e_les = les_dev = gap_les = float("nan")
                if not args.no_lesov:
                    try:
                        lp = lesov_plans(train, route, [solver], [T], RunSettings())[0][0]
                        e_les = energy_j(lesov_train(train), route, s0, s1, lp)
                        les_dev = lp.running_time_s - T
                        gap_les = (e_les - ref.energy_j) / judged * 100 if usable else float("nan")
                    except Exception as exc:  # source 004's reading may not apply to every train
                        print(f"  source 004: {type(exc).__name__}: {exc}")
                row = dict(track=track, train=train_name, s0=s0, s1=s1, supplement=sup, time_s=T,
                           ref_kwh=ref.energy_j / 3.6e6, lower_bound_kwh=(ref.lower_bound_j or float("nan")) / 3.6e6,
                           opt_kwh=e_opt / 3.6e6, gap_percent=gap, judged_gap_percent=judged_gap,
                           judged_denominator_kwh=judged / 3.6e6,
                           certified_gap_percent=100 * cert if cert is not None else float("nan"),
                           gap_kwh=(e_opt - ref.energy_j) / 3.6e6, opt_ms=t_opt * 1e3, ref_s=t_ref,
                           ref_cpu_s=cpu_ref, ref_traction_kwh=ref_traction / 3.6e6,
                           ref_regenerated_kwh=ref_regen / 3.6e6, opt_traction_kwh=e_opt_traction / 3.6e6,
                           intervals=ref.intervals, mesh=" ".join(f"{m[0]}:{m[1] / 3.6e6:.5f}" for m in ref.mesh),
                           ref_status=ref.status, bound_status=ref.bound_status, lesov_kwh=e_les / 3.6e6,
                           lesov_gap_percent=gap_les, opt_time_error_s=plan.running_time_s - T,
                           lesov_time_error_s=les_dev, commit=commit)  # fmt: skip
                rows.append(row)
                print(f"{track[:26]:26s} {train_name[:10]:10s} {s0:7.0f}-{s1:7.0f} {sup:4.2f} "
                      f"{row['ref_kwh']:9.3f} {row['opt_kwh']:9.3f} {row['gap_kwh']:8.4f} {gap:7.3f} {judged_gap:8.3f} "
                      f"{row['certified_gap_percent']:7.3f} {row['opt_ms']:7.0f} {cpu_ref:9.1f} {ref.intervals:6d} "
                      f"{gap_les:9.2f}"
                      + ("" if ref.status == "ok" else f"  ({ref.status})")
                      + ("" if ref.bound_status in ("ok", "") else f"  (bound: {ref.bound_status})"),
                      flush=True)  # fmt: skip
                if args.out:
                    import pandas as pd

                    pd.DataFrame([row]).to_csv(args.out, mode="a", header=not args.out.exists(), index=False)
    ok = [r for r in rows if r["judged_gap_percent"] == r["judged_gap_percent"]]
    if ok:
        gaps = [r["judged_gap_percent"] for r in ok]
        print(f"\ncases {len(rows)}, reference usable {len(ok)}")
        print(f"optimal vs reference (judged gap): median {statistics.median(gaps):.3f} %, max {max(gaps):.3f} %, "
              f"within 0.5 %: {sum(g <= 0.5 for g in gaps)}/{len(gaps)}, "
              f"within 0.1 %: {sum(g <= 0.1 for g in gaps)}/{len(gaps)}")  # fmt: skip
        short = [r["opt_ms"] for r in rows if r["s1"] - r["s0"] <= 10_000]
        if short:
            print(
                f"optimal per section <= 10 km: median {statistics.median(short):.0f} ms, max {max(short):.0f} ms"
            )
        print(
            f"reference CPU: median {statistics.median(r['ref_cpu_s'] for r in rows):.1f} s, "
            f"max {max(r['ref_cpu_s'] for r in rows):.1f} s"
        )


if __name__ == "__main__":
    main()
