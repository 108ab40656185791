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


def test_a_network_day_on_a_two_worker_cluster_equals_the_local_run(tmp_path, monkeypatch) -> None:
    distributed = pytest.importorskip("distributed")
    local = network_day(FILES)
    disturbed = [_disturbed(tmp_path)]
    sampled_local = network_day(disturbed, samples=3, seed=5)
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        remote = network_day(FILES, client=client)
        sampled_remote = network_day(disturbed, samples=3, seed=5, client=client)
        workers = {w for w in client.scheduler_info()["workers"]}
        # a path relative to this process's directory, which is not the workers' (they started
        # elsewhere): the workers must get the line read, not the path
        assert Path.cwd() != tmp_path
        monkeypatch.chdir(tmp_path)
        relative = network_day([disturbed[0].name], samples=3, seed=5, client=client)
    assert len(workers) == 2
    assert remote == local
    assert sampled_remote == sampled_local
    for d in relative["line_days"]:
        assert d.pop("file") == disturbed[0].name
    assert relative["line_days"] == [
        {k: v for k, v in d.items() if k != "file"} for d in sampled_local["line_days"]
    ]
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


def test_each_line_and_day_draws_its_own_stream_reproducibly(tmp_path) -> None:
    a = _disturbed(tmp_path)
    twin = tmp_path / "twin.yaml"
    twin.write_text(a.read_text())  # the same line twice: same name, same seed
    day = network_day([a, twin], samples=3, seed=5)
    first = [d for d in day["line_days"] if d["file"] == str(a)]
    second = [d for d in day["line_days"] if d["file"] == str(twin)]
    assert [d["sample"] for d in first] == [d["sample"] for d in second] == [0, 1, 2]
    # one seed for the network: the twin still draws other delays, day by day
    for x, y in zip(first, second, strict=True):
        assert [t["delay_s"] for t in x["trains"]] != [t["delay_s"] for t in y["trains"]]
    # reproducible, and a line's days do not depend on the other lines or their order
    assert network_day([a, twin], samples=3, seed=5) == day
    alone = network_day([a], samples=3, seed=5)["line_days"]
    assert alone == first
    # listed second, a is the second line of that name: it draws what the twin drew above
    swapped = [d for d in network_day([twin, a], samples=3, seed=5)["line_days"] if d["file"] == str(a)]
    assert [d["trains"] for d in swapped] == [d["trains"] for d in second]
    # another line's name is another stream
    other = tmp_path / "other.yaml"
    other.write_text(a.read_text().replace("\nname: ", "\nname: Other ", 1))
    renamed = network_day([other], samples=3, seed=5)["line_days"]
    assert renamed[0]["line"] != first[0]["line"]
    assert [d["trains"] for d in renamed] != [d["trains"] for d in first]
    assert network_day([a], samples=3, seed=6)["line_days"] != first
    # sampled days are not checked for conflicts: no count is claimed
    assert all(d["conflicts"] is None for d in day["line_days"])
    assert all(isinstance(d["conflicts"], int) for d in network_day([a])["line_days"])
