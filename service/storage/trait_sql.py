"""Every trait of the registry (``evolution.traits``) as SQL over the evaluations table: its
column where it has one, else its value in the evaluation's ``descriptors`` JSON (SQLite's
``json_extract``, PostgreSQL's ``->>``). The registry is read when a query is built, so a
trait registered after import is followed like a built-in one."""

from __future__ import annotations

from collections.abc import Iterable

from sqlalchemy import ColumnElement
from sqlalchemy.sql import FromClause

from softevo.evolution import traits
from softevo.service.storage.models import EvaluationRow


def trait_value(name: str, evaluations: FromClause | None = None) -> ColumnElement:
    """Trait ``name`` of each row of ``evaluations`` (the evaluations table or an alias of it,
    by default the table), labelled ``name``: its column, or a float read from
    ``descriptors`` (NULL where the evaluation has none). KeyError naming the choices for a
    trait not registered."""
    table = EvaluationRow.__table__ if evaluations is None else evaluations
    if traits.get(name).column:
        return table.c[name].label(name)
    return table.c.descriptors[name].as_float().label(name)


def trait_values(
    names: Iterable[str] | None = None, evaluations: FromClause | None = None
) -> list[ColumnElement]:
    """``trait_value`` of each of ``names`` (default: every registered trait), in order."""
    return [trait_value(name, evaluations) for name in (traits.names() if names is None else names)]
