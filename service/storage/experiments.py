"""Experiments: creation with their treatments and pending runs (``create_experiment``),
``resolve_experiment`` (a CLI reference to an id), API listings with run progress,
existence and freshness checks, and ``read_experiment(engine, id) -> ExperimentFrames`` (the
rows ``service.reports.data.load_experiment`` hands to the analyses).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import pandas as pd
from sqlalchemy import Connection, Engine, and_, func, or_, select, text, update

from softevo.errors import UserError
from softevo.evolution.run_status import RunStatus
from softevo.evolution.treatments import Treatment
from softevo.service.storage.export import (
    evaluation_rows,
    individual_columns,
    runs_frame,
    with_registered_traits,
)
from softevo.service.storage.models import (
    EvaluationRow,
    ExperimentRow,
    GenerationRow,
    PopulationMemberRow,
    RunRow,
    TreatmentRow,
    utcnow,
)
from softevo.service.storage.rows import dict_rows
from softevo.service.storage.runs import parse_reference
from softevo.service.storage.status import run_summary_select, with_best_by_world

STATUS_PRECEDENCE = ("running", "pending", "failed", "cancelled", "finished")


# -- creation and lookup ----------------------------------------------------------------------


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


def create_experiment(
    conn: Connection,
    name: str,
    treatments: Iterable[NewTreatment],
    preset: str | None = None,
    scale: str | None = None,
) -> tuple[int, list[int]]:
    """Insert an experiment, its treatments and pending runs; return (experiment id, run ids)."""
    experiment_id = conn.execute(
        ExperimentRow.__table__.insert().values(name=name, preset=preset, scale=scale, created_at=utcnow())
    ).inserted_primary_key[0]
    run_ids: list[int] = []
    for treatment in treatments:
        treatment_id = conn.execute(
            TreatmentRow.__table__.insert().values(
                experiment_id=experiment_id, name=treatment.name, settings=treatment.settings
            )
        ).inserted_primary_key[0]
        for run in treatment.runs:
            run_ids.append(_insert_run(conn, treatment_id, run))
    return experiment_id, run_ids


BUDGET_LOCK = (0x50F8, 0)  # PostgreSQL advisory lock (class, key) of the budget check


def lock_new_experiments(conn: Connection) -> None:
    """Hold, until ``conn``'s transaction ends, the lock that new experiments take: two
    requests that each read the unfinished work (``unfinished_work``), find room under the
    server budget and insert would otherwise both pass before either inserts. PostgreSQL: a
    transaction advisory lock (``BUDGET_LOCK``). SQLite: the write lock, taken by an UPDATE
    that changes nothing (pysqlite begins a transaction at the first write, so the reads
    after it see every experiment committed before; another writer waits its
    ``busy_timeout``)."""
    if conn.dialect.name == "postgresql":
        conn.execute(text("SELECT pg_advisory_xact_lock(:lock_class, :key)"),
                     {"lock_class": BUDGET_LOCK[0], "key": BUDGET_LOCK[1]})
    elif conn.dialect.name == "sqlite":
        table = ExperimentRow.__table__
        conn.execute(update(table).where(table.c.id == -1).values(name=table.c.name))


def unfinished_work(conn: Connection) -> list[tuple[dict[str, Any], int]]:
    """(settings, generations left over its pending and running runs) of every treatment with
    such a run: what the server has still to do (``service.runs.submit.unfinished_cost``)."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    left = (
        select(
            runs.c.treatment_id,
            func.sum(runs.c.generations - runs.c.generation - 1).label("left"),
        )
        .where(runs.c.status.in_([RunStatus.PENDING.value, RunStatus.RUNNING.value]))
        .group_by(runs.c.treatment_id)
        .subquery()
    )
    query = select(treatments.c.settings, left.c.left).join(left, left.c.treatment_id == treatments.c.id)
    return [(dict(settings), max(0, int(generations))) for settings, generations in conn.execute(query)]


