"""Errors trainsim raises for bad input and impossible requests."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

#: Longest value shown in a message; hostile files can hold values of megabytes.
MAX_SHOWN_VALUE_CHARS = 80

#: Longest reason shown for one problem (a reason that quotes a hostile value is cut).
MAX_REASON_CHARS = 1000


def shown_value(value: Any, limit: int = MAX_SHOWN_VALUE_CHARS) -> str:
    """``repr(value)`` cut to a readable length (with ``...`` where it was cut)."""
    try:
        shown = repr(value)
    except Exception:  # a hostile object whose repr fails must not hide the real error
        shown = f"<{type(value).__name__}>"
    if len(shown) > limit:
        shown = shown[: limit - 3] + "..."
    return shown


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input: where it is, what was found and what is allowed.

    ``field`` is a dotted path into the document (``formation[0].count``, ``sections.gradient``), or a
    spreadsheet cell (``B12``); ``value`` is the offending value as read (shown cut by
    :func:`shown_value`); ``allowed`` says in words what would be accepted.
    """

    reason: str
    file: str | None = None
    line: int | None = None
    field: str | None = None
    value: Any = None
    allowed: str | None = None

    def text(self, with_file: bool = True) -> str:
        """The problem as one sentence (no trailing full stop); without the file name if
        ``with_file`` is false (a list of problems of one file names it once)."""
        where = []
        if self.file and with_file:
            where.append(f"{self.file}" + (f", line {self.line}" if self.line else ""))
        elif self.line:
            where.append(f"line {self.line}")
        if self.field:
            where.append(f"field '{self.field}'")
        reason = (
            self.reason
            if len(self.reason) <= MAX_REASON_CHARS
            else self.reason[: MAX_REASON_CHARS - 3] + "..."
        )
        text = (": ".join([", ".join(where), reason]) if where else reason).rstrip(".")
        if self.value is not None:
            text += f" (got {shown_value(self.value)})"
        if self.allowed:
            text += f"; allowed: {self.allowed}"
        return text

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (the value as its cut repr unless it is a plain scalar)."""
        value = self.value
        if not (value is None or isinstance(value, bool | int | float | str)):
            value = shown_value(value)
        elif isinstance(value, str):
            value = value if len(value) <= MAX_SHOWN_VALUE_CHARS else shown_value(value)
        elif isinstance(value, float) and not math.isfinite(value):
            value = repr(value)
        return {
            "file": self.file,
            "line": self.line,
            "field": self.field,
            "value": value,
            "allowed": self.allowed,
            "reason": self.reason,
        }


class TrainsimError(Exception):
    """Base class of every error trainsim raises on purpose."""


class InputError(TrainsimError, ValueError):
    """Invalid user input: names the file, the field, the value and what is allowed.

    ``str(error)`` is one paragraph fit to show a user as it is. ``problems`` is the structured list
    behind it (one :class:`Problem` per thing wrong), for the CLI and the web application to show
    per field or cell without parsing the text. An error built with keyword arguments has exactly
    one problem; :meth:`from_problems` builds one from several.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        field: str | None = None,
        value: Any = None,
        allowed: str | None = None,
        line: int | None = None,
        problems: list[Problem] | None = None,
    ) -> None:
        self.file = file
        self.field = field
        self.value = value
        self.allowed = allowed
        self.line = line
        self.reason = message
        if problems:
            self.problems = list(problems)
        else:
            self.problems = [
                Problem(message, file=file, line=line, field=field, value=value, allowed=allowed)
            ]
        super().__init__(self._compose())

    @classmethod
    def from_problems(cls, problems: list[Problem], *, file: str | None = None) -> InputError:
        """One error for several problems (the first one gives the message's lead)."""
        if not problems:
            raise ValueError("an InputError needs at least one problem")
        if file:
            problems = [p if p.file else _with_file(p, file) for p in problems]
        first = problems[0]
        return cls(
            first.reason,
            file=first.file,
            field=first.field,
            value=first.value,
            allowed=first.allowed,
            line=first.line,
            problems=problems,
        )

    def _compose(self) -> str:
        if len(self.problems) == 1:
            return self.problems[0].text() + "."
        # several problems: "FILE: N problems: (1) line 3, field 'a': ...; (2) ..." (file named once)
        files = {p.file for p in self.problems}
        one_file = len(files) == 1 and None not in files
        shown = self.problems[:5]
        texts = [f"({i}) {p.text(with_file=not one_file)}" for i, p in enumerate(shown, 1)]
        text = f"{len(self.problems)} problems: " + "; ".join(texts)
        if one_file:
            text = f"{self.problems[0].file}: {text}"
        more = len(self.problems) - len(shown)
        if more > 0:
            text += f"; and {more} more problem{'s' if more > 1 else ''}"
        return text + "."

    def located(self, file: str) -> InputError:
        """The same error with the file name filled in (for errors raised below the file layer)."""
        if all(p.file for p in self.problems):
            return self
        error = InputError.from_problems([p if p.file else _with_file(p, file) for p in self.problems])
        return error

    def to_dicts(self) -> list[dict[str, Any]]:
        """The problems in JSON-ready form."""
        return [p.to_dict() for p in self.problems]


def _with_file(problem: Problem, file: str) -> Problem:
    return Problem(
        problem.reason,
        file=file,
        line=problem.line,
        field=problem.field,
        value=problem.value,
        allowed=problem.allowed,
    )


class InfeasibleError(TrainsimError):
    """A physically impossible request, e.g. a train that cannot start on a grade."""
