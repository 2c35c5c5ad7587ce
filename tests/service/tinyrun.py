"""Helpers for tests on real (tiny) runs: create, run inline, and snapshot a run's results."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, select

from softevo.evolution.treatments import Treatment
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import Executor, InlineExecutor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from softevo.service.storage.models import EvaluationRow, IndividualRow, PopulationMemberRow, RunRow
from tests.service.rq_support import Processes, service_env

TINY = Treatment(
    "land-water",
    0.1,
    population=4,
    generations=5,
    workspace=(4, 4, 4),
    cycles=2,
    switch_at=3,
    seed=11,
)


# what a snapshot compares of each evaluation (not its ids or timings)
SNAPSHOT_EVALUATION = (
    "generation", "environment", "age", "distance", "active_share", "voxel_count", "symmetry", "stable",
    "error",
)  # fmt: skip


def new_run(engine: Engine, treatment: Treatment = TINY) -> int:
    _, (run_id,) = create(engine, "test", [treatment])
    return run_id


def run_to_end(engine: Engine, run_id: int, executor: Executor | None = None) -> None:
    Coordinator(engine, executor or InlineExecutor()).run([run_id])


@contextmanager
def served(folder: Path, treatment: Treatment, **env: str) -> Iterator[tuple[Engine, str, int, str]]:
    """A finished tiny run of ``treatment`` in SQLite under ``folder`` and ``softevo serve`` on
    it (no coordinator; ``env``: more of the server's environment). Yields the engine, the
    database URL, the run's id and the server's base URL."""
    url = f"sqlite:///{folder / 'served.db'}"
    engine = open_database(url)
    run_id = new_run(engine, treatment)
    run_to_end(engine, run_id)
    group = Processes(folder, service_env(url, None, SOFTEVO_COORDINATOR="false", **env))
    try:
        _, base = group.serve()
        yield engine, url, run_id, base
    finally:
        group.stop_all()
        engine.dispose()


def stored(folder: Path, name: str, finished: bool = True) -> tuple[str, int]:
    """A SQLite database ``folder/name.db`` holding one tiny run, run to its end unless
    ``finished`` is false (then pending): (database URL, run id)."""
    url = f"sqlite:///{folder / f'{name}.db'}"
    engine = open_database(url)
    run_id = new_run(engine)
    if finished:
        run_to_end(engine, run_id)
    engine.dispose()
    return url, run_id


def reference_snapshot(folder: Path, treatment: Treatment = TINY) -> dict[str, Any]:
    """The snapshot of an undisturbed run of ``treatment`` (SQLite in ``folder``, this
    process): what an interrupted run must equal."""
    engine = open_database(f"sqlite:///{folder / 'ref.db'}")
    run_id = new_run(engine, treatment)
    run_to_end(engine, run_id)
    snap = snapshot(engine, run_id)
    engine.dispose()
    return snap


def snapshot(engine: Engine, run_id: int) -> dict[str, Any]:
    """Everything a run stored, keyed by the algorithm's local ids (comparable across DBs)."""
    ind, ev, pm = IndividualRow.__table__, EvaluationRow.__table__, PopulationMemberRow.__table__
    parent = ind.alias("parent")
    with engine.connect() as conn:
        individuals = conn.execute(
            select(ind.c.local_id, parent.c.local_id, ind.c.generation_born, ind.c.genome)
            .outerjoin(parent, ind.c.parent_id == parent.c.id)
            .where(ind.c.run_id == run_id)
            .order_by(ind.c.local_id)
        ).all()
        evaluations = conn.execute(
            select(ind.c.local_id, *(ev.c[name] for name in SNAPSHOT_EVALUATION))
            .join(ind, ev.c.individual_id == ind.c.id)
            .where(ev.c.run_id == run_id)
            .order_by(ev.c.generation, ind.c.local_id)
        ).all()
        members = conn.execute(
            select(pm.c.generation, ind.c.local_id, pm.c.front_rank, pm.c.age)
            .join(ind, pm.c.individual_id == ind.c.id)
            .where(pm.c.run_id == run_id)
            .order_by(pm.c.generation, ind.c.local_id)
        ).all()
        runs = RunRow.__table__
        run = conn.execute(
            select(runs.c.status, runs.c.generation, runs.c.algorithm_state).where(runs.c.id == run_id)
        ).one()
    return {
        "individuals": [tuple(r) for r in individuals],
        "evaluations": [tuple(r) for r in evaluations],
        "members": [tuple(r) for r in members],
        "run": tuple(run),
    }
