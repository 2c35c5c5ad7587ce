"""One stored evaluation in a database made at an older migration (its tables reflected, not
the current models): what the migration tests upgrade."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import sqlalchemy as sa


def store_one_evaluation(engine: sa.Engine, **evaluation: Any) -> sa.MetaData:
    """An experiment, treatment, run and individual, and one evaluation of the individual
    (``evaluation`` adds columns the old schema has); the reflected tables."""
    meta = sa.MetaData()
    meta.reflect(engine)
    now, t = datetime.now(UTC), meta.tables
    with engine.begin() as conn:
        conn.execute(t["experiments"].insert().values(id=1, name="old", created_at=now))
        conn.execute(t["treatments"].insert().values(id=1, experiment_id=1, name="land",
                                                     settings={"environment": "land", "stiffness_mpa": 0.1}))
        conn.execute(t["runs"].insert().values(id=1, treatment_id=1, repetition=0, seed=0, status="finished",
                                               generation=0, generations=1, created_at=now, updated_at=now))
        conn.execute(t["individuals"].insert().values(id=1, run_id=1, local_id=0, generation_born=0,
                                                      genome={}))
        conn.execute(t["evaluations"].insert().values(
            id=1, individual_id=1, run_id=1, generation=0, age=0, environment="land", stiffness=1e5,
            distance=2.5, active_share=0.25, voxel_count=12, stable=True, **evaluation))
    return meta
