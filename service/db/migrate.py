"""Run Alembic migrations programmatically.

The migration scripts live in the top-level ``migrations`` package, installed with the
project (``env.py``, ``script.py.mako`` and ``versions/*.py`` are package files), so an
installed coordinator finds them by importing ``migrations`` rather than by a path
relative to the working directory.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine

from softevo import migrations


def script_location() -> Path:
    """Directory of the installed ``migrations`` package."""
    return Path(migrations.__file__).resolve().parent


def alembic_config(engine: Engine) -> Config:
    """Alembic config that runs on ``engine`` (no alembic.ini needed)."""
    config = Config()
    config.set_main_option("script_location", str(script_location()))
    config.attributes["engine"] = engine
    return config


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Upgrade the schema of ``engine``'s database to ``revision``."""
    command.upgrade(alembic_config(engine), revision)
