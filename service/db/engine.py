"""Engine creation and schema migration.

``open_database(url)`` is the one entry point: it resolves the URL (argument, then the
``SOFTEVO_DB`` environment variable, then ``sqlite:///softevo.db``), checks that a SQLite
file can be written, builds the engine (SQLite: WAL journal, foreign keys on, busy timeout)
and upgrades the schema to the newest Alembic revision. ``database_reachable(engine)`` is
the health check.
"""

from __future__ import annotations

import os
from pathlib import Path

from sqlalchemy import Engine, create_engine, event, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError

from softevo.errors import UserError
from softevo.service.db.migrate import upgrade

DEFAULT_URL = "sqlite:///softevo.db"
SQLITE_BUSY_TIMEOUT_MS = 30_000
# connections per engine: the API's thread pool (40 threads) plus the coordinator and its run
# locks never wait for one (a wait of 30 s would be a 500 under load)
POOL_SIZE, MAX_OVERFLOW = 10, 40


def database_url(url: str | None = None) -> str:
    """The database URL to use: ``url``, else ``$SOFTEVO_DB``, else ``sqlite:///softevo.db``."""
    return url or os.environ.get("SOFTEVO_DB") or DEFAULT_URL


def _check_sqlite_path(database: str | None) -> None:
    """Raise UserError unless the SQLite file can be opened for writing (created if absent)."""
    if not database or database == ":memory:" or database.startswith("file:"):
        return
    path = Path(database).expanduser()
    if path.is_dir():
        raise UserError(f"database {database!r} is a directory")
    try:
        with open(path, "ab"):
            pass
    except OSError as exc:
        raise UserError(f"database {database!r} cannot be written: {exc.strerror}") from exc


def _sqlite_pragmas(dbapi_connection, _record) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()


def make_engine(url: str | None = None) -> Engine:
    """Build an engine for ``url`` (see ``database_url``); no schema changes."""
    resolved = database_url(url)
    try:
        parsed = make_url(resolved)
    except ArgumentError as exc:
        raise UserError(f"not a database URL: {resolved!r}") from exc
    if parsed.get_backend_name() == "sqlite":
        _check_sqlite_path(parsed.database)
        engine = create_engine(parsed, pool_size=POOL_SIZE, max_overflow=MAX_OVERFLOW)
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return create_engine(parsed, pool_pre_ping=True, pool_size=POOL_SIZE, max_overflow=MAX_OVERFLOW)


def open_database(url: str | None = None) -> Engine:
    """Engine for ``url`` with the schema upgraded to the newest migration."""
    engine = make_engine(url)
    upgrade(engine)
    return engine


def database_reachable(engine: Engine) -> bool:
    """Whether the database answers a trivial query (for health checks)."""
    try:
        with engine.connect() as conn:
            conn.execute(text("SELECT 1"))
    except Exception:
        return False
    return True
