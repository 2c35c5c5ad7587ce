"""``softevo dashboard``: the web dashboard on a database, without a coordinator.

It serves the read routes of ``softevo serve``'s FastAPI app (the read API and the
``/dashboard`` pages) with ``SOFTEVO_COORDINATOR=false``: it only reads (a write is 405, token
or not), so it can watch a ``softevo run`` writing to the same SQLite file.
Replays are simulated again on demand in one background process.
"""

from __future__ import annotations

from typing import Annotated

import typer


def check_database(url: str, create: bool = True) -> None:
    """UserError (one line) unless the database at ``url`` opens (and, unless ``create``,
    exists): checked before the server starts, whose startup would otherwise fail with a
    traceback. The dashboard does not create one (it would show a new empty one)."""
    from softevo.service.storage import open_database

    open_database(url, create=create).dispose()


def check_port(host: str, port: int) -> None:
    """UserError (one line) unless ``host:port`` can be listened on: checked before the
    server starts, which would otherwise log ``ERROR: ... address already in use`` and stop."""
    import socket

    from softevo.errors import UserError

    try:
        family, kind, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn binds
            probe.bind(address)
    except (OSError, OverflowError) as exc:
        reason = getattr(exc, "strerror", None) or exc
        raise UserError(f"cannot listen on {host}:{port}: {reason} (--host, --port)") from None


def dashboard(
    db: Annotated[
        str | None, typer.Option("--db", help="SQLAlchemy URL (default $SOFTEVO_DB or sqlite:///softevo.db)")
    ] = None,
    host: Annotated[str | None, typer.Option("--host", help="default $SOFTEVO_HOST or 127.0.0.1")] = None,
    port: Annotated[int | None, typer.Option("--port", help="default $SOFTEVO_PORT or 8000")] = None,
    log_level: Annotated[str, typer.Option("--log-level")] = "warning",
) -> None:
    """Browse experiments, runs and individuals in a web browser, with 3D replays.

    Serves http://HOST:PORT/dashboard/ (and the read API) on the database; drives no runs.
    """
    import logging

    import uvicorn

    from softevo.service.api.app import create_app
    from softevo.service.settings import Settings

    settings = Settings.load(db=db, host=host, port=port, coordinator=False)
    settings.check_safe()
    check_database(settings.db, create=False)
    check_port(settings.host, settings.port)
    logging.basicConfig(level=log_level.upper(), format="%(asctime)s %(name)s %(message)s")
    print(
        f"softevo dashboard on http://{settings.host}:{settings.port}/dashboard/ (Ctrl+C to stop)", flush=True
    )
    app = create_app(settings, read_only=True)
    uvicorn.run(app, host=settings.host, port=settings.port, log_level=log_level)


def register(app: typer.Typer) -> None:
    """Add ``dashboard`` to ``app``."""
    app.command(name="dashboard")(dashboard)
