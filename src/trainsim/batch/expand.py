"""Expanding a study into its runs: parameters per run, seeded samples and stable run ids.

Order of the runs (``run_index``): explicit runs (or the base) in the order written, then their
departures, then the sweep points (the first axis varies slowest), then the samples. A run id is the
SHA-256 of the run's parameters as canonical JSON (first 24 hex digits): the same run of the same study
always has the same id, whatever the executor, the chunking or the order in which runs finish, which is
what resuming an interrupted study relies on.

Samples are drawn in the process that expands the study, each field from its own NumPy PCG64 stream
seeded with the study's seed and the field's name, sample ``i`` from the stream's i-th uniform by
inverse transform: the values depend only on the study file, never on the order of the fields or on
the other fields. Sample ``i`` has the
same values at every sweep point and for every explicit run (common random numbers: differences
between design points are not blurred by different draws).
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from trainsim.errors import InputError

if TYPE_CHECKING:
    from trainsim.batch.study import DistributionSpec, ParamColumn, SamplesSpec, Study

#: The most runs one study may have (a study names them all in its results).
MAX_RUNS = 5_000_000

__all__ = ["Expansion", "RunTask", "draw_samples", "expand", "field_stream", "run_id"]

#: What a worker needs to compute one run: (run_index, entry index, departure [s] or None,
#: ((path, value, relative), ...)).
RunTask = tuple[int, int, float | None, tuple[tuple[str, Any, bool], ...]]


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    return str(obj)


def run_id(params: dict[str, Any]) -> str:
    """Stable id of a run: SHA-256 of its parameters as canonical JSON, 24 hex digits."""
    text = json.dumps(
        params, sort_keys=True, separators=(",", ":"), ensure_ascii=False, default=_json_default
    )
    return hashlib.sha256(text.encode()).hexdigest()[:24]


#: Smallest probability mass of a truncated normal between its min and max: below it (about 37
#: standard deviations into a tail, where Phi underflows) the bounds leave nothing of the distribution
#: that a double can represent (a study file's mistake, not a sample to draw).
MIN_TRUNCATED_MASS = 1e-290


def field_stream(seed: int, name: str) -> np.random.Generator:
    """The random stream of the sampled field ``name``: PCG64 seeded with the study's seed and the first
    128 bits of SHA-256 of the field's name. Fields are independent of one another and of their order
    in the study; adding or removing a field changes no other field's draws."""
    digest = hashlib.sha256(name.encode()).digest()
    words = [int.from_bytes(digest[4 * k : 4 * k + 4], "little") for k in range(4)]
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, *words])))


def _uniforms(seed: int, name: str, count: int) -> np.ndarray:
    """``count`` uniforms in the open interval (0, 1): the i-th is the i-th double of the field's stream
    (moved to the middle of its 2**-53 cell so that no inverse CDF sees 0 or 1)."""
    u = field_stream(seed, name).random(count)
    return (np.floor(u * 2.0**53) + 0.5) / 2.0**53


def _truncated_normal_ppf(u: np.ndarray, a: float, b: float) -> np.ndarray:
    """Inverse CDF of the standard normal truncated to [a, b] (a < b, either may be infinite): the
    quantile Phi^-1(Phi(a) + u (Phi(b) - Phi(a))), mirrored so that the interval's tail mass is taken
    from the lower tail, where Phi keeps its relative precision."""
    from scipy.special import ndtr, ndtri

    if a > 0.0:  # mirror: X = -Y with Y truncated to [-b, -a]
        return -_truncated_normal_ppf(1.0 - u, -b, -a)
    pa, pb = float(ndtr(a)), float(ndtr(b))
    if pb - pa < MIN_TRUNCATED_MASS:
        raise ValueError("no mass")
    return np.clip(ndtri(pa + u * (pb - pa)), a, b)


def _draw(dist: DistributionSpec, u: np.ndarray, name: str) -> list[Any]:
    """The values of one field by inverse transform of the uniforms ``u``: value i depends only on
    ``u[i]``, so sample i keeps its value whatever the sample count."""
    if dist.distribution == "choice":
        values = list(dist.values or [])
        w = np.ones(len(values)) if dist.weights is None else np.asarray(dist.weights, dtype=float)
        cum = np.cumsum(w)
        idx = np.minimum(np.searchsorted(cum, u * cum[-1], side="right"), len(values) - 1)
        return [values[int(i)] for i in idx]
    if dist.distribution == "uniform":
        x = dist.low + (dist.high - dist.low) * u  # type: ignore[operator]
    elif dist.distribution == "triangular":
        lo, mode, hi = float(dist.low), float(dist.mode), float(dist.high)  # type: ignore[arg-type]
        if lo == hi:
            x = np.full(len(u), lo)
        else:
            c = (mode - lo) / (hi - lo)
            x = np.where(
                u < c,
                lo + np.sqrt(u * (hi - lo) * (mode - lo)),
                hi - np.sqrt((1.0 - u) * (hi - lo) * (hi - mode)),
            )
    else:
        mean, std = float(dist.mean), float(dist.std)  # type: ignore[arg-type]
        lo = -np.inf if dist.min is None else float(dist.min)
        hi = np.inf if dist.max is None else float(dist.max)
        try:
            if std == 0.0:
                if not lo <= mean <= hi:
                    raise ValueError("mean outside")
                x = np.full(len(u), mean)
            else:
                x = mean + std * _truncated_normal_ppf(u, (lo - mean) / std, (hi - mean) / std)
        except ValueError:
            raise InputError(
                "the normal distribution has almost no probability between min and max",
                field=f"samples.fields.{name}",
                value={"mean": mean, "std": std, "min": dist.min, "max": dist.max},
                allowed=f"min and max enclosing at least {MIN_TRUNCATED_MASS:g} of the probability",
            ) from None
    return [float(v) for v in x]


