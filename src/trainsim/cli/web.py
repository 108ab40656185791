"""``trainsim serve``: the web application (register with ``app.command("serve")(serve)``)."""

from __future__ import annotations

from typing import Annotated

import typer


def serve(
    host: Annotated[
        str, typer.Option(help="address to listen on (127.0.0.1: this machine only)")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port")] = 8000,
) -> None:
    """Start the web application: train and track tables, runs and plots, live driving."""
    from trainsim.cli.context import user_errors

    with user_errors():  # a light install without the [web] extra is told what to install
        import uvicorn

        from trainsim.web import create_app

        app = create_app()
    shown = f"[{host}]" if ":" in host else host
    typer.echo(f"trainsim web application at http://{shown}:{port}/  (API docs at /docs; Ctrl+C to stop)")
    if host not in ("127.0.0.1", "localhost", "::1"):
        typer.echo("note: listening beyond this machine; the application has no login", err=True)
    uvicorn.run(app, host=host, port=port, log_level="warning", ws_max_size=64 * 1024)