def _insert_run(conn: Connection, treatment_id: int, run: NewRun) -> int:
    now = utcnow()
    return conn.execute(
        RunRow.__table__.insert().values(
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


def resolve_experiment(conn: Connection, reference: str) -> int:
    """The experiment named by ``e2``, ``exp-2``, ``2``, ``latest`` or its name (the newest of
    that name); UserError if there is none, or for a run (``r5``, ``run-5``: the message names
    its experiment)."""
    experiments = ExperimentRow.__table__
    kind, number = parse_reference(reference)
    if kind == "run" and not reference.strip().isdigit():
        raise UserError(_not_an_experiment(conn, reference, number))
    query = select(func.max(experiments.c.id))
    if kind in ("experiment", "run"):  # a bare number names an experiment here
        query = query.where(experiments.c.id == number)
    elif kind == "name":
        query = query.where(experiments.c.name == reference)
    found = conn.execute(query).scalar()
    if found is None:
        raise UserError(f"no experiment {reference!r}")
    return int(found)


def _not_an_experiment(conn: Connection, reference: str, run_id: int) -> str:
    """Why ``reference`` (a run: ``r5``) names no experiment, with the run's experiment."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    query = select(treatments.c.experiment_id).join(runs, runs.c.treatment_id == treatments.c.id)
    experiment_id = conn.execute(query.where(runs.c.id == run_id)).scalar()
    if experiment_id is None:
        return (f"{reference!r} names a run, and there is no run {run_id}; give an experiment (e2, latest, "
                "a name)")
    return f"{reference!r} names a run, not an experiment; run {run_id} is in experiment e{experiment_id}"


# -- the REST API's listings ------------------------------------------------------------------


def experiment_status(statuses: Sequence[str]) -> str:
    """An experiment's status from its runs' (see schemas.ExperimentOut.status)."""
    for status in STATUS_PRECEDENCE:
        if status in statuses:
            return status
    return RunStatus.PENDING.value


RUNS_PAGE = 100  # runs listed per experiment unless asked otherwise (ExperimentOut.runs)


def list_experiments(
    conn: Connection,
    experiment_id: int | None = None,
    limit: int = 1000,
    offset: int = 0,
    runs_limit: int = RUNS_PAGE,
    runs_offset: int = 0,
    newest_first: bool = False,
) -> list[dict[str, Any]]:
    """Experiments (schemas.ExperimentOut), oldest first (or newest), each with its status,
    progress and ``runs_total`` over all its runs and the page ``runs_offset`` ..
    ``runs_offset + runs_limit`` of its runs (in id order): a listing's size is bounded
    whatever the experiments hold."""
    table = ExperimentRow.__table__
    query = select(table.c.id, table.c.name, table.c.preset, table.c.scale, table.c.created_at)
    if experiment_id is not None:
        query = query.where(table.c.id == experiment_id)
    order = table.c.id.desc() if newest_first else table.c.id
    experiments = dict_rows(conn, query.order_by(order).limit(limit).offset(offset))
    if not experiments:
        return []
    ids = [e["id"] for e in experiments]
    tallies = _run_tallies(conn, ids)
    runs_of: dict[int, list[dict[str, Any]]] = {}
    for run in _run_pages(conn, ids, runs_limit, runs_offset):
        runs_of.setdefault(run["experiment_id"], []).append(run)
    for experiment in experiments:
        tally = tallies.get(experiment["id"], {})
        done = sum(t["done"] for t in tally.values())
        total = sum(t["total"] for t in tally.values())
        experiment["runs"] = runs_of.get(experiment["id"], [])
        experiment["runs_total"] = sum(t["runs"] for t in tally.values())
        experiment["status"] = experiment_status(list(tally))
        experiment["progress"] = {
            "generations_done": done,
            "generations_total": total,
            "fraction": done / total if total else 0.0,
        }
    return experiments


def _run_tallies(conn: Connection, experiment_ids: list[int]) -> dict[int, dict[str, dict[str, int]]]:
    """experiment id -> run status -> {runs, done (generations stored), total (generations)}."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    query = (
        select(
            treatments.c.experiment_id,
            runs.c.status,
            func.count().label("runs"),
            func.sum(runs.c.generation + 1).label("done"),  # generation -1: none stored yet
            func.sum(runs.c.generations).label("total"),
        )
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id.in_(experiment_ids))
        .group_by(treatments.c.experiment_id, runs.c.status)
    )
    tallies: dict[int, dict[str, dict[str, int]]] = {}
    for row in dict_rows(conn, query):
        counts = {key: max(0, int(row[key] or 0)) for key in ("runs", "done", "total")}
        tallies.setdefault(row["experiment_id"], {})[row["status"]] = counts
    return tallies


