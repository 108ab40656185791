"""What every ``trainsim`` command shares: exit codes, error reporting, console and scenario loading.

User errors (bad input, missing files, wrong options) end with one ``error: ...`` paragraph on stderr
(and, when the input error names several problems, one line per problem) and exit code 2, never a
traceback. A command that ran but whose result is not what was asked (any status other than ``ok``)
exits with 3 after printing its result.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from enum import Enum, IntEnum, StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from trainsim.errors import InputError, TrainsimError

if TYPE_CHECKING:
    from types import ModuleType

    from rich.console import Console

    from trainsim.model.scenario import Scenario


class ExitCode(IntEnum):
    """The exit codes of every ``trainsim`` command (documented in ``trainsim --help`` and the README)."""

    OK = 0
    #: a bug in trainsim (a traceback is printed: please report it)
    BUG = 1
    #: bad input: a file, a field or an option that cannot be used
    USER_ERROR = 2
    #: the command ran, but the result is not what was asked (status other than ok: see its message)
    NOT_AS_ASKED = 3
    #: the computing infrastructure failed (e.g. every Dask worker lost); the work can be resumed
    INFRASTRUCTURE = 4
    #: interrupted by Ctrl-C
    INTERRUPTED = 130


EXIT_CODES_HELP = (
    "Exit codes: 0 ok; 1 a bug in trainsim; 2 bad input (file, field or option); "
    "3 ran, but the result is not what was asked (status not ok); 4 the computing infrastructure "
    "failed (resumable); 130 interrupted."
)


def fail(message: str, code: int = ExitCode.USER_ERROR) -> typer.Exit:
    """Print ``error: message`` on stderr and return the Exit to raise."""
    # typer.echo, not rich: rich would wrap the message into several lines at the terminal width
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(code=int(code))


def report_input_error(exc: InputError) -> None:
    """Print an input error: one paragraph, or a lead line and one line per problem."""
    problems = getattr(exc, "problems", None) or []
    if len(problems) <= 1:
        typer.echo(f"error: {exc}", err=True)
        return
    files = {p.file for p in problems if p.file}
    lead = f" in {next(iter(files))}" if len(files) == 1 else ""
    typer.echo(f"error: {len(problems)} problems{lead}:", err=True)
    for p in problems:
        text = p.text()
        if lead and text.startswith(f"{p.file}"):
            text = text[len(p.file) :].lstrip(", :")
        typer.echo(f"  - {text}", err=True)


@contextmanager
def user_errors() -> Iterator[None]:
    """Turn trainsim's errors and file-system errors into ``error: ...`` and exit code 2."""
    try:
        yield
    except InputError as exc:
        report_input_error(exc)
        raise typer.Exit(code=int(ExitCode.USER_ERROR)) from None
    except TrainsimError as exc:
        raise fail(str(exc)) from None
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise fail(f"{where}{exc.strerror or exc}") from None
    except ImportError as exc:
        from trainsim.extras import missing_extra_message

        message = missing_extra_message(exc)
        if message is None:
            raise
        raise fail(message) from None


def exit_for_status(status: str) -> None:
    """Raise the exit of a result whose status is not ``ok`` (after its result was printed)."""
    if status != "ok":
        raise typer.Exit(code=int(ExitCode.NOT_AS_ASKED))


def require_file(path: Path, what: str) -> None:
    """An InputError unless ``path`` is an existing file."""
    if not path.exists():
        raise InputError(f"{what} not found", file=str(path))
    if not path.is_file():
        raise InputError(f"{what} is not a file", file=str(path))


def require_input(path: Path, what: str) -> None:
    """An InputError unless ``path`` is a file, or a folder the spreadsheet reader reads (CSV tables).

    Train, route and scenario inputs go through the loader, which reads a folder of CSV tables with the
    same reader as ``trainsim check`` (``trainsim.io.interchange.detect_interchange``): refusing the
    folder here made ``check`` accept what ``run`` and ``optimize`` refused (issue 13). Any other
    folder is refused with the message ``check`` gives for it."""
    if not path.exists():
        raise InputError(f"{what} not found", file=str(path))
    if path.is_dir():
        from trainsim.io.interchange import detect_interchange

        if detect_interchange(path) != "spreadsheet":
            raise InputError("this is a directory, not a file", file=str(path))
        return
    if not path.is_file():
        raise InputError(f"{what} is not a file", file=str(path))


def console() -> Console:
    """A rich console; 160 columns when the output is not a terminal (the section tables are wide)."""
    from rich.console import Console

    out = Console()
    if not out.is_terminal:
        # piped or captured output: the default 80 columns would fold the section table
        out = Console(width=160)
    return out


def echo_warnings(warnings: list[str]) -> None:
    """Each warning as ``warning: ...`` on stderr."""
    for warning in warnings:
        typer.echo(f"warning: {warning}", err=True)


def readers() -> ModuleType:
    """:mod:`trainsim.io.loader`, imported with pydantic's plugin look-up off while its models are built.

    pydantic looks for plugins in the entry points of every installed distribution when it builds its
    first model (25 - 30 ms CPU with 200 distributions, 5 % of a whole `trainsim run`); trainsim's file
    specs are built when their modules are imported and need no plugin. The variable is restored after
    the import, so models built later (the web application's) see the plugins as before."""
    import os

    previous = os.environ.get("PYDANTIC_DISABLE_PLUGINS")
    os.environ["PYDANTIC_DISABLE_PLUGINS"] = "__all__"
    try:
        from trainsim.io import loader
    finally:
        if previous is None:
            del os.environ["PYDANTIC_DISABLE_PLUGINS"]
        else:
            os.environ["PYDANTIC_DISABLE_PLUGINS"] = previous
    return loader


