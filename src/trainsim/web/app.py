"""The web application: ``create_app()`` builds the FastAPI app (JSON API, WebSocket, page, docs).

Everything the browser loads comes from this package or from installed Python packages (Plotly's
JavaScript from ``plotly``, Swagger UI and ReDoc from ``fastapi_offline``): no CDN, it works
offline.
"""

from __future__ import annotations

import json
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
from trainsim.web.config import WebSettings
from trainsim.web.sessions import COOKIE_NAME, HEADER_NAME, SessionStore, WebSession

STATIC_DIR = Path(__file__).parent / "static"
_SCOPE_KEY = "trainsim.session"


def plotly_js_path() -> Path:
    """Plotly's bundled JavaScript, shipped inside the ``plotly`` Python package."""
    return Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))


def docs_assets_dir() -> Path:
    """Swagger UI and ReDoc assets, shipped inside the ``fastapi_offline`` package."""
    return Path(str(resources.files("fastapi_offline") / "static"))


class _BodyTooLargeError(Exception):
    pass


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
        received = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise _BodyTooLargeError
            return message

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

        try:
            await self.app(scope, limited_receive, session_send)
        except _BodyTooLargeError:
            if not started:
                await self._too_large(send)

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
    app = FastAPI(
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
    app.state.web_settings = settings

    def session_for(request: Request) -> WebSession:
        scope = request.scope
        session = scope.get(_SCOPE_KEY)
        if session is None:
            cookie = request.cookies.get(COOKIE_NAME)
            sid = request.headers.get(HEADER_NAME) or cookie
            session, _ = store.get_or_create(sid)
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
