"""Read queries of the REST API: SQLAlchemy core over the models, bound parameters only.

Each function takes an open connection and returns plain dicts shaped like the response
schemas (``service.api.schemas``); ``None`` (or an empty list) where nothing matches, so the
routes decide about 404s. Floats that are not finite (NaN, inf) become None: JSON has no
such numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

from softevo.service.db.models import (
    EVALUATION_FIELDS,
    Evaluation,
    Experiment,
    Generation,
    Individual,
    PopulationMember,
    Run,
    RunStatus,
    Treatment,
)
from softevo.service.db.status import run_summary_select
from sqlalchemy import Connection, func, select

EVALUATION_COLUMNS = EVALUATION_FIELDS
STATUS_PRECEDENCE = ("running", "pending", "failed", "cancelled", "finished")


def finite(value: Any) -> Any:
    """``value`` with every non-finite float (also inside dicts and lists) replaced by None,
    and times without a zone (SQLite keeps UTC without it) marked UTC."""
    if isinstance(value, datetime) and value.tzinfo is None:
        return value.replace(tzinfo=UTC)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [finite(item) for item in value]
    return value


def _rows(conn: Connection, query) -> list[dict[str, Any]]:
    return [finite(dict(row)) for row in conn.execute(query).mappings()]


# -- runs ----------------------------------------------------------------------------------


def list_runs(
    conn: Connection,
    experiment_id: int | None = None,
    status: str | None = None,
    limit: int = 1000,
    offset: int = 0,
) -> list[dict[str, Any]]:
    """Run summaries (schemas.RunSummary), optionally of one experiment and/or one status."""
    query = run_summary_select(id_label="id")
    if experiment_id is not None:
        query = query.where(Treatment.__table__.c.experiment_id == experiment_id)
    if status is not None:
        query = query.where(Run.__table__.c.status == status)
    return _rows(conn, query.limit(limit).offset(offset))


def run_detail(conn: Connection, run_id: int) -> dict[str, Any] | None:
    """One run (schemas.RunOut) or None."""
    runs, treatments = Run.__table__, Treatment.__table__
    query = (
        select(
            runs.c.id,
            treatments.c.experiment_id,
            runs.c.status,
            runs.c.generation,
            runs.c.generations,
            runs.c.repetition,
            runs.c.seed,
            treatments.c.name.label("treatment_name"),
            treatments.c.settings,
            runs.c.error,
            runs.c.created_at,
            runs.c.updated_at,
        )
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(runs.c.id == run_id)
    )
    rows = _rows(conn, query)
    if not rows:
        return None
    row = rows[0]
    row["treatment"] = {"name": row.pop("treatment_name"), "settings": row.pop("settings")}
    row["best"] = best_of_run(conn, run_id)
    return row


def best_of_run(conn: Connection, run_id: int) -> dict[str, Any] | None:
    """The evaluation with the greatest distance in the run (first stored on a tie)."""
    evaluations = Evaluation.__table__
    query = (
        select(
            evaluations.c.individual_id,
            evaluations.c.generation,
            evaluations.c.environment,
            evaluations.c.distance,
            evaluations.c.active_share,
            evaluations.c.voxel_count,
        )
        .where(evaluations.c.run_id == run_id)
        .order_by(evaluations.c.distance.desc(), evaluations.c.id)
        .limit(1)
    )
    rows = _rows(conn, query)
    return rows[0] if rows else None


def run_status(conn: Connection, run_id: int) -> str | None:
    """The run's status, or None if there is no such run."""
    table = Run.__table__
    return conn.execute(select(table.c.status).where(table.c.id == run_id)).scalar()


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
    return _rows(conn, query)


# -- experiments ---------------------------------------------------------------------------


def experiment_status(statuses: Sequence[str]) -> str:
    """An experiment's status from its runs' (see schemas.ExperimentOut.status)."""
    for status in STATUS_PRECEDENCE:
        if status in statuses:
            return status
    return RunStatus.PENDING.value


