"""Read models for status displays and the REST layer: run summaries and lineage records."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from sqlalchemy import Connection, Engine, and_, func, select

from softevo.errors import UserError
from softevo.service.storage.models import ExperimentRow, GenerationRow, RunRow, TreatmentRow
from softevo.service.storage.phylogeny import ancestors
from softevo.service.storage.rows import dict_rows


def run_summary_select(id_label: str = "run_id"):
    """SELECT of every run's summary, ordered by id: ``id_label`` (the run id),
    experiment_id, experiment, treatment, repetition, seed, status, generation (last
    committed), generations, environment and best_distance of the last committed generation
    (None before any). Add ``.where``; ``with_best_by_world`` adds the best per world.

    The best at the last generation, not the best ever: a land -> water run's land walkers of
    generation 0 would otherwise stand for its water robots."""
    runs, treatments, experiments = RunRow.__table__, TreatmentRow.__table__, ExperimentRow.__table__
    last = GenerationRow.__table__.alias("last")
    return (
        select(
            runs.c.id.label(id_label),
            treatments.c.experiment_id,
            experiments.c.name.label("experiment"),
            treatments.c.name.label("treatment"),
            runs.c.repetition,
            runs.c.seed,
            runs.c.status,
            runs.c.generation,
            runs.c.generations,
            last.c.environment,
            last.c.best_distance,
        )
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .join(experiments, treatments.c.experiment_id == experiments.c.id)
        .outerjoin(last, and_(last.c.run_id == runs.c.id, last.c.generation == runs.c.generation))
        .order_by(runs.c.id)
    )


def best_by_world(conn: Connection, run_ids: Sequence[int]) -> dict[int, dict[str, float]]:
    """Per run of ``run_ids``: {world: best distance of any generation evaluated in it}, the
    worlds in the order the run first met them (a gradual switch's compound worlds too)."""
    generations = GenerationRow.__table__
    query = (
        select(
            generations.c.run_id,
            generations.c.environment,
            func.max(generations.c.best_distance).label("best"),
            func.min(generations.c.generation).label("first"),
        )
        .where(generations.c.run_id.in_(list(run_ids)))
        .group_by(generations.c.run_id, generations.c.environment)
        .order_by(generations.c.run_id, "first")
    )
    worlds: dict[int, dict[str, float]] = {run_id: {} for run_id in run_ids}
    for row in dict_rows(conn, query):
        worlds[row["run_id"]][row["environment"]] = row["best"]
    return worlds


def with_best_by_world(
    conn: Connection, rows: list[dict[str, Any]], id_key: str = "id"
) -> list[dict[str, Any]]:
    """``rows`` (of ``run_summary_select``), each with ``best_per_world`` added (a list, the
    worlds in the order the run met them: ``[{"environment", "distance"}]``, the keys of
    ``GET /runs/{id}``'s) and ``best_by_world`` (the same as {world: distance}, kept for
    clients written before issue 59; docs/contracts.md)."""
    worlds = best_by_world(conn, [row[id_key] for row in rows]) if rows else {}
    for row in rows:
        row["best_by_world"] = worlds[row[id_key]]
        row["best_per_world"] = [{"environment": world, "distance": distance}
                                 for world, distance in worlds[row[id_key]].items()]
    return rows


def run_summaries(engine: Engine, run_ids: Sequence[int]) -> list[dict[str, Any]]:
    """Per run, the columns of ``run_summary_select``, its ``error`` (why it failed) and
    ``best_by_world`` for ``run_ids``."""
    runs = RunRow.__table__
    query = run_summary_select().add_columns(runs.c.error).where(runs.c.id.in_(list(run_ids)))
    with engine.connect() as conn:
        return with_best_by_world(conn, dict_rows(conn, query), "run_id")


def lineage_records(engine: Engine, individual_id: int) -> list[dict[str, Any]]:
    """Ancestors newest first as plain dicts (docs/spec.md section 6, /individuals/{id}/lineage)."""
    frame = ancestors(engine, individual_id)
    if frame.empty:
        raise UserError(f"no individual {individual_id}")
    records = frame.astype(object).where(frame.notna(), None).to_dict(orient="records")
    return [{key: _plain(value) for key, value in record.items()} for record in records]


def _plain(value: Any) -> Any:
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
