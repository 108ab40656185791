"""The operation train graph in the web application (issue 17): the shipped operations run as
``trainsim operate`` runs them, answered with every train's operated and planned path, its blocking
times, the planned timetable's conflicts, the delay per station and the headway over the line."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.operations.blocking import minimum_headway
from trainsim.web import WebSettings, create_app
from trainsim.web.jobs import OPERATION_EXAMPLES
from trainsim.web.operation_payload import headway_profile

from .conftest import REPO

OPS = REPO / "examples" / "operations"


@pytest.fixture(scope="module")
def client() -> Iterator[TestClient]:
    with TestClient(create_app(WebSettings(workers=0, drive_hosts=0))) as c:
        yield c


def test_operation_example_gives_the_cli_train_graph_and_blocking_times(client: TestClient) -> None:
    r = client.post("/api/operations/metro_fixed_block")
    assert r.status_code == 200, r.text
    op = r.json()
    assert client.post("/api/operations/nope").status_code == 404
    cli = run_operation(read_operation(OPS / "metro_fixed_block.yaml"))
    assert op["status"] == cli.status and len(op["conflicts"]) == len(cli.conflicts)
    assert [t["id"] for t in op["trains"]] == [t.id for t in cli.trains]
    assert len(op["blocking"]) == len(cli.blocking)
    first = cli.blocking[0]
    assert op["blocking"][0] == {
        "train": first.train,
        "start_s": first.start_s,
        "end_s": first.end_s,
        "from_m": first.from_m,
        "to_m": first.to_m,
        "block": first.route,
        "resource": first.resource,
    }
    for t, c in zip(op["trains"], cli.trains, strict=True):
        assert t["time_s"][0] == pytest.approx(c.trajectory.time_s[0], abs=0.05)
        assert t["time_s"][-1] == pytest.approx(c.trajectory.time_s[-1], abs=0.05)
        assert t["planned_time_s"][-1] == pytest.approx(c.planned_trajectory.time_s[-1], abs=0.05)
        assert len(t["time_s"]) == len(t["position_m"]) <= 400
        # the delay per station is the core's, stop by stop
        assert [s["delay_s"] for s in t["stops"]] == [s.to_dict()["delay_s"] for s in c.stops]
    # the late train (100 s entry delay) is late at its first station by about that
    late = next(t for t in op["trains"] if t["id"] == "late")
    assert late["stops"][0]["delay_s"] == pytest.approx(100.0, abs=1.0)
    # every train's path lies inside its own blocking stairs: where the head is, its block is reserved
    t = op["trains"][0]
    mine = [b for b in op["blocking"] if b["train"] == t["id"]]
    for time_s, pos in list(zip(t["time_s"], t["position_m"], strict=True))[::20]:
        assert any(b["start_s"] <= time_s <= b["end_s"] and b["from_m"] <= pos <= b["to_m"] for b in mine)


def test_headway_over_the_line_peaks_at_the_cores_minimum_headway(client: TestClient) -> None:
    op = client.post("/api/operations/metro_fixed_block").json()
    cli = run_operation(read_operation(OPS / "metro_fixed_block.yaml"))
    assert len(op["headways"]) == len(cli.headways) > 0
    for h, c in zip(op["headways"], cli.headways, strict=True):
        assert (h["leader"], h["follower"]) == (c.leader, c.follower)
        assert len(h["position_m"]) == len(h["headway_s"]) > 1
        assert h["position_m"] == sorted(h["position_m"])
        # the highest point of the profile is the pair's minimum headway (core: required shift)
        assert max(h["headway_s"]) == pytest.approx(c.min_headway_s, abs=2e-3)


def test_headway_profile_of_two_blocks_by_hand() -> None:
    from trainsim.operations.blocking import BlockingTime

    def b(train: str, resource: str, start: float, end: float, lo: float, hi: float) -> BlockingTime:
        return BlockingTime(train, resource, resource, 0, start, start, start, end, end, lo, hi)

    # leader frees block 1 at 100 s and block 2 at 160 s; the follower needs them from 20 s and 90 s
    leader = [b("L", "b1", 0, 100, 0, 400), b("L", "b2", 50, 160, 400, 800)]
    follower = [b("F", "b1", 20, 120, 0, 400), b("F", "b2", 90, 200, 400, 800)]
    x, y = headway_profile(leader, follower, planned_headway_s=120.0)
    assert x == [200.0, 600.0]
    assert y == [100 - 20 + 120, 160 - 90 + 120]
    core = minimum_headway("L", leader, 0.0, "F", follower, 120.0)
    assert core is not None and max(y) == pytest.approx(core.min_headway_s)


def test_conflicts_are_marked_with_trains_block_time_and_overlap(client: TestClient) -> None:
    r = client.post("/api/operations/single_track")
    assert r.status_code == 200, r.text
    op = r.json()
    cli = run_operation(read_operation(OPS / "single_track.yaml"))
    assert op["status"] == cli.status == "conflicts"
    assert [c["trains"] for c in op["conflicts"]] == [[c.first, c.second] for c in cli.conflicts]
    for shown, c in zip(op["conflicts"], cli.conflicts, strict=True):
        assert shown["block"] == c.route and shown["time_s"] == pytest.approx(c.time_s, abs=1e-3)
        assert shown["overlap_s"] == pytest.approx(c.overlap_s, abs=1e-3) and shown["overlap_s"] > 0
        assert 0 <= shown["from_m"] < shown["to_m"] <= op["line_length_m"]


@pytest.mark.parametrize("name", list(OPERATION_EXAMPLES))
def test_every_shipped_operation_runs_as_the_cli_runs_it(client: TestClient, name: str) -> None:
    r = client.post(f"/api/operations/{name}")
    assert r.status_code == 200, r.text
    op = r.json()
    cli = run_operation(read_operation(OPS / OPERATION_EXAMPLES[name][0]))
    assert op["status"] == cli.status
    assert len(op["trains"]) == len(cli.trains) and len(op["conflicts"]) == len(cli.conflicts)
    assert len(op["headways"]) == len(cli.headways)
    listed = client.get("/api/operations").json()
    assert name in [e["name"] for e in listed]


def test_shipped_operation_files_equal_the_repository_examples() -> None:
    from trainsim.web.examples import EXAMPLES_DIR

    # the package has no tests/ folder: the copies name the TrainRuns trains in example_files/trainruns
    moved = ("../../tests/data/trainruns/trains/", "../trainruns/")
    for file, _ in OPERATION_EXAMPLES.values():
        shipped = (EXAMPLES_DIR / "operations" / file).read_text()
        assert shipped == (OPS / file).read_text().replace(*moved), file
    for extra in ("single_track_route.yaml", "main_line_route.yaml", "branch_line.railml"):
        assert (EXAMPLES_DIR / "operations" / extra).read_text() == (OPS / extra).read_text()
    for table in (OPS / "sheets_double_track" / "line").iterdir():
        shipped = EXAMPLES_DIR / "operations" / "sheets_double_track" / "line" / table.name
        assert shipped.read_text() == table.read_text()
    for train in ("local", "longdistance", "freight"):
        original = REPO / "tests" / "data" / "trainruns" / "trains" / f"{train}.yaml"
        assert (EXAMPLES_DIR / "trainruns" / f"{train}.yaml").read_text() == original.read_text()


def test_every_operation_example_of_the_repository_is_offered() -> None:
    import yaml

    files = [
        str(f.relative_to(OPS))
        for f in sorted(OPS.rglob("*.yaml"))
        if (yaml.safe_load(f.read_text()) or {}).get("schema") == "trainsim/operation"
    ]
    offered = [file for file, _ in OPERATION_EXAMPLES.values()]
    missing = sorted(set(files) - set(offered))
    assert not missing, (
        f"add to trainsim.web.jobs.OPERATION_EXAMPLES (and example_files/operations): {missing}"
    )
