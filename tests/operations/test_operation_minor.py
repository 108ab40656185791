"""Issue 17: the delay plot has a legend and units; every deadlocked train names what holds it; a shipped
example with disturbances for Monte Carlo studies."""

from __future__ import annotations

import trainsim
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.simulate import TrainService, simulate

SETTINGS = trainsim.RunSettings(max_step_m=20)


def _single_track_without_loops():
    length = 12_000.0
    geometry = trainsim.Route("geo", 0, length, (), (trainsim.SpeedLimit(0, length, 80 / 3.6),))
    stations = (
        StationLayout("A", 600, tracks=1),
        StationLayout("B", 6000, tracks=1),
        StationLayout("C", 11_400, tracks=1),
    )
    return build_line("single", length, "single_track", stations, Signalling()), geometry


def _deadlocked():
    train = trainsim.load_train("examples/metro_b/train.yaml")
    line, geometry = _single_track_without_loops()
    svcs = [
        TrainService("up1", train, "up", "A", "C", 0.0),
        TrainService("up2", train, "up", "A", "C", 120.0),
        TrainService("up3", train, "up", "A", "C", 240.0),
        TrainService("down1", train, "down", "C", "A", 0.0),
        TrainService("down2", train, "down", "C", "A", 120.0),
    ]
    return line, simulate(line, geometry, svcs, SETTINGS)


def test_delay_plot_has_a_legend_and_axis_units(tmp_path, monkeypatch) -> None:
    import matplotlib.pyplot as plt

    from trainsim.operations import plots

    line, res = _deadlocked()
    seen = {}
    monkeypatch.setattr(plt, "close", lambda fig: seen.setdefault("fig", fig))
    plots.delay_plot(line, res, tmp_path / "delays.png")
    (ax,) = seen["fig"].axes
    legend = ax.get_legend()
    assert legend is not None and [t.get_text() for t in legend.get_texts()]
    assert "[s]" in ax.get_ylabel() and ax.get_xlabel()
    assert (tmp_path / "delays.png").stat().st_size > 0


def test_every_deadlocked_train_names_its_holder() -> None:
    _line, res = _deadlocked()
    assert res.status == "deadlock"
    stuck = [t.id for t in res.trains if t.status == "deadlocked"]
    assert len(res.deadlock) == len(stuck) == 5
    ids = {"up1", "up2", "up3", "down1", "down2"}
    for entry in res.deadlock:
        assert "(held by " in entry, entry
        holder = entry.split("(held by ", 1)[1].split(")", 1)[0]
        assert holder in ids and not entry.startswith(f"train {holder} ")


def test_the_disturbed_metro_example_runs_a_monte_carlo_study() -> None:
    import json
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "trainsim", "operate", "examples/operations/metro_disturbed.yaml"]
    done = subprocess.run([*cmd, "--samples", "3", "--json"], capture_output=True, text=True, timeout=600)
    assert done.returncode in (0, 3), done.stderr
    mc = json.loads(done.stdout)["monte_carlo"]
    assert mc["samples"] == 3 and sum(mc["statuses"].values()) == 3
    assert set(mc["total_delay_s"]) >= {"mean", "p50", "p95", "max"}
    assert mc["total_delay_s"]["max"] > 0  # the disturbances do delay the trains
    assert len(mc["trains"]) == 14 and all("mean" in t["delay_s"] for t in mc["trains"])