def list_experiments(
    conn: Connection, experiment_id: int | None = None, limit: int = 1000, offset: int = 0
) -> list[dict[str, Any]]:
    """Experiments (schemas.ExperimentOut) with their runs and progress, oldest first."""
    table = Experiment.__table__
    query = select(table.c.id, table.c.name, table.c.preset, table.c.scale, table.c.created_at)
    if experiment_id is not None:
        query = query.where(table.c.id == experiment_id)
    experiments = _rows(conn, query.order_by(table.c.id).limit(limit).offset(offset))
    if not experiments:
        return []
    runs_query = run_summary_select(id_label="id").where(
        Treatment.__table__.c.experiment_id.in_([e["id"] for e in experiments])
    )
    runs_of: dict[int, list[dict[str, Any]]] = {}
    for run in _rows(conn, runs_query):
        runs_of.setdefault(run["experiment_id"], []).append(run)
    for experiment in experiments:
        runs = runs_of.get(experiment["id"], [])
        done = sum(max(0, run["generation"] + 1) for run in runs)
        total = sum(run["generations"] for run in runs)
        experiment["runs"] = runs
        experiment["status"] = experiment_status([run["status"] for run in runs])
        experiment["progress"] = {
            "generations_done": done,
            "generations_total": total,
            "fraction": done / total if total else 0.0,
        }
    return experiments


def experiment_exists(conn: Connection, experiment_id: int) -> bool:
    table = Experiment.__table__
    return conn.execute(select(table.c.id).where(table.c.id == experiment_id)).first() is not None


def experiment_generations(conn: Connection, experiment_id: int) -> int:
    """Generations stored over all runs of the experiment."""
    generations, runs, treatments = Generation.__table__, Run.__table__, Treatment.__table__
    return conn.execute(
        select(func.count())
        .select_from(generations)
        .join(runs, generations.c.run_id == runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
    ).scalar_one()


def experiment_updated_at(conn: Connection, experiment_id: int):
    """When a run of the experiment last changed (None without runs)."""
    runs, treatments = Run.__table__, Treatment.__table__
    return conn.execute(
        select(func.max(runs.c.updated_at))
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
    ).scalar()


# -- individuals ---------------------------------------------------------------------------


def _evaluation_fields(row: dict[str, Any]) -> dict[str, Any]:
    return {name: row[name] for name in EVALUATION_COLUMNS}


def _objectives(evaluation: dict[str, Any]) -> dict[str, Any]:
    return {
        "distance": evaluation["distance"],
        "active_share": evaluation["active_share"],
        "voxel_count": evaluation["voxel_count"],
    }


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
            *[ranked.c[name] for name in EVALUATION_COLUMNS],
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
    rows = _rows(conn, query)
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
                "objectives": _objectives(row),
                "evaluation": _evaluation_fields(row),
            }
            for row in rows
        ],
    }


def evaluations_of(conn: Connection, individual_id: int) -> list[dict[str, Any]]:
    """Every evaluation of an individual, oldest first."""
    table = Evaluation.__table__
    query = (
        select(*[table.c[name] for name in EVALUATION_COLUMNS])
        .where(table.c.individual_id == individual_id)
        .order_by(table.c.generation, table.c.id)
    )
    return _rows(conn, query)


def individual(conn: Connection, individual_id: int) -> dict[str, Any] | None:
    """One individual (schemas.IndividualOut) or None."""
    table = Individual.__table__
    rows = _rows(
        conn,
        select(
            table.c.id,
            table.c.run_id,
            table.c.local_id,
            table.c.parent_id,
            table.c.generation_born,
            table.c.genome,
            table.c.phenotype,
        ).where(table.c.id == individual_id),
    )
    if not rows:
        return None
    row = rows[0]
    row["evaluations"] = evaluations_of(conn, individual_id)
    latest = row["evaluations"][-1] if row["evaluations"] else None
    row["objectives"] = _objectives(latest) if latest else None
    row["descriptors"] = latest["descriptors"] if latest else None
    return row


def individual_context(conn: Connection, individual_id: int) -> dict[str, Any] | None:
    """What re-simulating an individual needs: genome, its run's treatment settings and seed,
    and its evaluations (environment, stiffness). None if there is no such individual."""
    individuals, runs, treatments = Individual.__table__, Run.__table__, Treatment.__table__
    rows = _rows(
        conn,
        select(individuals.c.id, individuals.c.genome, treatments.c.settings, runs.c.seed)
        .join(runs, individuals.c.run_id == runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(individuals.c.id == individual_id),
    )
    if not rows:
        return None
    row = rows[0]
    row["evaluations"] = evaluations_of(conn, individual_id)
    return row