def draw_samples(samples: SamplesSpec) -> dict[str, list[Any]]:
    """The sampled values of every field, ``count`` each, from the study's seed.

    Each field has its own stream, seeded by the study's seed and the field's name (`field_stream`);
    sample ``i`` of a field is the inverse CDF of the i-th uniform of that stream. A field's draws
    therefore depend only on (seed, name, distribution, i): not on the other fields, their order, or
    the number of samples.
    """
    return {
        path: _draw(dist, _uniforms(samples.seed, path, samples.count), path)
        for path, dist in samples.fields.items()
    }


@dataclass
class Expansion:
    """The runs of a study, column by column (index = run_index).

    Attributes:
        columns: the parameter columns, in order.
        values: column name -> value of each run (as written in the study or drawn).
        entry: index of each run's entry (base or explicit run).
        departure_s: departure time of each run [s since midnight] or None.
        run_ids: stable id of each run.
        driving: whether the runs are driven by a ``driving`` block (the results have the driving
            columns).
        multi_point: whether some runs use the multi-point model (the results have the coupler-force
            columns).
    """

    study_name: str
    fingerprint: str
    columns: list[ParamColumn]
    values: dict[str, list[Any]]
    entry: list[int]
    departure_s: list[float | None]
    run_ids: list[str]
    driving: bool = False
    multi_point: bool = False
    _overrides: list[ParamColumn] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._overrides = [c for c in self.columns if c.path is not None]

    def __len__(self) -> int:
        return len(self.run_ids)

    def task(self, i: int) -> RunTask:
        """What a worker needs to compute run ``i``."""
        overrides = tuple((c.path, self.values[c.name][i], c.relative) for c in self._overrides)
        return (i, self.entry[i], self.departure_s[i], overrides)  # type: ignore[return-value]

    def params(self, i: int) -> dict[str, Any]:
        """The parameters of run ``i`` by column name."""
        return {c.name: self.values[c.name][i] for c in self.columns}


def expand(study: Study) -> Expansion:
    """Every run of ``study``; InputError if the axes do not fit together, the study is too large or two
    runs would have the same parameters."""
    spec = study.spec
    axes_points = [axis.points() for axis in spec.axes]
    if spec.combine == "zip" and axes_points:
        lengths = {len(p) for p in axes_points}
        if len(lengths) > 1:
            raise InputError(
                "with 'combine: zip' every axis needs the same number of values",
                file=study.file,
                field="axes",
                value=[len(p) for p in axes_points],
            )
        combos = [tuple(itertools.chain.from_iterable(t)) for t in zip(*axes_points, strict=True)]
    else:
        combos = [tuple(itertools.chain.from_iterable(t)) for t in itertools.product(*axes_points)]
    sampled = draw_samples(spec.samples) if spec.samples is not None else None
    n_samples = spec.samples.count if spec.samples is not None else 1
    n_departures = sum(len(e.departures or (None,)) for e in study.entries)
    total = n_departures * len(combos) * n_samples
    if total > MAX_RUNS:
        raise InputError(
            f"the study expands to {total} runs, more than the {MAX_RUNS} allowed in one study",
            file=study.file,
            allowed="split it into several studies",
        )
    names = [c.name for c in study.columns]
    axis_cols = [c.name for c in study.columns if c.path is not None][: len(combos[0]) if combos else 0]
    sample_cols = [(c.name, c.path) for c in study.columns if c.path is not None][len(axis_cols) :]
    has_run = "run" in names
    has_dep = "departure_s" in names
    has_sample = "sample" in names
    values: dict[str, list[Any]] = {n: [] for n in names}
    entries: list[int] = []
    departures: list[float | None] = []
    ids: list[str] = []
    seen: dict[str, int] = {}
    for e, entry in enumerate(study.entries):
        for dep in entry.departures or (None,):
            for combo in combos:
                for s in range(n_samples):
                    row: dict[str, Any] = {}
                    if has_run:
                        row["run"] = entry.name
                    if has_dep:
                        row["departure_s"] = dep
                    if has_sample:
                        row["sample"] = s
                    row.update(zip(axis_cols, combo, strict=True))
                    if sampled is not None:
                        for name, path in sample_cols:
                            row[name] = sampled[path][s]  # type: ignore[index]
                    rid = run_id(row)
                    if rid in seen:
                        raise InputError(
                            f"runs {seen[rid]} and {len(ids)} have the same parameters {row}: every run "
                            "must differ (repeated axis values?)",
                            file=study.file,
                        )
                    seen[rid] = len(ids)
                    for k, v in row.items():
                        values[k].append(v)
                    entries.append(e)
                    departures.append(dep)
                    ids.append(rid)
    return Expansion(
        study.name,
        study.fingerprint,
        list(study.columns),
        values,
        entries,
        departures,
        ids,
        driving=study.driving,
        multi_point=study.multi_point,
    )
