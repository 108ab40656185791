"""The operation train graph in the web application (issue 17): a shipped operation run as
``trainsim operate`` runs it, answered with every train's path and its blocking times."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.web import WebSettings, create_app

from .conftest import REPO


def test_operation_example_gives_the_cli_train_graph_and_blocking_times() -> None:
    with TestClient(create_app(WebSettings(workers=0, drive_hosts=0))) as client:
        r = client.post("/api/operations/metro_fixed_block")
        assert r.status_code == 200, r.text
        op = r.json()
        assert client.post("/api/operations/nope").status_code == 404
    cli = run_operation(read_operation(REPO / "examples" / "operations" / "metro_fixed_block.yaml"))
    assert op["status"] == cli.status and op["conflicts"] == len(cli.conflicts)
    assert [t["id"] for t in op["trains"]] == [t.id for t in cli.trains]
    assert len(op["blocking"]) == len(cli.blocking)
    first = cli.blocking[0]
    assert op["blocking"][0] == {
        "train": first.train,
        "start_s": first.start_s,
        "end_s": first.end_s,
        "from_m": first.from_m,
        "to_m": first.to_m,
    }
    for t, c in zip(op["trains"], cli.trains, strict=True):
        assert t["time_s"][0] == pytest.approx(c.trajectory.time_s[0], abs=0.05)
        assert t["time_s"][-1] == pytest.approx(c.trajectory.time_s[-1], abs=0.05)
        assert len(t["time_s"]) == len(t["position_m"]) <= 400
    # every train's path lies inside its own blocking stairs: where the head is, its block is reserved
    t = op["trains"][0]
    mine = [b for b in op["blocking"] if b["train"] == t["id"]]
    for time_s, pos in list(zip(t["time_s"], t["position_m"], strict=True))[::20]:
        assert any(b["start_s"] <= time_s <= b["end_s"] and b["from_m"] <= pos <= b["to_m"] for b in mine)


def test_shipped_operation_file_equals_the_repository_example() -> None:
    from trainsim.web.examples import EXAMPLES_DIR

    shipped = (EXAMPLES_DIR / "operations" / "metro_fixed_block.yaml").read_text()
    assert shipped == (REPO / "examples" / "operations" / "metro_fixed_block.yaml").read_text()
