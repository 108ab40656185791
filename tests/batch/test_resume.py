"""Interrupted studies resume where they stopped: every run present exactly once."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from batchcases import metro_study

from trainsim.batch import load_study, read_results, run_study, study_from_dict
from trainsim.batch.sink import META_FILE, RESULTS_DIR
from trainsim.errors import InputError

#: 1200 runs in chunks of 10: about 2 s of work on 2 workers, killed after 3 chunks.
KILL_STUDY = metro_study(
    samples={
        "count": 1200,
        "seed": 5,
        "fields": {
            "train.formation[*].load_t": {"distribution": "uniform", "low": 0, "high": 18},
            "train.electrical.traction_efficiency": {"distribution": "uniform", "low": 0.85, "high": 0.95},
        },
    },
    chunk_size=10,
)


def _parts(out: Path) -> list[Path]:
    return sorted((out / RESULTS_DIR).glob("part-*.parquet"))


def _assert_exactly_once(out: Path, expected_ids: list[str]) -> None:
    ids = [i for p in _parts(out) for i in pq.read_table(p, columns=["run_id"]).column("run_id").to_pylist()]
    assert len(ids) == len(set(ids)), "a run was written twice"
    assert sorted(ids) == sorted(expected_ids), "a run is missing"


def _children(pid: int) -> list[int]:
    out = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True, check=False).stdout
    return [int(p) for p in out.split()]


def _alive(pid: int) -> bool:
    """Whether a process exists and is not a zombie (dead, waiting to be reaped)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_sigkill_mid_study_then_resume(write_study, tmp_path):
    study_file = write_study(KILL_STUDY)
    out = tmp_path / "out"
    cmd = [
        sys.executable,
        "-m",
        "trainsim.batch",
        str(study_file),
        "--out",
        str(out),
        "--workers",
        "2",
        "--no-progress",
    ]
    # a session of its own, so that whatever happens the test can clean up every process it started
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while len(_parts(out)) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        workers = _children(proc.pid)
        # SIGKILL to the study's process only, as `kill -9 PID`: its workers must not survive it
        proc.kill()
        proc.wait(timeout=30)
        assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode() if proc.stderr else ""
        assert len(workers) == 2
        deadline = time.monotonic() + 10
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not any(_alive(w) for w in workers), "a worker outlived the killed study"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    written = len(pq.read_table(out / RESULTS_DIR).column("run_id")) if _parts(out) else 0
    assert 30 <= written < 1200, f"the kill did not happen mid-study ({written} runs written)"

    study = load_study(study_file)
    ids = study.expand().run_ids
    outcome = run_study(study, out, executor="processes", workers=2)
    assert outcome.already_done == written and outcome.computed == 1200 - written
    assert outcome.complete and outcome.failed == 0
    _assert_exactly_once(out, ids)
    assert not list((out / RESULTS_DIR).glob(".*.tmp"))
    # a third start finds nothing to do
    again = run_study(study, out, executor="serial")
    assert again.computed == 0 and again.already_done == 1200


@pytest.fixture
def small():
    return study_from_dict(
        metro_study(
            axes=[{"field": "train.formation[*].load_t", "values": list(range(0, 20, 2))}], chunk_size=3
        ),
        "small.yaml",
    )


def test_lost_parts_are_computed_again_and_only_they(small, tmp_path):
    out = tmp_path / "out"
    first = run_study(small, out, executor="serial")
    assert first.chunks == 4
    reference = read_results(out, as_table=True)
    parts = _parts(out)
    parts[1].unlink()
    parts[3].unlink()
    # a chunk being written when the study was killed leaves a hidden temporary file
    (out / RESULTS_DIR / ".part-000000003-0000000000.parquet.tmp").write_bytes(b"PAR1 half a file")
    second = run_study(small, out, executor="serial")
    assert second.computed == 4 and second.already_done == 6
    _assert_exactly_once(out, small.expand().run_ids)
    assert read_results(out, as_table=True).equals(reference)
    assert not list((out / RESULTS_DIR).glob(".*.tmp"))


def test_another_study_in_the_same_output_is_refused(small, tmp_path):
    out = tmp_path / "out"
    run_study(small, out, executor="serial")
    other = study_from_dict(
        metro_study(axes=[{"field": "train.formation[*].load_t", "values": [0, 1]}]), "o.yaml"
    )
    with pytest.raises(InputError, match="results of another study"):
        run_study(other, out, executor="serial")
    restarted = run_study(other, out, executor="serial", restart=True)
    assert restarted.computed == 2 and len(read_results(out)) == 2
    assert (out / META_FILE).exists()
