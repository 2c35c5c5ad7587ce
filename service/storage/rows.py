"""Result rows as plain JSON-ready dicts: the read functions of the noun modules use these.

Floats that are not finite (NaN, inf) become None (JSON has no such numbers) and times
without a zone (SQLite keeps UTC without it) are marked UTC.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Connection


def finite(value: Any) -> Any:
    """``value`` with every non-finite float (also inside dicts and lists) replaced by None,
    and times without a zone marked UTC."""
    if isinstance(value, datetime) and value.tzinfo is None:
        return value.replace(tzinfo=UTC)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [finite(item) for item in value]
    return value


def columns(table, *names: str) -> list:
    """The columns of ``table`` named ``names``, in that order (for ``select(*columns(...))``)."""
    return [table.c[name] for name in names]


def dict_rows(conn: Connection, query) -> list[dict[str, Any]]:
    """Every row of ``query`` as a ``finite`` dict."""
    return [finite(dict(row)) for row in conn.execute(query).mappings()]
