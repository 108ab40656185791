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
        "without auxiliaries (traction / eta_t - regenerated x eta_r). Gap: (optimal - reference) / |reference|",
        "against the reference optimum (CasADi/IPOPT, one interval per 20 m and at least 1000, graded near",
        "stops; on net-regenerating descents the energies are negative, and near zero a relative gap of a",
        "few per cent is a few hundredths of a kWh); for several sections, the worst section. Source 004:",
        "our reading of Lesov et al.'s method (docs/OPTIMIZATION.md); where its",
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
    short = df[(df.s1 - df.s0) <= 10_000]
    out += [
        "",
        f"Cases: {len(df)} (section x supplement x train); reference converged in {len(ok)}.",
        f"Optimal vs reference: median gap {ok.gap_percent.median():.3f} %, within 1 %: "
        f"{(ok.gap_percent <= 1).sum()}/{len(ok)}, within 0.1 %: {(ok.gap_percent <= 0.1).sum()}/{len(ok)}; "
        f"flat tracks (00_reference*): max {flat.gap_percent.max():.3f} %.",
        f"Optimal wall time per section: median {df.opt_ms.median():.0f} ms, max {df.opt_ms.max():.0f} ms; "
        f"sections <= 10 km: median {short.opt_ms.median():.0f} ms, 90 % within "
        f"{short.opt_ms.quantile(0.9):.0f} ms, {(short.opt_ms <= 50).sum()}/{len(short)} within 50 ms, "
        f"max {short.opt_ms.max():.0f} ms.",
        f"Reference: median {ok.ref_s.median():.2f} s, max {ok.ref_s.max():.2f} s, at least "
        f"{ok.intervals.min()} intervals.",
        f"Schedule: the optimal strategy's largest time error {df.opt_time_error_s.abs().max():.3f} s.",
        "",
        "Cases more than 1 % above the reference:",
        "",
    ]
    above = ok[ok.gap_percent > 1.0].sort_values("gap_percent", ascending=False)
    out += [
        f"* {r.track}, {r.train}, {r.s0:.0f}-{r.s1:.0f} m, {r.supplement:.0%}: {r.gap_percent:+.2f} % "
        f"({r.gap_kwh:+.3f} kWh)"
        for r in above.itertuples()
    ] or ["* none"]
    below = ok[ok.gap_percent < -0.5].sort_values("gap_percent")
    out += [
        "",
        "Cases more than 0.5 % *below* the reference (IPOPT stops in a local optimum on these hilly",
        "sections, or its discretisation costs near zero net energy):",
        "",
    ]
    out += [
        f"* {r.track}, {r.train}, {r.s0:.0f}-{r.s1:.0f} m, {r.supplement:.0%}: {r.gap_percent:+.2f} % "
        f"({r.gap_kwh:+.3f} kWh)"
        for r in below.itertuples()
    ] or ["* none"]
    out += [
        "",
        "How the optimal strategy is built, and where the reference is not a certificate: docs/OPTIMIZATION.md.",
    ]
    print("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1])
