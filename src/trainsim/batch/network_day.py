"""A network-day: several lines in operation (one operation file each), each a day of trains, and
optionally sampled days (Monte Carlo of entry delays and disturbances), simulated locally or on a
Dask cluster with the same results.

The unit of work is one line on one day (``line_day``): it reads its operation file, samples the day
(sample ``k`` of ``n`` uses the ``k``-th stream spawned from the seed, exactly as
``trainsim.io.operation_run.monte_carlo``) and simulates it. Lines of a network are simulated
independently: trains do not pass from one file's line to another's.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation

#: Status order, worst last: the network-day's status is its worst line-day's.
STATUS_ORDER = ("ok", "conflicts", "stalled", "deadlock")


def line_day(
    path: str, sample: int | None = None, samples: int = 0, seed: int | None = None
) -> dict[str, Any]:
    """Simulate one line's day: the file's own timetable (``sample`` None) or sample ``sample`` of
    ``samples`` sampled days (seed: ``seed``, default the file's). Returns a picklable summary: per
    train its delay [s] and operated energy [kWh], the status, totals and the run-cache counts."""
    op = read_operation(path)
    services = op.services
    if sample is not None:
        sampler = op.disturbances if op.disturbances is not None else op.delays
        if sampler is None:
            raise InputError(
                "sampled days need a 'delays' or 'disturbances' block", file=str(path), field="delays"
            )
        base = sampler.seed if seed is None else seed
        stream = np.random.SeedSequence(base).spawn(samples)[sample]
        services = sampler.sample(op.given_services, np.random.default_rng(stream))
    res = run_operation(op, services, conflicts=sample is None, headways=False)
    trains = [
        {
            "id": t.id,
            "status": t.status,
            "delay_s": float(t.delay_s) if np.isfinite(t.delay_s) else None,
            "energy_kwh": float(t.energy_kwh) if np.isfinite(t.energy_kwh) else None,
        }
        for t in res.trains
    ]
    return {
        "file": str(path),
        "line": op.name,
        "sample": sample,
        "status": res.status,
        "trains": trains,
        "conflicts": len(res.conflicts),
        "total_delay_s": float(sum(t.delay_s for t in res.trains if np.isfinite(t.delay_s))),
        "energy_kwh": float(sum(t.energy_kwh for t in res.trains if np.isfinite(t.energy_kwh))),
    }


def _tasks(files: Sequence[str | Path], samples: int, seed: int | None) -> list[tuple]:
    if not files:
        raise InputError("a network-day needs at least one operation file", field="files", value=[])
    if not 0 <= samples <= 10_000:
        raise InputError("invalid number of samples", field="samples", value=samples, allowed="0 .. 10000")
    missing = [str(f) for f in files if not Path(f).is_file()]
    if missing:
        raise InputError("operation file not found", field="files", value=missing)
    if samples == 0:
        return [(str(f), None, 0, seed) for f in files]
    return [(str(f), k, samples, seed) for f in files for k in range(samples)]


def network_day(
    files: Sequence[str | Path], samples: int = 0, seed: int | None = None, client: Any = None
) -> dict[str, Any]:
    """Simulate every line of ``files`` (its own timetable, or ``samples`` sampled days each) locally
    (``client`` None) or on the Dask cluster of ``client`` (a ``distributed.Client``): the same line-day
    summaries either way, in the order of the files and samples.

    Returns ``status`` (the worst line-day status), ``line_days`` (``line_day`` summaries) and the
    totals ``total_delay_s`` and ``energy_kwh`` over all line-days."""
    tasks = _tasks(files, samples, seed)
    if client is None:
        days = [line_day(*t) for t in tasks]
    else:
        futures = client.map(line_day, *zip(*tasks, strict=True), pure=False)
        days = client.gather(futures)
    worst = max((d["status"] for d in days), key=lambda s: STATUS_ORDER.index(s) if s in STATUS_ORDER else 99)
    return {
        "status": worst,
        "line_days": days,
        "total_delay_s": float(sum(d["total_delay_s"] for d in days)),
        "energy_kwh": float(sum(d["energy_kwh"] for d in days)),
    }


__all__ = ["line_day", "network_day"]
