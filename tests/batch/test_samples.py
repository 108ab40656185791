"""Monte Carlo samples: each field seeded by its name, independent of the others, exact distributions.

The reorder / add-a-field tests fail if the fields were drawn from one stream (or seeded by their
position in the study), and the correlation test fails if two fields shared a stream.
"""

from __future__ import annotations

import numpy as np
import pytest
from batchcases import metro_study
from scipy import stats

from trainsim.batch import study_from_dict
from trainsim.batch.expand import draw_samples
from trainsim.batch.study import SamplesSpec
from trainsim.errors import InputError

LOAD = "train.formation[*].load_t"
EFF = "train.electrical.traction_efficiency"
VOLT = "train.electrical.line_voltage_v"
MASS = "train.formation[0].mass_t"
FIELDS = {
    LOAD: {"distribution": "uniform", "low": 0, "high": 18},
    EFF: {"distribution": "normal", "mean": 0.9, "std": 0.05, "max": 0.95},
    VOLT: {"distribution": "choice", "values": [900, 1000], "weights": [1, 3]},
    MASS: {"distribution": "triangular", "low": 0.9, "mode": 1.0, "high": 1.05, "relative": True},
}


def draws(fields: dict, count: int = 300, seed: int = 7) -> dict:
    return draw_samples(SamplesSpec.model_validate({"count": count, "seed": seed, "fields": fields}))


def test_reordering_the_fields_changes_no_draw():
    a = draws(FIELDS)
    b = draws(dict(reversed(list(FIELDS.items()))))
    assert list(b) == list(reversed(list(a)))
    for name in FIELDS:
        assert a[name] == b[name], name


def test_adding_or_removing_a_field_changes_no_other_draw():
    a = draws(FIELDS)
    extra = {"train.formation[1].load_t": {"distribution": "uniform", "low": 0, "high": 5}, **FIELDS}
    b = draws(extra)
    c = draws({k: v for k, v in FIELDS.items() if k != LOAD})
    for name in FIELDS:
        assert a[name] == b[name], name
        if name != LOAD:
            assert a[name] == c[name], name


def test_the_same_study_reordered_gives_the_same_runs():
    a = study_from_dict(metro_study(samples={"count": 20, "seed": 3, "fields": FIELDS}), "s.yaml").expand()
    rev = dict(reversed(list(FIELDS.items())))
    b = study_from_dict(metro_study(samples={"count": 20, "seed": 3, "fields": rev}), "s.yaml").expand()
    assert sorted(a.run_ids) == sorted(b.run_ids)
    for col in a.values:
        assert a.values[col] == b.values[col], col


def test_more_samples_keep_the_first_ones():
    assert draws(FIELDS, count=50) == {k: v[:50] for k, v in draws(FIELDS, count=300).items()}


def test_fields_are_independent_of_each_other():
    # two fields with the same distribution: one stream for both would give equal (or shifted) draws
    same = {
        "a": {"distribution": "uniform", "low": 0, "high": 1},
        "b": {"distribution": "uniform", "low": 0, "high": 1},
    }
    n = 20_000
    d = draws(same, count=n)
    a, b = np.array(d["a"]), np.array(d["b"])
    # correlation of independent uniforms: standard deviation 1/sqrt(n) = 0.007; 5 sigma
    assert abs(np.corrcoef(a, b)[0, 1]) < 5 / np.sqrt(n)
    # nor shifted copies of each other (one stream read in turns): lag-1 cross-correlation too
    assert abs(np.corrcoef(a[1:], b[:-1])[0, 1]) < 5 / np.sqrt(n)
    assert abs(np.corrcoef(a[:-1], b[1:])[0, 1]) < 5 / np.sqrt(n)
    # every field over the others of the mixed study
    mixed = draws(FIELDS, count=n)
    cols = np.array([mixed[k] for k in FIELDS], dtype=float)
    r = np.corrcoef(cols)
    assert np.all(np.abs(r[np.triu_indices(len(FIELDS), 1)]) < 5 / np.sqrt(n))


def test_seed_changes_every_field():
    a, b = draws(FIELDS, seed=1), draws(FIELDS, seed=2)
    for name in (LOAD, EFF, MASS):
        assert a[name] != b[name]


def test_distributions_match_scipy():
    """Kolmogorov-Smirnov against scipy.stats' own CDFs (an independent computation)."""
    n = 20_000
    fields = {
        "u": {"distribution": "uniform", "low": 2, "high": 5},
        "t": {"distribution": "triangular", "low": 0.9, "mode": 1.0, "high": 1.05},
        "n": {"distribution": "normal", "mean": 1000, "std": 50},
        "tn": {"distribution": "normal", "mean": 0.9, "std": 0.05, "min": 0.85, "max": 0.95},
        "tail": {"distribution": "normal", "mean": 0.0, "std": 1.0, "min": 8.0},  # far upper tail
        "c": {"distribution": "choice", "values": ["x", "y", "z"], "weights": [1, 0, 3]},
    }
    d = draws(fields, count=n)
    cdfs = {
        "u": stats.uniform(2, 3).cdf,
        "t": stats.triang((1.0 - 0.9) / 0.15, loc=0.9, scale=0.15).cdf,
        "n": stats.norm(1000, 50).cdf,
        "tn": stats.truncnorm(-1, 1, loc=0.9, scale=0.05).cdf,
        "tail": stats.truncnorm(8.0, np.inf).cdf,
    }
    for name, cdf in cdfs.items():
        assert stats.kstest(d[name], cdf).pvalue > 1e-3, name
    assert min(d["tail"]) >= 8.0 and np.isfinite(d["tail"]).all()
    c = np.array(d["c"])
    assert "y" not in set(c) and abs((c == "z").mean() - 0.75) < 0.02


def test_degenerate_and_impossible_normals():
    d = draws({"a": {"distribution": "normal", "mean": 3.0, "std": 0.0}}, count=5)
    assert d["a"] == [3.0] * 5
    with pytest.raises(InputError, match="almost no probability") as err:
        draws({"a": {"distribution": "normal", "mean": 0.0, "std": 1.0, "min": 50, "max": 51}})
    assert "samples.fields.a" in str(err.value)
