"""Runs: summaries and details for the API, one run with its treatment (``run_row``), its
best individual per world (``best_per_world``), what a CLI reference names (the one
resolver: ``resolve_runs``, ``resolve_run``, ``resolve_individual``), the active ones, and
``set_run_status``, the one way a run's status changes (besides the generation commit in
``service.storage.generations.record_generation``, which keeps a cancelled run cancelled).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sqlalchemy import Connection, Table, func, select, update

from softevo.errors import UserError
from softevo.evolution.run_status import RunStatus
from softevo.service.storage.models import (
    EvaluationRow,
    ExperimentRow,
    IndividualRow,
    RunRow,
    TreatmentRow,
    utcnow,
)
from softevo.service.storage.rows import columns, dict_rows
from softevo.service.storage.run_tree import BIRTH, NODE_OBJECTIVES
from softevo.service.storage.status import run_summary_select, with_best_by_world

ACTIVE = (RunStatus.PENDING.value, RunStatus.RUNNING.value)


def set_run_status(
    conn: Connection,
    run_ids: int | Sequence[int],
    status: RunStatus,
    error: str | None = None,
    *,
    only_from: Sequence[RunStatus] | None = None,
) -> int:
    """Set the status (and error message, None for none) of run ``run_ids`` (one id or
    several); with ``only_from``, only of those runs whose status is one of these (e.g. a
    cancel touches only pending or running runs). Returns how many runs changed."""
    table = RunRow.__table__
    ids = [run_ids] if isinstance(run_ids, int) else list(run_ids)
    query = update(table).where(table.c.id.in_(ids))
    if only_from is not None:
        query = query.where(table.c.status.in_([RunStatus(s).value for s in only_from]))
    result = conn.execute(query.values(status=RunStatus(status).value, error=error, updated_at=utcnow()))
    return result.rowcount


def active_run_ids(conn: Connection, run_ids: Sequence[int] | None = None) -> list[int]:
    """Ids of pending or running runs (among ``run_ids`` if given), in id order."""
    table = RunRow.__table__
    query = select(table.c.id).where(table.c.status.in_(ACTIVE)).order_by(table.c.id)
    if run_ids is not None:
        query = query.where(table.c.id.in_(list(run_ids)))
    return list(conn.execute(query).scalars())


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
        query = query.where(TreatmentRow.__table__.c.experiment_id == experiment_id)
    if status is not None:
        query = query.where(RunRow.__table__.c.status == status)
    return with_best_by_world(conn, dict_rows(conn, query.limit(limit).offset(offset)))


def run_detail(conn: Connection, run_id: int) -> dict[str, Any] | None:
    """One run (schemas.RunOut) or None."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
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
    rows = dict_rows(conn, query)
    if not rows:
        return None
    row = rows[0]
    row["treatment"] = {"name": row.pop("treatment_name"), "settings": row.pop("settings")}
    row["best_per_world"] = best_per_world(conn, run_id)
    row["best"] = row["best_per_world"][-1] if row["best_per_world"] else None  # its last world's
    return row


def best_of_run(conn: Connection, run_id: int, environment: str | None = None) -> dict[str, Any] | None:
    """The evaluation with the greatest distance in the run (in ``environment`` if given;
    first stored on a tie)."""
    evaluations = EvaluationRow.__table__
    query = (
        select(*columns(evaluations, *BIRTH, *NODE_OBJECTIVES))
        .where(evaluations.c.run_id == run_id)
        .order_by(evaluations.c.distance.desc(), evaluations.c.id)
        .limit(1)
    )
    if environment is not None:
        query = query.where(evaluations.c.environment == environment)
    rows = dict_rows(conn, query)
    return rows[0] if rows else None


def best_per_world(conn: Connection, run_id: int) -> list[dict[str, Any]]:
    """The run's best evaluation (``best_of_run``) in each world it was evaluated in, the
    worlds in the order the run first met them (its last world last)."""
    evaluations = EvaluationRow.__table__
    worlds = conn.execute(
        select(evaluations.c.environment)
        .where(evaluations.c.run_id == run_id)
        .group_by(evaluations.c.environment)
        .order_by(func.min(evaluations.c.generation), func.min(evaluations.c.id))
    ).scalars()
    return [best_of_run(conn, run_id, world) for world in list(worlds)]


def run_status(conn: Connection, run_id: int) -> str | None:
    """The run's status, or None if there is no such run."""
    table = RunRow.__table__
    return conn.execute(select(table.c.status).where(table.c.id == run_id)).scalar()


def reopen_runs(conn: Connection, run_ids: Sequence[int]) -> None:
    """Make cancelled or failed runs among ``run_ids`` resumable (status running, no error)."""
    set_run_status(conn, run_ids, RunStatus.RUNNING, only_from=(RunStatus.CANCELLED, RunStatus.FAILED))


def run_row(conn: Connection, run_id: int) -> dict[str, Any]:
    """The run with its treatment and experiment names and settings, as a dict."""
    runs, treatments, experiments = RunRow.__table__, TreatmentRow.__table__, ExperimentRow.__table__
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
    runs, treatments, experiments = RunRow.__table__, TreatmentRow.__table__, ExperimentRow.__table__
    query = select(runs.c.id).join(treatments, runs.c.treatment_id == treatments.c.id)
    kind, number = parse_reference(reference)
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


def resolve_run(conn: Connection, reference: str) -> int:
    """The one run ``reference`` names (``resolve_runs``): a run (``5``, ``r5``, ``run-5``)
    or an experiment of one run (``latest``, ``e2``, a name; ``softevo run`` makes those);
    UserError if it names none or several."""
    run_ids = resolve_runs(conn, reference)
    if len(run_ids) != 1:
        shown = ", ".join(f"r{i}" for i in run_ids[:5]) + (", ..." if len(run_ids) > 5 else "")
        raise UserError(f"{reference!r} names {len(run_ids)} runs ({shown}); give one, e.g. r{run_ids[0]}")
    return run_ids[0]


def resolve_individual(conn: Connection, reference: str) -> int:
    """The individual ``reference`` names: an individual id (``12``), or any other reference
    to one run (``resolve_run``: ``latest``, ``r5``, ``e2``, a name) for its best individual
    in its last world (``best_per_world``); UserError if there is none."""
    text = reference.strip()
    if text.isdigit():
        individuals = IndividualRow.__table__
        if conn.execute(select(individuals.c.id).where(individuals.c.id == int(text))).first() is None:
            raise UserError(f"no individual {int(text)}")
        return int(text)
    run_id = resolve_run(conn, text)
    best = best_per_world(conn, run_id)
    if not best:
        raise UserError(f"run {run_id} ({reference!r}) has no evaluated individual yet")
    return int(best[-1]["individual_id"])


def parse_reference(reference: str | None) -> tuple[str, int | None]:
    """(kind, number) of a CLI reference: kind is all, latest, run, experiment or name."""
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


def count_rows(conn: Connection, table: Table, run_id: int) -> int:
    """Number of rows of ``table`` belonging to run ``run_id`` (for tests and status)."""
    return conn.execute(select(func.count()).where(table.c.run_id == run_id)).scalar_one()
