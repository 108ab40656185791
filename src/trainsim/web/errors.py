"""Errors as JSON: every 4xx answer has a ``message`` and a ``detail`` list of field-level problems.

Shape of an error answer::

    {"message": "<train>, field 'formation[1].mass_t': out of range (got -3.0); allowed: > 0.",
     "detail": [{"field": "formation[1].mass_t", "loc": ["formation", 1, "mass_t"],
                 "msg": "out of range (got -3.0); allowed: > 0", "value": -3.0, "allowed": "> 0"}]}

``field`` uses the path notation of the core's messages (``a.b[2].c``); ``loc`` is the same path as a
list; ``msg`` is the core's validation message for that field. The page puts each ``msg`` next to
the input whose path is ``field``.
"""

from __future__ import annotations

import math
import re
from typing import Any

from fastapi import Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from trainsim.errors import InputError, Problem, TrainsimError, shown_value


class ApiError(Exception):
    """An error answer with a status code, a message and optional field-level detail."""

    def __init__(
        self,
        status: int,
        message: str,
        detail: list[dict[str, Any]] | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.detail = detail or []
        self.headers = headers or {}


def parse_field(field: str | None) -> list[str | int]:
    """``"a.b[1].c"`` -> ``["a", "b", 1, "c"]``."""
    if not field:
        return []
    parts: list[str | int] = []
    for piece in field.split("."):
        name, *indices = piece.replace("]", "").split("[")
        if name:
            parts.append(name)
        parts += [int(i) if i.isdigit() else i for i in indices]
    return parts


def format_loc(loc: list[str | int] | tuple[str | int, ...]) -> str:
    """``["a", "b", 1, "c"]`` -> ``"a.b[1].c"``."""
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else ("." if text else "") + str(part)
    return text


def _jsonable(value: Any) -> Any:
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if isinstance(value, int):
        return value if abs(value) < 2**53 else shown_value(value)
    if isinstance(value, str):
        return value if len(value) <= 80 else shown_value(value)
    return shown_value(value)


#: file-format advice that means nothing in a table cell, and what the cell says instead
_CELL_WORDING = [
    (
        re.compile(r"^'[\w.]+' takes a plain number in ([^;]+); to give a unit, write .* instead$"),
        r"enter a number in \1",
    ),
    (re.compile(r"\bYAML\b"), "file"),
    (re.compile(r"\bmapping\b"), "group of fields"),
]


def cell_wording(reason: str) -> str:
    """A reader's reason as a table cell's message (no file syntax: units are in the column name)."""
    for pattern, replacement in _CELL_WORDING:
        reason = pattern.sub(replacement, reason)
    return reason


def _problem_msg(reason: str, value: Any, allowed: str | None) -> str:
    msg = cell_wording(reason)
    if value is not None:
        msg += f" (got {shown_value(value)})"
    if allowed:
        msg += f"; allowed: {allowed}"
    return msg


def _part_texts(message: str, count: int) -> list[str | None]:
    """The text of each numbered problem of a message ``N problems: (1) ...; (2) ...``."""
    out: list[str | None] = []
    for i in range(1, count + 1):
        nxt = rf"; \({i + 1}\) " if i < count else r"\.?$"
        match = re.search(rf"\({i}\) (.*?)(?={nxt})", message, flags=re.S)
        out.append(match.group(1) if match else None)
    return out


def problems_of(exc: InputError) -> list[Problem]:
    """The error's problems as :class:`Problem` objects (older readers gave ``(field, reason)``
    pairs; a one-problem error without a list gives its own fields)."""
    out: list[Problem] = []
    given = getattr(exc, "problems", None) or []
    if len(given) == 1 and isinstance(given[0], tuple):
        given = []  # the error's own fields say more
    texts = _part_texts(exc.reason, len(given)) if given and isinstance(given[0], tuple) else []
    for i, p in enumerate(given):
        if isinstance(p, Problem):
            out.append(p)
        elif isinstance(p, tuple) and len(p) == 2:
            # older readers: the full text of each problem is in the message, "(i) path: text"
            reason, text = str(p[1]), texts[i] if i < len(texts) else None
            if text and p[0] and text.startswith(f"{p[0]}: "):
                reason = text[len(p[0]) + 2 :]
            out.append(Problem(reason, file=exc.file, line=exc.line, field=p[0] or None))
    if not out:
        out.append(
            Problem(
                exc.reason,
                file=exc.file,
                line=exc.line,
                field=exc.field,
                value=exc.value,
                allowed=exc.allowed,
            )
        )
    return out


def input_error_detail(exc: InputError, prefix: list[str | int] | None = None) -> list[dict[str, Any]]:
    """Field-level problems of a core InputError, one entry per :class:`trainsim.errors.Problem`
    (at most 50): ``field`` (path), ``loc``, ``msg`` (reason, value and what is allowed), ``value``,
    ``allowed``, ``line`` and ``file``."""
    prefix = list(prefix or [])
    detail = []
    for p in problems_of(exc)[:50]:
        loc = [*prefix, *parse_field(p.field)]
        detail.append(
            {
                "field": format_loc(loc) or None,
                "loc": loc,
                "msg": _problem_msg(p.reason, p.value, p.allowed),
                "value": _jsonable(p.value),
                "allowed": p.allowed,
                "line": p.line,
                "file": p.file,
            }
        )
    return detail


def input_error(exc: InputError, prefix: list[str | int] | None = None, file: str | None = None) -> ApiError:
    """A 422 answer for a core InputError; ``file`` replaces a temporary file name in the message."""
    message = str(exc)
    if file is not None and exc.file and exc.file != file:
        message = message.replace(exc.file, file)
    return ApiError(422, message, input_error_detail(exc, prefix))


def error_response(
    status: int,
    message: str,
    detail: list[dict[str, Any]] | None = None,
    headers: dict[str, str] | None = None,
) -> JSONResponse:
    return JSONResponse({"message": message, "detail": detail or []}, status_code=status, headers=headers)


async def _api_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return error_response(exc.status, exc.message, exc.detail, exc.headers)


async def _trainsim_error(request: Request, exc: Exception) -> JSONResponse:
    if isinstance(exc, InputError):
        err = input_error(exc)
        return error_response(err.status, err.message, err.detail)
    return error_response(422, str(exc))


async def _request_validation(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    detail = []
    for err in exc.errors():
        loc = [p for p in err.get("loc", ()) if p not in ("body", "query", "path")]
        detail.append({"field": format_loc(loc) or None, "loc": loc, "msg": err.get("msg", "invalid")})
    text = "; ".join(f"{d['field'] or 'request'}: {d['msg']}" for d in detail) or "invalid request"
    return error_response(422, f"invalid request: {text}", detail)


async def _http_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    return error_response(exc.status_code, str(exc.detail))


async def _recursion(request: Request, exc: Exception) -> JSONResponse:
    return error_response(422, "document nested too deeply; allowed: a plainer document")


def install(app: Any) -> None:
    """Register the JSON error handlers on a FastAPI app."""
    app.add_exception_handler(RecursionError, _recursion)
    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(TrainsimError, _trainsim_error)
    app.add_exception_handler(RequestValidationError, _request_validation)
    app.add_exception_handler(StarletteHTTPException, _http_error)
