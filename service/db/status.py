"""Read models for status displays and the REST layer: run summaries and lineage records."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from sqlalchemy import Engine, func, select

from softevo.errors import UserError
from softevo.service.db.models import Experiment, Generation, Run, Treatment
from softevo.service.db.phylogeny import ancestors


def run_summary_select(id_label: str = "run_id"):
    """SELECT of every run's summary, ordered by id: ``id_label`` (the run id),
    experiment_id, experiment, treatment, repetition, seed, status, generation (last
    committed), generations, best_distance (best ever, None before any). Add ``.where``."""
    runs, treatments, experiments = Run.__table__, Treatment.__table__, Experiment.__table__
    generations = Generation.__table__
    best = (
        select(generations.c.run_id, func.max(generations.c.best_distance).label("best_distance"))
        .group_by(generations.c.run_id)
        .subquery("best")
    )
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
            best.c.best_distance,
        )
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .join(experiments, treatments.c.experiment_id == experiments.c.id)
        .outerjoin(best, best.c.run_id == runs.c.id)
        .order_by(runs.c.id)
    )


def run_summaries(engine: Engine, run_ids: Sequence[int]) -> list[dict[str, Any]]:
    """Per run, the columns of ``run_summary_select`` for the runs ``run_ids``."""
    query = run_summary_select().where(Run.__table__.c.id.in_(list(run_ids)))
    with engine.connect() as conn:
        return [dict(row) for row in conn.execute(query).mappings()]


def lineage_records(engine: Engine, individual_id: int) -> list[dict[str, Any]]:
    """Ancestors newest first as plain dicts (SPEC.md section 6, /individuals/{id}/lineage)."""
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
