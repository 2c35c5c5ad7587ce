"""Phylogeny queries: recursive CTEs over ``individuals.parent_id``, returned as DataFrames.

All queries are SQLAlchemy core with bound parameters and run unchanged on SQLite and
PostgreSQL. An individual's traits (every trait of ``evolution.traits``, the registered ones
read from ``descriptors``: ``service.storage.trait_sql``) come from one of its evaluations:
``which="birth"`` (the default) takes its first evaluation (the one that selected it),
``which="latest"`` its last (after an environment switch, the one in the new world).
"""

from __future__ import annotations

from typing import Literal

import pandas as pd
from sqlalchemy import Connection, Engine, and_, func, literal, select

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.evolution.treatments import Treatment
from softevo.service.storage.models import (
    EvaluationRow,
    IndividualRow,
    PopulationMemberRow,
    RunRow,
    TreatmentRow,
)
from softevo.service.storage.trait_sql import trait_values

Which = Literal["birth", "latest"]
_CHOSEN = ("generation", "environment", "stiffness", "age")  # then every trait, stable, error


def _chosen_columns() -> tuple[str, ...]:
    """The columns an individual's chosen evaluation gives: ``_CHOSEN``, every
    registered trait (read when called), ``stable`` and ``error``."""
    return (*_CHOSEN, *traits.names(), "stable", "error")


def _frame(bind: Connection | Engine, query) -> pd.DataFrame:
    """Run ``query`` and return its rows as a DataFrame (columns kept when empty)."""
    if isinstance(bind, Engine):
        with bind.connect() as conn:
            return _frame(conn, query)
    result = bind.execute(query)
    frame = pd.DataFrame(result.fetchall(), columns=list(result.keys()))
    for column in ("parent_id", "last_generation"):
        if column in frame.columns:
            frame[column] = frame[column].astype("Int64")
    return frame


def _chosen_evaluation(which: Which):
    """Subquery: one evaluation per individual (its first or its last)."""
    evaluations = EvaluationRow.__table__
    order = evaluations.c.generation.asc() if which == "birth" else evaluations.c.generation.desc()
    plain = ("individual_id", *_CHOSEN, "stable", "error")
    ranked = select(
        *[evaluations.c[name] for name in plain],
        *trait_values(),
        func.row_number().over(partition_by=evaluations.c.individual_id, order_by=order).label("n"),
    ).subquery("ranked")
    return (
        select(*[ranked.c[name] for name in ("individual_id", *_chosen_columns())])
        .where(ranked.c.n == 1)
        .subquery("chosen")
    )


def _ancestor_cte(individual_id: int):
    """Recursive CTE: the individual (depth 0), its parent (depth 1), ... to the root."""
    individuals = IndividualRow.__table__
    anchor = select(
        individuals.c.id,
        individuals.c.parent_id,
        individuals.c.run_id,
        individuals.c.generation_born,
        literal(0).label("depth"),
    ).where(individuals.c.id == individual_id)
    cte = anchor.cte("ancestors", recursive=True)
    step = select(
        individuals.c.id,
        individuals.c.parent_id,
        individuals.c.run_id,
        individuals.c.generation_born,
        (cte.c.depth + 1).label("depth"),
    ).join(cte, individuals.c.id == cte.c.parent_id)
    return cte.union_all(step)


def ancestors(bind: Connection | Engine, individual_id: int, which: Which = "birth") -> pd.DataFrame:
    """The individual and its ancestors, newest first, to its root newcomer.

    Columns: depth (0 = the individual), id, parent_id, run_id, generation_born, and the
    chosen evaluation's generation, environment, stiffness, age, every trait
    (``evolution.traits.names()``), stable and error. Empty if the id is unknown.
    """
    cte = _ancestor_cte(individual_id)
    chosen = _chosen_evaluation(which)
    query = (
        select(
            cte.c.depth,
            cte.c.id,
            cte.c.parent_id,
            cte.c.run_id,
            cte.c.generation_born,
            *[chosen.c[name] for name in _chosen_columns()],
        )
        .outerjoin(chosen, chosen.c.individual_id == cte.c.id)
        .order_by(cte.c.depth)
    )
    return _frame(bind, query)


