"""The web application: ``create_app()`` builds the FastAPI app (JSON API, WebSocket, page, docs).

Everything the browser loads comes from this package or from installed Python packages (Plotly's
JavaScript from ``plotly``, Swagger UI and ReDoc from ``fastapi_offline``): no CDN, it works
offline.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from importlib import resources
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send

import trainsim
from trainsim.web import api, drive, errors
from trainsim.web.cache import RunCache
from trainsim.web.config import WebSettings
from trainsim.web.drivehost import DriveHosts
from trainsim.web.errors import ApiError
from trainsim.web.sessions import COOKIE_NAME, HEADER_NAME, SessionRateError, SessionStore, WebSession
from trainsim.web.workers import WorkerPool

STATIC_DIR = Path(__file__).parent / "static"
_SCOPE_KEY = "trainsim.session"


def plotly_js_path() -> Path:
    """Plotly's bundled JavaScript, shipped inside the ``plotly`` Python package."""
    return Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))


def docs_assets_dir() -> Path:
    """Swagger UI and ReDoc assets, shipped inside the ``fastapi_offline`` package."""
    return Path(str(resources.files("fastapi_offline") / "static"))


#: the page's Content-Security-Policy: everything from this server, nothing inline but styles (Plotly)
CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
    "connect-src 'self'; font-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
    "frame-ancestors 'none'"
)
#: Swagger UI and ReDoc start from an inline script and ReDoc uses a blob worker
CSP_DOCS = (
    "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data: blob:; worker-src 'self' blob:; connect-src 'self'; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'"
)


def host_allowed(host_header: str | None, allowed: tuple[str, ...]) -> bool:
    """Whether a ``Host`` header names this server (``allowed`` host names, ``*`` for any)."""
    if "*" in allowed:
        return True
    if not host_header:
        return False
    host = host_header.strip().lower()
    if host.startswith("["):  # [::1]:8000
        name = host[1 : host.find("]")] if "]" in host else host
    else:
        name = host.rsplit(":", 1)[0] if host.count(":") == 1 else host
    return name in allowed


class HostAndHeaders:
    """ASGI middleware: refuses requests whose ``Host`` is not this server's (DNS rebinding) with
    400 and adds the security headers (CSP, X-Frame-Options, nosniff, no referrer) to every answer."""

    def __init__(self, app: ASGIApp, allowed_hosts: tuple[str, ...]) -> None:
        self.app = app
        self.allowed_hosts = tuple(h.lower() for h in allowed_hosts)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        host = dict(scope.get("headers") or []).get(b"host", b"").decode("latin-1")
        if not host_allowed(host, self.allowed_hosts):
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008})
                return
            body = json.dumps(
                {
                    "message": f"unknown host {host[:80]!r}; allowed: {', '.join(self.allowed_hosts)} "
                    "(start the server with --allowed-host to add one)",
                    "detail": [],
                }
            ).encode()
            await send(
                {
                    "type": "http.response.start",
                    "status": 400,
                    "headers": [
                        (b"content-type", b"application/json"),
                        (b"content-length", str(len(body)).encode()),
                    ],
                }
            )
            await send({"type": "http.response.body", "body": body})
            return
        if scope["type"] == "websocket":
            await self.app(scope, receive, send)
            return
        path = scope.get("path", "")
        csp = CSP_DOCS if path in ("/docs", "/redoc") else CSP

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers") or [])
                headers += [
                    (b"content-security-policy", csp.encode()),
                    (b"x-frame-options", b"DENY"),
                    (b"x-content-type-options", b"nosniff"),
                    (b"referrer-policy", b"no-referrer"),
                ]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, with_headers)


class BoundedBodyAndSession:
    """ASGI middleware: rejects request bodies over ``max_bytes`` with 413, and hands a new
    session's id to the client (cookie and header) when the request made one."""

    def __init__(self, app: ASGIApp, max_bytes: int, cookie_max_age_s: int) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.cookie_max_age_s = cookie_max_age_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length")
        if length is not None and (not length.isdigit() or int(length) > self.max_bytes):
            await self._too_large(send)
            return
        started = False
        # read the whole body first (bounded), so that an oversized chunked body is a 413 whatever
        # the endpoint does with it
        chunks: list[bytes] = []
        received = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                return  # the client went away while sending
            body = message.get("body", b"")
            received += len(body)
            if received > self.max_bytes:
                await self._too_large(send)
                return
            chunks.append(body)
            if not message.get("more_body", False):
                break
        replayed = False

        async def limited_receive() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": b"".join(chunks), "more_body": False}
            return await receive()

        async def session_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                session: WebSession | None = scope.get(_SCOPE_KEY)
                if session is not None:
                    out = list(message.get("headers") or [])
                    out.append((HEADER_NAME.lower().encode(), session.id.encode()))
                    if scope.get(_SCOPE_KEY + ".cookie") != session.id:
                        cookie = (
                            f"{COOKIE_NAME}={session.id}; Path=/; HttpOnly; SameSite=Strict; "
                            f"Max-Age={self.cookie_max_age_s}"
                        )
                        out.append((b"set-cookie", cookie.encode()))
                    message = {**message, "headers": out}
            await send(message)

        await self.app(scope, limited_receive, session_send)

    async def _too_large(self, send: Send) -> None:
        body = json.dumps(
            {"message": f"request too large; allowed: at most {self.max_bytes} bytes", "detail": []}
        ).encode()
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})


