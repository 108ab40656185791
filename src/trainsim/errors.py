"""Errors trainsim raises for bad input and impossible requests."""

from __future__ import annotations

from typing import Any


class TrainsimError(Exception):
    """Base class of every error trainsim raises on purpose."""


class InputError(TrainsimError, ValueError):
    """Invalid user input: names the file, the field, the value and what is allowed.

    ``str(error)`` is one paragraph fit to show a user as it is.
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
    ) -> None:
        self.file = file
        self.field = field
        self.value = value
        self.allowed = allowed
        self.line = line
        self.reason = message
        super().__init__(self._compose())

    def _compose(self) -> str:
        where = []
        if self.file:
            where.append(f"{self.file}" + (f", line {self.line}" if self.line else ""))
        if self.field:
            where.append(f"field '{self.field}'")
        text = (": ".join([", ".join(where), self.reason]) if where else self.reason).rstrip(".")
        if self.value is not None:
            shown = repr(self.value)
            if len(shown) > 80:
                shown = shown[:77] + "..."
            text += f" (got {shown})"
        if self.allowed:
            text += f"; allowed: {self.allowed}"
        return text + "."

    def located(self, file: str) -> InputError:
        """The same error with the file name filled in (for errors raised below the file layer)."""
        if self.file:
            return self
        return InputError(
            self.reason,
            file=file,
            field=self.field,
            value=self.value,
            allowed=self.allowed,
            line=self.line,
        )


class InfeasibleError(TrainsimError):
    """A physically impossible request, e.g. a train that cannot start on a grade."""