def switch_generation(bind: Connection | Engine, run_id: int) -> int | None:
    """The generation at which run ``run_id`` changes environment (None if it never does)."""
    query = (
        select(TreatmentRow.__table__.c.settings)
        .join(RunRow.__table__, RunRow.__table__.c.treatment_id == TreatmentRow.__table__.c.id)
        .where(RunRow.__table__.c.id == run_id)
    )
    frame = _frame(bind, query)
    if frame.empty:
        raise UserError(f"no run {run_id}")
    return Treatment.from_settings(frame.iloc[0]["settings"]).switch_generation()


def population_lines(run_id: int, generation: int, label: str, down: bool):
    """A recursive CTE of every member of the population kept at ``generation`` (its id in
    column ``label``) with all its descendants (``down``) or all its ancestors: label, id,
    parent_id, generation_born, depth (0 = the member)."""
    ind, pm = IndividualRow.__table__, PopulationMemberRow.__table__
    anchor = (
        select(
            ind.c.id.label(label), ind.c.id, ind.c.parent_id, ind.c.generation_born, literal(0).label("depth")
        )
        .join(pm, pm.c.individual_id == ind.c.id)
        .where(pm.c.run_id == run_id, pm.c.generation == generation)
    )
    cte = anchor.cte("line", recursive=True)
    link = ind.c.parent_id == cte.c.id if down else ind.c.id == cte.c.parent_id
    step = select(
        cte.c[label], ind.c.id, ind.c.parent_id, ind.c.generation_born, (cte.c.depth + 1).label("depth")
    ).join(cte, link)
    return cte.union_all(step)


def transition_lineages(bind: Connection | Engine, run_id: int, switch_at: int | None = None) -> pd.DataFrame:
    """Descendants of the individuals alive when the environment switched.

    ``switch_at`` is the first generation in the new environment (default: from the run's
    treatment); the founders are the population kept at ``switch_at - 1``, which was moved
    and re-evaluated. Columns: founder_id, id, parent_id, generation_born, depth (0 = the
    founder), last_generation (the last generation whose population held it; NaN if never
    kept). Empty when the run has no transition.
    """
    if switch_at is None:
        switch_at = switch_generation(bind, run_id)
        if switch_at is None:
            return pd.DataFrame(
                columns=[
                    "founder_id",
                    "id",
                    "parent_id",
                    "generation_born",
                    "depth",
                    "last_generation",
                ]
            )
    members = PopulationMemberRow.__table__
    cte = population_lines(run_id, switch_at - 1, "founder_id", down=True)
    last = (
        select(members.c.individual_id, func.max(members.c.generation).label("last_generation"))
        .where(members.c.run_id == run_id)
        .group_by(members.c.individual_id)
        .subquery("last_kept")
    )
    query = (
        select(cte, last.c.last_generation)
        .outerjoin(last, last.c.individual_id == cte.c.id)
        .order_by(cte.c.founder_id, cte.c.depth, cte.c.id)
    )
    return _frame(bind, query)


def trait_changes(
    bind: Connection | Engine,
    individual_id: int,
    trait: str = "active_share",
    which: Which = "birth",
) -> pd.DataFrame:
    """Where ``trait`` changed along the line from the root newcomer to the individual.

    Rows, oldest first, of ancestors whose trait differs from their parent's. Columns: id,
    parent_id, generation_born, environment, previous, value. ``trait`` is any registered
    trait (``evolution.traits.names()``).
    """
    if trait not in traits.names():
        raise UserError(f"unknown trait {trait!r}; choose one of {', '.join(traits.names())}")
    cte = _ancestor_cte(individual_id)
    chosen = _chosen_evaluation(which)
    value = chosen.c[trait]
    line = (
        select(
            cte.c.id,
            cte.c.parent_id,
            cte.c.generation_born,
            cte.c.depth,
            chosen.c.environment,
            value.label("value"),
            func.lag(value).over(order_by=cte.c.depth.desc()).label("previous"),
        )
        .outerjoin(chosen, chosen.c.individual_id == cte.c.id)
        .subquery("line")
    )
    query = (
        select(
            line.c.id,
            line.c.parent_id,
            line.c.generation_born,
            line.c.environment,
            line.c.previous,
            line.c.value,
        )
        .where(and_(line.c.parent_id.is_not(None), line.c.previous != line.c.value))
        .order_by(line.c.depth.desc())
    )
    return _frame(bind, query)


def first_trait_change(
    bind: Connection | Engine, individual_id: int, trait: str = "active_share"
) -> int | None:
    """The first generation (of birth) at which ``trait`` changed along the individual's line."""
    changes = trait_changes(bind, individual_id, trait)
    return None if changes.empty else int(changes.iloc[0]["generation_born"])
