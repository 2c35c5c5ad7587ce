"""Individuals: one individual with its evaluations (for the API), its record for
re-simulation (``individual_record``: the one record ``analysis.robots.stored_task`` turns
into the task of an evaluation), the run it belongs to, and the map from an algorithm's local
ids to database ids.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import pandas as pd
from sqlalchemy import Connection, Engine, select

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.evolution.treatments import Treatment
from softevo.service.storage.export import with_registered_traits
from softevo.service.storage.models import (
    EVALUATION_FIELDS,
    EvaluationRow,
    IndividualRow,
    RunRow,
    TreatmentRow,
)
from softevo.service.storage.rows import dict_rows
from softevo.service.storage.runs import run_row

PAPER_COLUMNS = ("distance", "active_share", "voxel_count")  # objectives stored as columns too


def individual_run_id(conn: Connection, individual_id: int) -> int | None:
    """The run of an individual, or None if there is no such individual."""
    table = IndividualRow.__table__
    return conn.execute(select(table.c.run_id).where(table.c.id == individual_id)).scalar()


def local_to_db_ids(conn: Connection, run_id: int, local_ids: Iterable[int]) -> dict[int, int]:
    """Map the algorithm's local ids of a run to database ids (missing ones are left out)."""
    wanted = sorted(set(local_ids))
    if not wanted:
        return {}
    table = IndividualRow.__table__
    rows = conn.execute(
        select(table.c.local_id, table.c.id).where(table.c.run_id == run_id, table.c.local_id.in_(wanted))
    )
    return {local: db_id for local, db_id in rows}


def evaluation_fields(row: dict[str, Any]) -> dict[str, Any]:
    """The ``EVALUATION_FIELDS`` of a row and its ``traits`` (``trait_values``)."""
    fields = {name: row[name] for name in EVALUATION_FIELDS}
    return {**fields, "traits": trait_values(fields)}


def objectives(evaluation: dict[str, Any]) -> dict[str, Any]:
    """The objectives of an evaluation row, {name: value}: the paper's three columns, then
    every other objective its run selected on (its ``objectives`` JSON)."""
    columns = {name: evaluation[name] for name in PAPER_COLUMNS}
    stored = evaluation.get("objectives") or {}
    return {**columns, **{name: value for name, value in stored.items() if name not in columns}}


def evaluations_of(conn: Connection, individual_id: int) -> list[dict[str, Any]]:
    """Every evaluation of an individual, oldest first, each with ``traits``: {name: value}
    of every trait (``evolution.traits``; the registered ones from its ``descriptors``)."""
    table = EvaluationRow.__table__
    query = (
        select(*[table.c[name] for name in EVALUATION_FIELDS])
        .where(table.c.individual_id == individual_id)
        .order_by(table.c.generation, table.c.id)
    )
    return [evaluation_fields(row) for row in dict_rows(conn, query)]


def trait_values(evaluation: dict[str, Any]) -> dict[str, float | None]:
    """{name: value} of every trait of an evaluation row: its column, or its ``descriptors``."""
    stored = evaluation.get("descriptors") or {}
    return {name: evaluation[name] if name in evaluation else stored.get(name) for name in traits.names()}


def individual(conn: Connection, individual_id: int) -> dict[str, Any] | None:
    """One individual (schemas.IndividualOut) or None."""
    table = IndividualRow.__table__
    rows = dict_rows(
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
    row["objectives"] = objectives(latest) if latest else None
    row["descriptors"] = latest["descriptors"] if latest else None
    return row


def individual_record(engine: Engine, individual_id: int) -> dict[str, Any]:
    """The stored individual (id, run_id, genome, generation_born, ...), its run's treatment
    (``evolution.treatments.Treatment``) and seed, and its evaluations (a DataFrame, oldest
    first). UserError if there is no such individual."""
    table = IndividualRow.__table__
    with engine.connect() as conn:
        row = conn.execute(select(table).where(table.c.id == int(individual_id))).mappings().first()
        if row is None:
            raise UserError(f"no individual {individual_id}")
        run = run_row(conn, row["run_id"])
        evaluations = evaluation_frame(conn, int(individual_id))
    return {
        **dict(row),
        "treatment": Treatment.from_settings(run["settings"]),
        "treatment_name": run["treatment"],
        "experiment": run["experiment"],
        "seed": run["seed"],
        "repetition": run["repetition"],
        "evaluations": evaluations,
    }


def stored_genomes(conn: Connection, individual_ids: Iterable[int]) -> dict[int, tuple[dict, Treatment]]:
    """(genome, treatment) of many stored individuals in one query; unknown ids are left
    out."""
    ids = sorted({int(i) for i in individual_ids})
    if not ids:
        return {}
    individuals, runs, treatments = IndividualRow.__table__, RunRow.__table__, TreatmentRow.__table__
    query = (
        select(individuals.c.id, individuals.c.genome, treatments.c.settings)
        .join(runs, individuals.c.run_id == runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(individuals.c.id.in_(ids))
    )
    rows = conn.execute(query)
    return {int(i): (genome, Treatment.from_settings(settings)) for i, genome, settings in rows}


def evaluation_frame(conn: Connection, individual_id: int) -> pd.DataFrame:
    """An individual's evaluations as a DataFrame, oldest first (as ``evaluations_of``)."""
    table = EvaluationRow.__table__
    columns = ["generation", "age", "environment", "stiffness", *traits.columns(), "stable", "error",
               "descriptors"]
    result = conn.execute(
        select(*[table.c[name] for name in columns])
        .where(table.c.individual_id == individual_id)
        .order_by(table.c.generation, table.c.id)
    )
    return with_registered_traits(pd.DataFrame(result.fetchall(), columns=columns))
