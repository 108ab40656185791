"""``trainsim batch STUDY.yaml``: run a study (sweep, Monte Carlo, timetable) locally or on Dask.

Listed in :data:`trainsim.cli.app.COMMANDS`.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import ExitCode
from trainsim.cli.context import fail as _fail
from trainsim.errors import TrainsimError

__all__ = ["Executor", "batch"]


class Executor(StrEnum):
    """Where the runs are computed."""

    serial = "serial"
    processes = "processes"
    dask = "dask"


def batch(
    study: Annotated[Path, typer.Argument(help="Study file (schema: trainsim/study).", show_default=False)],
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            help="Dask scheduler address (e.g. tcp://10.0.0.5:8786): run the study on that cluster. "
            "Without it, a scheduler-address in Dask's configuration (DASK_SCHEDULER_ADDRESS) is used "
            "when set.",
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", "-j", min=1, help="Worker processes (default: every core available)."),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="Output directory (default: out/<study file name>)."),
    ] = None,
    report: Annotated[
        bool, typer.Option("--report/--no-report", help="Write plots and tables of the study to OUT/report.")
    ] = False,
    executor: Annotated[
        Executor | None,
        typer.Option(
            "--executor", help="serial, processes (default) or dask (a local cluster without --scheduler)."
        ),
    ] = None,
    chunk_size: Annotated[
        int | None,
        typer.Option(
            "--chunk-size",
            min=1,
            help="Runs per task (default: sized by each run's predicted, then measured, cost: 1-200 runs of about 0.5 s of work).",
        ),
    ] = None,
    restart: Annotated[
        bool,
        typer.Option("--restart/--no-restart", help="Discard the results already in OUT and start again."),
    ] = False,
    dry_run: Annotated[
        bool,
        typer.Option(
            "--dry-run/--no-dry-run", help="Check the study and say what would run, without running."
        ),
    ] = False,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Show a progress bar.")] = True,
) -> None:
    """Run a study: every run of a sweep, a Monte Carlo sample or a day's timetable, in parallel.

    Results go to OUT/results (a Parquet dataset: parameters and figures per run, failed runs with their
    error). A study that was interrupted resumes where it stopped when run again with the same OUT.
    """
    from trainsim.cli.context import user_errors

    with user_errors():  # a light install without the [batch] extra is told what to install
        from trainsim.batch import executors, load_study, run_study

    out_dir = out if out is not None else Path("out") / study.stem
    chosen = executor.value if executor is not None else None
    if scheduler is not None:
        if chosen not in (None, "dask"):
            raise _fail("--scheduler runs on Dask: leave out --executor or give --executor dask")
        chosen = "dask"
    try:
        if chosen is None:
            chosen = "dask" if executors.configured_scheduler() is not None else "processes"
        spec = load_study(study)
        if dry_run:
            _dry_run(spec, out_dir, chosen, workers)
            return
        outcome = run_study(
            spec,
            out_dir,
            executor=chosen,  # type: ignore[arg-type]
            workers=workers,
            scheduler=scheduler,
            chunk_size=chunk_size,
            restart=restart,
            progress=progress,
        )
    except executors.ClusterLostError as exc:  # workers or scheduler lost: exit 4, resumable
        raise _fail(str(exc), ExitCode.INFRASTRUCTURE) from None
    except TrainsimError as exc:
        raise _fail(str(exc)) from None
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise _fail(f"{where}{exc.strerror or exc}") from None
    except KeyboardInterrupt:
        typer.echo(
            f"interrupted: the runs written so far are in {out_dir}; run the same command again to resume",
            err=True,
        )
        raise typer.Exit(code=int(ExitCode.INTERRUPTED)) from None
    where = f"{outcome.executor}" + (f" x{outcome.workers}" if outcome.executor != "serial" else "")
    speed = (
        f"; {outcome.elapsed_s:.1f} s, {outcome.runs_per_s:.0f} runs/s on {where}" if outcome.computed else ""
    )
    typer.echo(
        f"{outcome.study}: {outcome.runs} runs ({outcome.computed} computed, {outcome.already_done} "
        f"already done), {outcome.failed} failed, {outcome.stalled} stalled{speed}"
    )
    typer.echo(f"results: {out_dir / 'results'}")
    if report:
        from trainsim.batch.report import write_report

        try:
            rep = write_report(out_dir)
        except TrainsimError as exc:
            raise _fail(str(exc)) from None
        typer.echo(f"report: {rep.markdown} ({len(rep.files)} files)")


def _dry_run(spec, out_dir: Path, executor: str, workers: int | None) -> None:
    from trainsim.batch.sink import ParquetSink

    expansion = spec.expand()
    done = 0
    if (out_dir / "study.json").exists():
        sink = ParquetSink(out_dir, expansion)
        done = len(sink.done_ids() & set(expansion.run_ids))
    typer.echo(f"{spec.name}: {len(expansion)} runs, {done} already in {out_dir}")
    typer.echo("parameters: " + (", ".join(c.name for c in expansion.columns) or "(none)"))
    typer.echo(f"would run on: {executor}" + (f" with {workers} workers" if workers else ""))