def create_app(settings: WebSettings | None = None) -> FastAPI:
    """The trainsim web application (page at ``/``, JSON API under ``/api``, docs at ``/docs``)."""
    settings = settings or WebSettings()
    pool = (
        WorkerPool(
            settings.workers,
            settings.job_time_limit_s,
            settings.job_memory_limit_bytes,
            settings.max_queued_jobs,
            settings.start_timeout_s,
        )
        if settings.workers > 0
        else None
    )

    hosts = DriveHosts(settings.drive_hosts, settings.start_timeout_s)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # in the background: the server answers at once, the first heavy request waits for it
        starting = [asyncio.ensure_future(hosts.start())]
        if pool is not None:
            starting.append(asyncio.ensure_future(pool.start()))
        try:
            yield
        finally:
            for task in starting:
                task.cancel()
            hosts.close()
            if pool is not None:
                pool.close()

    app = FastAPI(
        lifespan=lifespan,
        title="trainsim",
        version=trainsim.__version__,
        description=(
            "Train performance calculator: train and route parameters, runs, plots and live driving.\n\n"
            "Every request works on the caller's session, named by the `trainsim_session` cookie or the "
            "`X-Trainsim-Session` header (a new session's id comes back in both). Errors are JSON "
            "`{message, detail: [{field, loc, msg}]}`; `msg` is the core's validation message for "
            "`field` (path notation `formation[1].mass_t`). Live driving is the WebSocket `/api/drive` "
            "(messages in docs/WEB.md)."
        ),
        docs_url=None,
        redoc_url=None,
    )
    store = SessionStore(settings)
    app.state.store = store
    app.state.pool = pool
    app.state.run_cache = RunCache()
    app.state.drive_hosts = hosts
    app.state.web_settings = settings

    def session_for(request: Request) -> WebSession:
        scope = request.scope
        session = scope.get(_SCOPE_KEY)
        if session is None:
            cookie = request.cookies.get(COOKIE_NAME)
            sid = request.headers.get(HEADER_NAME) or cookie
            client = request.client.host if request.client else "unknown"
            try:
                session, _ = store.get_or_create(sid, client)
            except SessionRateError as exc:
                raise ApiError(
                    429,
                    f"{exc}; allowed: {settings.session_burst} new sessions at once and "
                    f"{settings.sessions_per_minute:g} per minute per client (send the session cookie "
                    "or X-Trainsim-Session header to keep using yours)",
                    headers={"Retry-After": f"{exc.retry_after_s:.0f}"},
                ) from exc
            scope[_SCOPE_KEY] = session
            scope[_SCOPE_KEY + ".cookie"] = cookie
        return session

    app.state.session_for = session_for
    errors.install(app)
    app.include_router(api.router)
    app.include_router(drive.router)
    app.add_middleware(
        BoundedBodyAndSession, max_bytes=settings.max_body_bytes, cookie_max_age_s=int(settings.session_ttl_s)
    )
    app.add_middleware(HostAndHeaders, allowed_hosts=settings.allowed_hosts)

    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    app.mount("/vendor/docs", StaticFiles(directory=docs_assets_dir()), name="docs-assets")

    @app.api_route("/vendor/plotly.min.js", methods=["GET", "HEAD"], include_in_schema=False)
    def plotly_js() -> FileResponse:
        return FileResponse(plotly_js_path(), media_type="text/javascript")

    @app.api_route("/", methods=["GET", "HEAD"], include_in_schema=False)
    def index() -> FileResponse:
        return FileResponse(
            STATIC_DIR / "index.html", media_type="text/html", headers={"Cache-Control": "no-cache"}
        )

    @app.get("/docs", include_in_schema=False)
    def swagger() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url="/openapi.json",
            title="trainsim API",
            swagger_js_url="/vendor/docs/swagger-ui-bundle.js",
            swagger_css_url="/vendor/docs/swagger-ui.css",
            swagger_favicon_url="/static/favicon.svg",
        )

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        return get_redoc_html(
            openapi_url="/openapi.json",
            title="trainsim API",
            redoc_js_url="/vendor/docs/redoc.standalone.js",
            redoc_favicon_url="/static/favicon.svg",
            with_google_fonts=False,
        )

    return app


def app_factory() -> Any:
    """For ``uvicorn --factory trainsim.web.app:app_factory``."""
    return create_app()
