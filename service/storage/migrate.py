"""Run Alembic migrations programmatically.

The migration scripts live in the ``softevo.migrations`` package, installed with the
project (``env.py``, ``script.py.mako`` and ``versions/*.py`` are package files), so an
installed coordinator finds them where that package is installed rather than by a path
relative to the working directory. The package is located, not imported: its ``env.py``
imports ``service.storage.models``, and runs only under Alembic.
"""

from __future__ import annotations

import fcntl
import importlib.util
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine, text

MIGRATION_LOCK = 0x50F8  # PostgreSQL advisory lock key held while the schema is upgraded


def script_location() -> Path:
    """Directory of the installed ``softevo.migrations`` package."""
    spec = importlib.util.find_spec("softevo.migrations")
    return Path(spec.origin).resolve().parent


def alembic_config(engine: Engine) -> Config:
    """Alembic config that runs on ``engine`` (no alembic.ini needed)."""
    config = Config()
    config.set_main_option("script_location", str(script_location()))
    config.attributes["engine"] = engine
    return config


@contextmanager
def one_at_a_time(engine: Engine) -> Iterator[None]:
    """Hold off every other process upgrading the same database: two coordinators started
    together on a new database would otherwise both create the schema (PostgreSQL: an
    advisory lock; SQLite file: a lock on ``<file>.migrate.lock``)."""
    url = engine.url
    if url.get_backend_name() == "postgresql":
        with engine.connect() as conn:
            conn.execute(text("SELECT pg_advisory_lock(:k)"), {"k": MIGRATION_LOCK})
            try:
                yield
            finally:
                conn.execute(text("SELECT pg_advisory_unlock(:k)"), {"k": MIGRATION_LOCK})
    elif url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
        with open(f"{url.database}.migrate.lock", "a") as handle:
            fcntl.flock(handle, fcntl.LOCK_EX)
            yield
    else:
        yield


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Upgrade the schema of ``engine``'s database to ``revision``, one process at a time.
    A database already at the newest revision is left alone, without the lock (no
    ``<file>.migrate.lock`` beside a SQLite file only read)."""
    config = alembic_config(engine)
    if revision == "head" and _at_head(engine, config):
        return
    with one_at_a_time(engine):
        command.upgrade(config, revision)


def _at_head(engine: Engine, config: Config) -> bool:
    heads = set(ScriptDirectory.from_config(config).get_heads())
    with engine.connect() as conn:
        return set(MigrationContext.configure(conn).get_current_heads()) == heads
