"""Engine creation and schema migration.

``open_database(url)`` is the one entry point: it resolves the URL (argument, then the
``SOFTEVO_DB`` environment variable, then ``sqlite:///softevo.db``), checks that a SQLite
file can be written, builds the engine (SQLite: WAL journal, foreign keys on, busy timeout)
and upgrades the schema to the newest Alembic revision. ``database_reachable(engine)`` is
the health check.
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import Engine, create_engine, event, text
from sqlalchemy.engine import URL, make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, NoSuchModuleError

from softevo.errors import UserError
from softevo.service.storage.migrate import upgrade

SQLITE_BUSY_TIMEOUT_MS = 30_000
# connections per engine: the API's thread pool (40 threads) plus the coordinator and its run
# locks never wait for one (a wait of 30 s would be a 500 under load)
POOL_SIZE, MAX_OVERFLOW = 10, 40


def database_url(url: str | None = None) -> str:
    """The database URL to use: ``url``, else ``Settings.db`` (``$SOFTEVO_DB`` or its default)."""
    if url:
        return url
    from softevo.service.settings import Settings  # pydantic-settings: only when no URL is given

    return Settings.load().db


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


def check_exists(url: str | None = None) -> None:
    """UserError ``no database at PATH`` unless ``url`` (see ``database_url``) is a SQLite
    file that exists, or not a SQLite file at all (a server says for itself)."""
    resolved = database_url(url)
    try:
        parsed = make_url(resolved)
    except ArgumentError as exc:
        raise UserError(f"not a database URL: {resolved!r}") from exc
    database = parsed.database
    if parsed.get_backend_name() != "sqlite" or not database or database == ":memory:":
        return
    if database.startswith("file:") or Path(database).expanduser().is_file():
        return
    raise UserError(f"no database at {database} (give --db URL or set SOFTEVO_DB)")


def _sqlite_pragmas(dbapi_connection, _record) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()


POSTGRES_INSTALL = "pip install 'softevo[postgres]'"  # pyproject's extra: psycopg


def make_engine(url: str | None = None) -> Engine:
    """Build an engine for ``url`` (see ``database_url``); no schema changes. An unknown
    dialect or a driver that is not installed is a UserError."""
    resolved = database_url(url)
    try:
        parsed = make_url(resolved)
    except ArgumentError as exc:
        raise UserError(f"not a database URL: {resolved!r}") from exc
    try:
        return _engine_for(parsed)
    except (NoSuchModuleError, ImportError) as exc:
        if parsed.get_backend_name() == "postgresql" and isinstance(exc, ImportError):
            raise UserError(
                f"database {shown(parsed)}: the PostgreSQL driver is not installed ({one_line(exc)}); "
                f"install the postgres extra: {POSTGRES_INSTALL}"
            ) from exc
        raise UserError(
            f"database {shown(parsed)}: no driver for {parsed.drivername!r} ({one_line(exc)}); "
            "softevo works with sqlite:///FILE and postgresql+psycopg://..."
        ) from exc


def _engine_for(parsed: URL) -> Engine:
    if parsed.get_backend_name() == "sqlite":
        _check_sqlite_path(parsed.database)
        engine = create_engine(parsed, pool_size=POOL_SIZE, max_overflow=MAX_OVERFLOW)
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return create_engine(parsed, pool_pre_ping=True, pool_size=POOL_SIZE, max_overflow=MAX_OVERFLOW)


def open_database(url: str | None = None, *, create: bool = True) -> Engine:
    """Engine for ``url`` with the schema upgraded to the newest migration. A database that
    cannot be reached or read (no server, a refused login, a file that is not a database) is
    a UserError of one line, naming the URL without its password. With ``create=False`` (the
    read-only commands) a SQLite file that does not exist is a UserError, not a new database."""
    if not create:
        check_exists(url)
    engine = make_engine(url)
    try:
        upgrade(engine)
    except DBAPIError as exc:
        engine.dispose()
        raise UserError(f"cannot open database {shown(engine.url)}: {one_line(exc.orig or exc)}") from exc
    return engine


def shown(url: URL) -> str:
    """``url`` as text, its password hidden."""
    return url.render_as_string(hide_password=True)


def one_line(exc: BaseException) -> str:
    """The first line of ``exc``'s message (drivers add hints on further lines)."""
    lines = str(exc).strip().splitlines()
    return lines[0].strip() if lines else type(exc).__name__


def database_reachable(engine: Engine) -> bool:
    """Whether the database answers a trivial query (for health checks)."""
    try:
        with engine.connect() as conn:
            conn.execute(text("SELECT 1"))
    except Exception:
        return False
    return True