def _run_pages(conn: Connection, experiment_ids: list[int], limit: int, offset: int) -> list[dict[str, Any]]:
    """Run summaries (``run_summary_select``) of the experiments, per experiment the ``limit``
    runs from its ``offset``-th in id order: one query, a window function over experiments."""
    if limit <= 0:
        return []
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    rank = func.row_number().over(partition_by=treatments.c.experiment_id, order_by=runs.c.id)
    ranked = (
        run_summary_select(id_label="id")
        .add_columns(rank.label("run_rank"))
        .where(treatments.c.experiment_id.in_(experiment_ids))
        .subquery()
    )
    columns = [column for column in ranked.c if column.name != "run_rank"]
    query = (
        select(*columns)
        .where(ranked.c.run_rank > offset, ranked.c.run_rank <= offset + limit)
        .order_by(ranked.c.id)
    )
    return with_best_by_world(conn, dict_rows(conn, query))


def experiment_exists(conn: Connection, experiment_id: int) -> bool:
    """Whether there is an experiment ``experiment_id``."""
    table = ExperimentRow.__table__
    return conn.execute(select(table.c.id).where(table.c.id == experiment_id)).first() is not None


def experiment_generations(conn: Connection, experiment_id: int) -> int:
    """Generations stored over all runs of the experiment."""
    generations, runs, treatments = GenerationRow.__table__, RunRow.__table__, TreatmentRow.__table__
    return conn.execute(
        select(func.count())
        .select_from(generations)
        .join(runs, generations.c.run_id == runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
    ).scalar_one()


def experiment_updated_at(conn: Connection, experiment_id: int):
    """When a run of the experiment last changed (None without runs)."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    return conn.execute(
        select(func.max(runs.c.updated_at))
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
    ).scalar()


# -- the analyses' input ----------------------------------------------------------------------


class ExperimentFrames(NamedTuple):
    """An experiment's rows as read (``analysis.data.experiment_data`` takes them in order)."""

    experiment: dict[str, Any]
    treatments: pd.DataFrame
    runs: pd.DataFrame
    summaries: pd.DataFrame
    members: pd.DataFrame
    evaluations: pd.DataFrame


def read_experiment(
    engine: Engine,
    experiment_id: int,
    generations: Iterable[int] = (),
    everything: bool = False,
    shown: Callable[[pd.DataFrame, pd.DataFrame], Iterable[int]] | None = None,
) -> ExperimentFrames:
    """Read experiment ``experiment_id`` (UserError if it does not exist or has no runs); see
    ``analysis.data`` for the frames. The populations are read at generation 0, at each
    run's last stored generation, at the generations ``shown(treatments, runs)`` gives (the
    analyses': ``service.reports.data.load_experiment``) and at ``generations``, with every
    evaluation of their members; ``everything``: every population and every evaluation (the
    rows ``softevo export`` writes)."""
    with engine.connect() as conn:
        experiment = _experiment_row(conn, experiment_id)
        treatments = _treatments_frame(conn, experiment_id)
        run_ids = _run_ids(conn, experiment_id)
        if not run_ids:
            raise UserError(f"experiment e{experiment_id} has no runs")
        runs = _with_last_generation(conn, runs_frame(conn, run_ids))
        wanted = None
        if not everything:
            chosen = shown(treatments, runs) if shown is not None else ()
            wanted = sorted({*chosen, *(int(g) for g in generations)})
        summaries = _generations_frame(conn, run_ids)
        members = _end_members(conn, run_ids, wanted)
        evaluations = _member_evaluations(conn, run_ids, wanted)
    return ExperimentFrames(experiment, treatments, runs, summaries, members, evaluations)


def _experiment_row(conn: Connection, experiment_id: int) -> dict[str, Any]:
    table = ExperimentRow.__table__
    row = conn.execute(select(table).where(table.c.id == experiment_id)).mappings().first()
    if row is None:
        raise UserError(f"no experiment e{experiment_id} (see `softevo status`)")
    return dict(row)


def _treatments_frame(conn: Connection, experiment_id: int) -> pd.DataFrame:
    table = TreatmentRow.__table__
    rows = conn.execute(
        select(table.c.name, table.c.settings)
        .where(table.c.experiment_id == experiment_id)
        .order_by(table.c.id)
    ).all()
    records = []
    for name, settings in rows:
        treatment = Treatment.from_settings(settings)
        record = treatment.to_settings()
        record["name"] = name
        record["switch_at"] = treatment.switch_generation()
        record["schedule"] = treatment.schedule_text()
        record["workspace"] = "x".join(str(n) for n in treatment.workspace)
        records.append(record)
    frame = pd.DataFrame.from_records(records)
    if not frame.empty:
        frame["switch_at"] = frame["switch_at"].astype("Int64")
    return frame


def _run_ids(conn: Connection, experiment_id: int) -> list[int]:
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    query = (
        select(runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
        .order_by(runs.c.id)
    )
    return [int(i) for i in conn.execute(query).scalars()]


def _with_last_generation(conn: Connection, runs: pd.DataFrame) -> pd.DataFrame:
    """``runs`` with each run's last stored ``generation`` and its ``error`` (why it failed)."""
    table = RunRow.__table__
    rows = conn.execute(
        select(table.c.id.label("run_id"), table.c.generation.label("generation"), table.c.error).where(
            table.c.id.in_([int(i) for i in runs["run_id"]])
        )
    ).all()
    last = pd.DataFrame(rows, columns=["run_id", "generation", "error"])
    return runs.merge(last, on="run_id", how="left")


def _end_member_filter(run_ids: list[int], wanted: list[int] | None):
    """WHERE clause: population rows of ``run_ids`` at a ``wanted`` generation or the run's
    last one (every generation when ``wanted`` is None)."""
    members, runs = PopulationMemberRow.__table__, RunRow.__table__
    if wanted is None:
        return members.c.run_id.in_(run_ids)
    return and_(
        members.c.run_id.in_(run_ids),
        or_(members.c.generation.in_(wanted), members.c.generation == runs.c.generation),
    )


def _end_members(conn: Connection, run_ids: list[int], wanted: list[int] | None) -> pd.DataFrame:
    """Population rows (run_id, generation, individual_id, front_rank) at the ``wanted``
    generations and the last stored generation of each run."""
    members, runs = PopulationMemberRow.__table__, RunRow.__table__
    columns = ["run_id", "generation", "individual_id", "front_rank"]
    result = conn.execute(
        select(*[members.c[name] for name in columns])
        .join(runs, members.c.run_id == runs.c.id)
        .where(_end_member_filter(run_ids, wanted))
        .order_by(members.c.run_id, members.c.generation, members.c.front_rank, members.c.individual_id)
    )
    return pd.DataFrame(result.fetchall(), columns=columns)


def evaluation_frequencies(engine: Engine, experiment_id: int) -> pd.DataFrame:
    """Every evaluation of the experiment's runs, two columns read: ``treatment`` (its name)
    and ``frequency`` (Hz): what the report counts the cap's cuts over (not only the
    members it loads)."""
    evaluations, runs, treatments = EvaluationRow.__table__, RunRow.__table__, TreatmentRow.__table__
    query = (
        select(treatments.c.name.label("treatment"), evaluations.c.frequency)
        .join(runs, evaluations.c.run_id == runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
    )
    with engine.connect() as conn:
        result = conn.execute(query)
        return pd.DataFrame(result.fetchall(), columns=["treatment", "frequency"])


def _member_evaluations(conn: Connection, run_ids: list[int], wanted: list[int] | None) -> pd.DataFrame:
    """Every evaluation of the individuals in ``_end_members`` (of every individual of the
    runs when ``wanted`` is None), with the export's individuals columns
    (``individual_columns()``) and ``objectives`` ({name: value} of the run's objectives)."""
    evaluations = EvaluationRow.__table__
    members, runs = PopulationMemberRow.__table__, RunRow.__table__
    if wanted is None:
        where = evaluations.c.run_id.in_(run_ids)
    else:
        where = evaluations.c.individual_id.in_(
            select(members.c.individual_id)
            .join(runs, members.c.run_id == runs.c.id)
            .where(_end_member_filter(run_ids, wanted))
        )
    result = conn.execute(evaluation_rows(where).add_columns(evaluations.c.objectives))
    frame = pd.DataFrame(result.fetchall(), columns=list(result.keys()))
    frame["parent_id"] = frame["parent_id"].astype("Int64")
    return with_registered_traits(frame)[[*individual_columns(), "objectives"]]


def _generations_frame(conn: Connection, run_ids: list[int]) -> pd.DataFrame:
    table = GenerationRow.__table__
    columns = [
        "run_id",
        "generation",
        "environment",
        "evaluations",
        "best_distance",
        "mean_distance",
        "front_size",
        "evaluation_seconds",
        "created_at",
    ]
    result = conn.execute(
        select(*[table.c[name] for name in columns])
        .where(table.c.run_id.in_(run_ids))
        .order_by(table.c.run_id, table.c.generation)
    )
    return pd.DataFrame(result.fetchall(), columns=columns)
