"""Figures of trainsim.plots, built from runs made in Python."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from trainsim import plots
from trainsim.analysis.acceleration import acceleration_analysis
from trainsim.constants import KMH
from trainsim.model import (
    Braking,
    EffortCurve,
    Electrical,
    GradientSection,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
)
from trainsim.sim.fastest import run_fastest
from trainsim.sim.result import RunResult


def constant_force_train(*, electrical: bool = True, regenerative: bool = True, decel: bool = False) -> Train:
    braking = (
        Braking(deceleration_mps2=0.8)
        if decel
        else Braking(
            service_force=EffortCurve.constant(150e3),
            regenerative=EffortCurve.constant(100e3) if regenerative else None,
        )
    )
    return Train(
        name="constant-force test train",
        mass_kg=200e3,
        rotating_mass_factor=1.1,
        length_m=100.0,
        max_speed_mps=80 * KMH,
        traction=EffortCurve.constant(150e3),
        braking=braking,
        resistance=(ResistanceTerm("Davis", Quadratic(2000.0, 20.0, 5.0)),),
        electrical=Electrical(line_voltage_v=1500.0, traction_efficiency=0.85, regenerative_efficiency=0.8)
        if electrical
        else None,
    )


def level_line(*, gradient: bool = False) -> Route:
    """2 km, a stop in the middle, a lower limit near the end (and optionally a 5 per mille climb)."""
    return Route(
        name="2 km test line",
        start_m=0.0,
        end_m=2000.0,
        stations=(Station("A", 0.0), Station("B", 1000.0, dwell_s=30.0), Station("C", 2000.0)),
        speed_limits=(SpeedLimit(0.0, 1500.0, 70 * KMH), SpeedLimit(1500.0, 2000.0, 50 * KMH)),
        gradients=(GradientSection(500.0, 1200.0, 5.0),) if gradient else (),
    )


@pytest.fixture(scope="module")
def case() -> tuple[RunResult, Route, Train]:
    train, route = constant_force_train(), level_line(gradient=True)
    return run_fastest(train, route), route, train


def assert_labelled(ax: Axes, x_unit: str | None, y_unit: str) -> None:
    if x_unit is not None:
        assert ax.get_xlabel() and f"[{x_unit}]" in ax.get_xlabel()
    assert ax.get_ylabel() and f"[{y_unit}]" in ax.get_ylabel()


def legend_texts(fig: Figure) -> list[str]:
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    return [t.get_text() for leg in legends for t in leg.get_texts()]


def test_speed_distance(case) -> None:
    result, route, train = case
    fig = plots.plot_speed_distance(result, route, train)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 2  # speed and, on a twin axis, the gradient
    ax, ax_g = fig.axes
    assert_labelled(ax, "km", "km/h")
    assert "[‰]" in ax_g.get_ylabel()
    assert ax.get_title()
    labels = legend_texts(fig)
    assert any("speed ceiling" in t for t in labels)
    assert any("line speed limit" in t for t in labels)
    assert any("gradient" in t for t in labels)
    # the speed curve spans the route in km
    speed = next(line for line in ax.get_lines() if line.get_label() == "speed")
    assert np.nanmax(speed.get_xdata()) == pytest.approx(2.0)
    # one marker line and one name per station
    names = {t.get_text() for t in ax.texts}
    assert {"A", "B", "C"} <= names


def test_speed_distance_elevation(case) -> None:
    result, route, train = case
    fig = plots.plot_speed_distance(result, route, train, profile="elevation")
    ax_e = fig.axes[1]
    assert "[m]" in ax_e.get_ylabel()
    elevation = ax_e.get_lines()[0].get_ydata()
    assert np.max(elevation) == pytest.approx(700 * 5 / 1000)  # 700 m at 5 per mille


def test_speed_time(case) -> None:
    result, _, _ = case
    fig = plots.plot_speed_time(result)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 1
    assert_labelled(fig.axes[0], "s", "km/h")
    assert fig.axes[0].get_title()
    assert "speed" in legend_texts(fig)


def test_effort_resistance() -> None:
    fig = plots.plot_effort_resistance(constant_force_train())
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert_labelled(ax, "km/h", "kN")
    labels = legend_texts(fig)
    for expected in ("maximum traction", "service braking", "regenerative braking"):
        assert expected in labels
    assert any("0 ‰" in t for t in labels) and any("10 ‰" in t for t in labels)
    dashed = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert dashed, "resistance on a gradient is dashed"
    # traction curve in kN: the constant 150 kN
    traction = next(line for line in ax.get_lines() if line.get_label() == "maximum traction")
    assert np.allclose(traction.get_ydata(), 150.0)


def test_effort_resistance_deceleration_braking() -> None:
    fig = plots.plot_effort_resistance(constant_force_train(decel=True), gradients_permille=(0.0, 10.0))
    labels = legend_texts(fig)
    assert any(t.startswith("service braking (0.8 m/s²") for t in labels)
    assert "regenerative braking" not in labels


def test_power_current(case) -> None:
    result, _, _ = case
    fig = plots.plot_power_current(result)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 2
    ax_p, ax_i = fig.axes
    assert_labelled(ax_p, None, "MW")
    assert_labelled(ax_i, "s", "A")
    labels = legend_texts(fig)
    assert "line current" in labels
    assert any("source 002" in t for t in labels if "current" not in t)
    assert any("source 002 convention" in t for t in labels)


def test_power_current_without_electrical() -> None:
    train, route = constant_force_train(electrical=False), level_line()
    fig = plots.plot_power_current(run_fastest(train, route))
    assert len(fig.axes) == 2
    assert any("no electrical data" in t.get_text() for t in fig.axes[1].texts)


def test_energy_sections(case) -> None:
    result, _, _ = case
    fig = plots.plot_energy_sections(result)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert_labelled(ax, None, "kWh")
    assert [t.get_text() for t in ax.get_xticklabels()] == ["A → B", "B → C"]
    assert len(ax.patches) == 3 * len(result.sections)  # traction, regenerated, net per section
    heights = [p.get_height() for p in ax.patches]
    first = result.sections[0].energy_kwh
    assert heights[0] == pytest.approx(first.traction)
    assert set(legend_texts(fig)) == {"traction (wheel)", "regenerated (to line)", "net (from line)"}


def test_acceleration_analysis() -> None:
    train = constant_force_train()
    analysis = acceleration_analysis(train, 2.0e6, 0.8, speeds_mps=np.linspace(0.0, 80.0, 81))
    fig = plots.plot_acceleration_analysis(analysis)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 2
    ax_p, ax_v = fig.axes
    assert_labelled(ax_p, "km/h", "kW")
    assert_labelled(ax_v, "km/h", "m/s")
    assert ax_p.get_title() and ax_v.get_title()
    assert analysis.balancing_speed_mps is not None
    assert any("balancing speed" in t for t in legend_texts(fig))


def test_acceleration_analysis_balancing_speed_out_of_range() -> None:
    # default speeds stop at the train's maximum speed, far below the balancing speed
    analysis = acceleration_analysis(constant_force_train(), 2.0e6, 0.8)
    fig = plots.plot_acceleration_analysis(analysis)
    ax_p = fig.axes[0]
    assert ax_p.get_xlim()[1] < 1.2 * 80  # not stretched to the balancing speed
    assert any("beyond the range shown" in t for t in legend_texts(fig))


def test_save_all(case, tmp_path: Path) -> None:
    result, route, train = case
    paths = plots.save_all(result, route, train, tmp_path / "plots")
    assert [p.name for p in paths] == list(plots.PLOT_FILES)
    for path in paths:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert path.stat().st_size > 1000


def test_no_pyplot_figures_left(case) -> None:
    result, route, train = case
    plots.plot_speed_distance(result, route, train)
    # plots never go through pyplot: nothing is registered in its global figure list
    pyplot = sys.modules.get("matplotlib.pyplot")
    if pyplot is not None:
        assert pyplot.get_fignums() == []
