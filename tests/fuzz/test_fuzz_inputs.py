"""The fuzz suite (issue 13): at least 10,000 seeded mutations of every shipped input kind, read through
the CLI's entry points (the run's reader and ``trainsim check``), must give no traceback, no hang over
5 s, no worker over 500 MB, and refuse every file known to be invalid with a message naming the file
and the field. See fuzzing.py for the mutations; ``python tests/fuzz/fuzzing.py N SEED`` reports.

TRAINSIM_FUZZ_CASES and TRAINSIM_FUZZ_SEED change the number of cases and the seed."""

from __future__ import annotations

import os
import time

import pytest
from fuzzing import CASE_TIMEOUT_S, SHARED, Tally, run, summary

pytestmark = pytest.mark.slow

CASES = int(os.environ.get("TRAINSIM_FUZZ_CASES", "10000"))
SEED = int(os.environ.get("TRAINSIM_FUZZ_SEED", "13"))


@pytest.fixture(scope="module")
def tally() -> Tally:
    t0 = time.perf_counter()
    result = run(CASES, SEED)
    print("\nfuzz:", summary(result, time.perf_counter() - t0))
    if result.by_origin:
        print("tracebacks by origin:", dict(result.by_origin.most_common()))
    return result


def _samples(tally: Tally) -> str:
    return "\n----\n".join(tally.samples[:10])


def test_every_kind_mutated_at_least_10000_times(tally: Tally) -> None:
    assert tally.cases >= min(CASES, 10_000) * 0.98  # a few mutations cannot be written (e.g. 10**400 keys)
    kinds = {"yaml", "xml", "csv", "xlsx"} | ({"json"} if (SHARED / "data" / "ttobench").is_dir() else set())
    assert kinds <= set(tally.by_kind), tally.by_kind


def test_no_traceback(tally: Tally) -> None:
    assert tally.tracebacks == 0, f"{dict(tally.by_origin)}\n{_samples(tally)}"


def test_no_hang(tally: Tally) -> None:
    assert tally.timeouts == 0, (
        f"{tally.timeouts} cases over {CASE_TIMEOUT_S} s: {dict(tally.timeouts_by_seed)}\n{_samples(tally)}"
    )


def test_memory_bounded(tally: Tally) -> None:
    assert tally.peak_rss_mb < 500, tally.peak_rss_mb


def test_invalid_files_refused_with_clear_messages(tally: Tally) -> None:
    assert tally.must_refuse > 50  # the suite does put invalid numbers into trainsim files
    assert tally.wrongly_accepted == 0, _samples(tally)
    assert tally.unclear_messages == 0, f"{dict(tally.unclear_by_seed)}\n{_samples(tally)}"
    assert tally.refused > tally.cases / 3
    assert tally.with_field > tally.refused / 2  # most refusals name the field


def test_check_and_run_agree(tally: Tally) -> None:
    assert tally.disagreements == 0, _samples(tally)
