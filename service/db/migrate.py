"""Run Alembic migrations programmatically.

The migration scripts live in the ``softevo.migrations`` package, installed with the
project (``env.py``, ``script.py.mako`` and ``versions/*.py`` are package files), so an
installed coordinator finds them where that package is installed rather than by a path
relative to the working directory. The package is located, not imported: its ``env.py``
imports ``service.db.models``, and runs only under Alembic.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine


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


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Upgrade the schema of ``engine``'s database to ``revision``."""
    command.upgrade(alembic_config(engine), revision)
