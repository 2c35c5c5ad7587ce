"""Alembic environment: migrates the engine handed over by ``service.storage.migrate``.

Run from the command line (``alembic -c migrations/alembic.ini upgrade head``) it builds
the engine from ``SOFTEVO_DB`` like the CLI does.
"""

from __future__ import annotations

from alembic import context

from softevo.service.storage.models import Base

config = context.config
target_metadata = Base.metadata


def _engine():
    engine = config.attributes.get("engine")
    if engine is None:
        from softevo.service.storage.engine import make_engine

        engine = make_engine(config.get_main_option("sqlalchemy.url") or None)
    return engine


def run_migrations_offline() -> None:
    """Emit SQL for ``--sql`` mode."""
    context.configure(
        url=str(_engine().url),
        target_metadata=target_metadata,
        literal_binds=True,
        render_as_batch=True,
    )
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    """Run migrations on a live connection (batch mode so SQLite can alter tables)."""
    engine = _engine()
    with engine.connect() as connection:
        context.configure(
            connection=connection,
            target_metadata=target_metadata,
            render_as_batch=connection.dialect.name == "sqlite",
            compare_type=True,
        )
        with context.begin_transaction():
            context.run_migrations()
        connection.commit()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
