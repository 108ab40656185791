"""A network-day of lines in operation through Dask: the same results as the local run."""

from __future__ import annotations

from pathlib import Path

import pytest

from trainsim.batch.network_day import network_day
from trainsim.errors import InputError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "operations"
FILES = [EXAMPLES / "metro_fixed_block.yaml", EXAMPLES / "metro_cbtc.yaml", EXAMPLES / "single_track.yaml"]
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _disturbed(tmp_path: Path) -> Path:
    root = EXAMPLES.parent
    text = FILES[0].read_text().replace("../metro_b/", f"{root / 'metro_b'}/")
    path = tmp_path / "metro_disturbed.yaml"
    block = "disturbances: {seed: 2, entry: {kind: exponential, mean_s: 90, probability: 0.5}, "
    block += "dwell: {kind: lognormal, median_s: 10, sigma: 0.8, probability: 0.3}}"
    path.write_text(text + "\n" + block + "\n")
    return path


def test_a_network_day_on_a_two_worker_cluster_equals_the_local_run(tmp_path) -> None:
    distributed = pytest.importorskip("distributed")
    local = network_day(FILES)
    disturbed = [_disturbed(tmp_path)]
    sampled_local = network_day(disturbed, samples=3, seed=5)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        remote = network_day(FILES, client=client)
        sampled_remote = network_day(disturbed, samples=3, seed=5, client=client)
        workers = {w for w in client.scheduler_info()["workers"]}
    assert len(workers) == 2
    assert remote == local
    assert sampled_remote == sampled_local
    assert [d["line"] for d in local["line_days"]] == [d["line"] for d in remote["line_days"]]
    assert local["status"] == "conflicts"  # the single-track example's planned timetable has conflicts
    # three sampled days differ from each other (seeded streams, not one stream reused)
    assert len({d["total_delay_s"] for d in sampled_local["line_days"]}) > 1


def test_bad_network_days_are_input_errors(tmp_path) -> None:
    with pytest.raises(InputError, match="at least one"):
        network_day([])
    with pytest.raises(InputError, match="not found"):
        network_day([tmp_path / "nope.yaml"])
    with pytest.raises(InputError, match="samples"):
        network_day(FILES[:1], samples=-1)
