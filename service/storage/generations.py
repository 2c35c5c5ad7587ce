"""Generations of a run: ``record_generation`` (one transaction stores a generation's
individuals, evaluations, population, summary and algorithm state), the stored
per-generation summaries, and the Pareto front of the population kept at a generation.

Every insert ignores rows already present (unique constraints), so recording the same
generation twice changes nothing: a coordinator killed after its commit but before it
noticed may safely record the generation again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import Connection, Table, case, func, select, update
from sqlalchemy.dialects import postgresql, sqlite

from softevo.errors import UserError
from softevo.evolution.run_status import RunStatus
from softevo.service.storage.individuals import evaluation_fields, local_to_db_ids, objectives
from softevo.service.storage.models import (
    EVALUATION_FIELDS,
    EvaluationRow,
    GenerationRow,
    IndividualRow,
    PopulationMemberRow,
    RunRow,
    utcnow,
)
from softevo.service.storage.rows import columns, dict_rows


@dataclass
class GenerationRecord:
    """Everything one generation adds to a run, keyed by the algorithm's local ids.

    individuals: new ones, dicts with local_id, parent_local_id (None for a newcomer),
        generation_born, genome (JSON), phenotype (JSON or None).
    evaluations: dicts with local_id and the ``EVALUATION_FIELDS``.
    members: the population kept, dicts with local_id, front_rank, age.
    summary: environment, evaluations, best_distance, mean_distance, front_size,
        evaluation_seconds, and anything else (kept in ``stats``).
    state: the algorithm's JSON state after this generation (for resume).
    """

    run_id: int
    generation: int
    individuals: list[dict[str, Any]] = field(default_factory=list)
    evaluations: list[dict[str, Any]] = field(default_factory=list)
    members: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)
    state: dict[str, Any] | None = None
    finished: bool = False
    failure: str | None = None  # why the run fails with this generation (its evaluations failed)


def insert_ignore(conn: Connection, table: Table, rows: Sequence[dict[str, Any]]) -> None:
    """INSERT rows, skipping any that collide with a unique constraint or primary key."""
    if not rows:
        return
    dialect = conn.dialect.name
    if dialect == "sqlite":
        statement = sqlite.insert(table).on_conflict_do_nothing()
    elif dialect == "postgresql":
        statement = postgresql.insert(table).on_conflict_do_nothing()
    else:  # pragma: no cover - only SQLite and PostgreSQL are supported
        raise UserError(f"unsupported database dialect {dialect!r}")
    conn.execute(statement, list(rows))


def record_generation(conn: Connection, record: GenerationRecord) -> None:
    """Store one generation (individuals, evaluations, population, summary, state).

    Call inside one transaction (``with engine.begin() as conn``): either all of the
    generation is stored, or none of it.
    """
    run_id = record.run_id
    parents = [i["parent_local_id"] for i in record.individuals if i["parent_local_id"] is not None]
    parent_ids = local_to_db_ids(conn, run_id, parents)
    insert_ignore(
        conn,
        IndividualRow.__table__,
        [
            {
                "run_id": run_id,
                "local_id": i["local_id"],
                "parent_id": None if i["parent_local_id"] is None else parent_ids[i["parent_local_id"]],
                "generation_born": i["generation_born"],
                "genome": i["genome"],
                "phenotype": i.get("phenotype"),
            }
            for i in record.individuals
        ],
    )
    locals_needed = [e["local_id"] for e in record.evaluations]
    locals_needed += [m["local_id"] for m in record.members]
    ids = local_to_db_ids(conn, run_id, locals_needed)
    insert_ignore(
        conn,
        EvaluationRow.__table__,
        [
            {
                "run_id": run_id,
                "individual_id": ids[e["local_id"]],
                **{k: e.get(k) for k in EVALUATION_FIELDS},
            }
            for e in record.evaluations
        ],
    )
    insert_ignore(
        conn,
        PopulationMemberRow.__table__,
        [
            {
                "run_id": run_id,
                "generation": record.generation,
                "individual_id": ids[m["local_id"]],
                "front_rank": m["front_rank"],
                "age": m.get("age", 0),
            }
            for m in record.members
        ],
    )
    insert_ignore(conn, GenerationRow.__table__, [_generation_row(record)])
    _advance_run(conn, record)


def _generation_row(record: GenerationRecord) -> dict[str, Any]:
    summary = dict(record.summary)
    row = {
        "run_id": record.run_id,
        "generation": record.generation,
        "environment": summary.pop("environment"),
        "evaluations": summary.pop("evaluations", len(record.evaluations)),
        "best_distance": summary.pop("best_distance"),
        "mean_distance": summary.pop("mean_distance"),
        "front_size": summary.pop("front_size"),
        "evaluation_seconds": summary.pop("evaluation_seconds", 0.0),
        "created_at": utcnow(),
    }
    row["stats"] = summary
    return row


def _advance_run(conn: Connection, record: GenerationRecord) -> None:
    """Move the run's committed generation forward (never backward) and store the state;
    a ``failure`` fails the run with it as its error.

    A run cancelled meanwhile (e.g. over HTTP, from another process) stays cancelled."""
    table = RunRow.__table__
    status = RunStatus.FINISHED if record.finished else RunStatus.RUNNING
    failure = {}
    if record.failure is not None:
        status, failure = RunStatus.FAILED, {"error": record.failure}
    cancelled = RunStatus.CANCELLED.value
    conn.execute(
        update(table)
        .where(table.c.id == record.run_id, table.c.generation < record.generation)
        .values(
            generation=record.generation,
            algorithm_state=record.state,
            status=case((table.c.status == cancelled, cancelled), else_=status.value),
            updated_at=utcnow(),
            **failure,
        )
    )


GENERATION_FIELDS = (  # schemas.GenerationOut
    "generation", "environment", "evaluations", "best_distance", "mean_distance", "front_size",
    "evaluation_seconds", "stats", "created_at",
)  # fmt: skip


def generations(conn: Connection, run_id: int) -> list[dict[str, Any]]:
    """Per-generation statistics of a run (schemas.GenerationOut), oldest first."""
    table = GenerationRow.__table__
    query = (
        select(*columns(table, *GENERATION_FIELDS))
        .where(table.c.run_id == run_id)
        .order_by(table.c.generation)
    )
    return dict_rows(conn, query)


def front(conn: Connection, run_id: int, generation: int | None) -> dict[str, Any] | None:
    """The non-dominated members (front rank 0) of the population kept at ``generation``
    (default: the latest stored), each with its latest evaluation up to that generation.
    None if the run has no such generation."""
    members, individuals, evaluations = (
        PopulationMemberRow.__table__,
        IndividualRow.__table__,
        EvaluationRow.__table__,
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
