"""``trainsim serve``: the web application (register with ``app.command("serve")(serve)``)."""

from __future__ import annotations

from typing import Annotated

import typer

_LOOPBACK = ("127.0.0.1", "localhost", "::1")


def serve(
    host: Annotated[
        str, typer.Option(help="address to listen on (127.0.0.1: this machine only)")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port")] = 8000,
    allowed_host: Annotated[
        list[str] | None,
        typer.Option(
            help="a host name the browser may use to reach the server (repeat for several); requests "
            "naming another host get 400. Always allowed: 127.0.0.1, localhost, ::1 and --host",
        ),
    ] = None,
    workers: Annotated[
        int, typer.Option(min=1, max=64, help="worker processes for validation, uploads and runs")
    ] = 2,
    drive_hosts: Annotated[int, typer.Option(min=1, max=64, help="processes hosting the live drives")] = 2,
    time_limit_s: Annotated[
        float, typer.Option(min=1.0, max=3600.0, help="wall-clock limit of one request's work [s]")
    ] = 30.0,
    memory_limit_mb: Annotated[
        int, typer.Option(min=64, max=1_048_576, help="memory one request's work may take [MiB]")
    ] = 1024,
) -> None:
    """Start the web application: train and track tables, runs and plots, live driving."""
    from trainsim.cli.context import user_errors

    with user_errors():  # a light install without the [web] extra is told what to install
        import uvicorn

        from trainsim.web import WebSettings, create_app

        hosts = tuple(dict.fromkeys((*_LOOPBACK, host, *(allowed_host or ()))))
        settings = WebSettings(
            allowed_hosts=hosts,
            workers=workers,
            drive_hosts=drive_hosts,
            job_time_limit_s=time_limit_s,
            job_memory_limit_bytes=memory_limit_mb * 1024 * 1024,
        )
        app = create_app(settings)
    shown = f"[{host}]" if ":" in host else host
    typer.echo(f"trainsim web application at http://{shown}:{port}/  (API docs at /docs; Ctrl+C to stop)")
    if host not in _LOOPBACK:
        typer.echo("note: listening beyond this machine; the application has no login", err=True)
        if not allowed_host:
            typer.echo(
                "note: browsers must use the address given to --host; add names they use with --allowed-host",
                err=True,
            )
    uvicorn.run(app, host=host, port=port, log_level="warning", ws_max_size=64 * 1024)
