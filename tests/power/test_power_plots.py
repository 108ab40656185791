"""The plots of every power output written by ``trainsim power --out``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from trainsim.cli import app
from trainsim.io.power_file import load_power_file
from trainsim.power.output import moving_rms_a, substation_current_figure
from trainsim.power.simulation import RMS_WINDOWS_S
from trainsim.power.study import FeedbackSettings, run_study

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "power" / "metro_750v_diode.yaml"
NEW_PLOTS = (
    "train_current.png",
    "substation_current.png",
    "losses.png",
    "stray_current.png",
    "time_lost.png",
)


def test_cli_writes_the_new_plots(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["power", str(EXAMPLE), "--out", str(out)])
    assert result.exit_code == 0, result.output
    for name in NEW_PLOTS:
        path = out / name
        assert path.exists(), name
        assert path.stat().st_size > 10_000, name
    quiet = tmp_path / "quiet"
    result = CliRunner().invoke(app, ["power", str(EXAMPLE), "--out", str(quiet), "--no-plots"])
    assert result.exit_code == 0, result.output
    assert not list(quiet.glob("*.png"))


@pytest.fixture(scope="module")
def result():
    spec, network, services = load_power_file(EXAMPLE)
    sim = spec.simulation
    fb = FeedbackSettings(
        sim.feedback.enabled,
        sim.feedback.max_iterations,
        sim.feedback.tolerance,
        sim.feedback.method,
        sim.feedback.knock_on,
        sim.feedback.buffer_s,
    )
    return run_study(network, services, dt_s=sim.step_s, start_s=sim.start_s, end_s=sim.end_s, feedback=fb)


def test_rms_lines_match_the_summary(result):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary = result.summary()
    fig = substation_current_figure(result, plt)
    try:
        lines = {line.get_gid(): line for ax in fig.axes for line in ax.get_lines() if line.get_gid()}
        checked = 0
        for window in RMS_WINDOWS_S:
            t, rms = moving_rms_a(result, window)
            for si, sub in enumerate(summary["substations"]):
                expected = sub["rms_current_max_a"][f"{int(window)}s"]
                gid = f"rms_{int(window)}s_{sub['id']}"
                if expected is None:  # run shorter than the window: no line
                    assert gid not in lines
                    continue
                y = np.asarray(lines[gid].get_ydata())
                np.testing.assert_allclose(y, rms[:, si])
                np.testing.assert_allclose(np.asarray(lines[gid].get_xdata()), t)
                assert np.max(y) == pytest.approx(expected, rel=1e-9)
                checked += 1
        assert checked >= 2 * len(summary["substations"])
        top = fig.axes[0]
        for si, sub in enumerate(result.network.substations):
            (line,) = [ln for ln in top.get_lines() if ln.get_label() == sub.id]
            np.testing.assert_array_equal(line.get_ydata(), result.substation_current_a[:, si])
        n_events = sum(len(s["overload_events"]) for s in summary["substations"])
        assert len(top.patches) == n_events
    finally:
        plt.close(fig)
