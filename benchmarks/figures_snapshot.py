"""Every figure of every example's fastest run, saved and compared (issue 14's "changes no figure").

Speed work must change no figure of any example by more than 1e-9 relative and must stay bit-for-bit
identical across runs. This script records, for every ``examples/**/scenario*.yaml`` (run as a
single-point fastest run) and for the TrainRuns.jl trains on the ``realworld`` path (mass point and
homogeneous strip), the whole summary (status, warnings, running times, energies per section, peak
currents, energy balance) and, of the trace, its length and the sum, first and last value of every
column. ``save`` writes them to a JSON file (keep it out of git, e.g. in /tmp); ``compare`` runs again
and prints the largest relative difference per case and overall, and exits 1 above the tolerance or
when a status, warning or trace length differs.

Run: python benchmarks/figures_snapshot.py save /tmp/figures_before.json
     python benchmarks/figures_snapshot.py compare /tmp/figures_before.json [--tolerance 1e-9]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model.scenario import RunSettings
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[1]
TRAINRUNS_DIRS = (ROOT.parent / "shared" / "data" / "trainruns", ROOT / "tests" / "data" / "trainruns")


def cases() -> list[tuple[str, Any, Any, RunSettings]]:
    out = []
    for path in sorted((ROOT / "examples").rglob("scenario*.yaml")):
        sc = trainsim.load_scenario(path)
        out.append((str(path.relative_to(ROOT)), sc.train, sc.route, sc.settings))
    data = next((d for d in TRAINRUNS_DIRS if (d / "paths" / "realworld.yaml").exists()), None)
    if data is not None:
        for name in ("freight", "local", "longdistance"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                train = load_train(data / "trains" / f"{name}.yaml")
            for mass_model in ("mass_point", "homogeneous_strip"):
                route = load_route(data / "paths" / "realworld.yaml", mass_model=mass_model)
                out.append((f"trainruns {name} realworld {mass_model}", train, route, RunSettings()))
    return out


def figures(train, route, settings) -> dict[str, Any]:
    """The summary of a run with its trace, the summary without, and the trace's column digests."""
    full = run_fastest(train, route, settings)
    bare = run_fastest(train, route, settings, trace=False)
    out: dict[str, Any] = {"summary": full.summary(), "summary_no_trace": bare.summary()}
    tr = full.trace
    digest: dict[str, Any] = {"points": len(tr)}
    for name in tr.__dataclass_fields__:
        x = np.asarray(getattr(tr, name), dtype=float)
        digest[name] = [float(np.nansum(x)), float(x[0]), float(x[-1])]
    out["trace"] = digest
    return out


def snapshot() -> dict[str, Any]:
    return {name: figures(train, route, settings) for name, train, route, settings in cases()}


def _diff(a: Any, b: Any, path: str, out: list[tuple[float, str]], exact: list[str]) -> None:
    """Collect the relative differences of numbers, and the paths of anything else that differs."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                exact.append(f"{path}/{k}: missing on one side")
            else:
                _diff(a[k], b[k], f"{path}/{k}", out, exact)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            exact.append(f"{path}: length {len(a)} != {len(b)}")
        for j, (x, y) in enumerate(zip(a, b, strict=False)):
            _diff(x, y, f"{path}[{j}]", out, exact)
    elif isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or isinstance(b, str):
        if a != b:
            exact.append(f"{path}: {a!r} != {b!r}")
    elif isinstance(a, int | float) and isinstance(b, int | float):
        if a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)):
            out.append((0.0, path))
        else:
            out.append((abs(a - b) / max(abs(a), abs(b), 1e-300), path))
    elif a != b:
        exact.append(f"{path}: {a!r} != {b!r}")


def compare(before: dict[str, Any], after: dict[str, Any], tolerance: float) -> bool:
    worst_all = (0.0, "")
    ok = True
    for case in sorted(set(before) | set(after)):
        if case not in before or case not in after:
            print(f"{case}: only on one side")
            ok = False
            continue
        rel: list[tuple[float, str]] = []
        exact: list[str] = []
        # the trace's sums are of large arrays: compared like the rest, relative to their magnitude
        _diff(before[case], after[case], "", rel, exact)
        worst = max(rel) if rel else (0.0, "")
        worst_all = max(worst_all, worst)
        flag = "" if worst[0] <= tolerance and not exact else "  <-- EXCEEDS"
        where = f" at {worst[1]}" if worst[0] > 0 else " (every figure bit for bit)"
        print(f"{case:55s} max rel diff {worst[0]:.3e}{where}{flag}")
        for e in exact[:5]:
            print(f"    differs: {e}")
        ok = ok and worst[0] <= tolerance and not exact
    print(f"overall max relative difference: {worst_all[0]:.3e} {worst_all[1] if worst_all[0] > 0 else ''}")
    return ok


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("action", choices=("save", "compare"))
    ap.add_argument("file")
    ap.add_argument("--tolerance", type=float, default=1e-9)
    args = ap.parse_args()
    snap = snapshot()
    if args.action == "save":
        Path(args.file).write_text(json.dumps(snap, indent=1, allow_nan=True))
        print(f"saved {len(snap)} cases to {args.file}")
        return 0
    before = json.loads(Path(args.file).read_text())
    again = snapshot()
    same = json.dumps(snap, allow_nan=True) == json.dumps(again, allow_nan=True)
    print(f"bit-for-bit identical across two runs in this process: {same}")
    ok = compare(before, snap, args.tolerance)
    return 0 if ok and same else 1


if __name__ == "__main__":
    sys.exit(main())
