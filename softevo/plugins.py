"""Extensions a deployment loads into every ``softevo`` process: the modules named in
``SOFTEVO_PLUGINS`` (comma-separated, importable), imported when the command line starts, so
that what they register (a trait: ``evolution.traits.register``; an objective:
``evolution.selection.register_objective``; a world: ``sim.worlds.register``; a treatment
option: ``evolution.options.declare``) is known to the
coordinator, the API, the dashboard and the report alike."""

from __future__ import annotations

import importlib
import os

from softevo.errors import UserError

VARIABLE = "SOFTEVO_PLUGINS"


def load_plugins(value: str | None = None) -> list[str]:
    """Import each module of ``value`` (default ``$SOFTEVO_PLUGINS``); the names imported.
    UserError naming the module for one that cannot be imported."""
    value = os.environ.get(VARIABLE, "") if value is None else value
    names = [name.strip() for name in value.split(",") if name.strip()]
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise UserError(f"{VARIABLE}: cannot import {name!r} ({exc})") from None
    return names
