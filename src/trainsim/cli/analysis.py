"""``trainsim analyze-acceleration``: source 001's power-limited acceleration analysis of a train."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import console, require_file, user_errors


def analyze_acceleration(
    train: Annotated[Path, typer.Argument(help="Train file (format detected).")],
    power_kw: Annotated[float, typer.Option("--power-kw", help="Nominal traction power P_nom in kW.")],
    efficiency: Annotated[
        float, typer.Option("--efficiency", help="Nominal-to-wheel efficiency eta (0 < eta <= 1).")
    ],
    dt: Annotated[float, typer.Option("--dt", help="Time step of the speed increment in seconds.")] = 1.0,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Directory for acceleration_analysis.png.")
    ] = None,
) -> None:
    """Source 001's power-limited acceleration analysis: P_available(v), dv(v) and the balancing speed."""
    from trainsim.constants import KMH, KW

    with user_errors():
        require_file(train, "train file")
        from trainsim.analysis.acceleration import acceleration_analysis
        from trainsim.io import loader

        t = loader.load_train(train)
        analysis = acceleration_analysis(t, power_kw * KW, efficiency, dt_s=dt)
        written: Path | None = None
        if out is not None:
            from trainsim.plots import plot_acceleration_analysis

            out.mkdir(parents=True, exist_ok=True)
            written = out / "acceleration_analysis.png"
            plot_acceleration_analysis(analysis).savefig(written, dpi=120)

    from rich.table import Table
    from rich.text import Text

    out_console = console()
    vb = analysis.balancing_speed_mps
    out_console.print(
        f"{t.name}: P_nom {power_kw:g} kW, efficiency {efficiency:g}, k {analysis.mass_factor:g}",
        markup=False,
        highlight=False,
    )
    if vb is None:
        out_console.print("balancing speed: none (the resistance never takes the whole power)")
    else:
        note = " (above the train's maximum speed)" if vb > t.max_speed_mps else ""
        out_console.print(f"balancing speed: {vb / KMH:.1f} km/h{note}", highlight=False)
    table = Table(title="available power and speed increment")
    for name in ("speed [km/h]", "P_available [kW]", f"dv in {dt:g} s [m/s]", "mean acceleration [m/s²]"):
        table.add_column(Text(name), justify="right")  # Text: '[km/h]' is not markup
    n = len(analysis.speed_mps)
    for k in sorted({*range(0, n, max(1, n // 10)), n - 1}):
        table.add_row(
            f"{analysis.speed_mps[k] / KMH:.1f}",
            f"{analysis.available_power_w[k] / KW:.0f}",
            f"{analysis.delta_v_mps[k]:.3f}",
            f"{analysis.mean_acceleration_mps2[k]:.3f}",
        )
    out_console.print(table)
    if written is not None:
        out_console.print(f"wrote {written}", markup=False, highlight=False)
