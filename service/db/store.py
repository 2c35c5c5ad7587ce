"""Writes of experiments and generations, and the run lookups the CLI and coordinator share
(``run_row``, ``resolve_runs``, ``resolve_experiment``); SQLAlchemy core, bound parameters.
``set_run_status`` (defined in ``service.db.runs``) is importable from here too.

Every insert ignores rows already present (unique constraints), so recording the same
generation twice changes nothing: a coordinator killed after its commit but before it
noticed may safely record the generation again.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
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
    utcnow,
)
from softevo.service.db.runs import set_run_status
from sqlalchemy import Connection, Table, case, func, select, update
from sqlalchemy.dialects import postgresql, sqlite

from softevo.errors import UserError

__all__ = [
    "GenerationRecord",
    "NewRun",
    "NewTreatment",
    "count_rows",
    "create_experiment",
    "insert_ignore",
    "local_to_db_ids",
    "record_generation",
    "reopen_runs",
    "resolve_experiment",
    "resolve_runs",
    "run_row",
    "set_run_status",
]


@dataclass(frozen=True)
class NewRun:
    """A run to create: repetition index and seed."""

    repetition: int
    seed: int
    generations: int


@dataclass(frozen=True)
class NewTreatment:
    """A treatment to create: its name, JSON settings and runs."""

    name: str
    settings: dict[str, Any]
    runs: Sequence[NewRun]


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


def create_experiment(
    conn: Connection,
    name: str,
    treatments: Iterable[NewTreatment],
    preset: str | None = None,
    scale: str | None = None,
) -> tuple[int, list[int]]:
    """Insert an experiment, its treatments and pending runs; return (experiment id, run ids)."""
    experiment_id = conn.execute(
        Experiment.__table__.insert().values(name=name, preset=preset, scale=scale, created_at=utcnow())
    ).inserted_primary_key[0]
    run_ids: list[int] = []
    for treatment in treatments:
        treatment_id = conn.execute(
            Treatment.__table__.insert().values(
                experiment_id=experiment_id, name=treatment.name, settings=treatment.settings
            )
        ).inserted_primary_key[0]
        for run in treatment.runs:
            run_ids.append(_insert_run(conn, treatment_id, run))
    return experiment_id, run_ids


def _insert_run(conn: Connection, treatment_id: int, run: NewRun) -> int:
    now = utcnow()
    return conn.execute(
        Run.__table__.insert().values(
            treatment_id=treatment_id,
            repetition=run.repetition,
            seed=run.seed,
            status=RunStatus.PENDING.value,
            generation=-1,
            generations=run.generations,
            created_at=now,
            updated_at=now,
        )
    ).inserted_primary_key[0]


def local_to_db_ids(conn: Connection, run_id: int, local_ids: Iterable[int]) -> dict[int, int]:
    """Map the algorithm's local ids of a run to database ids (missing ones are left out)."""
    wanted = sorted(set(local_ids))
    if not wanted:
        return {}
    table = Individual.__table__
    rows = conn.execute(
        select(table.c.local_id, table.c.id).where(table.c.run_id == run_id, table.c.local_id.in_(wanted))
    )
    return {local: db_id for local, db_id in rows}


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
        Individual.__table__,
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
        Evaluation.__table__,
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
        PopulationMember.__table__,
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
    insert_ignore(conn, Generation.__table__, [_generation_row(record)])
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
    """Move the run's committed generation forward (never backward) and store the state.

    A run cancelled meanwhile (e.g. over HTTP, from another process) stays cancelled."""
    table = Run.__table__
    status = RunStatus.FINISHED if record.finished else RunStatus.RUNNING
    cancelled = RunStatus.CANCELLED.value
    conn.execute(
        update(table)
        .where(table.c.id == record.run_id, table.c.generation < record.generation)
        .values(
            generation=record.generation,
            algorithm_state=record.state,
            status=case((table.c.status == cancelled, cancelled), else_=status.value),
            updated_at=utcnow(),
        )
    )


def reopen_runs(conn: Connection, run_ids: Sequence[int]) -> None:
    """Make cancelled or failed runs among ``run_ids`` resumable (status running, no error)."""
    set_run_status(conn, run_ids, RunStatus.RUNNING, only_from=(RunStatus.CANCELLED, RunStatus.FAILED))


def run_row(conn: Connection, run_id: int) -> dict[str, Any]:
    """The run with its treatment and experiment names and settings, as a dict."""
    runs, treatments, experiments = Run.__table__, Treatment.__table__, Experiment.__table__
    row = (
        conn.execute(
            select(
                runs,
                treatments.c.name.label("treatment"),
                treatments.c.settings,
                treatments.c.experiment_id,
                experiments.c.name.label("experiment"),
            )
            .join(treatments, runs.c.treatment_id == treatments.c.id)
            .join(experiments, treatments.c.experiment_id == experiments.c.id)
            .where(runs.c.id == run_id)
        )
        .mappings()
        .first()
    )
    if row is None:
        raise UserError(f"no run {run_id}")
    return dict(row)


def resolve_runs(conn: Connection, reference: str | None) -> list[int]:
    """Run ids named by a CLI reference, in id order.

    ``None``: every run. ``5``, ``r5`` or ``run-5``: run 5. ``e2`` or ``exp-2``: the runs of
    experiment 2. ``latest``: the runs of the newest experiment. Anything else: the runs of
    the experiment(s) with that name.
    """
    runs, treatments, experiments = Run.__table__, Treatment.__table__, Experiment.__table__
    query = select(runs.c.id).join(treatments, runs.c.treatment_id == treatments.c.id)
    kind, number = _parse_reference(reference)
    if kind == "latest":
        kind, number = "experiment", conn.execute(select(func.max(experiments.c.id))).scalar()
    if kind == "run":
        query = query.where(runs.c.id == number)
    elif kind == "experiment":
        query = query.where(treatments.c.experiment_id == number)
    elif kind == "name":
        query = query.join(experiments, treatments.c.experiment_id == experiments.c.id).where(
            experiments.c.name == reference
        )
    ids = list(conn.execute(query.order_by(runs.c.id)).scalars())
    if not ids and reference is not None:
        raise UserError(f"no run or experiment {reference!r}")
    return ids


def _parse_reference(reference: str | None) -> tuple[str, int | None]:
    if reference is None:
        return "all", None
    text = reference.strip().lower()
    if text == "latest":
        return "latest", None
    for prefix, kind in (
        ("run-", "run"),
        ("r", "run"),
        ("exp-", "experiment"),
        ("e", "experiment"),
        ("", "run"),
    ):
        rest = text.removeprefix(prefix) if text.startswith(prefix) else None
        if rest is not None and rest.isdigit():
            return kind, int(rest)
    return "name", None


def resolve_experiment(conn: Connection, reference: str) -> int:
    """The experiment named by ``e2``, ``exp-2``, ``2``, ``latest`` or its name (the newest of
    that name); UserError if there is none."""
    experiments = Experiment.__table__
    kind, number = _parse_reference(reference)
    query = select(func.max(experiments.c.id))
    if kind in ("experiment", "run"):  # a bare number names an experiment here
        query = query.where(experiments.c.id == number)
    elif kind == "name":
        query = query.where(experiments.c.name == reference)
    found = conn.execute(query).scalar()
    if found is None:
        raise UserError(f"no experiment {reference!r}")
    return int(found)


def count_rows(conn: Connection, table: Table, run_id: int) -> int:
    """Number of rows of ``table`` belonging to run ``run_id`` (for tests and status)."""
    return conn.execute(select(func.count()).where(table.c.run_id == run_id)).scalar_one()