class MassModel(StrEnum):
    """How line resistance applies over the train (railtoolkit / TrainRuns.jl ``massModel``)."""

    mass_point = "mass_point"
    homogeneous_strip = "homogeneous_strip"


def load_scenario(
    scenario: Path | None, train: Path | None, route: Path | None, mass_model: MassModel | None
) -> Scenario:
    """The scenario of a command: a scenario file, or a train file and a route file."""
    loader = readers()

    if scenario is not None:
        if train is not None or route is not None:
            raise InputError("give a scenario file or --train and --route, not both")
        if mass_model is not None:
            raise InputError(
                "--mass-model applies to a route given with --route; "
                "a scenario file says itself how its route is read"
            )
        require_input(scenario, "scenario file")
        return loader.load_scenario(scenario)
    if train is None or route is None:
        raise InputError("give a scenario file, or both --train and --route")
    require_input(train, "train file")
    require_input(route, "route file")
    if mass_model is None:
        return loader.scenario_from_files(train, route)
    from trainsim.model.scenario import Scenario

    t = loader.load_train(train)
    r = loader.load_route(route, mass_model=mass_model.value)
    return Scenario(name=f"{t.name} on {r.name}", train=t, route=r)


# ====================================================================== options without pydantic
# typer (0.2x) coerces every option through a pydantic TypeAdapter, built on first use: for `trainsim
# run` that imported pydantic's schema machinery and, through its plugin loader, importlib.metadata
# (about 30 ms CPU of a 0.7 s process, issue 14) only to turn "5" into 5.0. The plain coercion below
# does the plain cases itself with typer's own functions (a path, a number written plainly, text, a
# choice) and hands every other value, and every value it cannot take, to typer's own coercion: the
# messages of bad options stay typer's. With a typer that does not coerce this way nothing changes.

#: numbers written plainly (digits, one point, an exponent): their value is the same in Python and
#: pydantic; anything else (inf, nan, underscores, spaces) goes to typer's own coercion
_INT = re.compile(r"[+-]?[0-9]{1,15}")
_FLOAT = re.compile(r"[+-]?(?:[0-9]{1,17}(?:\.[0-9]{0,17})?|\.[0-9]{1,17})(?:[eE][+-]?[0-9]{1,3})?")

#: the plain coercion declines: typer's own does the work
_TYPER = object()


class PlainCoercion:
    """A typer runtime parameter (``coerce(value, param, ctx)``) doing the plain cases itself."""

    def __init__(self, functions: tuple[Any, Any, Any]) -> None:
        self._choice, self._path, self._typer_runtime = functions
        self._typer: Any = None

    def coerce(self, value: Any, param: Any, ctx: Any) -> Any:
        multi = param.multiple or param.nargs == -1
        if value is None:
            return () if multi else None  # as typer's RuntimeParam.coerce
        out = _TYPER if multi else self._plain(value, param, ctx)
        if out is not _TYPER:
            return out
        if self._typer is None:
            self._typer = self._typer_runtime(param.type_descriptor)
        return self._typer.coerce(value, param=param, ctx=ctx)

    def _plain(self, value: Any, param: Any, ctx: Any) -> Any:
        descriptor = param.type_descriptor
        info = descriptor.parameter_info
        annotation = descriptor.annotation
        if descriptor.is_file or info.parser is not None or descriptor.is_ranged:
            return _TYPER
        if annotation in (int, float, str) and type(value) is annotation:
            return value
        if isinstance(value, str):
            if annotation is int and _INT.fullmatch(value):
                return int(value)
            if annotation is float and _FLOAT.fullmatch(value):
                return float(value)
            if annotation is str:
                return value
        if annotation is float and type(value) is int:
            return float(value)
        if isinstance(annotation, type) and issubclass(annotation, Enum):
            try:
                return self._choice(
                    value, choices=list(annotation), case_sensitive=info.case_sensitive, ctx=ctx
                )
            except ValueError:
                return _TYPER
        if annotation is Path and descriptor.is_path and info.path_type is None:
            if isinstance(value, str) and value:
                value = Path(value)
            if isinstance(value, Path):
                try:
                    return self._path(value, info, path_type=Path, param=param, ctx=ctx)
                except Exception:  # typer's own coercion raises its message
                    return _TYPER
        return _TYPER


def use_plain_coercion(params: Iterable[Any]) -> None:
    """Give the parameters of a command built by typer (``command.get_params(ctx)``) the plain
    coercion, if typer has the runtime coercion this module knows (else leave them as they are)."""
    try:
        from typer._coercion import build_runtime_param
        from typer._param_types import coerce_cli_choice, coerce_cli_path
    except ImportError:
        return
    functions = (coerce_cli_choice, coerce_cli_path, build_runtime_param)
    for param in params:
        if (
            "_runtime_param" in vars(param)
            and param._runtime_param is None
            and hasattr(param, "type_descriptor")
        ):
            param._runtime_param = PlainCoercion(functions)
