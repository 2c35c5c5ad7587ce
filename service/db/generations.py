"""Generations of a run: the stored per-generation summaries and the Pareto front of the
population kept at a generation (writes: ``service.db.store.record_generation``).
"""

from __future__ import annotations

from typing import Any

from softevo.service.db.individuals import evaluation_fields, objectives
from softevo.service.db.models import EVALUATION_FIELDS, Evaluation, Generation, Individual, PopulationMember
from softevo.service.db.rows import dict_rows
from sqlalchemy import Connection, func, select


def generations(conn: Connection, run_id: int) -> list[dict[str, Any]]:
    """Per-generation statistics of a run (schemas.GenerationOut), oldest first."""
    table = Generation.__table__
    query = (
        select(
            table.c.generation,
            table.c.environment,
            table.c.evaluations,
            table.c.best_distance,
            table.c.mean_distance,
            table.c.front_size,
            table.c.evaluation_seconds,
            table.c.stats,
            table.c.created_at,
        )
        .where(table.c.run_id == run_id)
        .order_by(table.c.generation)
    )
    return dict_rows(conn, query)


def front(conn: Connection, run_id: int, generation: int | None) -> dict[str, Any] | None:
    """The non-dominated members (front rank 0) of the population kept at ``generation``
    (default: the latest stored), each with its latest evaluation up to that generation.
    None if the run has no such generation."""
    members, individuals, evaluations = (
        PopulationMember.__table__,
        Individual.__table__,
        Evaluation.__table__,
    )
    if generation is None:
        generation = conn.execute(
            select(func.max(members.c.generation)).where(members.c.run_id == run_id)
        ).scalar()
        if generation is None:
            return None
    ranked = (
        select(
            evaluations,
            func.row_number()
            .over(partition_by=evaluations.c.individual_id, order_by=evaluations.c.generation.desc())
            .label("n"),
        )
        .where(evaluations.c.run_id == run_id, evaluations.c.generation <= generation)
        .subquery("ranked")
    )
    query = (
        select(
            individuals.c.id,
            individuals.c.local_id,
            individuals.c.parent_id,
            individuals.c.generation_born,
            members.c.age.label("member_age"),
            members.c.front_rank,
            *[ranked.c[name] for name in EVALUATION_FIELDS],
        )
        .join(individuals, members.c.individual_id == individuals.c.id)
        .join(ranked, (ranked.c.individual_id == individuals.c.id) & (ranked.c.n == 1))
        .where(
            members.c.run_id == run_id,
            members.c.generation == generation,
            members.c.front_rank == 0,
        )
        .order_by(ranked.c.distance.desc(), individuals.c.id)
    )
    rows = dict_rows(conn, query)
    exists = conn.execute(
        select(members.c.run_id)
        .where(members.c.run_id == run_id, members.c.generation == generation)
        .limit(1)
    ).first()
    if exists is None:
        return None
    return {
        "run_id": run_id,
        "generation": generation,
        "individuals": [
            {
                "id": row["id"],
                "local_id": row["local_id"],
                "parent_id": row["parent_id"],
                "generation_born": row["generation_born"],
                "age": row["member_age"],
                "front_rank": row["front_rank"],
                "objectives": objectives(row),
                "evaluation": evaluation_fields(row),
            }
            for row in rows
        ],
    }
