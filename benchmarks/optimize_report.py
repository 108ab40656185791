"""Turn the CSV of bench_optimize.py into the markdown table of docs/optimization_benchmark.md.

Run: python benchmarks/optimize_report.py table.csv > docs/optimization_benchmark.md
"""

from __future__ import annotations

import sys

import pandas as pd


def main(path: str) -> None:
    df = pd.read_csv(path)
    ok = df[df.ref_status == "ok"]
    out = [
        "# Optimal strategy against the reference optimum (TTOBench)",
        "",
        "Measured with `python benchmarks/bench_optimize.py --out table.csv` (this table: "
        "`python benchmarks/optimize_report.py table.csv`) on the 2-core development machine, shared with",
        "other jobs while it ran (wall times are upper bounds). Energy: net electrical energy drawn from the line",
        "without auxiliaries (traction / eta_t - regenerated x eta_r). Gap: optimal strategy against the",
        "reference optimum (CasADi/IPOPT, >= 1000 intervals, graded near stops); for several sections, the",
        "worst section. Source 004: our reading of Lesov et al.'s method (docs/OPTIMIZATION.md); where its",
        "time error is positive its run is late (it cannot meet tight schedules with 0.8 f_u recuperative",
        "braking), so its energy is not comparable there.",
        "",
        "| track | train | sections | gap 5 % | gap 10 % | gap 20 % | gap 30 % | optimal ms (median) "
        "| reference s (median) | source 004 gap (median) | source 004 max late s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (track, train), g in df.groupby(["track", "train"], sort=False):
        gaps = [f"{g[g.supplement.round(2) == sup].gap_percent.max():.3f} %" for sup in (0.05, 0.1, 0.2, 0.3)]
        out.append(
            f"| {track} | {train} | {g.s0.nunique()} | " + " | ".join(gaps) + f" | {g.opt_ms.median():.0f} "
            f"| {g.ref_s.median():.2f} | {g.lesov_gap_percent.median():.1f} % | {g.lesov_time_error_s.max():+.1f} |"
        )
    flat = ok[ok.track.str.startswith("00_reference")]
    out += [
        "",
        f"Cases: {len(df)} (section x supplement x train); reference converged in {len(ok)}.",
        f"Optimal vs reference: median gap {ok.gap_percent.median():.3f} %, within 1 %: "
        f"{(ok.gap_percent <= 1).sum()}/{len(ok)}, within 0.1 %: {(ok.gap_percent <= 0.1).sum()}/{len(ok)}; "
        f"flat tracks (00_reference*): max {flat.gap_percent.max():.3f} %.",
        f"Optimal wall time per section: median {df.opt_ms.median():.0f} ms, max {df.opt_ms.max():.0f} ms "
        f"(sections <= 10 km: median {df[(df.s1 - df.s0) <= 10_000].opt_ms.median():.0f} ms).",
        f"Reference: median {ok.ref_s.median():.2f} s, max {ok.ref_s.max():.2f} s.",
        f"Schedule: the optimal strategy's largest time error {df.opt_time_error_s.abs().max():.3f} s.",
        "",
        "Where the gap is large (real lines with many limit changes and grades: CH_*, CN_*, SE_*, the",
        "speed-limit variants), the missing parts of the construction are named in docs/OPTIMIZATION.md.",
        "Those cases are open work.",
    ]
    print("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1])
