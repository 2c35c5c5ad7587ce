"""Fixtures: a migrated database on SQLite (a temporary file) and, when
``SOFTEVO_TEST_POSTGRES`` names a server, the same tests on PostgreSQL."""

from __future__ import annotations

import os

import pytest
from sqlalchemy import Engine, text

from softevo.service.storage import open_database
from softevo.service.storage.models import Base

POSTGRES_URL = os.environ.get("SOFTEVO_TEST_POSTGRES")
BACKENDS = [
    "sqlite",
    pytest.param(
        "postgresql",
        marks=[
            pytest.mark.postgres,
            pytest.mark.skipif(not POSTGRES_URL, reason="SOFTEVO_TEST_POSTGRES is not set"),
        ],
    ),
]


def _reset_postgres(url: str) -> None:
    from softevo.service.storage import make_engine

    engine = make_engine(url)
    with engine.begin() as conn:
        Base.metadata.drop_all(conn)
        conn.execute(text("DROP TABLE IF EXISTS alembic_version"))
    engine.dispose()


@pytest.fixture(params=BACKENDS)
def db_url(request, tmp_path) -> str:
    """URL of an empty database (SQLite file, or a wiped PostgreSQL database)."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'softevo.db'}"
    _reset_postgres(POSTGRES_URL)
    return POSTGRES_URL


@pytest.fixture
def engine(db_url) -> Engine:
    """A migrated engine, disposed after the test."""
    engine = open_database(db_url)
    yield engine
    engine.dispose()
