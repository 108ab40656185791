"""The ``trainsim`` application: the table of commands, loaded only when one is called.

Each command lives in a module of its own in this package. ``trainsim --help`` lists them from
:data:`COMMANDS` without importing any of them (or numpy, pandas, numba ...), so that help and
start-up stay fast; ``trainsim NAME`` imports the one module it runs.

A new command: write ``def name(...)`` with typer annotations in ``trainsim/cli/<module>.py`` (using
:mod:`trainsim.cli.context`) and add one entry to :data:`COMMANDS`.
"""

from __future__ import annotations

import importlib
from typing import Annotated, Any, NamedTuple

import typer
from typer.core import TyperCommand, TyperGroup

from trainsim.cli.context import EXIT_CODES_HELP, use_plain_coercion


class CommandEntry(NamedTuple):
    """Where a command lives and the one line that ``trainsim --help`` shows for it."""

    module: str
    function: str
    summary: str
    hidden: bool = False


#: Every command, in the order ``trainsim --help`` lists them.
COMMANDS: dict[str, CommandEntry] = {
    "run": CommandEntry("trainsim.cli.run", "run", "Simulate the fastest run of a train over a route."),
    "check": CommandEntry("trainsim.cli.interchange", "check", "Read a file and say what it holds."),
    "optimize": CommandEntry("trainsim.cli.optimize", "optimize", "Drive to a timetable with least energy."),
    "batch": CommandEntry("trainsim.cli.batch", "batch", "Run a study (sweep, Monte Carlo, timetable)."),
    "convert": CommandEntry(
        "trainsim.cli.interchange", "convert", "Convert railML, spreadsheets, railtoolkit to trainsim YAML."
    ),
    "export-results": CommandEntry(
        "trainsim.cli.interchange", "export_results", "Run and write trace and summary as CSV/Parquet/JSON."
    ),
    "runtimes": CommandEntry(
        "trainsim.cli.interchange", "runtimes", "Write computed running times back into a railML timetable."
    ),
    "analyze-acceleration": CommandEntry(
        "trainsim.cli.analysis", "analyze_acceleration", "Power-limited acceleration analysis (source 001)."
    ),
    "power": CommandEntry("trainsim.cli.power", "power", "Many trains on a DC or AC power supply network."),
    "operate": CommandEntry(
        "trainsim.cli.operate", "operate", "Many trains on a signalled line: delays, conflicts, headways."
    ),
    "serve": CommandEntry("trainsim.cli.web", "serve", "Start the web application."),
    # `trainsim run` runs multi-point scenarios too; the old name stays for scripts that use it
    "multipoint": CommandEntry(
        "trainsim.cli.multipoint", "multipoint", "Same as `trainsim run` on a multi-point scenario.", True
    ),
}


def load_command(name: str) -> Any:
    """The click command behind ``trainsim NAME`` (imports its module)."""
    entry = COMMANDS[name]
    function = getattr(importlib.import_module(entry.module), entry.function)
    single = typer.Typer(add_completion=False, pretty_exceptions_enable=False, rich_markup_mode=None)
    single.command(name, cls=PlainCommand, hidden=entry.hidden, epilog=EXIT_CODES_HELP)(function)
    command = typer.main.get_command(single)
    command.name = name
    return command


class PlainCommand(TyperCommand):
    """A command whose options are coerced without pydantic where they are plain (cli/context.py)."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        use_plain_coercion(self.get_params(ctx))
        return super().parse_args(ctx, args)


class LazyCommands(TyperGroup):
    """A group whose commands are imported when called, and listed from the table for help."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        use_plain_coercion(self.get_params(ctx))  # --version and --help too, even when not given
        return super().parse_args(ctx, args)

    def list_commands(self, ctx: Any) -> list[str]:
        return [*super().list_commands(ctx), *(n for n in COMMANDS if n not in self.commands)]

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        if cmd_name in self.commands or cmd_name not in COMMANDS:
            return super().get_command(ctx, cmd_name)
        command = load_command(cmd_name)
        self.commands[cmd_name] = command
        return command

    def format_commands(self, ctx: Any, formatter: Any) -> None:
        rows = [(name, entry.summary) for name, entry in COMMANDS.items() if not entry.hidden]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            shown = version("trainsim")
        except PackageNotFoundError:  # run from a source tree without an install
            from trainsim import __version__ as shown
        typer.echo(f"trainsim {shown}")
        raise typer.Exit()


app = typer.Typer(
    name="trainsim",
    cls=LazyCommands,
    help="Train performance calculator: fastest runs, energy, line current, energy-efficient driving, "
    "studies and plots.",
    epilog=EXIT_CODES_HELP,
    no_args_is_help=True,
    add_completion=False,
    # plain click help: it wraps long lines instead of cutting them, and does not import rich
    rich_markup_mode=None,
    # a traceback is only ever shown for a bug; plain tracebacks are easier to report than rich ones
    pretty_exceptions_enable=False,
)


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit."),
    ] = False,
) -> None:
    """Train performance calculator: fastest runs, energy, line current, energy-efficient driving,
    studies and plots."""


def main() -> None:
    """Entry point of ``trainsim`` and ``python -m trainsim``."""
    app(prog_name="trainsim")
