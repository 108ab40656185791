"""Turn the CSVs of bench_optimize.py into docs/optimization_benchmark.md (and its CSV).

Run: python benchmarks/optimize_report.py table.csv [more.csv ...] [--journeys journeys.csv ...]
         [--csv docs/optimization_benchmark.csv] [--missing-reason TEXT] [--notes reading.md]
         > docs/optimization_benchmark.md
The cases expected are bench_optimize's (every TTOBench track x train x section, the metro with and
without regeneration, the heavy haul, at 5/10/20/30 %): the header lists every one without a row.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

#: The judged gap's denominator is never below this fraction of the reference's traction energy [-]
#: (the header of docs/optimization_benchmark.md argues it).
TRACTION_FLOOR_FRACTION = 0.10
#: Targets of issue 16 on the judged gap [%]: every case, and 95 % of them.
TARGET_ALL_PERCENT = 0.5
TARGET_MOST_PERCENT = 0.1
#: Energy counts as rising with running time beyond this [kWh] (far below any figure the table shows).
MONOTONE_TOLERANCE_KWH = 1e-6
#: The reference's CPU-time limit of the mesh refinement and, separately, of the bound [s].
REFERENCE_CPU_LIMIT_S = 30.0
SUPPLEMENTS = (0.05, 0.10, 0.20, 0.30)


def judged_denominator_kwh(reference_net_kwh: float, reference_traction_kwh: float) -> float:
    """max(|net energy|, TRACTION_FLOOR_FRACTION x traction energy drawn) of the reference [kWh]: a
    net energy near zero (a net-regenerating section) is the difference of two large flows, and a
    relative gap on it measures nothing a planner pays for; elsewhere it is |net| unchanged."""
    return max(abs(reference_net_kwh), TRACTION_FLOOR_FRACTION * reference_traction_kwh, 1e-3)


def reachable_window_s(
    fastest_s: np.ndarray, fastest_t: np.ndarray, position_m: float, running_time_s: float
) -> tuple[float, float]:
    """(earliest, latest) time [s from departure] at which any run of the section that keeps
    ``running_time_s`` can pass ``position_m``: the fastest run (arrays of position [m] and time [s])
    is ahead of every run at every position, so no run passes sooner than it, and none that passes
    later than the schedule minus the fastest run's time from the point to the stop arrives on time."""
    t_fast = float(np.interp(position_m, fastest_s, fastest_t))
    rest = float(fastest_t[-1]) - t_fast
    return t_fast, running_time_s - rest


def mesh_change_percent(mesh: str) -> float:
    """How far the reference's last mesh doubling moved its optimum [%] (``mesh`` as bench_optimize
    writes it: "intervals:kWh ..."); nan with fewer than two grids. The reference itself is no
    closer to the optimum of the continuous problem than about this."""
    if not isinstance(mesh, str):
        return float("nan")
    energies = [float(m.split(":")[1]) for m in mesh.split()]
    if len(energies) < 2:
        return float("nan")
    return abs(energies[-1] - energies[-2]) / max(abs(energies[-1]), 1e-3) * 100


def _pct(x: float, digits: int = 3) -> str:
    return "–" if pd.isna(x) else f"{x:.{digits}f} %"


def _kwh(x: float) -> str:
    return "–" if pd.isna(x) else f"{x:+.4f}"


def expected_cases() -> set[tuple[str, str, float, float]]:
    """(track, train, s0, s1) of every section bench_optimize measures (without running anything)."""
    import bench_optimize

    args = argparse.Namespace(extra_only=False, no_extra=False, extra_first=False, tracks=None, trains=None)
    out = set()
    for track, train, _t, _r, sections in bench_optimize.cases(args):
        for s0, s1 in sections:
            out.add((track, train, round(float(s0), 2), round(float(s1), 2)))
    return out


def monotone_sections(df: pd.DataFrame) -> tuple[int, list[str]]:
    """(sections checked, the sections whose optimal energy rises with running time)."""
    bad, n = [], 0
    for (track, train, s0, s1), sec in df.groupby(["track", "train", "s0", "s1"], sort=False):
        if len(sec) < 2:
            continue
        n += 1
        rises = sec.sort_values("time_s").opt_kwh.diff().dropna()
        if (rises > MONOTONE_TOLERANCE_KWH).any():
            bad.append(f"{track} / {train} {s0:.0f}-{s1:.0f} m (+{rises.max():.4f} kWh)")
    return n, bad


def section_table(df: pd.DataFrame, usable: pd.DataFrame) -> list[str]:
    out = [
        "| track | train | sections | judged gap 5 % | 10 % | 20 % | 30 % | largest kWh above | certified (worst) "
        "| energy falls with time | reference CPU s (median / max) | reference status ok |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (track, train), g in df.groupby(["track", "train"], sort=False):
        u = usable[(usable.track == track) & (usable.train == train)]
        gaps = [_pct(u[u.supplement.round(2) == sup].judged_gap_percent.max()) for sup in SUPPLEMENTS]
        n, bad = monotone_sections(g)
        mono = "–" if n == 0 else ("yes" if not bad else f"NO ({len(bad)})")
        out.append(
            f"| {track} | {train} | {g.s0.nunique()} | "
            + " | ".join(gaps)
            + f" | {_kwh(u.gap_kwh.max()) if len(u) else '–'} | {_pct(g.certified_gap_percent.max())} | {mono} "
            f"| {g.ref_cpu_s.median():.1f} / {g.ref_cpu_s.max():.1f} | {(g.ref_status == 'ok').sum()}/{len(g)} |"
        )
    return out


def header(commits: list[str]) -> list[str]:
    return [
        "# Optimal strategy against the certified reference (TTOBench, metro, heavy haul)",
        "",
        "Generated: `python benchmarks/bench_optimize.py --out table.csv` (two processes, each a share of",
        "the tracks), `python benchmarks/bench_optimize.py --journeys --out journeys.csv`, then",
        "`python benchmarks/optimize_report.py table*.csv --journeys journeys.csv --csv",
        "docs/optimization_benchmark.csv > docs/optimization_benchmark.md`. Commit measured: "
        + ", ".join(f"`{c}`" for c in commits)
        + " (each CSV row records it).",
        "",
        "**Energies**: net electrical energy drawn from the line without auxiliaries [kWh], as trainsim's",
        "simulator accounts the optimal strategy's run, and the reference's objective. **Reference**: the",
        "direct transcription (CasADi/IPOPT) with at least 1000 intervals and one per 20 m, doubled until",
        "the optimum moves by less than 0.01 %, within **30 s of CPU time** (IPOPT's `max_cpu_time` and",
        "the refinement's budget by `time.process_time`: a wall-clock limit made the reference's result",
        "depend on the machine's load); the rows whose mesh did not converge in that budget use the last",
        "converged grid (status `mesh not converged`), `–` where none converged. *certified*: (optimal -",
        "lower bound) / |lower bound|, the bound being the global optimum of the convex relaxation on",
        "the reference's last grid (its own 30 s of CPU). *reference CPU s*: the whole certified",
        "reference of a case, refinement and bound (each limited to 30 s CPU).",
        "",
        "**Judged gap** = (optimal - reference) / max(|reference|, 10 % of the reference's traction",
        "energy), the difference in kWh beside it. Why a floor: on a net-regenerating section (a descent",
        "with regeneration) the net energy is the difference of the energy drawn for traction and the",
        "energy returned, and can be near zero (-0.097 kWh on CN_Songjiazhuang_Yizhuang 3906-6272 m with",
        "the FLIRT, where the train draws several kWh and returns as much); a relative gap on that",
        "difference is unbounded and says nothing about the driving. A planner judges a driving advice",
        "by the energy it moves: taking at least a tenth of the traction energy as the denominator keeps",
        "every section whose net energy is at least 10 % of its traction energy (every section without",
        "regeneration, and most with it) judged on |net| exactly, and judges the rest on a share of what",
        "the train draws (0.5 % of a tenth = 0.05 % of the traction energy: far tighter than the",
        "uncertainty of any efficiency figure). The plain gap on |reference| is in the CSV",
        "(`gap_percent`) for every row. Targets (issue 16): every case within 0.5 %, 95 % within 0.1 %;",
        "energy falling with running time on every section; the reference within 30 s.",
        "",
    ]


def coverage(df: pd.DataFrame, missing_reason: str) -> list[str]:
    """Which expected cases have no row, and why."""
    try:
        expected = expected_cases()
    except Exception as exc:  # the data beside the checkout may be absent: say so, do not guess
        return [f"**Coverage not checked** ({type(exc).__name__}: {exc}).", ""]
    have = {}
    for (track, train, s0, s1), g in df.groupby(["track", "train", "s0", "s1"]):
        have[(track, train, round(float(s0), 2), round(float(s1), 2))] = {round(x, 2) for x in g.supplement}
    full = {k for k, sups in have.items() if sups >= set(SUPPLEMENTS)}
    partial = {k: sorted(set(SUPPLEMENTS) - sups) for k, sups in have.items() if k not in full}
    absent = sorted(expected - set(have))
    n_expected = len(expected) * len(SUPPLEMENTS)
    n_have = sum(len(s & set(SUPPLEMENTS)) for s in have.values())
    out = [
        f"**Coverage**: {n_have} of the {n_expected} cases expected ({len(expected)} sections x 4 supplements)."
    ]
    if not absent and not partial:
        out += ["Every expected case was measured.", ""]
        return out
    out += [
        f"**Missing** ({n_expected - n_have} cases): {missing_reason}",
        "",
    ]
    by_line: dict[tuple[str, str], list[str]] = {}
    for track, train, s0, s1 in absent:
        by_line.setdefault((track, train), []).append(f"{s0:.0f}-{s1:.0f}")
    for (track, train, s0, s1), sups in sorted(partial.items()):
        by_line.setdefault((track, train), []).append(
            f"{s0:.0f}-{s1:.0f} at {', '.join(f'{100 * x:.0f} %' for x in sups)}"
        )
    trains_of: dict[str, list[str]] = {}
    for (track, train), secs in sorted(by_line.items()):
        n_sections = len({k for k in expected if k[0] == track and k[1] == train})
        if len(secs) == n_sections and all(" at " not in s for s in secs):
            trains_of.setdefault(track, []).append(train)  # nothing measured on this line with this train
        else:
            out.append(f"- {track} / {train}: {'; '.join(secs)} m")
    for track, trains in trains_of.items():
        n_sections = len({k[2:] for k in expected if k[0] == track})
        out.append(f"- {track}: all {n_sections} section(s) at all 4 supplements with {', '.join(trains)}")
    out.append("")
    return out


def summary(df: pd.DataFrame, usable: pd.DataFrame) -> list[str]:
    out = [
        f"**Cases measured**: {len(df)} (section x supplement x train); reference usable in {len(usable)}."
    ]
    if len(usable):
        j = usable.judged_gap_percent
        n = len(usable)
        within_all = (j <= TARGET_ALL_PERCENT).sum()
        within_most = (j <= TARGET_MOST_PERCENT).sum()
        out += [
            f"Judged gap: median {j.median():.3f} %, max {j.max():.3f} %; within {TARGET_ALL_PERCENT} %: "
            f"**{within_all}/{n}** (target: all), within {TARGET_MOST_PERCENT} %: **{within_most}/{n}** = "
            f"{100 * within_most / n:.1f} % (target: 95 %). Plain gap on |reference|: max "
            f"{usable.gap_percent.max():.3f} %, within 0.5 % {(usable.gap_percent <= 0.5).sum()}/{n}. "
            f"Difference: max {usable.gap_kwh.max():+.4f} kWh, min {usable.gap_kwh.min():+.4f} kWh "
            "(negative: the optimal strategy below the reference's transcription).",
        ]
    cert = df[df.certified_gap_percent.notna() & df.certified_gap_percent.map(math.isfinite)]
    if len(cert):
        own = (cert.ref_kwh - cert.lower_bound_kwh) / cert.lower_bound_kwh.abs() * 100
        out.append(
            f"Certified gap (optimal vs lower bound) in {len(cert)} cases: median "
            f"{cert.certified_gap_percent.median():.3f} %, max {cert.certified_gap_percent.max():.3f} %; the "
            f"reference above its own bound by median {own.median():.4f} %, at most {own.max():.4f} %."
        )
    moved = df.mesh.map(mesh_change_percent).dropna()
    if len(moved):
        out.append(
            f"The reference's last mesh doubling moved its optimum by median {moved.median():.4f} %, max "
            f"{moved.max():.4f} % ({len(moved)} cases with two grids or more; the first grid alone in "
            f"{len(df) - len(moved)}): a judged gap below that is within the reference's own uncertainty."
        )
    n, bad = monotone_sections(df)
    out.append(
        f"Energy falls with running time on {n - len(bad)}/{n} sections with two or more supplements measured"
        + (": rises on " + "; ".join(bad) if bad else ".")
    )
    over = (df.ref_cpu_s > REFERENCE_CPU_LIMIT_S).sum()
    out.append(
        f"Reference CPU (refinement and bound): median {df.ref_cpu_s.median():.1f} s, max "
        f"{df.ref_cpu_s.max():.1f} s, above {REFERENCE_CPU_LIMIT_S:.0f} s in {over}/{len(df)} (the bound has its "
        f"own 30 s); wall time median {df.ref_s.median():.1f} s, max {df.ref_s.max():.1f} s on a shared, loaded "
        f"machine. Status ok in {(df.ref_status == 'ok').sum()}/{len(df)}; "
        f"{df.ref_status.str.startswith('mesh not converged').sum()} mesh not converged within the budget, "
        f"{(~df.ref_status.isin(['ok']) & ~df.ref_status.str.startswith('mesh not converged')).sum()} other "
        f"(time limit / not converged / infeasible); lower bound ok in {(df.bound_status == 'ok').sum()}."
    )
    if "lesov_gap_percent" in df and df.lesov_gap_percent.notna().any():
        les = df[df.lesov_gap_percent.notna()]
        out.append(
            f"Source 004's method (our documented reading, its own braking): judged gap median "
            f"{les.lesov_gap_percent.median():.1f} %, max {les.lesov_gap_percent.max():.1f} % ({len(les)} cases)."
        )
    out.append(
        "Optimal-strategy times in the CSV (`opt_ms`) are wall times on a shared, loaded machine and do not "
        "measure the speed targets (`bench_optimize.py --speed` does)."
    )
    return [*out, ""]


def worst_rows(usable: pd.DataFrame) -> list[str]:
    over = usable[usable.judged_gap_percent > TARGET_ALL_PERCENT].sort_values(
        "judged_gap_percent", ascending=False
    )
    worst = usable.sort_values("judged_gap_percent", ascending=False).head(max(10, len(over)))
    out = [
        f"## Largest judged gaps ({len(over)} above {TARGET_ALL_PERCENT} %)",
        "",
        "| track | train | section m | supplement | reference kWh | traction kWh | optimal kWh | difference kWh "
        "| judged gap | plain gap | certified | reference's last doubling | reference status |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for _, r in worst.iterrows():
        out.append(
            f"| {r.track} | {r.train} | {r.s0:.0f}-{r.s1:.0f} | {100 * r.supplement:.0f} % | {r.ref_kwh:.3f} "
            f"| {r.ref_traction_kwh:.3f} | {r.opt_kwh:.3f} | {r.gap_kwh:+.4f} | {_pct(r.judged_gap_percent)} "
            f"| {_pct(r.gap_percent)} | {_pct(r.certified_gap_percent)} | {_pct(mesh_change_percent(r.mesh), 4)} "
            f"| {r.ref_status[:40]} |"
        )
    return [*out, ""]


def journey_table(jf: pd.DataFrame) -> list[str]:
    out = [
        "## Timing windows (TTOBench journeys)",
        "",
        "The optimal strategy with its windows enforced (`optimize.windows`, as `optimize(...,",
        'strategy="optimal")` drives them) against the certified reference with the same windows. A',
        "window is reachable where the fastest run passes before its latest time and leaves time to",
        "arrive on schedule after its earliest time (the fastest run is ahead of every run at every",
        "position). A window no run can meet goes to the reference moved to the nearest reachable",
        "time, max(1 s, 0.5 % of the section's time) inside, so that both are compared on runs that",
        "come as close to it as possible; *result status* is `optimize`'s status of the whole journey.",
        "",
        "| journey | train | window | time window s | reachable s | no run meets it by | optimal passes s "
        "| reference passes s | optimal kWh | reference kWh | difference kWh | judged gap | reference status "
        "| result status |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def b(x) -> str:
        return "–" if pd.isna(x) else f"{x:g}"

    for _, r in jf.iterrows():
        miss = "reachable" if r.no_run_meets_by_s <= 0 else f"**{r.no_run_meets_by_s:.1f} s**"
        # an infeasible or unconverged reference's last iterate is no energy to compare with
        usable = not pd.isna(r.judged_gap_percent)
        ref_kwh = f"{r.ref_kwh:.3f}" if usable else "–"
        gap_kwh = f"{r.gap_kwh:+.4f}" if usable else "–"
        if r.reachable_from_s > r.reachable_to_s:
            # the fastest run itself takes longer than the section's schedule: no window is the cause
            miss = (
                f"**no run keeps the schedule** (fastest {r.reachable_from_s - r.reachable_to_s:.1f} s over)"
            )
        out.append(
            f"| {r.journey} | {r.train} | {r.window} | {b(r.earliest_s)}-{b(r.latest_s)} "
            f"| {r.reachable_from_s:.1f}-{r.reachable_to_s:.1f} | {miss} | {r.opt_pass_s:.1f} "
            f"({r.opt_miss_s:+.1f}) | {r.ref_pass_s:.1f} | {r.opt_kwh:.3f} | {ref_kwh} | {gap_kwh} "
            f"| {_pct(r.judged_gap_percent)} | {r.ref_status[:30]} | {r.result_status} |"
        )
    reach = jf[(jf.no_run_meets_by_s <= 0) & (jf.reachable_from_s <= jf.reachable_to_s)]
    met = (reach.opt_miss_s.abs() <= 0.5).sum()
    out += [
        "",
        f"Reachable windows met by the optimal strategy (within 0.5 s): {met}/{len(reach)}; windows no run can "
        f"meet (or in a section whose schedule no run keeps): {len(jf) - len(reach)}, each with result status other "
        "than ok: "
        f"{bool((jf.drop(reach.index).result_status != 'ok').all())}. Judged gap max "
        f"{jf.judged_gap_percent.max():.3f} % (within 0.5 %: "
        f"{(jf.judged_gap_percent <= 0.5).sum()}/{jf.judged_gap_percent.notna().sum()}). Passing times in s from "
        "the section's departure; (+x) the optimal strategy's miss.",
        "",
    ]
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("tables", nargs="+", type=Path)
    parser.add_argument("--journeys", nargs="*", type=Path, default=[])
    parser.add_argument("--csv", type=Path, default=None, help="write every row (both kinds) here")
    parser.add_argument(
        "--notes",
        type=Path,
        default=None,
        help="markdown written by hand, printed after the summary as its reading",
    )
    parser.add_argument(
        "--missing-reason",
        default="not reached by the benchmark run before the deadline (see the lead's notes).",
    )
    args = parser.parse_args(argv)
    df = pd.concat([pd.read_csv(p) for p in args.tables], ignore_index=True)
    df = df.drop_duplicates(subset=["track", "train", "s0", "s1", "supplement"], keep="last")
    df["ref_status"] = df.ref_status.fillna("")
    df["bound_status"] = df.bound_status.fillna("")
    usable = df[df.judged_gap_percent.notna()]
    jf = pd.concat([pd.read_csv(p) for p in args.journeys], ignore_index=True) if args.journeys else None
    commits = sorted(set(df.commit.dropna()) | (set(jf.commit.dropna()) if jf is not None else set()))
    out = header(commits)
    out += coverage(df, args.missing_reason)
    out += summary(df, usable)
    if args.notes:
        out += ["## Reading (written by hand, from the rows below)", "", args.notes.read_text().strip(), ""]
    out += ["## Per line and train (worst section per supplement)", "", *section_table(df, usable), ""]
    if len(usable):
        out += worst_rows(usable)
    if jf is not None and len(jf):
        jf["ref_status"] = jf.ref_status.fillna("")
        out += journey_table(jf)
    print("\n".join(out))
    if args.csv:
        rows = [df.assign(kind="section")]
        if jf is not None and len(jf):
            rows.append(jf.assign(kind="journey window"))
        pd.concat(rows, ignore_index=True).to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
